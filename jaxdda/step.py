"""One PB-DDA time step and its rollout (the pipeline of paper Section 4).

    state --detect--> contacts --impacts--> v* --contact VI--> p --integrate--> state'
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from jaxdda.bodies.mass import external_load, inverse_on_subspace, mass_matrix
from jaxdda.contact.detect import detect
from jaxdda.contact.kinematics import (apply_jacobian, apply_jacobian_t, clockwise, gap_change, gap_frame,
                                       jacobians)
from jaxdda.integrate import free_displacement, impact_time, matvec, newmark_velocity
from jaxdda.solver import pc
from jaxdda.types import ContactReport, Contacts, Model, Params, State, StepInfo


def _warm_start(prev_key: jax.Array, prev_force: jax.Array, key: jax.Array, valid: jax.Array) -> jax.Array:
    """Last step's force of the same feature pair, else zero (sort + binary search)."""
    order = jnp.argsort(prev_key)
    sorted_key = prev_key[order]
    pos = jnp.clip(jnp.searchsorted(sorted_key, key), 0, key.shape[0] - 1)
    match = valid & (sorted_key[pos] == key)
    return jnp.where(match[:, None], prev_force[order[pos]], 0.0)


def _flexibility(jac: jax.Array, c: Contacts, inv: jax.Array, n_bodies: int):
    """W = J inv J^T as a function, and its diagonal (C, 2)."""
    def apply_w(p):
        return apply_jacobian(jac, c, matvec(inv, apply_jacobian_t(jac, c, p, n_bodies)))

    diag = (jnp.einsum("cij,cjk,cik->ci", jac[:, 0], inv[c.a], jac[:, 0])
            + jnp.einsum("cij,cjk,cik->ci", jac[:, 1], inv[c.b], jac[:, 1]))
    return apply_w, diag


def detection_reach(model: Model, state: State, params: Params) -> tuple[jax.Array, jax.Array]:
    """Per body: the distance (N,) it may travel this step plus half the margin d0, and
    the angle (N,) it may turn.

    Twice the velocity terms: an impact may reverse a body, and a pair is checked with
    the sum of its two reaches, so impacts falling anywhere inside the step are found.
    """
    spin = jnp.abs(state.velocity[:, 2])
    speed = jnp.linalg.norm(state.velocity[:, :2], axis=-1) + spin * model.bound_radius
    accel = jnp.linalg.norm(params.gravity) * model.gravity_scale
    reach = 2.0 * params.dt * speed + params.dt ** 2 * accel + 0.5 * params.margin
    turn = 2.0 * params.dt * spin
    return jnp.where(model.fixed, 0.5 * params.margin, reach), jnp.where(model.fixed, 0.0, turn)


