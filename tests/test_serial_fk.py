"""The chain's forward kinematics from DH tables and screws, the DH kernel, Jacobians and
validation [Lopez-Villagomez, eqs. 2-6], [Pineiro]."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

import jaxkin
from jaxkin import lie, serial
from jaxkin.serial import _kinematics, dh
from tests.helpers import BATCH_SHAPES, compilations

# PUMA-560-type arm, standard DH (Corke's Robotics Toolbox p560 kinematic parameters, metres).
from tests.references.serial import PUMA

RNG = np.random.default_rng(5)


def _fk(chain, q):
    """The one documented way to the tip's 4x4 transform: ``jaxkin.fk(chain, q).x.p``."""
    return np.asarray(jaxkin.fk(chain, q).x.p)


def _fk_dh(table, q):
    """The chain of a DH table (``serial.from_dh``): its tip transform at ``q``."""
    return _fk(serial.from_dh(table), q)


def _lopez_villagomez_arm(l1=0.5, l2=0.4, l3=0.3):
    """[Lopez-Villagomez, Table 1]: d = (L1, 0, 0), a = (0, L2, L3), alpha = (90 deg, 0, 0)."""
    return dh.DHTable.create(
        a=[0.0, l2, l3], alpha=[np.pi / 2, 0.0, 0.0], d=[l1, 0.0, 0.0], joint_types="RRR"
    )


