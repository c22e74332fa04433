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

Retiming is fuzzed against its invariances (a joint's unit, the path parameter's and the
time's scale, limits of any size on a joint held still, none on one that moves), and worlds
(the PUMA 560 and its obstacles scaled by 1e-3..1e3, degenerate primitives, padding obstacles
far away) through ``collision.check`` against the per-primitive queries and
``collision.collides`` against ``collision.check``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxkin
from jaxkin import Jet, Status, collision, delta, dyad, scara, serial, timing

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


# ------------------------------------------------------------------------------ retiming
# One shape for every example: 8 candidates of 3 joints, 6 waypoints, 4 grid intervals each.
T_CANDIDATES, T_WAYPOINTS, T_JOINTS = 8, 6, 3
T_SCALES = {np.float32: 3, np.float64: 12}  # decades of the unit and time scalings


def _joint_paths(rng: np.random.Generator) -> np.ndarray:
    """Smooth random waypoints ``(8, 6, 3)``: sums of two sines per joint; joint 2 of
    candidate 0 held still (a joint that does not move needs no limit)."""
    s = np.linspace(0.0, 1.0, T_WAYPOINTS)[None, :, None]
    amp = rng.uniform(0.3, 1.5, (T_CANDIDATES, 1, T_JOINTS))
    phase = rng.uniform(0.0, 2.0 * np.pi, (T_CANDIDATES, 2, T_JOINTS))
    way = amp * (np.sin(np.pi * s + phase[:, :1]) + 0.5 * np.sin(2 * np.pi * s + phase[:, 1:]))
    way[0, :, 2] = 0.7
    return way


def _scaled(path, unit, stretch, dtype):
    """``path`` with joint ``j`` in a unit ``unit[j]`` times smaller and its parameter ``s``
    stretched by ``stretch``: ``q -> q unit``, ``dq/ds -> dq/ds unit / stretch``, ..."""
    s, q, dq, ddq = (np.asarray(x, np.float64) for x in (path.s, path.q, path.dq, path.ddq))
    arrays = (s * stretch, q * unit, dq * unit / stretch, ddq * unit / stretch**2)
    return timing.JointPath(*(jnp.asarray(x, dtype) for x in arrays))


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), dtype=dtypes)
def test_retiming_limits_units_and_scales(data, dtype):
    """TOPP-RA against its own invariances, over every scale a dtype holds well: a joint's
    unit (positions and limits times ``c_j``, 1e-12..1e12 in float64) and the path
    parameter's (``s`` times ``l``) change no duration; limits ``v k``, ``a k^2`` divide
    every duration by ``k``; a joint held still is not limited by a zero, tiny, huge or
    infinite limit; one that moves is UNTIMEABLE with a zero speed limit or no acceleration
    limit (inf), and a huge limit (1e12 times) on every joint but one changes nothing that
    the other's does not bound. Durations within 1e-9 (float64) or 1e-3 (float32)."""
    decades = T_SCALES[dtype]
    rng = np.random.default_rng(data.draw(st.integers(0, 2**31 - 1)))
    unit = 10.0 ** rng.uniform(-decades, decades, T_JOINTS)
    k = 10.0 ** data.draw(st.floats(-decades, decades))
    stretch = 10.0 ** data.draw(st.floats(-decades, decades))
    rtol = 1e-3 if dtype == np.float32 else 1e-9
    path = timing.path_from_waypoints(jnp.asarray(_joint_paths(rng), dtype), subdivisions=4)
    v = rng.uniform(0.5, 2.0, (T_CANDIDATES, T_JOINTS))
    a = rng.uniform(1.0, 4.0, (T_CANDIDATES, T_JOINTS))
    still = data.draw(st.sampled_from([(0.0, np.inf), (np.inf, 0.0), (1e-30, 1e-30), (1e30, 1e30)]))
    v[0, 2], a[0, 2] = still

    def retime(p, v_max, a_max):
        result = timing.retime(p, jnp.asarray(v_max, dtype), jnp.asarray(a_max, dtype))
        return np.asarray(result.status), np.asarray(result.duration, np.float64)

    status, duration = retime(path, v, a)
    assert np.all(status == Status.OK) and np.all(duration > 0)
    units = retime(_scaled(path, unit, stretch, dtype), v * unit, a * unit)
    np.testing.assert_array_equal(units[0], status)
    np.testing.assert_allclose(units[1] * 1.0, duration, rtol=rtol)
    faster = retime(path, v * k, a * k * k)
    np.testing.assert_array_equal(faster[0], status)
    np.testing.assert_allclose(faster[1] * k, duration, rtol=rtol)
    # Candidate 0 with its still joint's limits of any size: the same duration.
    v_free, a_free = v.copy(), a.copy()
    v_free[0, 2], a_free[0, 2] = 1.0, 1.0
    np.testing.assert_allclose(retime(path, v_free, a_free)[1][0], duration[0], rtol=rtol)
    # A moving joint with no speed, or no acceleration limit: that candidate only fails.
    v_bad, a_bad = v.copy(), a.copy()
    v_bad[1, 0], a_bad[2, 1] = 0.0, np.inf
    bad = retime(path, v_bad, a_bad)
    assert bad[0][1] == bad[0][2] == Status.UNTIMEABLE and np.all(bad[1][1:3] == 0.0)
    np.testing.assert_allclose(bad[1][3:], duration[3:], rtol=rtol)
    # Huge limits on joints 1 and 2: joint 0 alone bounds the motion, as with 1e6 times.
    huge, larger = (retime(path, v * [1, f, f], a * [1, f, f])[1] for f in (1e6, 1e12))
    np.testing.assert_allclose(larger[1:], huge[1:], rtol=1e-6 if dtype == np.float64 else 1e-2)


