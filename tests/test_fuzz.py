"""Fuzzing over every scale a dtype can hold: statuses against an independent classification.

Random geometries and targets are drawn at unit scale, classified there in NumPy float64 by
geometry written here (the triangle inequality for the dyad and the SCARA, the intersection of
each Delta chain's elbow circle with the rod sphere's section, the reach shell of the
anthropomorphic arm), then scaled by ``s`` (float32: 1e-9 to 1e9, float64: 1e-150 to 1e150) and
cast to the dtype under test. Elements within a relative band of the workspace boundary are
left out of the status comparison (float32 rounds the scaled inputs by ~1e-7 and singular
bands are ``sqrt(eps)`` wide); everything else must match, every output must be finite, the
round trip ``fk(ik(t))`` must return ``t`` to a stated tolerance in units of the robot's size,
and the gradient of a status-masked loss must be finite. Every example compiles nothing new:
batches have one size and geometries are traced data.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxkin
from jaxkin import Jet, Status, delta, dyad, scara, serial

N = 64
BAND = 1e-2  # relative distance to the boundary below which a status is not compared
SCALES = {np.float32: (-9, 9), np.float64: (-150, 150)}
SETTINGS = settings(
    max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)


def _finite(tree) -> bool:
    return all(
        bool(np.all(np.isfinite(np.asarray(x))))
        for x in jax.tree.leaves(tree)
        if np.issubdtype(np.asarray(x).dtype, np.floating)
    )


def _check_classification(res, back, grad, reachable, clear, dtype):
    """Statuses OK/UNREACHABLE as the independent classification says (away from the
    boundary band), everything finite; returns the OK mask and the round-trip tolerance."""
    status = np.asarray(res.status)
    want = np.where(reachable, Status.OK, Status.UNREACHABLE)
    np.testing.assert_array_equal(status[clear], want[clear])
    assert _finite(res) and _finite(back) and _finite(grad)
    return status == Status.OK, 1e-4 if dtype == np.float32 else 1e-10


def _case(draw, dtype):
    lo, hi = SCALES[dtype]
    exponent = draw(st.floats(lo, hi))
    seed = draw(st.integers(0, 2**31 - 1))
    return 10.0**exponent, np.random.default_rng(seed)


dtypes = st.sampled_from([np.float32, np.float64])


# --------------------------------------------------------------------------------- the dyad
@jax.jit
def _dyad(a, b, l_ac, l_bc):
    res = dyad.solve(a, b, l_ac, l_bc)

    def loss(b_p):
        r = dyad.solve(a, Jet(b_p, b.v, b.a), l_ac, l_bc)
        ok = r.status == Status.OK
        return jnp.sum(jnp.where(ok, r.phi.p + r.phi.a + r.c.v[..., 0], 0.0))

    return res, jax.grad(loss)(b.p)


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), dtype=dtypes)
def test_dyad_statuses_at_every_scale(data, dtype):
    s, rng = _case(data.draw, dtype)
    l_ac, l_bc = rng.uniform(0.1, 1.0, 2)
    a = rng.uniform(-2, 2, (N, 2))
    b = a + rng.uniform(-1.5, 1.5, (N, 2)) * (l_ac + l_bc)
    b[:4] = a[:4] + [[1e3, 0.0], [0.0, -1e5], [3e4, 3e4], [1e6, 1.0]]  # far beyond the reach
    dist = np.hypot(*(b - a).T)
    reach_out, reach_in = l_ac + l_bc, abs(l_ac - l_bc)
    reachable = (dist < reach_out) & (dist > reach_in)
    clear = (np.abs(dist - reach_out) > BAND * reach_out) & (
        np.abs(dist - reach_in) > BAND * reach_out
    )
    rates = rng.normal(size=(2, N, 2))
    jets = [Jet.of(x * s, r * s, r * s) for x, r in ((a, rates[0]), (b, rates[1]))]
    jets = [j.astype(dtype) for j in jets]
    res, grad = _dyad(*jets, dtype(l_ac * s), dtype(l_bc * s))
    status = np.asarray(res.status)
    want = np.where(reachable, Status.OK, Status.UNREACHABLE)
    np.testing.assert_array_equal(status[clear], want[clear])
    assert _finite(res) and _finite(grad)
    ok = status == Status.OK
    # C is at l_ac from A and l_bc from B (units of the reach; float32: 1e-4).
    c = np.asarray(res.c.p, np.float64) / s
    tol = 1e-4 if dtype == np.float32 else 1e-10
    np.testing.assert_allclose(np.hypot(*(c - a).T)[ok], l_ac, atol=tol * reach_out)
    np.testing.assert_allclose(np.hypot(*(c - b).T)[ok], l_bc, atol=tol * reach_out)


# ------------------------------------------------------------------------------- the SCARA
@jax.jit
def _scara(robot, d):
    res = scara.ik(robot, d)
    back = scara.fk(robot, res.q)

    def loss(p):
        r = scara.ik(robot, Jet(p, d.v, d.a))
        return jnp.sum(jnp.where((r.status == Status.OK)[..., None], r.q.p + r.q.a, 0.0))

    return res, back, jax.grad(loss)(d.p)


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), dtype=dtypes)
def test_scara_statuses_and_round_trip_at_every_scale(data, dtype):
    s, rng = _case(data.draw, dtype)
    l_oa, l_ab, l_bc = rng.uniform(0.2, 1.0, 3)
    d = np.c_[rng.uniform(-1.6, 1.6, (N, 2)) * (l_ab + l_bc), rng.uniform(-1, 1, N)]
    d[:3, 0] = [1e3, -1e5, 1e6]  # far beyond the reach
    r = np.hypot(d[:, 0], d[:, 1])
    reach_out, reach_in = l_ab + l_bc, abs(l_ab - l_bc)
    reachable = (r < reach_out) & (r > reach_in)
    clear = (np.abs(r - reach_out) > BAND * reach_out) & (np.abs(r - reach_in) > BAND * reach_out)
    robot = scara.Scara(dtype(l_oa * s), dtype(l_ab * s), dtype(l_bc * s))
    jet = Jet.of(d * s, rng.normal(size=d.shape) * s, rng.normal(size=d.shape) * s).astype(dtype)
    res, back, grad = _scara(robot, jet)
    ok, tol = _check_classification(res, back, grad, reachable, clear, dtype)
    err = np.abs(np.asarray(back.x.p, np.float64) / s - d)[ok]
    assert np.all(err <= tol * (l_oa + reach_out + np.abs(d[ok])))


# ------------------------------------------------------------------------------- the Delta
def _delta_reachable(p, robot):
    """Chain by chain: the elbow circle (radius l_arm about the actuator axis, in the chain's
    plane) must meet the rod sphere's section by that plane. Returns (reachable, clearance)."""
    r_base, r_platform, l_arm, l_rod = robot
    ok = np.ones(len(p), bool)
    clearance = np.full(len(p), np.inf)
    for phi in np.radians([-90.0, 30.0, 150.0]):
        u = np.array([np.cos(phi), np.sin(phi), 0.0])
        t = np.array([-np.sin(phi), np.cos(phi), 0.0])
        q = p + r_platform * u - r_base * u  # the rod's far end seen from the actuator axis
        radial, tangential, z = q @ u, q @ t, q[:, 2]
        rho_sq = l_rod**2 - tangential**2
        rho = np.sqrt(np.maximum(rho_sq, 0.0))
        delta_ = np.hypot(radial, z)
        meets = (rho_sq > 0) & (delta_ <= l_arm + rho) & (delta_ >= np.abs(l_arm - rho))
        ok &= meets
        gaps = np.minimum(np.abs(delta_ - (l_arm + rho)), np.abs(delta_ - np.abs(l_arm - rho)))
        clearance = np.minimum(clearance, np.where(rho_sq > 0, gaps, np.abs(tangential) - l_rod))
    return ok, clearance


