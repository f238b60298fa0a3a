"""Blocks meshed into 3-node triangles (paper 6.1) against closed forms and invariants.

One static scene holds three independent meshed blocks (one compilation):
* a column (nu = 0) held at its base and loaded on top: the exact uniaxial answer;
* a block resting on a frictionless floor under gravity: the virial identity
  sum A sigma = integral of x (x) body force, exact for any mesh at equilibrium;
* a block hanging from a spring at one node: the spring stretches m g / k.
A free meshed block spinning in space checks momentum, a conforming mesh and no false
growth under finite rotation. Case 7.9 has its own module (tests/paper)."""
import numpy as np
import pytest

import jaxdda
from jaxdda.errors import SceneError
from jaxdda.scene.mesh import rectangle_mesh

G = 9.81
RHO = 2000.0
E = 1e9
COLUMN = dict(W=1.0, H=2.0, F=-1e3, at=(0.0, 0.0))
BLOCK = dict(W=1.0, H=0.5, at=(3.0, 0.0))
HANGING = dict(W=0.6, H=0.4, k=2e8, at=(6.0, 0.0))


def _corner_nodes(nodes, x, y):
    return np.flatnonzero(np.isclose(nodes[:, 0], x) & np.isclose(nodes[:, 1], y))


@pytest.fixture(scope="module")
def static():
    # Static analysis: each step removes all but ~2M/dt^2 / (K + 2M/dt^2) < 1e-3 of the error.
    sb = jaxdda.SceneBuilder(dt=0.1, gravity=(0.0, -G), dynamic=0.0)
    # Column: nu = 0, no weight, fixed base nodes, consistent nodal loads of F on top.
    x0, y0 = COLUMN["at"]
    nodes, tris = rectangle_mesh(x0, y0, x0 + COLUMN["W"], y0 + COLUMN["H"], 2, 4)
    column = sb.add_mesh(nodes, tris, RHO, E, 0.0, gravity=False, fixed_nodes=np.flatnonzero(nodes[:, 1] == y0))
    top = np.flatnonzero(nodes[:, 1] == y0 + COLUMN["H"])
    for k in top:
        end = nodes[k, 0] in (x0, x0 + COLUMN["W"])
        sb.add_load(int(column.holder[k]), (0.0, COLUMN["F"] * (0.25 if end else 0.5)), at=nodes[k])
    # Block on a fixed frictionless floor (nu = 0.3, plane strain; the built-in mesher).
    x0, y0 = BLOCK["at"]
    block = sb.add_meshed_polygon([(x0, y0), (x0 + BLOCK["W"], y0), (x0 + BLOCK["W"], y0 + BLOCK["H"]),
                                   (x0, y0 + BLOCK["H"])], RHO, E, 0.3, max_edge=0.3, plane="strain")
    sb.add_polygon([(x0 - 0.5, y0 - 0.5), (x0 + 1.5, y0 - 0.5), (x0 + 1.5, y0), (x0 - 0.5, y0)], RHO, fixed=True)
    # Block hanging from a spring at its top middle node (a mesh symmetric about that node).
    x0, y0 = HANGING["at"]
    w, h = HANGING["W"], HANGING["H"]
    nodes, tris = rectangle_mesh(x0, y0, x0 + w, y0 + h, 2, 2)
    hang = sb.add_mesh(nodes, tris, RHO, E, 0.25)
    anchor = sb.add_polygon([(x0, y0 + h + 1.0), (x0 + w, y0 + h + 1.0), (x0 + w, y0 + h + 1.5), (x0, y0 + h + 1.5)],
                            RHO, fixed=True)
    node = int(_corner_nodes(hang.nodes, x0 + w / 2, y0 + h)[0])
    sb.add_spring(anchor, int(hang.holder[node]), (x0 + w / 2, y0 + h + 1.0), hang.nodes[node], HANGING["k"])
    scene = sb.build()
    return scene, jaxdda.simulate(scene, 16), dict(column=column, block=block, hang=hang, hang_node=node)


def test_column_under_end_load_is_the_uniaxial_closed_form(static):
    scene, run, meshes = static
    column = meshes["column"]
    W, H, F = COLUMN["W"], COLUMN["H"], COLUMN["F"]
    disp = run.mesh_nodes(column)[-1] - column.nodes
    y = column.nodes[:, 1] - COLUMN["at"][1]
    # v(y) = F y / (E W), u = 0 (nu = 0: no lateral strain), sigma_y = F / W everywhere.
    np.testing.assert_allclose(disp[:, 1], F * y / (E * W), rtol=0, atol=1e-9 * abs(F) * H / (E * W))
    np.testing.assert_allclose(disp[:, 0], 0.0, atol=1e-9 * abs(F) * H / (E * W))
    stress = run.stress[-1, list(column.bodies)]
    np.testing.assert_allclose(stress[:, 1], F / W, rtol=1e-9)
    np.testing.assert_allclose(stress[:, [0, 2]], 0.0, atol=1e-9 * abs(F / W))


