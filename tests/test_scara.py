"""Tests of jaxkin.scara: IK (analytic and autodiff) and FK against independent sources.

Independent sources: sympy differentiation of the closed-form IK along the paper's spiral
(eq. 16); the corrected (docs/errata.md) theta1_ddot(0) = 0.309; the 2R IK ([Pineiro], [UANL]:
``q2 = +/- acos((r^2 - l2^2 - l3^2) / (2 l2 l3))``); central finite differences of IK
positions; the FK round trip; reflection geometry; the NumPy reference in tests/references.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mpmath
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxkin import Jet, Status, lift, scara
from tests.helpers import BATCH_SHAPES, compilations, fd_rates, tree_allfinite
from tests.references.scara import ik_numpy

L_OA, L_AB, L_BC = 150.0, 80.0, 50.0
W = math.pi / 2.0
PAPER = scara.Scara.create(L_OA, L_AB, L_BC)
N = 64  # batch size of the random tests (one size: fewer compilations)


def spiral(t) -> Jet:
    """Eq. 16 with its exact time derivatives, shape (..., 3)."""
    t = np.asarray(t, float)
    s, c = np.sin(W * t), np.cos(W * t)
    p = np.stack([100.0 + 20.0 * s, -20.0 * c, 50.0 + 10.0 * t], -1)
    v = np.stack([20.0 * W * c, 20.0 * W * s, np.full_like(t, 10.0)], -1)
    a = np.stack([-20.0 * W * W * s, 20.0 * W * W * c, np.zeros_like(t)], -1)
    return Jet.of(p, v, a)


def random_reachable(rng, shape, l_ab=L_AB, l_bc=L_BC, min_sin_beta=0.05, z_scale=100.0):
    """Random targets inside the annulus with random rates.

    Targets keep sin(beta) >= min_sin_beta (lowered to half the largest sin(beta) the geometry
    allows, l_bc / l_ab when the forearm is shorter) and r >= 0.05 (l_ab + l_bc) from the axis,
    where theta's rates grow like 1/r (ill-conditioned when l_ab ~ l_bc).
    """
    n = int(np.prod(shape, dtype=int))
    inner, outer = abs(l_ab - l_bc), l_ab + l_bc
    threshold = min(min_sin_beta, 0.5 * min(1.0, l_bc / l_ab))
    r = np.empty(0)
    while r.size < n:
        cand = rng.uniform(max(inner, 0.05 * outer), outer, 4 * n)
        u = (l_ab**2 + cand**2 - l_bc**2) / (2 * l_ab * cand)
        r = np.concatenate([r, cand[1.0 - u * u >= threshold**2]])
    r = r[:n]
    ang = rng.uniform(-np.pi, np.pi, n)
    p = np.stack([r * np.cos(ang), r * np.sin(ang), rng.uniform(0, z_scale, n)], -1)
    v = rng.normal(size=(n, 3)) * 0.1 * outer
    a = rng.normal(size=(n, 3)) * 0.1 * outer
    return Jet.of(*(x.reshape(*shape, 3) for x in (p, v, a)))


def assert_jet_close(x: Jet, y: Jet, rtol: float, err_msg: str = ""):
    """Each of p, v, a agrees to rtol relative to the largest entry of that array."""
    for name in ("p", "v", "a"):
        xa, ya = np.asarray(getattr(x, name)), np.asarray(getattr(y, name))
        scale = max(np.max(np.abs(ya)), 1.0)
        np.testing.assert_allclose(xa, ya, rtol=0, atol=rtol * scale, err_msg=f"{err_msg} {name}")


# --------------------------------------------------------------------------- spiral, sympy


@pytest.fixture(scope="module")
def sympy_spiral():
    """Closed-form IK along eq. 16, differentiated by sympy, evaluated in 30-digit mpmath."""
    t = sp.symbols("t", real=True)
    x = 100 + 20 * sp.sin(sp.pi / 2 * t)
    y = -20 * sp.cos(sp.pi / 2 * t)
    z = 50 + 10 * t
    r = sp.sqrt(x**2 + y**2)
    funcs = {}
    for mode in (1, -1):
        beta = sp.acos((L_AB**2 + r**2 - L_BC**2) / (2 * L_AB * r))  # law of cosines
        theta1 = sp.atan2(y, x) + mode * beta
        theta_bc = sp.atan2(y - L_AB * sp.sin(theta1), x - L_AB * sp.cos(theta1))
        exprs = [theta1, theta1 - theta_bc, L_OA - z]
        table = [[e, sp.diff(e, t), sp.diff(e, t, 2)] for e in exprs]
        funcs[mode] = sp.lambdify(t, table, modules="mpmath")

    def evaluate(mode: int, t_value: str) -> np.ndarray:
        with mpmath.workdps(30):
            rows = funcs[mode](mpmath.mpf(t_value))
            return np.array([[float(v) for v in row] for row in rows])  # (joint, order)

    return evaluate


@pytest.mark.parametrize("method", ["analytic", "autodiff"])
@pytest.mark.parametrize("mode", [1, -1])
def test_spiral_matches_sympy(sympy_spiral, mode, method):
    times = ["0", "0.7", "1.3", "2.5", "4.1", "6.6", "8"]
    res = scara.ik(PAPER, spiral(np.array([float(s) for s in times])), branch=mode, method=method)
    assert np.all(np.asarray(res.status) == Status.OK)
    for i, t in enumerate(times):
        ref = sympy_spiral(mode, t)  # rows theta1, theta2, l3; columns p, v, a
        got = np.stack([res.q.p[i], res.q.v[i], res.q.a[i]], axis=-1)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12, err_msg=f"t={t}")


def test_spiral_theta1_ddot_at_zero_is_errata_value():
    """docs/errata.md: the true theta1_ddot at t = 0 is 0.309 rad/s^2 (mode +1)."""
    res = scara.ik(PAPER, spiral(0.0), branch=1)
    assert abs(float(res.q.a[0]) - 0.309) < 5e-4
    res_other = scara.ik(PAPER, spiral(0.0), branch=-1)
    assert abs(float(res_other.q.a[0]) - 0.309) > 0.1  # the value belongs to mode +1 only


@pytest.mark.parametrize("mode", [1, -1])
def test_spiral_rates_match_finite_differences(mode):
    def position(t):
        return np.asarray(scara.ik(PAPER, spiral(t).p, branch=mode).q.p)

    for t in (0.3, 1.9, 5.2, 7.4):
        res = scara.ik(PAPER, spiral(t), branch=mode)
        v_fd, a_fd = fd_rates(position, t, scale=1.0)
        # Richardson-extrapolated central differences: ~1e-11 (v) and ~1e-8 (a) relative.
        np.testing.assert_allclose(res.q.v, v_fd, rtol=1e-8, atol=1e-9)
        np.testing.assert_allclose(res.q.a, a_fd, rtol=1e-6, atol=1e-7)


# --------------------------------------------------------------------------- practical case


@pytest.mark.parametrize("point", [(1.0, 1.0), (3.0, 1.0), (3.0, 3.0), (1.0, 3.0), (2.0, 2.0)])
def test_practical_case_matches_textbook_2r(point):
    """[UANL]: l1 = 3 (column), l2 = 3, l3 = 2 m, plate at z = 2 m; both elbows."""
    robot = scara.Scara.create(3.0, 3.0, 2.0)
    px, py = point
    d = np.array([px, py, 2.0])
    r2 = px * px + py * py
    for mode in (1, -1):
        res = scara.ik(robot, d, branch=mode)
        assert int(res.status) == Status.OK
        q2 = float(scara.relative_elbow_angle(res.q.p[1]))  # [UANL]'s q2
        # Textbook 2R [Pineiro]: the elbow angle's cosine, and q1 from q2.
        q2_ref = math.acos((r2 - 9.0 - 4.0) / (2 * 3.0 * 2.0))
        q2_ref = -q2_ref if mode == 1 else q2_ref  # mode +1: elbow left, forearm clockwise
        q1_ref = math.atan2(py, px) - math.atan2(
            2.0 * math.sin(q2_ref), 3.0 + 2.0 * math.cos(q2_ref)
        )
        assert q2 == pytest.approx(q2_ref, abs=1e-13)
        assert math.remainder(float(res.q.p[0]) - q1_ref, 2 * math.pi) == pytest.approx(
            0, abs=1e-13
        )
        assert float(res.q.p[2]) == pytest.approx(1.0, abs=1e-15)  # q3 = l1 - Pz


# --------------------------------------------------------------------------- methods, round trip


# Each (shape, mode) pair compiles both methods: pair shapes with modes to keep the file fast.
@pytest.mark.parametrize(
    ("shape", "mode"), [*zip(BATCH_SHAPES, [1, -1, 1, -1], strict=True), ((N,), -1), ((N,), 1)]
)
def test_analytic_equals_autodiff(shape, mode):
    rng = np.random.default_rng(7)
    d = random_reachable(rng, shape)
    ana = scara.ik(PAPER, d, branch=mode)
    auto = scara.ik(PAPER, d, branch=mode, method="autodiff")
    assert ana.q.shape == (*shape, 3)
    assert ana.status.shape == shape and ana.status.dtype == jnp.int8
    np.testing.assert_array_equal(ana.status, auto.status)
    np.testing.assert_array_equal(ana.margin, auto.margin)
    for name in ("p", "v", "a"):
        np.testing.assert_allclose(
            getattr(ana.q, name), getattr(auto.q, name), rtol=1e-10, atol=1e-10, err_msg=name
        )


@pytest.mark.parametrize("mode", [1, -1])
def test_round_trip_random(mode):
    rng = np.random.default_rng(11)
    d = random_reachable(rng, (N,))
    res = scara.ik(PAPER, d, branch=mode)
    assert np.all(np.asarray(res.status) == Status.OK)
    # Positions: fk(ik(d)) == d; rates: FK's link-rate formulas reproduce D's v and a, and
    # agree with the position-level FK lifted by autodiff.
    at_rest = scara.fk(PAPER, res.q.p)
    np.testing.assert_allclose(at_rest.x.p, d.p, rtol=0, atol=1e-12 * 150)
    assert not np.any(np.asarray(at_rest.x.v)) and np.all(np.asarray(at_rest.status) == 0)
    d_back = scara.fk(PAPER, res.q).x
    assert_jet_close(d_back, d, rtol=1e-12)
    lengths = [jnp.asarray(x) for x in (PAPER.l_oa, PAPER.l_ab, PAPER.l_bc)]
    assert_jet_close(d_back, lift(scara._fk_position)(res.q, *lengths), rtol=1e-13)


@settings(max_examples=25, deadline=None, derandomize=True)  # reproducible in CI
@given(
    l_oa=st.floats(0.1, 10.0),
    l_ab=st.floats(0.1, 10.0),
    l_bc=st.floats(0.1, 10.0),
    seed=st.integers(0, 2**31),
)
def test_round_trip_random_geometry(l_oa, l_ab, l_bc, seed):
    robot = scara.Scara.create(l_oa, l_ab, l_bc)
    d = random_reachable(np.random.default_rng(seed), (N,), l_ab, l_bc, z_scale=l_oa)
    # Rates lose accuracy like eps / sin(beta)^2; random_reachable keeps sin(beta) >= s_min.
    s_min = min(0.05, 0.5 * min(1.0, l_bc / l_ab))
    for mode in (1, -1):
        res = scara.ik(robot, d, branch=mode)
        assert np.all(np.asarray(res.status) == Status.OK)
        back = scara.fk(robot, res.q).x
        np.testing.assert_allclose(back.p, d.p, rtol=0, atol=1e-12 * max(l_ab + l_bc, l_oa))
        assert_jet_close(back, d, rtol=1e-13 / s_min**2)


def test_modes_give_mirror_elbows():
    rng = np.random.default_rng(3)
    d = random_reachable(rng, (N,))
    plus = scara.ik(PAPER, d, branch=1)
    minus = scara.ik(PAPER, d, branch=-1)
    c = np.asarray(d.p[:, :2])
    u = c / np.linalg.norm(c, axis=-1, keepdims=True)
    # The elbow B in the arm plane: the end of the first link segment.
    b = np.asarray(PAPER.link_segments(plus.q.p, d.p)[..., 0, 1, :2])
    b_minus = np.asarray(PAPER.link_segments(minus.q.p, d.p)[..., 0, 1, :2])
    reflected = 2.0 * np.sum(b * u, -1, keepdims=True) * u - b  # across the line O-C
    np.testing.assert_allclose(b_minus, reflected, rtol=0, atol=1e-12 * 130)
    # Mode +1 elbow left of O->C (positive cross product), mode -1 right.
    assert np.all(c[:, 0] * b[:, 1] - c[:, 1] * b[:, 0] > 0)
    # theta2 of the two modes are opposite (mod 2 pi), and in (0, pi) mod 2 pi for mode +1.
    t2p, t2m = np.asarray(plus.q.p[:, 1]), np.asarray(minus.q.p[:, 1])
    np.testing.assert_allclose(np.sin(t2p), -np.sin(t2m), atol=1e-12)
    assert np.all(np.sin(t2p) > 0)


def test_relative_elbow_angle():
    theta2 = jnp.array([0.5, -0.5, 3.5, -3.5, 2 * math.pi + 0.25])
    np.testing.assert_allclose(
        scara.relative_elbow_angle(theta2),
        [-0.5, 0.5, 2 * math.pi - 3.5, 3.5 - 2 * math.pi, -0.25],
        atol=1e-14,
    )
    jet = scara.relative_elbow_angle(Jet.of(theta2, theta2 * 2, theta2 * 3))
    np.testing.assert_allclose(jet.v, -2 * theta2)
    np.testing.assert_allclose(jet.a, -3 * theta2)


# --------------------------------------------------------------------------- statuses


def test_statuses_on_and_outside_the_annulus():
    # l_ab = 80 > l_bc = 50: annulus 30 <= r <= 130.
    pts = np.array(
        [
            [130.0, 0.0, 10.0],  # outer boundary: stretched arm, beta = 0
            [0.0, -30.0, 10.0],  # inner boundary, l_ab > l_bc: folded arm, beta = 0
            [130.0 + 1e-3, 0.0, 10.0],  # just outside
            [0.0, 29.99, 10.0],  # just inside the hole
            [0.0, 0.0, 10.0],  # at the axis
            [129.99, 0.0, 10.0],  # just inside: fine
            [30.01, 0.0, 10.0],
        ]
    )
    expected = [
        Status.SINGULAR_EXTENDED,
        Status.SINGULAR_EXTENDED,
        Status.UNREACHABLE,
        Status.UNREACHABLE,
        Status.UNREACHABLE,
        Status.OK,
        Status.OK,
    ]
    for method, mode in (("analytic", 1), ("analytic", -1), ("autodiff", 1)):
        d = Jet.of(pts, np.ones_like(pts), np.ones_like(pts))
        res = scara.ik(PAPER, d, branch=mode, method=method)
        np.testing.assert_array_equal(res.status, expected)
        assert tree_allfinite(res)
        bad = np.asarray(res.status) != Status.OK
        assert np.all(np.asarray(res.q.v)[bad] == 0) and np.all(np.asarray(res.q.a)[bad] == 0)
        # Singular poses have valid positions: the round trip holds there.
        np.testing.assert_allclose(scara.fk(PAPER, res.q.p).x.p[:2], pts[:2], atol=1e-9)
        margin = np.asarray(res.margin)
        assert np.all(margin[:2] == 0) and np.all(margin[2:5] < 0) and np.all(margin[5:] > 0)


def test_statuses_forearm_longer_and_equal_links():
    longer = scara.Scara.create(1.0, 1.0, 3.0)  # annulus 2 <= r <= 4
    res = scara.ik(longer, np.array([[2.0, 0.0, 0.0], [4.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_array_equal(
        res.status, [Status.SINGULAR_FOLDED, Status.SINGULAR_EXTENDED, Status.UNREACHABLE]
    )
    equal = scara.Scara.create(1.0, 2.0, 2.0)
    res = scara.ik(equal, Jet.of(np.zeros(3), np.ones(3), np.ones(3)))
    assert int(res.status) == Status.SINGULAR_COINCIDENT
    assert tree_allfinite(res)


@pytest.mark.parametrize("method", ["analytic", "autodiff"])
def test_mixed_batch_is_finite_with_finite_gradients(method):
    p = np.array(
        [
            [100.0, 10.0, 20.0],  # OK
            [200.0, 0.0, 20.0],  # unreachable
            [np.nan, 0.0, 20.0],  # invalid position
            [100.0, 10.0, np.inf],  # invalid z
            [130.0, 0.0, 20.0],  # singular
            [90.0, -20.0, 5.0],  # OK
        ]
    )
    v = np.ones_like(p)
    v[0, 0] = np.nan  # invalid velocity on an otherwise fine point
    d = Jet.of(p, v, np.ones_like(p))
    res = scara.ik(PAPER, d, method=method)
    expected = [
        Status.INVALID_INPUT,
        Status.UNREACHABLE,
        Status.INVALID_INPUT,
        Status.INVALID_INPUT,
        Status.SINGULAR_EXTENDED,
        Status.OK,
    ]
    np.testing.assert_array_equal(res.status, expected)
    assert tree_allfinite(res)
    np.testing.assert_array_equal(np.asarray(res.margin)[[0, 2, 3]], -1.0)

    def loss(p, robot):
        out = scara.ik(robot, Jet.of(p, v, jnp.ones_like(p)), method=method)
        ok = out.ok[..., None]
        return jnp.sum(jnp.where(ok, out.q.p**2 + out.q.v**2 + out.q.a**2, 0.0))

    grads = jax.grad(loss, argnums=(0, 1))(jnp.asarray(p), PAPER)
    assert tree_allfinite(grads)
    assert np.any(np.asarray(grads[0][5]) != 0)  # the good element still has a gradient
    assert np.all(np.asarray(grads[0][:5]) == 0)


# --------------------------------------------------------------------------- limits


def test_joint_limits_status():
    robot = scara.Scara.create(L_OA, L_AB, L_BC, limits={"theta1": (-1.0, 1.0), "l3": (0.0, 120.0)})
    p = np.array(
        [
            [100.0, 0.0, 50.0],  # inside every limit (mode +1: theta1 ~ 0.5)
            [0.0, 100.0, 50.0],  # theta1 ~ 2.1: out of limits
            [100.0, 0.0, 10.0],  # l3 = 140: out of limits
            [130.0, 0.0, 10.0],  # singular and out of limits: stays singular
            [500.0, 0.0, 50.0],  # unreachable
        ]
    )
    d = Jet.of(p, np.ones_like(p), np.zeros_like(p))
    res = scara.ik(robot, d)
    np.testing.assert_array_equal(
        res.status,
        [
            Status.OK,
            Status.OUT_OF_LIMITS,
            Status.OUT_OF_LIMITS,
            Status.SINGULAR_EXTENDED,
            Status.UNREACHABLE,
        ],
    )
    # A singular solution keeps its status; the limits say it is outside them (l3 = 140).
    inside = np.asarray(robot.limits.contains(res.q.p))
    np.testing.assert_array_equal(inside[:4], [True, False, False, False])
    free = scara.ik(PAPER, d)
    np.testing.assert_array_equal(free.status[:4], [0, 0, 0, Status.SINGULAR_EXTENDED])
    # OUT_OF_LIMITS keeps the (valid) rates: identical to the unlimited robot's.
    np.testing.assert_array_equal(res.q.v[:3], free.q.v[:3])
    assert np.any(np.asarray(res.q.v[1]) != 0)


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: scara.Scara.create(-1.0, 1.0, 1.0), "l_oa"),
        (lambda: scara.Scara.create(1.0, 0.0, 1.0), "l_ab"),
        (lambda: scara.Scara.create(1.0, 1.0, np.nan), "l_bc"),
        (lambda: scara.Scara.create(1.0, 1.0, 1.0, limits={"theta9": (0, 1)}), "limits"),
        (lambda: scara.Scara.create(1.0, 1.0, 1.0, limits={"theta1": (1, 0)}), "theta1"),
        (lambda: scara.Scara.create(1.0, 1.0, 1.0, limits={"l3": 5.0}), "l3"),
        (lambda: scara.Scara.create(1.0, 1.0, 1.0, limits=[1, 2]), "limits"),
        (lambda: scara.ik(PAPER, np.zeros(2)), "d"),
        (lambda: scara.ik(PAPER, np.zeros(3), branch=0), "branch"),
        (lambda: scara.ik(PAPER, np.zeros(3), method="numeric"), "method"),
        (lambda: scara.ik((150.0, 80.0, 50.0), np.zeros(3)), "robot"),
        (lambda: scara.Scara(1.0, -2.0, 1.0), "Scara.l_ab"),
        (lambda: scara.ik(scara.Scara(np.ones(4), 1.0, 1.0), np.zeros((3, 3))), "batch"),
        (lambda: scara.fk(PAPER, np.zeros((5, 2))), "q"),
    ],
)
def test_bad_input_raises_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# --------------------------------------------------------------------------- batching, jit


def test_jit_over_trajectories_without_recompilation():
    rng = np.random.default_rng(5)
    d1 = random_reachable(rng, (4, 6))
    d2 = random_reachable(rng, (4, 6))
    scara.ik(PAPER, d1)
    with compilations() as count:
        res2 = scara.ik(PAPER, d2)
    assert count.n == 0
    assert res2.q.shape == (4, 6, 3)
    # Under a user's jit the result equals the eager call (tracers skip host validation).
    jitted = jax.jit(lambda robot, d: scara.ik(robot, d, branch=-1))
    assert_jet_close(jitted(PAPER, d2).q, scara.ik(PAPER, d2, branch=-1).q, rtol=1e-15)


def test_batched_geometry_equals_loop():
    rng = np.random.default_rng(9)
    lengths = np.array([[150.0, 80.0, 50.0], [100.0, 60.0, 70.0], [10.0, 5.0, 4.0]])
    robots = scara.Scara.create(*lengths.T)
    d = Jet.of(
        np.array([[100.0, 20.0, 30.0], [50.0, -80.0, 20.0], [-3.0, 4.0, 1.0]]),
        rng.normal(size=(3, 3)),
        rng.normal(size=(3, 3)),
    )
    batched = scara.ik(robots, d, branch=-1)
    for i in range(3):
        single = scara.ik(scara.Scara.create(*lengths[i]), d[i], branch=-1)
        assert_jet_close(batched.q[i], single.q, rtol=1e-14)
    # vmap over a geometry batch gives the same as broadcasting.
    vmapped = jax.vmap(lambda r, x: scara.ik(r, x, branch=-1))(robots, d)
    assert_jet_close(vmapped.q, batched.q, rtol=1e-14)


# --------------------------------------------------------------------------- float32


def test_float32_accuracy():
    """Measured bounds, documented in jaxkin/scara.py (errors relative per element)."""
    rng = np.random.default_rng(21)
    d64 = random_reachable(rng, (2000,))
    ref = scara.ik(PAPER, d64)
    for method in scara.METHODS:
        res = scara.ik(PAPER, d64.astype(jnp.float32), method=method)
        assert res.q.dtype == jnp.float32
        assert res.margin.dtype == jnp.float32
        assert np.all(np.asarray(res.status) == Status.OK)
        # name: (median bound, 99th percentile bound, max bound); measured 3e-8 medians,
        # 99th percentiles 6e-8 / 1e-6 / 7e-6, maxima 8e-8 / 3e-5 / 1e-4 (on 20,000 points).
        bounds = {"p": (1e-7, 2e-7, 3e-7), "v": (1e-7, 5e-6, 1e-4), "a": (1e-7, 3e-5, 4e-4)}
        for name, (med, p99, worst) in bounds.items():
            x = np.asarray(getattr(res.q, name), np.float64)
            y = np.asarray(getattr(ref.q, name))
            err = np.max(np.abs(x - y), axis=-1) / np.max(np.abs(y), axis=-1)
            assert np.median(err) < med, (method, name, np.median(err))
            assert np.percentile(err, 99) < p99, (method, name, np.percentile(err, 99))
            assert np.max(err) < worst, (method, name, np.max(err))
    # Along the spiral (sin(beta)^2 >= 0.09) each joint and rate to ~1e-6 of its range.
    d = spiral(np.linspace(0.0, 8.0, N))
    r64, r32 = scara.ik(PAPER, d), scara.ik(PAPER, d.astype(jnp.float32))
    for name in ("p", "v", "a"):
        x = np.asarray(getattr(r32.q, name), np.float64)[:, :2]
        y = np.asarray(getattr(r64.q, name))[:, :2]
        assert np.all(np.max(np.abs(x - y), 0) < 3e-6 * np.max(np.abs(y), 0)), name


# --------------------------------------------------------------------------- NumPy reference


@pytest.mark.parametrize("mode", [1, -1])
def test_numpy_reference_equals_jaxkin(mode):
    d = random_reachable(np.random.default_rng(13), (N,))
    q, q_d, q_dd = ik_numpy(
        np.asarray(d.p), np.asarray(d.v), np.asarray(d.a), L_OA, L_AB, L_BC, mode
    )
    res = scara.ik(PAPER, d, branch=mode)
    assert_jet_close(res.q, Jet.of(q, q_d, q_dd), rtol=1e-9)