@jax.jit
def _delta(robot, p, theta):
    ik = delta.ik(robot, p)
    fk = delta.fk(robot, theta)
    closed = delta.fk_closed_form(robot, theta)
    grad = jax.grad(
        lambda x: jnp.sum(jnp.where(delta.ik(robot, x).ok[..., None], delta.ik(robot, x).q.p, 0.0))
    )(p)
    return ik, fk, closed, grad


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), dtype=dtypes)
def test_delta_statuses_and_fk_at_every_scale(data, dtype):
    s, rng = _case(data.draw, dtype)
    l_rod = 1.0
    r_base, r_platform, l_arm = rng.uniform(0.1, 0.3), rng.uniform(0.02, 0.1), rng.uniform(0.3, 0.7)
    geometry = (r_base, r_platform, l_arm, l_rod)
    size = l_arm + l_rod
    p = np.c_[rng.uniform(-1, 1, (N, 2)) * size, -rng.uniform(0.0, 1.3, N) * size]
    p[:3] = [[2 * size, 0, -size], [0, 0, -1e5], [1e6, 0, 0]]  # beyond the reach, twice and far
    reachable, clearance = _delta_reachable(p, geometry)
    clear = np.abs(clearance) > BAND * size
    theta = rng.uniform(-0.3, 1.2, (N, 3))
    robot = jax.tree.map(lambda x: jnp.asarray(x * s, dtype), delta.Delta(*geometry))
    robot = robot.replace(theta_min=-np.inf, theta_max=np.inf)
    ik, fk, closed, grad = _delta(robot, jnp.asarray(p * s, dtype), jnp.asarray(theta, dtype))
    status = np.asarray(ik.status)
    solved = (status == Status.OK) | (status == Status.SINGULAR)
    np.testing.assert_array_equal(solved[clear], reachable[clear])
    assert not solved[:3].any() and np.all(np.asarray(ik.margin)[:3] < 0)
    assert _finite(ik) and _finite(fk) and _finite(closed) and _finite(grad)
    # Newton FK against the closed form where both are OK (units of the robot's size).
    both = (np.asarray(fk.status) == Status.OK) & (np.asarray(closed.status) == Status.OK)
    tol = 1e-3 if dtype == np.float32 else 1e-9
    diff = np.abs(np.asarray(fk.x.p, np.float64) - np.asarray(closed.x, np.float64)) / s
    assert np.all(diff[both] <= tol * size)
    assert np.all(
        np.asarray(fk.status)[np.asarray(closed.status) == Status.OK] != Status.NOT_CONVERGED
    )


