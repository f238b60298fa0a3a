"""The step's stages on their own (jaxdda/step/), on two- and three-body scenes, against
closed forms: the operators of a rigid body, K^-1 J^T p against dense matrices, the
contact frame of a disk over a floor, the prediction, impact rows, velocity jump, contact VI
and end of a disk striking a floor inside the step, cement rupture, the end state of a free
body."""
import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdda
from jaxdda.solver.fista_newton import Solution
from jaxdda.step import frame as frame_stage
from jaxdda.step.contact_vi import linearisation_point
from jaxdda.step.jump import held_clusters, impact_rows
from jaxdda.step.operators import apply_w, assemble, flexibility, respond
from jaxdda.step.predict import impact_instants, predict
from jaxdda.step.report import contact_report, step_info
from jaxdda.step.resolve import impacts_then_contacts, step_end
from jaxdda.step.rupture import rupture
from jaxdda.step.update import update

DT, RHO, R = 0.01, 2.0, 0.5


def _disks_on_floor(gap=0.004):
    """Two disks above a fixed floor (top face y = 0), the first ``gap`` above it, the
    second 0.002 m right of the first (both within the step's detection reach)."""
    sb = jaxdda.SceneBuilder(dt=DT, gravity=(0.0, -10.0))
    sb.add_polygon(vertices=[(-5.0, -1.0), (5.0, -1.0), (5.0, 0.0), (-5.0, 0.0)], density=1.0, fixed=True)
    sb.add_disk(center=(0.0, R + gap), radius=R, density=RHO, velocity=(0.3, -1.0), angular_velocity=2.0)
    sb.add_disk(center=(2 * R + 0.002, R + gap), radius=R, density=RHO)
    return sb.build()


@pytest.fixture(scope="module")
def scene():
    return _disks_on_floor()


@pytest.fixture(scope="module")
def staged(scene):
    def stages(model, state, params):
        model, ops = assemble(model, state, params)
        return model, ops, frame_stage.contact_frame(model, state, params)

    return jax.jit(stages)(scene.model, scene.state, scene.params)


def test_operators_of_a_rigid_disk(scene, staged):
    _, ops, _ = staged
    m = RHO * math.pi * R ** 2
    i = 0.5 * m * R ** 2
    unit = jnp.zeros((3, 6)).at[1, 0].set(1.0).at[1, 2].set(1.0)
    # K_eff^-1 of a rigid body is (2 M / dt^2)^-1 on its 3 dofs, M_imp^-1 = M^-1; a fixed body none.
    k_y = np.asarray(jaxdda.groups.apply(ops.k_inv, unit))[1]
    np.testing.assert_allclose(k_y[[0, 2]], [DT ** 2 / (2 * m), DT ** 2 / (2 * i)], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(jaxdda.groups.apply(ops.m_inv, unit))[1, [0, 2]], [1 / m, 1 / i], rtol=1e-12)
    assert np.all(np.asarray(jaxdda.groups.apply(ops.k_inv, unit))[0] == 0.0)
    np.testing.assert_allclose(np.asarray(ops.load)[1, :2], [0.0, -10.0 * m], rtol=1e-12)
    np.testing.assert_allclose(float(ops.momentum), max(m * 1.0 + 10.0 * m * DT, m * 0.3, i * 2.0), rtol=1e-12)


