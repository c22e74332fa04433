"""RRR dyad [Noriega, sec. 2]: every check uses a source independent of the kernel.

Independent sources: sympy (C and phi from atan2/acos, differentiated symbolically), central
finite differences along smooth trajectories, the geometric invariants, and hand-built singular
configurations. Analytic and autodiff paths are also compared with each other.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxkin import Jet, Status, dyad
from tests.helpers import BATCH_SHAPES, compilations, fd_rates, tree_allfinite

t = sp.symbols("t", real=True)


def _close(actual, desired, rtol):
    """assert_allclose with the tolerance relative to the array's magnitude."""
    desired = np.asarray(desired)
    np.testing.assert_allclose(actual, desired, rtol=rtol, atol=rtol * np.max(np.abs(desired)))


# ---------------------------------------------------------------- sympy reference
def _sympy_reference(a_xy, b_xy, l_ac, l_bc, mode, t0):
    """C, phi and their two time derivatives at t0 from the textbook law-of-cosines form."""
    dx, dy = b_xy[0] - a_xy[0], b_xy[1] - a_xy[1]
    l = sp.sqrt(dx**2 + dy**2)
    beta = sp.acos((l_ac**2 + l**2 - l_bc**2) / (2 * l_ac * l))
    phi = sp.atan2(dy, dx) + mode * beta
    cx, cy = a_xy[0] + l_ac * sp.cos(phi), a_xy[1] + l_ac * sp.sin(phi)
    out = {}
    for name, expr in (("cx", cx), ("cy", cy), ("phi", phi)):
        out[name] = [float(sp.diff(expr, t, k).subs(t, t0).evalf(30)) for k in range(3)]
    return out


def _jet_at(xy, t0):
    return Jet.of(*([float(sp.diff(c, t, k).subs(t, t0)) for c in xy] for k in range(3)))