def test_block_on_a_floor_satisfies_the_virial_identity(static):
    """At equilibrium, sum_e A_e sigma_e = sum of x (x) f over the loads: with the floor's
    reactions at y = 0, integral sigma_y dA = -rho g W H^2 / 2 and the other two vanish. It
    holds exactly for the finite element field (y e_y is a virtual displacement of it);
    the geometry moved by the strain rho g H / E is the only error."""
    scene, run, meshes = static
    block = meshes["block"]
    bodies = list(block.bodies)
    area = np.asarray(scene.model.area)[bodies]
    total = (area[:, None] * run.stress[-1, bodies]).sum(0)
    W, H = BLOCK["W"], BLOCK["H"]
    weight_moment = RHO * G * W * H ** 2 / 2
    strain = RHO * G * H / E
    np.testing.assert_allclose(total[1], -weight_moment, rtol=strain)
    np.testing.assert_allclose(total[[0, 2]], 0.0, atol=strain * weight_moment)
    assert run.info.converged.all()
    assert run.info.max_penetration.max() < 1e-9


def test_block_hanging_on_a_spring_stretches_it_by_its_weight(static):
    scene, run, meshes = static
    hang, node = meshes["hang"], meshes["hang_node"]
    weight = RHO * G * float(np.asarray(scene.model.area)[list(hang.bodies)].sum())
    drop = run.mesh_nodes(hang)[-1, node] - hang.nodes[node]
    np.testing.assert_allclose(drop[1], -weight / HANGING["k"], rtol=1e-9)
    # Sideways the block is held only by the spring's geometric stiffness (weight / length,
    # 1e-5 of k), which a static analysis converges slowly: it stays put to 1e-6 of the drop.
    assert abs(drop[0]) < 1e-6 * weight / HANGING["k"]
    np.testing.assert_allclose(run.connector_force[-1, 0, 0], weight, rtol=1e-9)


def test_mesh_stays_conforming(static):
    """Every element that holds a node puts it at the same place."""
    scene, run, meshes = static
    verts = run.vertices()[-1]
    for mesh in meshes.values():
        if not hasattr(mesh, "triangles"):
            continue
        where = {}
        for element, body in enumerate(mesh.bodies):
            for j, node in enumerate(mesh.triangles[element]):
                where.setdefault(int(node), []).append(verts[body, j])
        spread = max(np.ptp(np.array(p), axis=0).max() for p in where.values())
        assert spread < 1e-13


def test_spinning_meshed_block_moves_as_a_rigid_body():
    """A free meshed block thrown with v and spun at omega (no gravity): its centre of mass
    moves at v (to round-off), its area stays within the centrifugal strain rho omega^2
    R^2 / E (a linear field turned by 4 rad without the mesh's co-rotation would grow by
    sum (omega dt)^2 / 2 = 2e-2), and its nodes stay within that strain of the rigid motion."""
    v, omega, dt, steps = np.array([1.0, 0.5]), 2.0, 0.005, 400
    sb = jaxdda.SceneBuilder(dt=dt, gravity=(0.0, 0.0))
    nodes, tris = rectangle_mesh(-0.5, -0.25, 0.5, 0.25, 4, 2)
    mesh = sb.add_mesh(nodes, tris, RHO, E, 0.25, velocity=v, angular_velocity=omega)
    scene = sb.build()
    run = jaxdda.simulate(scene, steps)
    t = run.time
    mass = np.asarray(scene.model.area)
    centre = (mass[:, None] * run.centroid).sum(1) / mass.sum()
    np.testing.assert_allclose(centre, v * t[:, None], rtol=0, atol=1e-12)
    pos = run.mesh_nodes(mesh)
    a, b = pos[:, tris[:, 1]] - pos[:, tris[:, 0]], pos[:, tris[:, 2]] - pos[:, tris[:, 0]]
    area = 0.5 * (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]).sum(-1)
    radius = np.linalg.norm(nodes, axis=1).max()
    strain = RHO * omega ** 2 * radius ** 2 / E
    assert np.abs(area / area[0] - 1.0).max() < 2 * strain
    assert run.info.converged.all()