def test_respond_and_w_agree_with_dense_matrices(staged):
    _, ops, frame = staged
    c, jac = frame.contacts, frame.jac
    rng = np.random.default_rng(0)
    p = jnp.where(c.valid[:, None], jnp.asarray(rng.normal(size=frame.p0.shape)), 0.0)
    q = jnp.where(c.valid[:, None], jnp.asarray(rng.normal(size=frame.p0.shape)), 0.0)
    # dense: J (C*3, N*6) and K_eff^-1 (N*6, N*6), block-diagonal for independent bodies
    n = ops.vel.shape[0]
    dense_j = np.zeros((c.valid.shape[0] * 3, n * 6))
    for k in np.flatnonzero(np.asarray(c.valid)):
        for side, body in ((0, int(c.a[k])), (1, int(c.b[k]))):
            dense_j[3 * k:3 * k + 3, 6 * body:6 * body + 6] += np.asarray(jac[k, side])
    dense_k = np.zeros((n * 6, n * 6))
    for body in range(n):
        dense_k[6 * body:6 * body + 6, 6 * body:6 * body + 6] = np.asarray(ops.k_inv.single[body])
    expect = (dense_k @ dense_j.T @ np.asarray(p).ravel()).reshape(n, 6)
    np.testing.assert_allclose(np.asarray(respond(ops.k_inv, jac, c, p)), expect, rtol=1e-12, atol=1e-18)
    operand, diag = flexibility(jac, c, ops.k_inv)
    w = dense_j @ dense_k @ dense_j.T
    rows = np.repeat(np.asarray(c.valid), 3)  # padding rows are never read
    np.testing.assert_allclose(np.asarray(apply_w(operand, p)).ravel()[rows], (w @ np.asarray(p).ravel())[rows],
                               rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(np.asarray(diag).ravel()[rows], np.diag(w)[rows], rtol=1e-12, atol=1e-18)
    # W is symmetric: <q, W p> = <p, W q>
    np.testing.assert_allclose(float(jnp.sum(q * apply_w(operand, p))), float(jnp.sum(p * apply_w(operand, q))),
                               rtol=1e-12)


def test_w_diagonal_within_a_dof_group_is_that_of_w():
    # The bolted slope's blocks are one dof group, every contact within it: the diagonal of
    # W = J D J^T that the solver scales by (own blocks and the two sides' coupling) against
    # e^T W e from apply_w, which applies D through the group's own map.
    scene = jaxdda.examples.get("bolted-slope")

    def stages(model, state, params):
        model, ops = assemble(model, state, params)
        return ops, frame_stage.contact_frame(model, state, params)

    ops, frame = jax.jit(stages)(scene.model, scene.state, scene.params)
    c, valid = frame.contacts, np.flatnonzero(np.asarray(frame.contacts.valid))
    group = np.asarray(ops.k_inv.body_group)
    assert len(valid) and np.all(group[np.asarray(c.a)[valid]] == group[np.asarray(c.b)[valid]])
    assert np.all(group[np.asarray(c.a)[valid]] >= 0)
    operand, diag = flexibility(frame.jac, c, ops.k_inv)
    n = c.valid.shape[0]
    units = jnp.eye(3 * n).reshape(3 * n, n, 3)
    w = jax.vmap(lambda e: apply_w(operand, e))(units).reshape(3 * n, 3 * n)
    np.testing.assert_allclose(np.asarray(diag)[valid], np.diagonal(np.asarray(w)).reshape(n, 3)[valid], rtol=1e-13)


def test_contact_frame_of_disks_over_a_floor(scene, staged):
    _, _, frame = staged
    c = frame.contacts
    valid = np.flatnonzero(np.asarray(c.valid))
    pairs = {(int(c.a[k]), int(c.b[k])): k for k in valid}
    floor_row = next(k for (a, b), k in pairs.items() if {a, b} == {0, 1})
    disks_row = next(k for (a, b), k in pairs.items() if {a, b} == {1, 2})
    np.testing.assert_allclose(float(frame.gap0[floor_row]), 0.004, atol=1e-14)
    np.testing.assert_allclose(abs(float(frame.normal[floor_row, 1])), 1.0, atol=1e-14)
    np.testing.assert_allclose(float(frame.gap0[disks_row]), 0.002, atol=1e-14)
    np.testing.assert_allclose(abs(float(frame.normal[disks_row, 0])), 1.0, atol=1e-14)
    assert not np.asarray(frame.cemented).any()
    assert np.all(np.asarray(frame.p0) == 0.0)  # a first step remembers no force


def test_gap_change_is_exact_for_a_translation_and_a_turn(scene, staged):
    model, _, frame = staged
    d = jnp.zeros((3, 6)).at[1, 1].set(-0.07).at[1, 2].set(1.3)  # disk 1 down 0.07 m, turned (a disk: no change)
    change = frame_stage.gap_change_by(model, scene.state, frame.contacts, d)
    c = frame.contacts
    for k in np.flatnonzero(np.asarray(c.valid)):
        pair = {int(c.a[k]), int(c.b[k])}
        if pair == {0, 1}:
            np.testing.assert_allclose(float(change[k]), -0.07, atol=1e-14)
        if pair == {1, 2}:  # centres 1.002 apart across x, now 0.07 apart in y
            np.testing.assert_allclose(float(change[k]), math.hypot(1.002, 0.07) - 1.002, atol=1e-14)


def test_a_normal_force_has_no_moment_about_a_round_sides_centre():
    # Skewed frames, where the lever arm -r n is -r n only up to round-off: a disk's normal
    # row has no rotation entry at all, on side a (outside a line, a disk, a ring's hole) and
    # on side b (a disk, a ring's hole); a polygon vertex's keeps its lever.
    from jaxdda.contact.kinematics import gap_frame, jacobians
    from jaxdda.types import B_HOLE, B_LINE, B_POINT, Contacts

    k = 5
    zero2 = jnp.zeros((k, 2))
    vertex = jnp.zeros((k, 2)).at[4].set([0.3, -0.2])  # the last contact: a polygon's vertex
    edge_q, edge_e = zero2.at[0].set([-1.0, 0.1]), zero2.at[0].set([1.0, -0.25])
    c = Contacts(valid=jnp.ones(k, bool), a=jnp.array([0, 0, 0, 1, 3], jnp.int32),
                 b=jnp.array([1, 2, 2, 2, 1], jnp.int32), ra=jnp.array([0.37, 0.37, 0.37, 0.5, 0.0]),
                 pa=vertex, btype=jnp.array([B_LINE, B_POINT, B_HOLE, B_HOLE, B_LINE], jnp.int32),
                 rb=jnp.array([0.0, 0.8, 2.9, 2.9, 0.0]), qb=edge_q.at[4].set([-1.0, 0.1]),
                 eb=edge_e.at[4].set([1.0, -0.25]), key=jnp.arange(k, dtype=jnp.int64), edge=jnp.zeros(k, jnp.int32))
    centroid = jnp.array([[0.1234567, 0.987654], [0.3, -0.6], [1.1, 1.3], [0.2, 0.1]])
    rotation = jnp.array([0.3, 0.71, -0.4, 1.9])
    gap, normal, point = gap_frame(c, centroid, rotation)
    assert np.all(np.abs(np.asarray(normal)).min(-1) > 0.05)  # no axis-aligned normal
    jac = np.asarray(jacobians(c, normal, point, gap, centroid))  # (C, side, row, dof)
    assert np.all(jac[:4, 0, 0, 2] == 0.0)  # side a: a disk
    assert np.all(jac[1:4, 1, 0, 2] == 0.0)  # side b: a disk, a ring's hole
    assert jac[0, 1, 0, 2] != 0.0 and jac[4, 0, 0, 2] != 0.0  # an edge's body, a vertex's: a lever

@pytest.mark.smoke
def test_warm_start_takes_the_force_of_the_same_feature_pair():
    key = jnp.asarray([7, 3, -1])
    force = jnp.asarray([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [0.0, 0.0, 0.0]])
    got = frame_stage.warm_start(key, force, jnp.asarray([3, 9, 7]))
    np.testing.assert_array_equal(np.asarray(got), [[4.0, 5.0, 6.0], [0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])


def test_rupture_breaks_a_joint_that_still_opens_and_keeps_one_that_holds():
    scene = jaxdda.examples.get("paper-7.8")
    model, state, params = scene.model, scene.state, scene.params
    n_joints = model.joint_key.shape[0]
    cemented = jnp.asarray([True, True, False])
    joint = jnp.asarray([0, 1, 0])
    force = jnp.asarray([[-500.0, 0.0, 0.0], [-400.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    w_nn = jnp.full(3, 1e-6)
    # joint 0 opens by 1e-6 m at its full share (lacking 1 N), joint 1 stays closed
    integrity, tension = rupture(model, state, params, cemented, joint, force, jnp.asarray([1e-6, 0.0, 0.0]), w_nn,
                                 jnp.asarray(1.0))
    assert n_joints == 2
    np.testing.assert_array_equal(np.asarray(integrity), [0.0, 1.0])
    np.testing.assert_array_equal(np.asarray(tension), [500.0, 400.0])
    # a smoothed rupture of width 4 N keeps 1 - 1 / 4 of it (less the round-off allowance,
    # 10 tol times the largest force)
    smooth = dataclasses.replace(params, rupture_width=jnp.asarray(4.0))
    integrity, _ = rupture(model, state, smooth, cemented, joint, force, jnp.asarray([1e-6, 0.0, 0.0]), w_nn,
                           jnp.asarray(0.0))
    lacking = 1.0 - 10.0 * float(params.tol) * 500.0
    np.testing.assert_allclose(np.asarray(integrity), [1.0 - lacking / 4.0, 1.0], rtol=1e-12)


def test_update_turns_a_rigid_block_about_its_centroid_exactly():
    sb = jaxdda.SceneBuilder(dt=DT)
    sb.add_polygon(vertices=[(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (0.0, 1.0)], density=1.0)
    scene = sb.build()
    base, state, params = scene.model, scene.state, scene.params
    model, ops = assemble(base, state, params)
    d = jnp.zeros((1, 6)).at[0, :3].set(jnp.asarray([0.3, -0.2, 0.9]))
    v = jnp.zeros((1, 6)).at[0, :3].set(jnp.asarray([1.0, 2.0, 3.0]))
    new = update(base, model, state, params, ops, d, v, state.contact_key, state.contact_force,
                 state.joint_integrity)
    np.testing.assert_allclose(np.asarray(new.centroid[0]), np.asarray(state.centroid[0]) + [0.3, -0.2], atol=1e-14)
    np.testing.assert_allclose(float(new.rotation[0]), 0.9, atol=1e-15)
    np.testing.assert_allclose(np.asarray(new.stretch[0]), np.eye(2), atol=1e-14)  # rigid: no strain
    np.testing.assert_allclose(float(new.time), float(state.time) + DT, rtol=1e-15)
    np.testing.assert_array_equal(np.asarray(new.velocity), np.asarray(v))


def test_report_sums_the_parts_in_the_global_frame(staged):
    model, _, frame = staged
    c = frame.contacts
    p1 = jnp.zeros_like(frame.p0).at[:, 0].set(2.0).at[:, 1].set(1.0).at[:, 2].set(0.5)
    p2 = jnp.zeros_like(frame.p0).at[:, 0].set(3.0)
    up, right = jnp.zeros_like(frame.normal).at[:, 1].set(1.0), jnp.zeros_like(frame.normal).at[:, 0].set(1.0)
    report = contact_report(frame, frame.point, up, ((p1, up), (p2, right)))
    k = int(np.flatnonzero(np.asarray(c.valid))[0])
    # p1: normal 2 up, shear 1 along up turned clockwise (+x); p2: normal 3 along +x
    np.testing.assert_allclose(np.asarray(report.force[k]), [1.0 + 3.0, 2.0], atol=1e-15)
    assert float(report.bearing[k]) == 5.0 and float(report.moment[k]) == 0.5
    assert np.all(np.asarray(report.force)[~np.asarray(c.valid)] == 0.0)
    sol = Solution(jnp.zeros(()), jnp.asarray(3, jnp.int32), jnp.asarray(1e-9), jnp.asarray(True))
    stacked = Solution(jnp.zeros(2), jnp.asarray([4, 5], jnp.int32), jnp.asarray([1e-12, 1e-7]),
                       jnp.asarray([True, False]))
    info = step_info(model, frame, (sol, stacked), jnp.zeros(0), jnp.zeros(0), jnp.zeros((0, 4)), report)
    assert int(info.iterations) == 12 and float(info.residual) == 1e-7 and not bool(info.converged)
    assert int(info.n_contacts) == int(np.sum(np.asarray(c.valid)))


# -- predict, impacts, contact VI and end: a disk striking a floor inside the step --------
E, V0, H0 = 0.5, 1.0, 0.004  # restitution, speed down, start gap
T_STAR = (-V0 + math.sqrt(V0 ** 2 + 2 * 10.0 * H0)) / 10.0  # H0 = V0 t + 5 t^2


@pytest.fixture(scope="module")
def striking():
    sb = jaxdda.SceneBuilder(dt=DT, gravity=(0.0, -10.0))
    sb.add_material("bouncy", restitution=E)
    sb.add_polygon(vertices=[(-5.0, -1.0), (5.0, -1.0), (5.0, 0.0), (-5.0, 0.0)], density=1.0, fixed=True,
                   material="bouncy")
    sb.add_disk(center=(0.0, R + H0), radius=R, density=RHO, velocity=(0.0, -V0), material="bouncy")
    scene = sb.build()

    def stages(model, state, params):
        model, ops = assemble(model, state, params)
        frame = frame_stage.contact_frame(model, state, params)
        pred = predict(model, state, params, ops, frame)
        rows = impact_rows(model, state, params, ops, frame, pred)
        solved = impacts_then_contacts(model, state, params, ops, frame, pred, rows)
        return frame, pred, rows, solved, step_end(model, params, ops, frame, rows, solved)

    out = jax.jit(stages)(scene.model, scene.state, scene.params)
    row = int(np.flatnonzero(np.asarray(out[0].contacts.valid))[0])
    assert int(np.sum(np.asarray(out[0].contacts.valid))) == 1
    return scene, row, out


def test_predict_times_the_impact_on_the_free_path(striking):
    _, k, (_, pred, _, _, _) = striking
    np.testing.assert_allclose(float(pred.t_row[k]), T_STAR, rtol=1e-10)
    assert bool(pred.isolated[k]) and bool(pred.engaged[k]) and not bool(pred.loaded[k])
    np.testing.assert_allclose(np.asarray(pred.accel)[1, :3], [0.0, -10.0, 0.0], atol=1e-12)


def test_the_impact_time_is_differentiated_at_its_root(striking):
    # t* solves H0 + h = (V0 + v) t + 5 t^2: by the implicit function theorem
    # dt*/dh = 1 / (V0 + 10 t*) and dt*/dv = -t* / (V0 + 10 t*), the refit loop unseen.
    scene, k, _ = striking

    def t_star(v, h):
        state = scene.state.replace(velocity=scene.state.velocity.at[1, 1].add(-v),
                                    displacement=scene.state.displacement.at[1, 1].add(h))
        model, ops = assemble(scene.model, state, scene.params)
        frame = frame_stage.contact_frame(model, state, scene.params)
        return predict(model, state, scene.params, ops, frame).t_row[k]

    rates = jax.jit(jax.jacfwd(t_star, argnums=(0, 1)))(0.0, 0.0)
    speed = V0 + 10.0 * T_STAR
    np.testing.assert_allclose([float(r) for r in rates], [-T_STAR / speed, 1.0 / speed], rtol=1e-10)


def test_impact_rows_read_the_velocity_at_the_instant(striking):
    _, k, (_, _, rows, _, _) = striking
    np.testing.assert_allclose(float(rows.v_minus[k, 0]), -(V0 + 10.0 * T_STAR), rtol=1e-10)
    assert bool(rows.struck[k])


def test_velocity_jump_is_newtons_law_at_the_instant(striking):
    _, k, (_, _, _, solved, _) = striking
    jump = solved.jump
    kick = (1.0 + E) * (V0 + 10.0 * T_STAR)  # v+ = -e v- at t*, carried back to the start
    np.testing.assert_allclose(np.asarray(jump.v_star)[1, :3], [0.0, -V0 + kick, 0.0], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.asarray(jump.shift)[1, :3], [0.0, -kick * T_STAR, 0.0], rtol=1e-10, atol=1e-15)
    assert bool(jump.win.windowed[k])
    np.testing.assert_allclose(float(jump.win.t_win[k]), T_STAR, rtol=1e-10)


def test_step_end_is_the_exact_bounce_and_the_contact_opens(striking):
    _, k, (_, _, _, _, res) = striking
    up, h = E * (V0 + 10.0 * T_STAR), DT - T_STAR
    np.testing.assert_allclose(np.asarray(res.displacement)[1, :3], [0.0, -H0 + up * h - 5.0 * h ** 2, 0.0],
                               rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(np.asarray(res.velocity)[1, :3], [0.0, up - 10.0 * h, 0.0], rtol=1e-10, atol=1e-12)
    assert float(res.force[k, 0]) == 0.0 and float(res.gap_end[k]) > 0.0


def test_linearisation_point_cuts_each_body_at_its_first_overlap(striking):
    scene, k, (frame, _, _, _, _) = striking
    c = frame.contacts
    d_pred = jnp.zeros((2, 6)).at[1, 1].set(-5.0 * H0)
    # the predictor overlaps the floor by 4 H0 (> d0): cut to where the gap closes
    change = jnp.where(c.valid, -5.0 * H0, 0.0)
    cut = linearisation_point(scene.model, scene.params, c, frame.gap0, d_pred, change)
    np.testing.assert_allclose(np.asarray(cut)[1, 1], -float(frame.gap0[k]), rtol=1e-12)
    np.testing.assert_allclose(float(frame.gap0[k]), H0, rtol=1e-12)
    # one that does not overlap by more than d0 is kept
    kept = linearisation_point(scene.model, scene.params, c, frame.gap0, d_pred, jnp.where(c.valid, -H0, 0.0))
    np.testing.assert_array_equal(np.asarray(kept), np.asarray(d_pred))


def test_a_loaded_cluster_reads_its_rows_at_0_and_jumps_at_its_impact():
    # A body 1 resting on a fixed floor 0 (a sustained contact) is struck by body 2 at t*:
    # its impact rows are read at 0 (Moreau), its velocities jump at t*, in one cluster.
    from types import SimpleNamespace
    model = SimpleNamespace(n_bodies=3, fixed=jnp.array([True, False, False]))
    c = SimpleNamespace(a=jnp.array([1, 2]), b=jnp.array([0, 1]))
    t_row, t_jump, label = impact_instants(model, c, engaged=jnp.array([True, True]),
                                           loaded=jnp.array([True, False]), striking=jnp.array([False, True]),
                                           t_own=jnp.array([jnp.inf, 0.004]))
    np.testing.assert_array_equal(np.asarray(t_row), [0.0, 0.0])
    np.testing.assert_array_equal(np.asarray(t_jump), [0.004, 0.004])
    assert label[0] == label[1] < 3


@pytest.mark.parametrize("approach, held", [(0.0, False), (2.5e-11, False), (1e-9, False), (1e-7, True),
                                             (0.5, True)])
def test_a_cluster_is_held_where_its_support_approaches_beyond_round_off(approach, held):
    # Rows 0, 1 form one cluster: a sustained contact approaching at ``approach`` and the
    # struck row, whose gap rate the impact changes by 1 m/s; row 2, another cluster, no
    # impact. An approach below sqrt(eps) of the change (1.5e-8 m/s) is round-off (a
    # resting contact under Newmark, 2.5e-11 m/s) and holds nothing; above it, it holds.
    got = held_clusters(jnp.array([approach, 0.0, 0.0]), jnp.array([0.0, -1.0, 0.0]), jnp.array([1, 1, 3]), 3)
    np.testing.assert_array_equal(np.asarray(got), [held, held, False])