def _sympy_dh(a, alpha, d, theta):
    """Rz(theta) Tz(d) Tx(a) Rx(alpha), built from elementary sympy matrices."""
    c, s = sp.cos, sp.sin
    rz = sp.Matrix([[c(theta), -s(theta), 0, 0], [s(theta), c(theta), 0, 0], [0, 0, 1, 0],
                    [0, 0, 0, 1]])  # fmt: skip
    tz = sp.Matrix([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, d], [0, 0, 0, 1]])
    tx = sp.Matrix([[1, 0, 0, a], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    rx = sp.Matrix([[1, 0, 0, 0], [0, c(alpha), -s(alpha), 0], [0, s(alpha), c(alpha), 0],
                    [0, 0, 0, 1]])  # fmt: skip
    return rz * tz * tx * rx


def test_dh_transform_matches_elementary_product():
    syms = sp.symbols("a alpha d theta")
    f = sp.lambdify(syms, _sympy_dh(*syms), "numpy")
    vals = RNG.normal(size=(6, 4))
    ours = dh.dh_transform(vals[:, 0], vals[:, 1], vals[:, 2], vals[:, 3])
    for row, mat in zip(vals, ours, strict=True):
        np.testing.assert_allclose(mat, np.array(f(*row), dtype=float), atol=1e-15)


def test_dh_transform_is_lopez_villagomez_arm_eq2():
    # [Lopez-Villagomez, eq. 2], transcribed entry by entry.
    a, al, d, th = 0.3, 0.7, -0.2, 1.1
    ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
    eq2 = np.array(
        [
            [ct, -ca * st, sa * st, a * ct],
            [st, ca * ct, -sa * ct, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    np.testing.assert_allclose(dh.dh_transform(a, al, d, th), eq2, atol=1e-16)


def test_lopez_villagomez_arm_arm_matches_sympy_and_hand_formula():
    l1, l2, l3 = 0.5, 0.4, 0.3
    t1, t2, t3 = sp.symbols("t1 t2 t3")
    total = (
        _sympy_dh(0, sp.pi / 2, l1, t1) * _sympy_dh(l2, 0, 0, t2) * _sympy_dh(l3, 0, 0, t3)
    )  # [Lopez-Villagomez, eqs. 3-6]
    f = sp.lambdify((t1, t2, t3), sp.simplify(total), "numpy")
    table = _lopez_villagomez_arm(l1, l2, l3)
    q = RNG.uniform(-np.pi, np.pi, size=(5, 3))
    q[0] = 0.0
    q[1] = [np.pi / 2, 0.0, -np.pi / 2]
    ours = _fk_dh(table, q)
    for qi, mat in zip(q, ours, strict=True):
        np.testing.assert_allclose(mat, np.array(f(*qi), dtype=float), atol=1e-15)
        # Hand-derived wrist position: r = L2 c2 + L3 c23, p = (c1 r, s1 r, L1 + L2 s2 + L3 s23).
        r = l2 * np.cos(qi[1]) + l3 * np.cos(qi[1] + qi[2])
        z = l1 + l2 * np.sin(qi[1]) + l3 * np.sin(qi[1] + qi[2])
        np.testing.assert_allclose(
            mat[:3, 3], [np.cos(qi[0]) * r, np.sin(qi[0]) * r, z], atol=1e-15
        )
    # q = 0: arm stretched along +x at height L1, eq. 3's frame 1 has z1 = -y0... by hand:
    np.testing.assert_allclose(
        ours[0],
        [[1, 0, 0, l2 + l3], [0, 0, -1, 0], [0, 1, 0, l1], [0, 0, 0, 1]],
        atol=1e-15,
    )


def test_planar_2r_closed_form():
    table = dh.DHTable.create(a=[1.0, 0.7], alpha=[0.0, 0.0], d=[0.0, 0.0])
    q = RNG.normal(size=(8, 2))
    t = _fk_dh(table, q)
    c1, s1 = np.cos(q[:, 0]), np.sin(q[:, 0])
    c12, s12 = np.cos(q.sum(1)), np.sin(q.sum(1))
    np.testing.assert_allclose(t[:, 0, 3], c1 + 0.7 * c12, atol=1e-15)
    np.testing.assert_allclose(t[:, 1, 3], s1 + 0.7 * s12, atol=1e-15)
    rot = np.stack([np.stack([c12, -s12], -1), np.stack([s12, c12], -1)], -2)
    np.testing.assert_allclose(t[:, :2, :2], rot, atol=1e-15)
    np.testing.assert_allclose(t[:, 2, 2], 1.0)


def test_prismatic_joint_and_offsets():
    # Cylindrical-type chain R P P: q2 lifts along z0' (alpha1 = 0), q3 extends along x.
    table = dh.DHTable.create(
        a=[0.0, 0.0, 0.0],
        alpha=[0.0, -np.pi / 2, 0.0],
        d=[0.2, 0.1, 0.05],
        theta=[0.3, 0.0, 0.0],
        joint_types=["R", "P", "P"],
    )
    q = np.array([0.4, 0.6, 0.25])
    t = _fk_dh(table, q)
    # By hand: base rotation phi = 0.3 + 0.4 about z; height 0.2 + (0.1 + 0.6); reach
    # 0.05 + 0.25 along z2 = Rx(-90 deg) z1 = y1 = (-sin phi, cos phi, 0), horizontal.
    phi = 0.7
    np.testing.assert_allclose(t[:3, 3], [-0.3 * np.sin(phi), 0.3 * np.cos(phi), 0.9], atol=1e-15)
    syms = [_sympy_dh(0, 0, 0.2, 0.3 + 0.4), _sympy_dh(0, -sp.pi / 2, 0.1 + 0.6, 0),
            _sympy_dh(0, 0, 0.05 + 0.25, 0)]  # fmt: skip
    np.testing.assert_allclose(
        t, np.array((syms[0] * syms[1] * syms[2]).evalf(), dtype=float), atol=1e-15
    )


def test_all_frames_of_the_dh_kernel():
    table = dh.DHTable.create(**PUMA)
    q = RNG.normal(size=(3, 6))
    frames = np.asarray(dh.transforms(table, jnp.asarray(q), all_frames=True))
    assert frames.shape == (3, 6, 4, 4)
    np.testing.assert_allclose(frames[:, -1], dh.transforms(table, jnp.asarray(q)), atol=1e-15)
    links = np.asarray(dh.dh_transform(table.a, table.alpha, table.d, table.theta + q))
    acc = np.broadcast_to(np.eye(4), (3, 4, 4))
    for i in range(6):
        acc = acc @ links[:, i]
        np.testing.assert_allclose(frames[:, i], acc, atol=1e-15)
    # The chain built from the table has the same tip (two product orders: a few ulp).
    np.testing.assert_allclose(_fk_dh(table, q), frames[:, -1], atol=1e-15)


def _random_table(rng, joint_types):
    n = len(joint_types)
    return dh.DHTable.create(
        a=rng.uniform(-1, 1, n),
        alpha=rng.uniform(-np.pi, np.pi, n),
        d=rng.uniform(-1, 1, n),
        theta=rng.uniform(-np.pi, np.pi, n),
        joint_types=joint_types,
    )


def _body_screws(chain):
    """``B_i = Ad(M^-1) S_i`` by NumPy, from the chain's base-frame screws."""
    screws, home = np.asarray(chain.screws), np.asarray(chain.home)
    rot, p = home[:3, :3], home[:3, 3]
    w, v = screws[:, :3], screws[:, 3:]
    return np.concatenate([w @ rot, (v - np.cross(p, w)) @ rot], axis=1)


@pytest.mark.parametrize("joint_types", ["RR", "RPR", "PRRP", "RRRRRRR"])
def test_chain_from_dh_and_from_screws_match_the_dh_kernel(joint_types):
    rng = np.random.default_rng(len(joint_types))
    table = _random_table(rng, joint_types)
    chain = serial.from_dh(table)
    assert chain.joint_types == joint_types
    q = rng.normal(size=(10, len(joint_types)))
    expected = np.asarray(dh.transforms(table, jnp.asarray(q)))
    np.testing.assert_allclose(_fk(chain, q), expected, atol=1e-13)
    space = serial.from_screws(chain.screws, chain.home)
    np.testing.assert_array_equal(_fk(space, q), _fk(chain, q))
    body = serial.from_screws(_body_screws(chain), chain.home, frame="body")
    np.testing.assert_allclose(body.screws, chain.screws, atol=1e-14)
    np.testing.assert_allclose(_fk(body, q), expected, atol=1e-13)


def test_pineiro_planar_2r_body_chain():
    # [Pineiro]: M = Trans(2, 0, 0), B1 = (0, 0, 1, 0, 2, 0), B2 = (0, 0, 1, 0, 1, 0), L = 1 m.
    home = np.eye(4)
    home[0, 3] = 2.0
    screws = np.array([[0, 0, 1, 0, 2, 0], [0, 0, 1, 0, 1, 0]], dtype=float)
    q = RNG.normal(size=(6, 2))
    t = _fk(serial.from_screws(screws, home, frame="body"), q)
    np.testing.assert_allclose(t[:, 0, 3], np.cos(q[:, 0]) + np.cos(q.sum(1)), atol=1e-15)
    np.testing.assert_allclose(t[:, 1, 3], np.sin(q[:, 0]) + np.sin(q.sum(1)), atol=1e-15)
    np.testing.assert_allclose(t[:, 0, 0], np.cos(q.sum(1)), atol=1e-15)
    # Space screws of the same arm: S1 = (0,0,1, 0,0,0), S2 = (0,0,1, 0,-1,0).
    space = np.array([[0, 0, 1, 0, 0, 0], [0, 0, 1, 0, -1, 0]], dtype=float)
    np.testing.assert_allclose(_fk(serial.from_screws(space, home), q), t, atol=1e-15)


@jax.jit
def _twists_by_autodiff(chain, q):
    """Space and body Jacobians from jax.jacfwd of FK: [V_s] = dT T^-1, [V_b] = T^-1 dT."""
    t = _kinematics.pose(chain, q)
    dt = jnp.moveaxis(jax.jacfwd(lambda x: _kinematics.pose(chain, x))(q), -1, 0)  # (n,4,4)
    inv = lie.se3_inverse(t)
    return lie.se3_vee(dt @ inv).T, lie.se3_vee(inv @ dt).T


@pytest.mark.parametrize("joint_types", ["RRR", "RPRP", "RRRRRR"])
def test_jacobians_match_autodiff(joint_types):
    rng = np.random.default_rng(7)
    chain = serial.from_dh(_random_table(rng, joint_types))
    for q in rng.normal(size=(2, len(joint_types))):
        js, jb = _twists_by_autodiff(chain, jnp.asarray(q))
        np.testing.assert_allclose(serial.space_jacobian(chain, q), js, atol=1e-13)
        np.testing.assert_allclose(serial.body_jacobian(chain, q), jb, atol=1e-13)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_batch_shapes_and_loop(shape):
    chain = serial.from_dh(dh.DHTable.create(**PUMA))
    q = RNG.normal(size=(*shape, 6))
    t = _fk(chain, q)
    assert t.shape == (*shape, 4, 4)
    assert serial.space_jacobian(chain, q).shape == (*shape, 6, 6)
    flat, t_flat = q.reshape(-1, 6), t.reshape(-1, 4, 4)
    for i in range(min(len(flat), 3)):
        np.testing.assert_allclose(t_flat[i], _fk(chain, flat[i]), atol=1e-15)


def test_no_recompilation_and_user_jit():
    table = dh.DHTable.create(**PUMA)
    q = RNG.normal(size=(4, 6))
    chain = serial.from_dh(table)
    _fk(chain, q)
    serial.space_jacobian(chain, q)
    other = dh.DHTable.create(**{**PUMA, "a": [0.1, 0.5, 0.0, 0.0, 0.0, 0.0]})
    renamed = serial.from_dh(other, joint_names=list("abcdef"), tip_link="flange")
    with compilations() as count:
        _fk(renamed, q + 1.0)
        serial.space_jacobian(renamed, -q)
    assert count.n == 0
    # Under a user's jit, with the geometry traced (calibration-style differentiation).
    fk = jax.jit(lambda c, x: jaxkin.fk(c, x).x.p)
    np.testing.assert_allclose(fk(chain, q), _fk(chain, q), atol=1e-15)
    grad = jax.grad(lambda c: jaxkin.fk(c, q).x.p[..., 0, 3].sum())(chain)
    assert np.all(np.isfinite(np.asarray(grad.screws)))


def test_float32_and_nan_isolation():
    chain = serial.from_dh(_lopez_villagomez_arm())
    q = RNG.normal(size=(5, 3)).astype(np.float32)
    t32 = _fk(chain.astype(jnp.float32), q)
    assert t32.dtype == np.float32
    np.testing.assert_allclose(t32, _fk(chain, q.astype(np.float64)), atol=1e-6)
    q = np.zeros((3, 3))
    q[1, 0] = np.nan
    result = jaxkin.fk(chain, q)
    assert [jaxkin.Status(int(s)).name for s in result.status] == ["OK", "INVALID_INPUT", "OK"]
    assert np.all(np.isfinite(np.asarray(result.x.p)))
    np.testing.assert_array_equal(result.x.p[1], _fk(chain, np.zeros(3)))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(a=[[0.0, 1.0]], alpha=[0, 0], d=[0, 0]), r"DHTable\.a must be of shape \(-1,\)"),
        (dict(a=[0.0, 1.0], alpha=[0.0], d=[0, 0]), "alpha: expected 2 entries"),
        (dict(a=[0.0, 1.0], alpha=[0, 0], d=[0, np.nan]), r"DHTable\.d must be an array of finite"),
        (dict(a=[0.0, 1.0], alpha=[0, 0], d=[0, 0], theta=[0, 0, 0]), "theta: expected 2"),
        (dict(a=[0.0, 1.0], alpha=[0, 0], d=[0, 0], joint_types="RX"), "joint_types"),
        (dict(a=[0.0, 1.0], alpha=[0, 0], d=[0, 0], joint_types="RRR"), "joint_types"),
        (dict(a=[], alpha=[], d=[]), "at least one joint"),
    ],
)
def test_malformed_dh_tables(kwargs, match):
    with pytest.raises(ValueError, match=match):
        dh.DHTable.create(**kwargs)


def test_bad_inputs():
    chain = serial.from_dh(_lopez_villagomez_arm())
    with pytest.raises(ValueError, match=r"q: .*shape \(\.\.\., 3\)"):
        jaxkin.fk(chain, np.zeros((4, 2)))
    with pytest.raises(ValueError, match=r"q: expected shape \(\.\.\., 3\)"):
        serial.body_jacobian(chain, np.zeros(2))
    with pytest.raises(ValueError, match="table: expected a serial.DHTable"):
        serial.from_dh({"a": 1})
    with pytest.raises(ValueError, match="chain: expected a serial.Chain"):
        serial.space_jacobian(_lopez_villagomez_arm(), np.zeros(3))


@pytest.mark.parametrize(
    "screws, home, frame, match",
    [
        (np.zeros((2, 5)), np.eye(4), "space", r"screws: expected shape \(m, 6\)"),
        (np.zeros((0, 6)), np.eye(4), "space", "screws: expected shape"),
        ([[0, 0, 2.0, 0, 0, 0]], np.eye(4), "space", "rows \\[0\\] are not unit screws"),
        ([[0, 0, 0.0, 0, 0, 0]], np.eye(4), "space", "not unit screws"),
        ([[0, 0, 0.0, 0, 3.0, 0]], np.eye(4), "space", "not unit screws"),
        ([[0, 0, np.nan, 0, 0, 0]], np.eye(4), "space", "not unit screws"),
        ([[0, 0, 1.0, 0, 0, 0]], np.eye(3), "space", "home: expected shape \\(4, 4\\)"),
        ([[0, 0, 1.0, 0, 0, 0]], 2 * np.eye(4), "space", "home: expected a rigid"),
        ([[0, 0, 1.0, 0, 0, 0]], np.diag([1.0, 1.0, -1.0, 1.0]), "space", "home: expected"),
        ([[0, 0, 1.0, 0, 0, 0]], np.eye(4), "world", "frame must be one of"),
    ],
)
def test_malformed_screws(screws, home, frame, match):
    with pytest.raises(ValueError, match=match):
        serial.from_screws(screws, home, frame)


def test_chain_create_refuses_malformed_fields():
    screws, home = np.array([[0, 0, 1.0, 0, 0, 0]]), np.eye(4)
    with pytest.raises(ValueError, match=r"Chain\.screws must be an array of finite"):
        serial.Chain.create([[0, 0, np.nan, 0, 0, 0]], home)
    with pytest.raises(ValueError, match=r"Chain\.joint_names: expected 1 unique"):
        serial.Chain.create(screws, home, joint_names=["a", "b"])
    with pytest.raises(ValueError, match=r"Chain\.joint_kinds"):
        serial.Chain.create(screws, home, joint_kinds=["hinge"])
    with pytest.raises(ValueError, match=r"Chain\.tip_link: expected a string"):
        serial.Chain.create(screws, home, tip_link=3)