def step(model: Model, state: State, params: Params) -> tuple[State, StepInfo]:
    """Advance one step of length params.dt. Pure: jit, vmap and scan apply."""
    n, dt = model.n_bodies, params.dt
    proj = model.dof_projector
    mass = mass_matrix(model, params)
    m_inv = inverse_on_subspace(mass, proj)
    k_inv = inverse_on_subspace(2.0 * mass / dt ** 2, proj)  # rigid: K = 0
    load = external_load(model, params)
    vel = matvec(proj, state.velocity)

    contacts, needed = detect(model, state.centroid, state.rotation, *detection_reach(model, state, params))
    c = contacts
    centroid = state.centroid
    gap_now, normal, point = gap_frame(c, centroid, state.rotation)
    jac = jacobians(c, normal, point, gap_now, centroid)
    # Gaps as (gap at the origin) + (exact change over the displacement since): a body
    # at 50 m that moved 1e-13 m keeps its gaps exact, not rounded to ulp(50 m).
    origin, no_turn = state.origin, jnp.zeros_like(state.rotation)
    gap_ref = gap_frame(c, origin, no_turn)[0]

    def gap_at(shift, turn):
        return gap_ref + gap_change(c, origin, no_turn, state.displacement + shift, state.rotation + turn)

    gap0 = gap_at(jnp.zeros_like(centroid), no_turn)
    mat_a, mat_b = model.material[c.a], model.material[c.b]
    mu = params.friction[mat_a, mat_b]
    restitution = params.restitution[mat_a, mat_b]

    # Force scale of the scene this step: residuals far below it are round-off.
    momentum = jnp.max(jnp.abs(matvec(mass, vel)) + jnp.abs(load) * dt, initial=0.0)

    # 1. Impacts: Newton's law at the impact time t*, impulses P (velocity level).
    # A contact that carried force last step is sustained, not struck: it is closed (its
    # gap, however small, is not a free fall to an impact), it takes part in the impact
    # solve (so impulses pass through a resting stack) and it does not bounce.
    p0 = _warm_start(state.contact_key, state.contact_force, c.key, c.valid)
    sustained = p0[:, 0] > 0
    accel = 2.0 * (free_displacement(k_inv, mass, load, vel, dt) - vel * dt) / dt ** 2
    v_rel, a_rel = apply_jacobian(jac, c, vel), apply_jacobian(jac, c, accel)
    t_hit, hits = impact_time(gap0, v_rel[:, 0], a_rel[:, 0], dt)
    t_hit = jnp.where(hits & ~sustained, t_hit, 0.0)
    v_hit = v_rel + a_rel * t_hit[:, None]
    impacting = c.valid & ((hits & (v_hit[:, 0] < 0)) | sustained)
    bounce = jnp.where(sustained, 0.0, restitution)
    b_imp = jnp.stack([(1.0 + bounce) * v_hit[:, 0], v_hit[:, 1]], -1)
    apply_m, diag_m = _flexibility(jac, c, m_inv, n)
    imp = pc.solve(apply_m, diag_m, b_imp, mu, impacting, jnp.zeros_like(b_imp), params.tol, params.max_iter,
                   momentum)
    v_star = vel + matvec(m_inv, apply_jacobian_t(jac, c, imp.force, n))
    shift = -matvec(m_inv, apply_jacobian_t(jac, c, imp.force * t_hit[:, None], n))

    # 2. Contact forces over the step (eq. 39); gap evaluated exactly at the predictor.
    d_free = free_displacement(k_inv, mass, load, v_star, dt)
    d_pred = d_free + shift
    gap_pred = gap_at(d_pred[:, :2], d_pred[:, 2])
    # The force acts along the normal of the mid-step configuration: normal to the chord
    # of the motion, so a frictionless sustained contact does no work (energy is kept on
    # curved tracks; with the start normal it would do work p n.d every step).
    mid_centroid, mid_rotation = centroid + 0.5 * d_pred[:, :2], state.rotation + 0.5 * d_pred[:, 2]
    gap_mid, normal_mid, point_mid = gap_frame(c, mid_centroid, mid_rotation)
    jac_mid = jacobians(c, normal_mid, point_mid, gap_mid, mid_centroid)
    b_con = jnp.stack([gap_pred, apply_jacobian(jac_mid, c, d_pred)[:, 1]], -1)
    apply_k, diag_k = _flexibility(jac_mid, c, k_inv, n)
    con = pc.solve(apply_k, diag_k, b_con, mu, c.valid, p0, params.tol, params.max_iter, momentum / dt)

    # 3. Integrate: Newmark velocity from d; geometry from d plus the impact shift.
    d = d_free + matvec(k_inv, apply_jacobian_t(jac_mid, c, con.force, n))
    new_vel = newmark_velocity(d, v_star, dt, proj)
    d_geo = d + shift
    new_state = State(
        time=state.time + dt,
        origin=origin,
        displacement=state.displacement + d_geo[:, :2],
        rotation=state.rotation + d_geo[:, 2],
        velocity=new_vel,
        contact_key=c.key,
        contact_force=con.force,
    )

    def to_global(nt, nrm):
        return nt[:, :1] * nrm + nt[:, 1:] * clockwise(nrm)

    force = jnp.where(c.valid[:, None], to_global(imp.force / dt, normal) + to_global(con.force, normal_mid), 0.0)
    report = ContactReport(
        valid=c.valid, a=c.a, b=c.b, point=point_mid, normal=normal_mid,
        normal_force=jnp.sum(force * normal_mid, -1), shear_force=jnp.sum(force * clockwise(normal_mid), -1),
        force=force, gap=gap0)
    capacity = jnp.array(dataclasses.astuple(model.capacity), jnp.int32)
    info = StepInfo(
        iterations=imp.iterations + con.iterations,
        residual=jnp.maximum(imp.residual, con.residual),
        converged=imp.converged & con.converged,
        needed=needed,
        overflow=jnp.any(needed > capacity),
        n_contacts=jnp.sum(c.valid).astype(jnp.int32),
        max_penetration=jnp.maximum(0.0, -jnp.min(jnp.where(c.valid, gap0, 0.0))),
        contacts=report,
    )
    return new_state, info


def rollout(model: Model, state: State, params: Params, steps: int):
    """Scan ``step`` ``steps`` times. Returns (final state, (states, infos)) where
    ``states`` stacks the state after each step."""
    def body(s, _):
        s2, info = step(model, s, params)
        return s2, (s2, info)

    return jax.lax.scan(body, state, None, length=steps)