# -------------------------------------------------------------------------------- worlds
# One shape for every example: the PUMA 560 (lengths as traced data, so a new scale compiles
# nothing), 32 configurations, a world of 4 spheres, 3 capsules, 3 boxes and a half-space.
W_CONFIGS = 32
PUMA = (0.4318, 0.0203, 0.15005, 0.4318, 0.05)  # a2, a3, d3, d4, d6 (m)
FAR = 1e5  # a padding obstacle's distance, in robot sizes


def _puma(s: float, dtype) -> serial.Puma560:
    lengths = (jnp.asarray(x * s, dtype) for x in PUMA)
    return serial.Puma560(0.0, *lengths, link_radius=jnp.asarray(0.05 * s, dtype))


def _random_world(rng: np.random.Generator, s: float, far: bool, dtype) -> collision.World:
    """Obstacles in a cube of half-side 1 (times ``s``) with a degenerate one of each kind (a
    sphere of radius 0, a capsule of length 0, a flat box); with ``far``, a padding obstacle
    of each kind ``FAR`` away (as a fixed-size world is padded), else a fourth ordinary one."""

    def spot(n):
        return rng.uniform(-1.0, 1.0, (n, 3))

    padding = np.array([[FAR, FAR, FAR]]) if far else spot(1)
    centres = np.concatenate([spot(3), padding])
    radii = np.r_[0.0, rng.uniform(0.02, 0.1, 3)]
    a = np.concatenate([spot(2), padding])
    b = np.concatenate([a[:1], spot(1), padding + 0.1])  # capsule 0 has length 0
    half = rng.uniform(0.02, 0.2, (3, 3))
    half[0, rng.integers(3)] = 0.0  # a flat box
    rotation = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(3)])
    rotation *= np.sign(np.linalg.det(rotation))[:, None, None]  # proper rotations
    box_centres = np.concatenate([spot(2), padding])
    floor = -FAR if far else -1.0
    return collision.World.create(
        spheres=collision.Spheres.create(centres * s, radii * s, dtype),
        capsules=collision.Capsules.create(a * s, b * s, rng.uniform(0.02, 0.06, 3) * s, dtype),
        boxes=collision.Boxes.create(box_centres * s, half * s, rotation, dtype),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [floor * s], dtype),
    )


def _world_case(data, dtype, far):
    s = 10.0 ** data.draw(st.floats(-3.0, 3.0))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**31 - 1)))
    q = jnp.asarray(rng.uniform(-3.0, 3.0, (W_CONFIGS, 6)), dtype)
    return s, _puma(s, dtype), _random_world(rng, s, far, dtype), q


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), dtype=dtypes, far=st.booleans())
def test_world_check_equals_the_per_primitive_queries_at_every_scale(data, dtype, far):
    """``collision.check``'s fused pass against the per-primitive queries
    (``nearest_obstacles``, ``self_distances``), the robot and its world scaled by 1e-3..1e3,
    with degenerate obstacles (radius 0, length 0, a flat box) and padding ones far away:
    the same clearance (1e-12 float64, 1e-5 float32, of the robot's size) and verdicts away
    from contact."""
    from jaxkin.collision.check import _check_per_primitive

    s, robot, world, q = _world_case(data, dtype, far)
    body, pairs = collision.prepare(robot)
    fused = collision.check(robot, q, world)
    reference = jax.jit(_check_per_primitive)(robot, body, pairs, q, world)
    size = s * (sum(PUMA) + 0.1)
    tol = (1e-5 if dtype == np.float32 else 1e-12) * size
    clearance = np.asarray(fused.clearance, np.float64)
    np.testing.assert_allclose(clearance, np.asarray(reference.clearance, np.float64), atol=tol)
    away = np.abs(clearance) > tol
    np.testing.assert_array_equal(np.asarray(fused.collides)[away], clearance[away] <= 0)
    np.testing.assert_array_equal(np.asarray(fused.status), np.asarray(reference.status))


def _verdict_against_check(data, dtype, far):
    s, robot, world, q = _world_case(data, dtype, far)
    exact = collision.check(robot, q, world)
    verdict = collision.collides(robot, q, world)
    clearance = np.asarray(exact.clearance, np.float64)
    size = s * (sum(PUMA) + 0.1)
    away = np.abs(clearance) > (1e-4 if dtype == np.float32 else 1e-10) * size
    flagged, hit = np.asarray(verdict.collides), np.asarray(exact.collides)
    assert not np.any(hit & ~flagged), "a collision the exact clearance reports is missed"
    np.testing.assert_array_equal(flagged[away], hit[away], err_msg=f"clearance {clearance}")


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), dtype=dtypes, far=st.booleans())
def test_world_verdict_equals_the_check_at_every_scale(data, dtype, far):
    """``collision.collides`` (the fast verdict) against ``collision.check`` on the same
    scaled worlds: every collision flagged, and the same verdict away from contact (1e-10
    float64, 1e-4 float32, of the robot's size). Float32 with padding obstacles far away is
    the next test's."""
    if dtype == np.float32 and far:
        far = False
    _verdict_against_check(data, dtype, far)


@pytest.mark.slow
@SETTINGS
@given(data=st.data())
def test_world_verdict_in_float32_with_padding_far_away(data):
    """Float32 worlds padded with obstacles 1e5 robot sizes away: the verdict should still
    equal the exact check away from contact."""
    _verdict_against_check(data, np.float32, True)