def test_meshed_block_carrying_a_block_slides_down_an_incline():
    """A meshed block on a 30 degree incline (mu = 0.3), with a rigid block resting on it
    (mu = 0.9 between them, so it rides along): both slide at g (sin a - mu cos a) from
    rest. Gravity is tilted instead of the incline. Contacts act on the mesh's nodes both
    ways (its nodes on the incline, the rigid block's corners on its top edges); the only
    error is the elastic deformation, of size (rho g H / E) H with H = 0.8 m the stack."""
    angle, mu, steps, dt = np.radians(30.0), 0.3, 150, 0.002
    sb = jaxdda.SceneBuilder(dt=dt, gravity=(G * np.sin(angle), -G * np.cos(angle)))
    sb.add_material("rock", friction=mu, restitution=0.0)
    sb.add_material("grip", friction=0.9, restitution=0.0)
    sb.set_interface("rock", "grip", friction=0.9)
    sb.add_polygon([(-1.0, -0.5), (6.0, -0.5), (6.0, 0.0), (-1.0, 0.0)], RHO, fixed=True, material="rock")
    nodes, tris = rectangle_mesh(0.0, 0.0, 1.0, 0.5, 4, 2)
    mesh = sb.add_mesh(nodes, tris, RHO, 1e10, 0.25, material="rock")
    rider = sb.add_polygon([(0.3, 0.5), (0.7, 0.5), (0.7, 0.8), (0.3, 0.8)], RHO, material="grip")
    scene = sb.build()
    run = jaxdda.simulate(scene, steps)
    elements = list(mesh.bodies)
    mass = np.asarray(scene.model.area)[elements]
    centre = (mass[:, None] * run.centroid[:, elements]).sum(1) / mass.sum()
    slid = 0.5 * G * (np.sin(angle) - mu * np.cos(angle)) * run.time ** 2
    deformation = RHO * G * 0.8 ** 2 / 1e10
    np.testing.assert_allclose(centre[:, 0] - centre[0, 0], slid, rtol=0, atol=deformation)
    np.testing.assert_allclose(run.centroid[:, rider, 0] - run.centroid[0, rider, 0], slid, rtol=0, atol=deformation)
    assert run.info.max_penetration.max() < 1e-9
    assert run.info.converged.all()


def test_gradient_through_a_meshed_block_is_the_closed_form():
    """Forward mode (as calibration's Levenberg-Marquardt uses) through a static run of a one-cell column (two elements, top nodes
    loaded by F / 2 each): the top displacement is F H / (E W), so d/dE = -F H / (E^2 W);
    element 0 holds the two fixed base nodes and one top node, so its centroid moves by a
    third of that."""
    import dataclasses

    import jax
    import jax.numpy as jnp

    W, H, F = 1.0, 2.0, -1e3
    sb = jaxdda.SceneBuilder(dt=0.1, gravity=(0.0, 0.0), dynamic=0.0)
    nodes, tris = rectangle_mesh(0.0, 0.0, W, H, 1, 1)
    mesh = sb.add_mesh(nodes, tris, 1.0, E, 0.0, fixed_nodes=[0, 1])
    for k in (2, 3):
        sb.add_load(int(mesh.holder[k]), (0.0, F / 2), at=nodes[k])
    scene = sb.build()
    assert sorted(tris[0].tolist())[:2] == [0, 1]

    def centroid_drop(young):
        params = dataclasses.replace(scene.params, young=jnp.full_like(scene.params.young, young))
        end, _ = jaxdda.rollout(scene.model, scene.state, params, 4)
        return end.displacement[0, 1]

    value, grad = jax.jvp(centroid_drop, (E,), (1.0,))
    np.testing.assert_allclose(value, F * H / (E * W) / 3, rtol=1e-9)
    np.testing.assert_allclose(grad, -F * H / (E ** 2 * W) / 3, rtol=1e-9)


@pytest.mark.smoke
def test_bad_meshes_name_the_triangle_or_node():
    nodes = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    cases = [
        ([(0, 2, 1)], "triangle 0 [0, 2, 1] is inverted"),
        ([(0, 1, 2), (0, 1, 1)], "triangle 1 [0, 1, 1] repeats a node"),
        ([(0, 1, 5)], "triangle 0 [0, 1, 5] names a node outside 0..3"),
        ([(0, 1, 2)], "node 3 belongs to no triangle"),
    ]
    for triangles, message in cases:
        sb = jaxdda.SceneBuilder(dt=0.01)
        with pytest.raises(SceneError, match=r"mesh 0: " + message.replace("[", r"\[").replace("]", r"\]")):
            sb.add_mesh(nodes, triangles, RHO, E)
    flat = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)]
    with pytest.raises(SceneError, match="mesh 0: triangle 0 .* degenerate"):
        jaxdda.SceneBuilder(dt=0.01).add_mesh(flat, [(0, 1, 2)], RHO, E)
    square = [(0, 1, 2), (0, 2, 3)]
    for kwargs, message in [(dict(density=-1.0), "mesh 0: field 'density'"), (dict(young=0.0), "mesh 0: field 'young'"),
                            (dict(fixed_nodes=[7]), "mesh 0: field 'fixed_nodes' names node 7"),
                            (dict(poisson=0.5), r"element 0 of mesh 0\): field 'poisson'"),
                            (dict(fixed_nodes=[0], velocity=(1.0, 0.0)), "mesh 0: a block with fixed nodes")]:
        args = dict(density=RHO, young=E) | kwargs
        with pytest.raises(SceneError, match=message):
            jaxdda.SceneBuilder(dt=0.01).add_mesh(nodes, square, **args)
    sb = jaxdda.SceneBuilder(dt=0.01)
    sb.add_mesh(nodes, square, RHO, E)
    sb.add_disk((0.5, 0.5), 0.2, RHO)
    with pytest.raises(SceneError, match=r"body \d \(element \d of mesh 0\) and body 2 \(disk\) interpenetrate"):
        sb.build()