@pytest.mark.parametrize("method", ["analytic", "autodiff"])
@pytest.mark.parametrize("mode", [1, -1])
@pytest.mark.parametrize(
    "a_xy, b_xy, l_ac, l_bc, t0",
    [
        ((0.3 * sp.cos(t), 0.2 * t), (2 + 0.5 * sp.sin(2 * t), 0.4 * t**2), 1.7, 1.2, 0.6),
        ((sp.Integer(1), sp.Integer(-1)), (-1 + 0.2 * t, 0.5 + sp.sin(t)), 2.5, 1.4, 1.3),
        ((0.1 * t**2, sp.Integer(0)), (-2 - 0.3 * t, -0.5 * t), 1.0, 2.0, 0.9),
    ],
)
def test_matches_sympy_reference(a_xy, b_xy, l_ac, l_bc, t0, mode, method):
    ref = _sympy_reference(a_xy, b_xy, l_ac, l_bc, mode, t0)
    res = dyad.solve(_jet_at(a_xy, t0), _jet_at(b_xy, t0), l_ac, l_bc, mode, method)
    assert res.status == Status.OK
    for k, field in enumerate(("p", "v", "a")):
        c = getattr(res.c, field)
        np.testing.assert_allclose(c, [ref["cx"][k], ref["cy"][k]], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(getattr(res.phi, field), ref["phi"][k], rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------- random non-singular cases
finite = st.floats(-3.0, 3.0, allow_nan=False)
lengths = st.floats(0.2, 3.0)


@st.composite
def dyad_cases(draw):
    vec = st.tuples(finite, finite)
    a = Jet.of(draw(vec), draw(vec), draw(vec))
    b = Jet.of(draw(vec), draw(vec), draw(vec))
    return a, b, draw(lengths), draw(lengths)


@settings(max_examples=60, deadline=None)
@given(dyad_cases(), st.sampled_from([1, -1]))
def test_analytic_equals_autodiff(case, mode):
    a, b, l_ac, l_bc = case
    analytic = dyad.solve(a, b, l_ac, l_bc, mode, "analytic")
    autodiff = dyad.solve(a, b, l_ac, l_bc, mode, "autodiff")
    np.testing.assert_array_equal(analytic.status, autodiff.status)
    np.testing.assert_array_equal(analytic.margin, autodiff.margin)
    if analytic.status != Status.OK or analytic.margin < 1e-3:
        return  # rates are 0 placeholders (checked elsewhere) or ill-conditioned
    for x, y in ((analytic.c, autodiff.c), (analytic.phi, autodiff.phi)):
        # One kernel, positions scaled back in a different order: equal to an ulp or two.
        np.testing.assert_allclose(x.p, y.p, rtol=1e-15, atol=1e-15 * (l_ac + l_bc))
        _close(x.v, y.v, 1e-10)
        _close(x.a, y.a, 1e-10)


@settings(max_examples=60, deadline=None)
@given(dyad_cases(), st.sampled_from([1, -1]))
def test_geometric_invariants_and_side(case, mode):
    a, b, l_ac, l_bc = case
    res = dyad.solve(a, b, l_ac, l_bc, mode)
    if res.status != Status.OK:
        return
    c, ap, bp = np.asarray(res.c.p), np.asarray(a.p), np.asarray(b.p)
    np.testing.assert_allclose(np.linalg.norm(c - ap), l_ac, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(c - bp), l_bc, rtol=1e-12, atol=1e-12 * l_ac)
    ab, ac = bp - ap, c - ap
    cross = ab[0] * ac[1] - ab[1] * ac[0]
    assert np.sign(cross) == mode  # mode +1: C left of A->B
    # phi is the paper's unwrapped theta + mode * beta (eqs. 9-10).
    beta = np.arccos((l_ac**2 + ab @ ab - l_bc**2) / (2 * l_ac * np.linalg.norm(ab)))
    theta = np.arctan2(ab[1], ab[0]) if ab[1] != 0 else np.arctan2(0.0, ab[0])
    np.testing.assert_allclose(res.phi.p, theta + mode * beta, rtol=1e-9, atol=1e-9)
    # Velocity constraints: (C - A).(C_dot - A_dot) = 0 and (C - B).(C_dot - B_dot) = 0.
    cv = np.asarray(res.c.v)
    scale = 1.0 + np.abs(cv).max() + np.abs(np.asarray(b.v)).max()
    assert abs(ac @ (cv - np.asarray(a.v))) < 1e-9 * scale * l_ac
    assert abs((c - bp) @ (cv - np.asarray(b.v))) < 1e-9 * scale * l_ac


# ---------------------------------------------------------------- finite differences
def _smooth_path(rng, center):
    """A smooth planar path with exact derivatives: sums of two sinusoids per coordinate."""
    amp, freq, phase = rng.uniform(0.05, 0.3, (3, 2, 2))
    freq = 1.0 + 2.0 * freq

    def at(s, k):
        angle = freq * s + phase * 10
        terms = [np.sin, np.cos, lambda x: -np.sin(x)][k](angle) * amp * freq**k
        return (center if k == 0 else 0.0) + terms.sum(axis=-1)

    return at


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("method", ["analytic", "autodiff"])
def test_rates_match_finite_differences_along_trajectories(seed, method):
    rng = np.random.default_rng(seed)
    a_path = _smooth_path(rng, np.array([0.0, 0.0]))
    b_path = _smooth_path(rng, np.array([1.5, 0.4]))
    l_ac, l_bc, mode = 1.2, 0.9, (1 if seed % 2 else -1)

    def solve_at(s):
        a = Jet.of(a_path(s, 0), a_path(s, 1), a_path(s, 2))
        b = Jet.of(b_path(s, 0), b_path(s, 1), b_path(s, 2))
        return dyad.solve(a, b, l_ac, l_bc, mode, method)

    for s in np.linspace(0.0, 2.0, 5):
        res = solve_at(s)
        assert res.status == Status.OK
        for jet, pick in ((res.c, lambda r: r.c.p), (res.phi, lambda r: r.phi.p)):
            v_fd, a_fd = fd_rates(lambda x, pick=pick: np.asarray(pick(solve_at(x))), s)
            _close(jet.v, v_fd, 1e-9)
            _close(jet.a, a_fd, 1e-7)  # second differences: O(h^4) error ~1e-9, rounding ~1e-8


# ---------------------------------------------------------------- statuses
def _constructed_cases():
    """(a, b, l_ac, l_bc, expected status, expected C or None), each built by hand."""
    s = np.sin(0.3)
    c = np.cos(0.3)
    nan = float("nan")
    return [
        ((0, 0), (2, 0), 1.5, 1.0, Status.OK, None),
        ((0, 0), (3, 0), 1.0, 1.0, Status.UNREACHABLE, None),  # too far
        ((0, 0), (0.5, 0), 2.0, 1.0, Status.UNREACHABLE, None),  # inside the inner circle
        ((1, 1), (1, 1), 2.0, 1.0, Status.UNREACHABLE, None),  # A = B, unequal links
        ((0, 0), (2, 0), 1.0, 1.0, Status.SINGULAR_EXTENDED, (1, 0)),  # C between A and B
        ((0, 0), (1, 0), 2.0, 1.0, Status.SINGULAR_EXTENDED, (2, 0)),  # B between A and C
        ((0, 0), (1, 0), 1.0, 2.0, Status.SINGULAR_FOLDED, (-1, 0)),  # A between C and B
        (
            (1, 2),
            (1 + 5 * c, 2 + 5 * s),
            2.0,
            3.0,
            Status.SINGULAR_EXTENDED,
            (1 + 2 * c, 2 + 2 * s),
        ),
        ((1, 1), (1, 1), 1.5, 1.5, Status.SINGULAR_COINCIDENT, None),
        ((0, 0), (2 * (1 - 1e-6), 0), 1.0, 1.0, Status.OK, None),  # near, not at, the boundary
        ((0, nan), (2, 0), 1.5, 1.0, Status.INVALID_INPUT, None),
        ((0, 0), (2, 0), nan, 1.0, Status.INVALID_INPUT, None),
        ((0, 0), (np.inf, 0), 1.5, 1.0, Status.INVALID_INPUT, None),
    ]


@pytest.mark.parametrize("method", ["analytic", "autodiff"])
def test_every_status_on_constructed_cases_in_one_batch(method):
    cases = _constructed_cases()
    a = Jet.constant(np.array([case[0] for case in cases], float))
    b = Jet.constant(np.array([case[1] for case in cases], float))
    l_ac = np.array([case[2] for case in cases])
    l_bc = np.array([case[3] for case in cases])
    res = dyad.solve(a, b, l_ac, l_bc, 1, method)
    np.testing.assert_array_equal(res.status, [case[4] for case in cases])
    assert tree_allfinite(res)
    for i, case in enumerate(cases):
        if case[5] is not None:
            np.testing.assert_allclose(res.c.p[i], case[5], atol=1e-12)
        if case[4] != Status.OK:
            np.testing.assert_array_equal(res.c.v[i], 0.0)
            np.testing.assert_array_equal(res.phi.a[i], 0.0)
    margin = np.asarray(res.margin)
    assert np.all(margin[res.status == Status.UNREACHABLE] < 0)
    assert np.all(margin[res.status == Status.OK] > 0)
    assert np.all(margin[np.isin(res.status, [2, 3, 4])] == 0)


@pytest.mark.parametrize("mode", [1, -1])
def test_position_equals_the_position_part_of_solve(mode):
    """``dyad.position`` on constructed cases (every status) and random dyads, per-element and
    scalar lengths: C, phi, status and margin equal ``solve``'s; gradients stay finite."""
    rng = np.random.default_rng(21)
    cases = _constructed_cases()
    a = np.concatenate([[c[0] for c in cases], rng.normal(size=(200, 2)) * 0.3])
    b = np.concatenate([[c[1] for c in cases], rng.normal(size=(200, 2)) * 0.3 + [1.5, 0]])
    l_ac = np.concatenate([[c[2] for c in cases], rng.uniform(0.5, 1.5, 200)])
    l_bc = np.concatenate([[c[3] for c in cases], rng.uniform(0.5, 1.5, 200)])
    for lengths in ((l_ac, l_bc), (1.1, 0.8)):
        full = dyad.solve(a, b, *lengths, mode)
        pos = dyad.position(a, b, *lengths, mode)
        assert pos.c.shape == (len(a), 2) and pos.phi.shape == (len(a),)
        np.testing.assert_array_equal(pos.status, full.status)
        # Same formulas; XLA may fuse them differently, so equal to rounding.
        np.testing.assert_allclose(pos.c, full.c.p, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(pos.phi, full.phi.p, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(pos.margin, full.margin, rtol=1e-14, atol=1e-14)
        assert tree_allfinite(pos)
    grad = jax.grad(lambda b: dyad.position(a, b, l_ac, l_bc, mode).c.sum())(jnp.asarray(b))
    assert tree_allfinite(grad)
    with pytest.raises(ValueError, match="b: expected shape"):
        dyad.position(a, b[:, :1], 1.0, 1.0)
    with pytest.raises(ValueError, match="l_bc"):
        dyad.position(a, b, 1.0, -1.0)
    with pytest.raises(ValueError, match="mode"):
        dyad.position(a, b, 1.0, 1.0, mode=0)


@pytest.mark.parametrize("shape", [(33,), (3, 11)])
def test_autodiff_with_bad_elements_equals_analytic(shape):
    """The autodiff path on a batch holding an invalid and an unreachable element: the same
    statuses as the analytic path, finite placeholders, and the same values elsewhere."""
    rng = np.random.default_rng(17)
    a = Jet.of(*(rng.normal(size=(*shape, 2)) * 0.2 for _ in range(3)))
    b_p = rng.normal(size=(*shape, 2)) * 0.2 + [1.6, 0.0]
    b_p[(0,) * len(shape)] = np.nan  # one invalid element
    b_p[tuple(s - 1 for s in shape)] = [9.0, 0.0]  # one unreachable
    b = Jet.of(b_p, *rng.normal(size=(2, *shape, 2)))
    l_ac = rng.uniform(0.8, 1.4, shape)
    args = (a, b, l_ac, 0.9, -1, "autodiff")
    autodiff = dyad.solve(*args)
    for x in jax.tree.leaves(autodiff):
        assert x.shape[: len(shape)] == shape and np.all(np.isfinite(x))
    analytic = dyad.solve(a, b, l_ac, 0.9, -1, "analytic")
    np.testing.assert_array_equal(autodiff.status, analytic.status)
    assert autodiff.status[(0,) * len(shape)] == Status.INVALID_INPUT
    assert autodiff.status[tuple(s - 1 for s in shape)] == Status.UNREACHABLE
    # As in test_analytic_equals_autodiff: rates compared where well conditioned.
    ok = (np.asarray(analytic.status) == Status.OK) & (np.asarray(analytic.margin) >= 1e-3)
    for x, y in ((autodiff.c, analytic.c), (autodiff.phi, analytic.phi)):
        _close(np.asarray(x.p)[ok], np.asarray(y.p)[ok], 1e-14)  # same kernel: an ulp
        _close(np.asarray(x.v)[ok], np.asarray(y.v)[ok], 1e-10)
        _close(np.asarray(x.a)[ok], np.asarray(y.a)[ok], 1e-10)


def test_a_bad_element_does_not_change_its_neighbours():
    rng = np.random.default_rng(5)
    a = Jet.of(*(rng.normal(size=(6, 2)) * 0.1 for _ in range(3)))
    b = Jet.of(rng.normal(size=(6, 2)) * 0.1 + [1.5, 0], rng.normal(size=(6, 2)), a.a)
    clean = dyad.solve(a, b, 1.0, 1.0)
    poisoned = Jet(b.p.at[2].set(jnp.nan), b.v.at[4].set(jnp.inf), b.a)
    dirty = dyad.solve(a, poisoned, 1.0, 1.0)
    keep = np.array([0, 1, 3, 5])
    np.testing.assert_array_equal(dirty.c.a[keep], clean.c.a[keep])
    assert list(np.asarray(dirty.status)[[2, 4]]) == [Status.INVALID_INPUT] * 2


@pytest.mark.parametrize("method", ["analytic", "autodiff"])
def test_gradients_are_finite_on_a_batch_mixing_every_status(method):
    cases = _constructed_cases()
    a = Jet.of(np.array([c[0] for c in cases], float), np.ones((len(cases), 2)))
    b = Jet.of(np.array([c[1] for c in cases], float), np.ones((len(cases), 2)) * 0.5)
    l_ac = jnp.array([c[2] for c in cases])
    l_bc = jnp.array([c[3] for c in cases])

    def loss(a, b, l_ac, l_bc):
        res = dyad.solve(a, b, l_ac, l_bc, 1, method)
        ok = res.status == Status.OK
        masked = jnp.where(ok[:, None], res.c.p + res.c.v + res.c.a, 0.0).sum()
        return masked + jnp.where(ok, res.phi.a, 0.0).sum() + res.margin.sum() + res.c.p.sum()

    grads = jax.grad(loss, argnums=(0, 1, 2, 3))(a, b, l_ac, l_bc)
    assert tree_allfinite(grads)
    assert np.abs(np.asarray(grads[1].p[0])).sum() > 0  # the OK element does get a gradient


@pytest.mark.parametrize("method", ["analytic", "autodiff"])
def test_scalar_lengths_equal_broadcast_lengths(method):
    """Scalar l_ac/l_bc take a separate (scalar) path: same values as per-element arrays; a
    non-finite scalar length makes every element INVALID_INPUT with finite gradients."""
    rng = np.random.default_rng(9)
    a = Jet.of(*(rng.normal(size=(40, 2)) * 0.2 for _ in range(3)))
    b = Jet.of(rng.normal(size=(40, 2)) * 0.2 + [1.6, 0], *rng.normal(size=(2, 40, 2)))
    scalar = dyad.solve(a, b, 1.2, 0.9, -1, method)
    arrays = dyad.solve(a, b, np.full(40, 1.2), np.full(40, 0.9), -1, method)
    # Equal to rounding: the scalar path folds terms such as 0.5 / l_ac before multiplying.
    for x, y in zip(jax.tree.leaves(scalar), jax.tree.leaves(arrays), strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)
    assert np.any(scalar.status == Status.OK) and np.any(scalar.status != Status.OK)

    def loss(l_ac):
        res = dyad.solve(a, b, l_ac, 0.9, 1, method)
        return jnp.where(res.ok, res.phi.a, 0.0).sum() + res.c.p.sum() + res.margin.sum()

    nan_result = dyad.solve(a, b, float("nan"), 0.9, 1, method)
    assert np.all(nan_result.status == Status.INVALID_INPUT) and tree_allfinite(nan_result)
    assert np.isfinite(jax.grad(loss)(jnp.nan)) and jax.grad(loss)(1.2) != 0


# ---------------------------------------------------------------- batching and compilation
@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_batch_shapes_and_per_element_equality(shape):
    rng = np.random.default_rng(1)
    a = Jet.of(*(rng.normal(size=(*shape, 2)) * 0.2 for _ in range(3)))
    b = Jet.of(*(rng.normal(size=(*shape, 2)) * 0.2 + [1.4, 0.2] for _ in range(3)))
    res = dyad.solve(a, b, 1.0, 0.8, -1)
    assert res.c.shape == (*shape, 2) and res.status.shape == shape
    assert res.status.dtype == jnp.int8
    flat = jax.tree.map(lambda x: np.asarray(x).reshape(-1, *np.shape(x)[len(shape) :]), (a, b))
    for i in range(int(np.prod(shape))):
        one = dyad.solve(flat[0][i], flat[1][i], 1.0, 0.8, -1)
        # vectorised and scalar code round differently: 1e-14 of the acceleration's size
        got = np.asarray(res.c.a).reshape(-1, 2)[i]
        np.testing.assert_allclose(got, one.c.a, rtol=0, atol=1e-14 * np.abs(one.c.a).max())


def test_lengths_broadcast_per_element():
    a = Jet.constant(np.zeros((3, 2)))
    b = Jet.constant(np.array([[1.0, 0.0]] * 3))
    res = dyad.solve(a, b, np.array([1.0, 2.0, 5.0]), 1.0)
    np.testing.assert_array_equal(
        res.status, [Status.OK, Status.SINGULAR_EXTENDED, Status.UNREACHABLE]
    )


def test_jit_vmap_over_candidates_and_samples_without_recompilation():
    rng = np.random.default_rng(2)

    def batch(seed_shift):
        r = np.random.default_rng(seed_shift)
        a = Jet.of(*(r.normal(size=(8, 16, 2)) * 0.1 for _ in range(3)))
        b = Jet.of(*(r.normal(size=(8, 16, 2)) * 0.1 + [1.0, 0.5] for _ in range(3)))
        return a, b

    a, b = batch(0)
    first = dyad.solve(a, b, 1.0, 0.7)
    with compilations() as count:
        second = dyad.solve(*batch(1), 1.0, 0.7)
    assert count.n == 0
    assert not np.allclose(first.c.p, second.c.p)

    # A user's own jit(vmap(...)) around solve traces it with tracers: no host checks fail.
    user = jax.jit(jax.vmap(lambda a, b: dyad.solve(a, b, 1.0, 0.7).c.a))
    np.testing.assert_allclose(user(a, b), first.c.a, rtol=1e-13)
    del rng


def test_plain_arrays_are_points_at_rest():
    res = dyad.solve(np.zeros(2), np.array([2.0, 0.0]), 1.5, 1.0)
    assert res.status == Status.OK
    np.testing.assert_array_equal(res.c.v, 0.0)
    x = (1.5**2 + 4 - 1) / 4  # C.x from the law of cosines, by hand
    np.testing.assert_allclose(res.c.p, [x, np.sqrt(1.5**2 - x**2)], rtol=1e-15)


# ---------------------------------------------------------------- float32
def test_float32_accuracy():
    """Measured float32 error on well-conditioned dyads (sin(beta) > 0.05), stated in dyad.py."""
    rng = np.random.default_rng(3)
    n = 4000
    a = Jet.of(*(rng.normal(size=(n, 2)) * s for s in (0.3, 1.0, 1.0)))
    b = Jet.of(*(rng.normal(size=(n, 2)) * s + o for s, o in ((0.3, [1.6, 0]), (1, 0), (1, 0))))
    ref = dyad.solve(a, b, 1.2, 0.9)
    f32 = dyad.solve(a.astype(jnp.float32), b.astype(jnp.float32), 1.2, 0.9)
    assert f32.c.p.dtype == jnp.float32 and f32.phi.a.dtype == jnp.float32
    good = np.asarray((ref.status == 0) & (f32.status == 0) & (ref.margin > 0.05**2))
    assert good.mean() > 0.5

    def rel(x, y):
        x, y = np.asarray(x, float)[good], np.asarray(y)[good]
        return np.max(np.abs(x - y)) / np.max(np.abs(y))

    assert rel(f32.c.p, ref.c.p) < 3e-6
    assert rel(f32.c.v, ref.c.v) < 2e-4
    assert rel(f32.c.a, ref.c.a) < 5e-4
    assert np.mean(ref.status != f32.status) < 0.01


# ---------------------------------------------------------------- boundary errors
@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"l_ac": 0.0}, "l_ac"),
        ({"l_bc": -1.0}, "l_bc"),
        ({"l_ac": np.array([1.0, -2.0])}, "l_ac"),
        ({"a": np.zeros((3, 3))}, "a: expected shape"),
        ({"b": np.zeros(3)}, "b: expected shape"),
        ({"a": np.zeros((3, 2)), "b": np.ones((4, 2))}, "do not broadcast"),
        ({"mode": 0}, "mode"),
        ({"mode": 2}, "mode"),
        ({"mode": True}, "mode"),
        ({"method": "numeric"}, "method"),
        ({"a": Jet(np.zeros(2), np.zeros(3), np.zeros(2))}, "one shape"),
    ],
)
def test_bad_input_raises_value_error_naming_the_argument(kwargs, match):
    args = {"a": np.zeros(2), "b": np.array([1.0, 0.0]), "l_ac": 1.0, "l_bc": 1.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        dyad.solve(**args)


def test_raise_if_failed_names_indices():
    res = dyad.solve(np.zeros((3, 2)), np.array([[1.0, 0], [9.0, 0], [1.0, 0]]), 1.0, 1.0)
    assert list(np.asarray(res.ok)) == [True, False, True]
    with pytest.raises(RuntimeError, match=r"index \(1,\): UNREACHABLE"):
        res.raise_if_failed()