# ------------------------------------------------------------------------------------ arms
@jax.jit
def _arm(robot, target):
    res = jaxkin.ik(robot, target)
    back = jaxkin.fk(robot, res.q)
    grad = jax.grad(
        lambda t: jnp.sum(
            jnp.where(jaxkin.ik(robot, t).ok[..., None], jaxkin.ik(robot, t).q.p, 0.0)
        )
    )(target)
    return res, back, grad


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), dtype=dtypes)
def test_anthropomorphic_reach_at_every_scale(data, dtype):
    s, rng = _case(data.draw, dtype)
    l1, l2, l3 = rng.uniform(0.2, 1.0, 3)
    p = rng.uniform(-1.5, 1.5, (N, 3)) * (l2 + l3) + [0.0, 0.0, l1]
    p[:3] = [[1e3, 0, 0], [0, 1e5, 0], [0, 0, -1e6]]
    dist = np.linalg.norm(p - [0.0, 0.0, l1], axis=-1)
    reachable = (dist < l2 + l3) & (dist > abs(l2 - l3))
    size = l1 + l2 + l3
    clear = (np.abs(dist - (l2 + l3)) > BAND * size) & (np.abs(dist - abs(l2 - l3)) > BAND * size)
    clear &= np.hypot(p[:, 0], p[:, 1]) > BAND * size  # off the base axis (a singular set)
    robot = serial.Anthropomorphic(dtype(l1 * s), dtype(l2 * s), dtype(l3 * s))
    res, back, grad = _arm(robot, jnp.asarray(p * s, dtype))
    ok, tol = _check_classification(res, back, grad, reachable, clear, dtype)
    assert np.all(np.abs(np.asarray(back.x.p, np.float64) / s - p)[ok] <= tol * size)
    assert np.all(np.asarray(res.margin)[~reachable & clear] < 0)


@pytest.mark.slow
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_puma_round_trip_at_the_ends_of_the_range(dtype):
    """The PUMA's analytic IK at the smallest and largest scales: same statuses and joint
    angles as at unit scale (float32 1e-4 rad, float64 1e-9 rad), round trip in units of the
    arm's size."""
    lo, hi = SCALES[dtype]
    q = np.random.default_rng(3).uniform(0.3, 1.2, (N, 6))
    results = []
    for s in (1.0, 10.0**lo, 10.0**hi):
        puma = serial.Puma560(0.0, 0.4318 * s, 0.0203 * s, 0.15005 * s, 0.4318 * s, 0.05 * s)
        target = jaxkin.fk(puma, q.astype(dtype)).x.p
        res, back, grad = _arm(puma, target)
        assert _finite(res) and _finite(back) and _finite(grad)
        size = 0.4318 * 2 + 0.0203 + 0.15005 + 0.05
        err = np.abs(np.asarray(back.x.p, np.float64) - np.asarray(target, np.float64))
        ok = np.asarray(res.status) == Status.OK
        assert np.all(err[ok][..., :3, 3] <= (1e-4 if dtype == np.float32 else 1e-10) * size * s)
        results.append((np.asarray(res.status), np.asarray(res.q.p, np.float64)))
    for status, angles in results[1:]:
        np.testing.assert_array_equal(status, results[0][0])
        ok = status == Status.OK
        tol = 1e-3 if dtype == np.float32 else 1e-9
        np.testing.assert_allclose(angles[ok], results[0][1][ok], atol=tol)
