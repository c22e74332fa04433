"""SO(3)/SE(3) helpers: against jax.scipy.linalg.expm, each other, and autodiff identities."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.scipy.linalg import expm

from jaxkin import lie
from tests.helpers import BATCH_SHAPES, tree_allfinite

RNG = np.random.default_rng(1)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _twists_with_angles(angles, rng=RNG):
    """Twists (k, 6) whose rotation angle is each of ``angles``."""
    angles = np.asarray(angles, dtype=np.float64)
    axes = _unit(rng.normal(size=(len(angles), 3)))
    v = rng.normal(size=(len(angles), 3))
    return np.concatenate([axes * angles[:, None], v], axis=-1)


# Angles that exercise the exact formulas, the Taylor branch (< 0.055 in float64) and both
# sides of the switch, pi/2 (the so3_log branch switch) and the approach to pi.
ANGLES = [0.0, 1e-12, 1e-8, 1e-4, 0.01, 0.05, 0.06, 0.5, 1.0, np.pi / 2 - 1e-9, 2.0, 3.0,
          np.pi - 1e-4, np.pi - 1e-7, np.pi - 1e-10]  # fmt: skip


def test_hat_vee():
    a, b = RNG.normal(size=(2, 5, 3))
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", lie.hat(a), b), np.cross(a, b))
    np.testing.assert_allclose(lie.vee(lie.hat(a)), a)
    np.testing.assert_allclose(lie.hat(a), -np.swapaxes(lie.hat(a), -1, -2))
    xi = RNG.normal(size=(4, 6))
    np.testing.assert_allclose(lie.se3_vee(lie.se3_hat(xi)), xi)
    mat = lie.se3_hat(xi)
    np.testing.assert_allclose(mat[..., 3, :], 0.0)
    np.testing.assert_allclose(mat[..., :3, 3], xi[:, 3:])


def test_exp_matches_expm():
    xi = _twists_with_angles(ANGLES)
    np.testing.assert_allclose(lie.se3_exp(xi), jax.jit(expm)(lie.se3_hat(xi)), atol=1e-13)
    np.testing.assert_allclose(
        lie.so3_exp(xi[:, :3]), jax.jit(expm)(lie.hat(xi[:, :3])), atol=1e-13
    )


def test_exp_closed_form_rotation_about_z():
    # Hand-computed: rotation by t about z through the point (1, 0, 0) (v = -w x r).
    t = 0.7
    xi = np.array([0.0, 0.0, t, 0.0, -t, 0.0])  # w = (0,0,1) t, v = -w x (1,0,0) t
    expected = np.array(
        [
            [np.cos(t), -np.sin(t), 0.0, 1.0 - np.cos(t)],
            [np.sin(t), np.cos(t), 0.0, -np.sin(t)],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    np.testing.assert_allclose(lie.se3_exp(xi), expected, atol=1e-15)


def test_log_inverts_exp():
    xi = _twists_with_angles(ANGLES)
    back = np.asarray(lie.se3_log(lie.se3_exp(xi)))
    # Near pi the axis is recovered to ~eps / (pi - t)^0 from the symmetric part: 1e-9 abs.
    np.testing.assert_allclose(back, xi, atol=1e-9, rtol=0)
    small = np.array([a < 0.5 for a in ANGLES])
    np.testing.assert_allclose(back[small], xi[small], atol=1e-14, rtol=1e-12)


def test_log_at_exactly_pi():
    for axis in (np.array([1.0, 0.0, 0.0]), _unit(np.array([1.0, -2.0, 0.5]))):
        rot = np.asarray(lie.so3_exp(axis * np.pi))
        omega = np.asarray(lie.so3_log(rot))
        np.testing.assert_allclose(np.linalg.norm(omega), np.pi, rtol=1e-12)
        np.testing.assert_allclose(lie.so3_exp(omega), rot, atol=1e-12)
        grad = jax.jit(jax.jacfwd(lie.so3_log))(jnp.asarray(rot))
        assert tree_allfinite(grad)


def test_exp_of_log_random_transforms():
    xi = _twists_with_angles(RNG.uniform(0.0, np.pi, size=50))
    transforms = lie.se3_exp(xi)
    np.testing.assert_allclose(lie.se3_exp(lie.se3_log(transforms)), transforms, atol=1e-12)


_expm_jacobian = jax.jit(jax.jacfwd(lambda x: expm(lie.se3_hat(x))))


@pytest.mark.parametrize("angle", [0.0, 1e-9, 0.05, 0.06, 1.3, np.pi - 1e-6])
def test_exp_jacobian_matches_expm(angle):
    xi = jnp.asarray(_twists_with_angles([angle])[0])
    ours = jax.jit(jax.jacfwd(lie.se3_exp))(xi)
    reference = _expm_jacobian(xi)
    assert tree_allfinite(ours)
    np.testing.assert_allclose(ours, reference, atol=1e-10)
    np.testing.assert_allclose(jax.jacrev(lie.se3_exp)(xi), ours, atol=1e-12)


_jac_exp = jax.jit(jax.jacfwd(lie.se3_exp))
_jac_log = jax.jit(jax.jacfwd(lie.se3_log))


@pytest.mark.parametrize("angle", [0.0, 1e-9, 0.05, 0.06, 1.3, np.pi / 2 + 1e-3, np.pi - 1e-3])
def test_log_jacobian_inverts_exp_jacobian(angle):
    # d log(exp(xi)) / d xi = I: chain rule through the 16 entries of the matrix.
    xi = jnp.asarray(_twists_with_angles([angle])[0])
    transform = lie.se3_exp(xi)
    d_exp = _jac_exp(xi).reshape(16, 6)
    d_log = _jac_log(transform).reshape(6, 16)
    assert tree_allfinite(d_log)
    tol = 1e-9 if angle < 3.0 else 1e-6  # conditioning near pi: |d log| ~ 1 / (pi - t)
    np.testing.assert_allclose(d_log @ d_exp, np.eye(6), atol=tol)


def test_grad_of_log_at_identity_is_finite_and_correct():
    # so3_log(exp(w)) near 0: the gradient of |log|^2 / 2 along exp is w itself.
    def half_sq(w):
        return 0.5 * jnp.sum(lie.so3_log(lie.so3_exp(w)) ** 2)

    grad = jax.jit(jax.grad(half_sq))
    for w in (jnp.zeros(3), jnp.array([1e-10, -2e-10, 0.0]), jnp.array([0.01, 0.02, -0.01])):
        np.testing.assert_allclose(grad(w), w, atol=1e-14)


def test_adjoint_and_inverse():
    transforms = lie.se3_exp(_twists_with_angles(RNG.uniform(0.0, 3.0, size=6)))
    xi = RNG.normal(size=(6, 6))
    ad = lie.adjoint(transforms)
    lhs = lie.se3_hat(np.einsum("...ij,...j->...i", ad, xi))
    inv = lie.se3_inverse(transforms)
    rhs = transforms @ lie.se3_hat(xi) @ inv
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)
    np.testing.assert_allclose(transforms @ inv, np.broadcast_to(np.eye(4), (6, 4, 4)), atol=1e-14)
    np.testing.assert_allclose(lie.adjoint(inv), np.linalg.inv(ad), atol=1e-12)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_batch_shapes(shape):
    xi = RNG.normal(size=(*shape, 6))
    transforms = lie.se3_exp(xi)
    assert transforms.shape == (*shape, 4, 4)
    assert lie.se3_log(transforms).shape == (*shape, 6)
    assert lie.adjoint(transforms).shape == (*shape, 6, 6)
    flat = xi.reshape(-1, 6)
    expected = np.stack([lie.se3_exp(row) for row in flat]).reshape(*shape, 4, 4)
    np.testing.assert_allclose(transforms, expected, atol=1e-15)


def test_float32():
    xi = _twists_with_angles([0.0, 1e-4, 0.3, 0.7, 1.5, 2.5, 3.1]).astype(np.float32)
    transforms = lie.se3_exp(xi)
    assert transforms.dtype == jnp.float32
    back = lie.se3_log(transforms)
    assert back.dtype == jnp.float32
    # float32 round trip, measured ~1e-6; near pi (3.1) the axis loses ~eps/(pi - t)^... 1e-4.
    np.testing.assert_allclose(back, xi, atol=2e-4)
    reference = np.asarray(lie.se3_exp(xi.astype(np.float64)))
    np.testing.assert_allclose(transforms, reference, atol=2e-6)


# ------------------------------------------------------------------ quaternions and distances
@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_quaternions_against_scipy(xp):
    """Shepperd's method and the quadratic map against scipy's ``Rotation``, every branch of
    Shepperd's choice (near-identity and half-turns about each axis) included; ``w >= 0``."""
    from scipy.spatial.transform import Rotation

    rotvec = np.concatenate(
        [RNG.normal(size=(20, 3)), 1e-9 * RNG.normal(size=(2, 3)), np.pi * np.eye(3)]
    )
    mats = Rotation.from_rotvec(rotvec).as_matrix()
    want = Rotation.from_rotvec(rotvec).as_quat()[:, [3, 0, 1, 2]]
    want = np.where(want[:, :1] < 0, -want, want)
    jit = jax.jit if xp is jnp else (lambda f: f)  # one compilation, not one per operation
    quat = np.asarray(jit(lambda m: lie.matrix_to_quaternion(m, xp=xp))(mats))
    signs = np.where(np.abs(want[:, :1]) < 1e-12, np.sign(np.sum(quat * want, -1))[:, None], 1)
    np.testing.assert_allclose(quat, signs * want, atol=1e-15)
    assert np.all(quat[:, 0] >= 0.0)
    scaled = quat * RNG.uniform(0.5, 2.0, (len(quat), 1))  # any non-zero length
    back = jit(lambda q: lie.quaternion_to_matrix(q, xp=xp))(scaled)
    np.testing.assert_allclose(back, mats, atol=1e-15)
    a, b = (Rotation.from_rotvec(RNG.normal(size=(5, 3))) for _ in range(2))
    qa, qb = (r.as_quat()[:, [3, 0, 1, 2]] for r in (a, b))
    product = np.asarray(jit(lambda x, y: lie.quaternion_product(x, y, xp=xp))(qa, qb))
    np.testing.assert_allclose(lie.quaternion_to_matrix(product, xp=np), (a * b).as_matrix())


def test_hemisphere_signs_make_neighbours_agree():
    quat = RNG.normal(size=(3, 12, 4))
    for signs in (lie.hemisphere_signs(quat, xp=np), jax.jit(lie.hemisphere_signs)(quat)):
        signs = np.asarray(signs)
        flipped = quat * signs[..., None]
        assert np.all(signs[:, 0] == 1.0) and np.all(np.abs(signs) == 1.0)
        assert np.all(np.sum(flipped[:, 1:] * flipped[:, :-1], -1) >= 0.0)
