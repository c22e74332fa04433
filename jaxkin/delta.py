"""The Delta parallel robot of seed 002 (Cardona): IK, FK, rates, singularities, workspace.

Convention (ERRATA seed 002; the paper's figures are not available):

* origin at the centre of the fixed platform (base), z up; the moving platform hangs below the
  base (z < 0 in normal operation);
* chain i (i = 1, 2, 3) has its actuator axis at ``A_i = r_base u_i`` with the radial unit
  vector ``u_i = (cos phi_i, sin phi_i, 0)``, ``phi_i = -90 + 120 (i - 1)`` degrees: chain 1 lies
  in the YZ plane on the -y side, chains 2 and 3 follow at +120 and +240 degrees
  (counter-clockwise seen from +z);
* ``theta_i = 0`` with the arm horizontal pointing radially outward, positive *downward*:
  the elbow is ``E_i = A_i + l_arm (cos theta_i u_i - sin theta_i e_z)``;
* the platform does not rotate; its joint i is at ``D_i = p + r_platform u_i``, and the
  parallelogram keeps ``|D_i - E_i| = l_rod``.

Lengths are in the user's unit (the paper's robot, ``Delta.paper()``, is in cm).

Inverse kinematics (eqs. 1-7, corrected per ERRATA). Let ``Q_i = p - (r_base - r_platform) u_i``
and its chain-local coordinates ``a = Q_i . u_i`` (radial), ``b = Q_i . (e_z x u_i)``
(tangential), ``z``. The constraint ``(a - l_arm cos th)^2 + b^2 + (z + l_arm sin th)^2 =
l_rod^2`` is the paper's eq. 5, ``2 T L cos th + 2 z L sin th = K`` with ``T = -a`` (the paper's
``OA + y0 - G'D'`` for chain 1), ``L = l_arm`` and ``K = l_rod^2 - b^2 - T^2 - L^2 - z^2``. With
``t = tan(th / 2)`` it becomes ``e1 t^2 + e2 t + e3 = 0`` (eq. 6, "e - 3" read as e3) with
``e1 = K + 2 T L``, ``e2 = -4 z L``, ``e3 = K - 2 T L``, and discriminant ``D = e2^2 - 4 e1 e3``.
The roots are taken in the stable form ``t = 2 e3 / (-e2 -/+ sqrt(D))`` (no division by e1,
which changes sign inside the workspace).

Root choice (the paper: "only the negative root worked in our tests"). The elbow's radial
coordinate is ``r_base + l_arm cos th`` and ``cos th = (1 - t^2) / (1 + t^2)`` decreases with
``|t|``: the elbow-out solution (elbow farther out from the z axis) is the root of *smaller*
``|t|``, i.e. the one whose denominator ``-e2 -/+ sqrt(D)`` has the larger magnitude:
``t_out = -2 e3 / (e2 + sign(e2) sqrt(D))``. For a hanging platform (z < 0, so e2 > 0) this is
``2 e3 / (-e2 - sqrt(D))``, which equals the paper's eq. 7 with the *plus* sign
(``(-e2 + sqrt(D)) / (2 e1)``); the paper's "negative root" ``(-e2 - sqrt(D)) / (2 e1)`` is the
elbow-in one in this convention (the paper measured z positive downward and theta positive
upward, which swaps the two). Conveniently the elbow-out root is also the cancellation-free
one. The elbow-in root is ``t_in = -(e2 + sign(e2) sqrt(D)) / (2 e1)``. Both are evaluated as
``theta = 2 atan2(num, den)`` with ``den >= 0``, so ``e1 = 0`` (theta_in = +/- pi) is harmless;
theta lies in (-pi, pi].

Forward kinematics by Newton-Raphson (eqs. 8-16, corrected): unknown ``p`` (the quaternion part
is the identity, the platform does not rotate), residuals
``r_i(p) = (|p + r_platform u_i - E_i(theta_i)|^2 - l_rod^2) / (2 l_rod)`` (length units, about
``|D_i - E_i| - l_rod`` near the solution), Jacobian by forward-mode autodiff, explicit 3x3
adjugate solve, per-element convergence in one ``lax.while_loop`` (``jaxkin.newton``) run on
cache-sized chunks of the batch (``jaxkin._chunks``), and for large batches on one part of the
batch per CPU core, each from its own host thread (``jaxkin._threads``: XLA runs a loop's body
on one core; measured 1.3-1.55x faster at batch 1e6 on 2 cores); converged where
``max|r| <= tol * (l_arm + l_rod)``. The loop solves the equivalent system
``(r_1, r_2 - r_1, r_3 - r_1)``, whose last two rows are linear in ``p`` (same Newton iterates,
~30 % fewer operations a trip); ``residual``, ``conditioning`` and ``status`` are evaluated for
``r`` itself at the returned point.

Compilation: a ``Delta`` whose fields are Python numbers is compiled into the kernels as
constants (one compilation per geometry, cached; measured 1.4x faster for the Newton FK and
2.5x for the closed form at batch 1e6 than runtime geometry). A traced or batched geometry
(gradients with respect to the design, ``vmap`` over robots) is passed as data instead.
Derivatives through the solution come from the implicit function theorem
(``lax.custom_root``), so ``jaxkin.lift`` of fk gives exact velocity and acceleration.

Default initial guess: with the sphere centres ``C_i = E_i - r_platform u_i`` (``p`` lies at
distance ``l_rod`` from each), the centroid ``c`` of the three centres lowered by
``sqrt(max(l_rod^2 - mean_i |C_i - c|_xy^2, l_rod^2 / 4))``: exact when the three elbows are at
the same height, and always below the centres, so Newton lands on the lower (physical, hanging)
assembly. Pass ``guess`` (e.g. the previous sample of a trajectory) to warm-start.

Closed form FK (three-sphere intersection): ``a = C_2 - C_1``, ``b = C_3 - C_1``, ``n = a x b``;
the circumcentre ``O = C_1 + ((|a|^2 b - |b|^2 a) x n) / (2 |n|^2)`` and
``p = O +/- h n`` with ``h^2 = (l_rod^2 - |O - C_1|^2) / |n|^2``; ``p`` is the lower one,
``p_upper`` its mirror through the plane of the centres.

Rates. With ``d_i = D_i - E_i`` and ``E_i' = dE_i/dtheta_i = -l_arm (sin th u_i + cos th e_z)``,
differentiating ``|d_i|^2 = l_rod^2`` gives the constraint Jacobians
``J_p = [d_1; d_2; d_3]`` (3x3, the platform Jacobian) and
``J_theta = diag(d_i . E_i')`` (the actuator Jacobian), with ``J_p p_dot = J_theta theta_dot``,
and for the accelerations (``E_i'' = -(E_i - A_i)``)::

    d_i . p_ddot - (d_i . E_i') theta_ddot_i = (d_i . E_i'') theta_dot_i^2 - |d_i_dot|^2,
    d_i_dot = p_dot - E_i' theta_dot_i.

``method="analytic"`` uses these; ``method="autodiff"`` lifts the position solvers with
``jaxkin.lift`` (nested jvp). Both agree to ~1e-12 in float64.

Singularity measures (both in [0, 1], 0 at the singularity, scale-free):

* inverse-type (serial): ``min_i |d_i . E_i'| / (l_arm l_rod)``, the cosine of the angle
  between rod i and the velocity of elbow i: 0 where a rod is perpendicular to it, i.e. the arm
  and the rod's projection on the arm's plane are aligned (both IK branches meet: the workspace
  boundary);
* direct-type (parallel): ``|det [d_1; d_2; d_3]| / l_rod^3``, the volume spanned by the unit
  rod vectors: 0 where the three rods are coplanar (both FK assemblies meet, the platform
  gains a degree of freedom).

A measure ``m`` with ``m^2 <= sqrt(eps(dtype))`` gives status ``SINGULAR`` (``m`` below ~1.2e-4 in
float64, ~0.019 in float32). The square is what the solvers compute without cancellation (a
discriminant, a squared height): rounding there is ~eps relative, so ``m`` itself carries
~sqrt(eps) noise near a singularity, and a band on ``m^2`` at sqrt(eps) matches the dyad's
length tolerance (``jaxkin.dyad``: ``sin(beta)^2 ~ 2 sqrt(eps)`` at its band edge).

Statuses (``jaxkin.Status``), most basic first:

* ik: ``INVALID_INPUT`` (non-finite p), ``UNREACHABLE`` (some chain has
  ``D / (4 l_arm l_rod)^2 < -sqrt(eps)``: the target is outside that chain's torus), ``SINGULAR``
  (``|D| / (4 l_arm l_rod)^2 <= sqrt(eps)``: on the workspace boundary, position valid, rates
  not), ``OUT_OF_LIMITS`` (solved but outside the actuator limits), ``OK``. ``margin`` = the
  smallest signed inverse measure over the chains, ``sign(D) sqrt(|D|) / (4 l_arm l_rod)``, which
  equals the inverse-type measure at a solution and is negative outside the workspace:
  continuous, usable as a barrier.
* fk: ``INVALID_INPUT`` (non-finite theta or guess), ``SINGULAR`` (direct-type: the squared
  Hadamard ratio of the Jacobian, which is the direct measure at a solution, <= sqrt(eps)),
  ``NOT_CONVERGED`` (including theta for which the mechanism cannot be assembled: use
  ``fk_closed_form`` to tell), ``OUT_OF_LIMITS``, ``OK``.
* fk_closed_form: with ``w = h^2 |n|^2 / l_rod^2`` (the squared sine of the rods' elevation
  above the plane of the centres): ``INVALID_INPUT``, ``UNREACHABLE`` (``w < -sqrt(eps)``: no
  common point of the three spheres), ``SINGULAR`` (collinear centres, or ``|w| <= sqrt(eps)``:
  the two assemblies meet, a direct singularity), ``OUT_OF_LIMITS``, ``OK``.

Placeholders: where the status is not OK, rates are 0; unreachable IK returns the angle of the
nearest (tangent) configuration, unreachable closed-form FK returns the circumcentre ``O``;
non-finite input is replaced by a harmless value before any arithmetic (double-where), so values
and gradients stay finite for the rest of the batch.

Float32 (measured on 2,000 random workspace points of the paper's robot, see
``tests/test_delta.py::test_float32``): IK angles within 6e-7 rad of float64; closed-form FK
within 1e-5 cm; Newton FK needs ``tol`` of at least ~1e-6 (1e-12 is below float32 resolution,
so most elements would report ``NOT_CONVERGED`` after ``max_iter``), and its float32 default is
8 eps = 9.5e-7: all converge in <= 4 iterations to within 6e-5 cm (about 1e-6 of the reach).
The singular bands widen with ``sqrt(eps)`` (measure below ~0.02 in float32).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _chunks, _threads, _validate, newton
from ._numerics import all_finite, computed_once, safe_sqrt, singular_rtol
from ._trig import cos_alone, sin_alone
from .jet import Jet, lift
from .result import SolverResult
from .status import STATUS_DTYPE, Status

BRANCHES = ("out", "in")
METHODS = ("analytic", "autodiff")
LOWER = 0
UPPER = 1

# Radial unit vectors u_i = (cos phi_i, sin phi_i), phi_i = -90, 30, 150 degrees.
_SQRT3_2 = math.sqrt(3.0) / 2.0
_UX = (0.0, _SQRT3_2, -_SQRT3_2)
_UY = (-1.0, 0.5, 0.5)


def _any3(x: Array) -> Array:
    """``any`` over a last axis of size 3, written elementwise: XLA on CPU runs reductions over
    a tiny minor axis as separate slow loops, elementwise ORs fuse with their producers."""
    return x[..., 0] | x[..., 1] | x[..., 2]


def _finite3(x: Array) -> Array:
    return ~_any3(~jnp.isfinite(x))


def _radial(dtype) -> tuple[Array, Array]:
    return jnp.asarray(_UX, dtype), jnp.asarray(_UY, dtype)


@dataclasses.dataclass(frozen=True)
class Delta:
    """Geometry of a Delta robot (see the module docstring for the frame and angles).

    Attributes:
        r_base: radius of the fixed platform, centre to actuator axis (scalar, length).
        r_platform: radius of the moving platform, centre to rod joint (scalar, length).
        l_arm: length of the actuated arm, actuator axis to elbow (scalar, length).
        l_rod: length of the parallelogram rods, elbow to platform joint (scalar, length).
        theta_min: lower actuator limit (scalar, rad), ``-inf`` for none.
        theta_max: upper actuator limit (scalar, rad), ``+inf`` for none.

    All fields are pytree leaves (differentiable, e.g. for calibration; vmappable over a batch
    of robots). Concrete values are validated when you construct a ``Delta``: lengths positive
    and finite, ``theta_min < theta_max``. Pytree operations (gradients, ``tree.map``) rebuild
    instances without validation, so a gradient may hold negative "lengths".
    """

    r_base: Any
    r_platform: Any
    l_arm: Any
    l_rod: Any
    theta_min: Any = -math.inf
    theta_max: Any = math.inf

    def __post_init__(self) -> None:
        fields = (self.r_base, self.r_platform, self.l_arm, self.l_rod)
        limits = (self.theta_min, self.theta_max)
        # Only validate real values: pytree unflattening may pass tracers or placeholders.
        if not all(_is_number(x) for x in (*fields, *limits)):
            return
        for name in ("r_base", "r_platform", "l_arm", "l_rod"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != ():
                raise ValueError(f"{name} must be a scalar, got shape {value.shape}")
            _validate.positive_length(value, name)
        lo = np.asarray(self.theta_min, dtype=float)
        hi = np.asarray(self.theta_max, dtype=float)
        if lo.shape != () or hi.shape != ():
            raise ValueError("theta_min and theta_max must be scalars")
        if np.isnan(lo) or np.isnan(hi) or not lo < hi:
            raise ValueError(f"need theta_min < theta_max, got {float(lo)} and {float(hi)}")

    @classmethod
    def paper(cls) -> Delta:
        """The robot of the paper's workspace study, in cm: (7, 2.5, 15.5, 30)."""
        return cls(7.0, 2.5, 15.5, 30.0)

    def with_limits(self, theta_min: float, theta_max: float) -> Delta:
        """The same robot with actuator limits (rad)."""
        return dataclasses.replace(self, theta_min=theta_min, theta_max=theta_max)


_DELTA_FIELDS = ("r_base", "r_platform", "l_arm", "l_rod", "theta_min", "theta_max")


def _delta_flatten(robot: Delta):
    children = tuple(getattr(robot, name) for name in _DELTA_FIELDS)
    keys = tuple(jax.tree_util.GetAttrKey(name) for name in _DELTA_FIELDS)
    return tuple(zip(keys, children, strict=True)), None


def _delta_unflatten(_aux: None, children) -> Delta:
    # Bypass __init__/__post_init__: tree operations carry gradients and tracers, not robots.
    robot = object.__new__(Delta)
    for name, value in zip(_DELTA_FIELDS, children, strict=True):
        object.__setattr__(robot, name, value)
    return robot


jax.tree_util.register_pytree_with_keys(Delta, _delta_flatten, _delta_unflatten)


def _is_number(x: Any) -> bool:
    if isinstance(x, bool):
        return False
    if isinstance(x, int | float | np.number):
        return True
    if isinstance(x, np.ndarray | jax.Array) and _validate.is_concrete(x):
        return np.issubdtype(np.asarray(x).dtype, np.number)
    return False


def _params(robot: Delta, dtype) -> tuple[Array, ...]:
    return tuple(
        jnp.asarray(getattr(robot, f), dtype)
        for f in ("r_base", "r_platform", "l_arm", "l_rod", "theta_min", "theta_max")
    )


# ----------------------------------------------------------------------------------- results


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class IKResult(SolverResult):
    """Inverse kinematics of a batch.

    Attributes:
        theta: Jet of the actuator angles, shape ``(..., 3)`` (rad).
        status: ``int8`` codes, shape ``(...)``.
        margin: smallest signed inverse-type singularity measure, shape ``(...)``: in (0, 1]
            inside the workspace, 0 on its boundary, negative outside.
    """

    theta: Jet
    status: Array
    margin: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class FKResult(SolverResult):
    """Forward kinematics by Newton-Raphson.

    Attributes:
        p: Jet of the platform centre, shape ``(..., 3)``.
        converged: shape ``(...)``.
        iterations: Newton updates applied, ``int32``, shape ``(...)``.
        residual: ``max_i |r_i|`` (length units, see the module docstring), shape ``(...)``.
        conditioning: direct-type singularity measure at ``p`` (Jacobian Hadamard ratio).
        status: ``int8`` codes, shape ``(...)``.
    """

    p: Jet
    converged: Array
    iterations: Array
    residual: Array
    conditioning: Array
    status: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class ClosedFormFKResult(SolverResult):
    """Forward kinematics by three-sphere intersection.

    Attributes:
        p: lower solution (the physical one for a hanging Delta), shape ``(..., 3)``.
        p_upper: the mirror solution, shape ``(..., 3)``.
        status: ``int8`` codes, shape ``(...)``.
    """

    p: Array
    p_upper: Array
    status: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SingularityResult(SolverResult):
    """Singularity measures, each in [0, 1] with 0 at the singularity, shape ``(...)``.

    Attributes:
        inverse: ``min_i |d_i . E_i'| / (l_arm l_rod)`` (actuator Jacobian degenerate).
        direct: ``|det [d_1; d_2; d_3]| / l_rod^3`` (platform Jacobian degenerate).
        status: ``SINGULAR`` where either measure squared is <= sqrt(eps), ``INVALID_INPUT``,
            or ``OK``.
    """

    inverse: Array
    direct: Array
    status: Array


# ------------------------------------------------------------------------------ position level


def _ik_position(robot: Delta, p: Array, branch: str) -> tuple[Array, Array, Array, Array]:
    """Actuator angles, their cosines and sines, and the signed inverse measure, ``(..., 3)``."""
    dtype = p.dtype
    r_base, r_platform, l_arm, l_rod, _, _ = _params(robot, dtype)
    ux, uy = _radial(dtype)
    x, y, z = p[..., 0:1], p[..., 1:2], p[..., 2:3]  # broadcast against the chain axis
    a = x * ux + y * uy - (r_base - r_platform)  # radial coordinate of Q_i from A_i
    b = -x * uy + y * ux  # tangential coordinate
    t_coef = -a  # the paper's T
    # Eq. 5: 2 T L cos(theta) + 2 z L sin(theta) = K.
    k = l_rod * l_rod - b * b - t_coef * t_coef - l_arm * l_arm - z * z
    e1 = k + 2.0 * t_coef * l_arm  # eq. 6 (ERRATA: "e - 3" is e3)
    e2 = -4.0 * z * l_arm
    e3 = k - 2.0 * t_coef * l_arm
    disc = e2 * e2 - 4.0 * e1 * e3
    sqrt_disc = safe_sqrt(disc)
    sign_e2 = jnp.where(e2 >= 0, 1.0, -1.0).astype(dtype)
    big = jnp.abs(e2) + sqrt_disc  # |e2 + sign(e2) sqrt(D)|, never a cancellation
    if branch == "out":
        # t_out = -2 e3 / (e2 + sign(e2) sqrt(D)) (stable form of eq. 7, see module docstring).
        num, den = -2.0 * e3 * sign_e2, big
    else:
        # t_in = -(e2 + sign(e2) sqrt(D)) / (2 e1).
        sign_e1 = jnp.where(e1 >= 0, 1.0, -1.0).astype(dtype)
        num, den = -sign_e2 * big * sign_e1, 2.0 * jnp.abs(e1)
    degenerate = (num == 0) & (den == 0)  # z = 0 and D = 0 and e3 = 0: any angle; take 0
    den = jnp.where(degenerate, 1.0, den)
    # XLA's atan2, not jaxkin._trig.atan2: the polynomial made delta.ik alone 1.2x faster at
    # 1e6 but plan.evaluate on the Delta 1.5x slower (1e3 x 100 samples), measured.
    theta = 2.0 * jnp.arctan2(num, den)
    # cos and sin of theta = 2 atan2(num, den), algebraically (no further transcendentals).
    norm_sq = num * num + den * den
    cos_theta = (den * den - num * num) / norm_sq
    sin_theta = 2.0 * num * den / norm_sq
    # Signed inverse measure sign(D) sqrt(|D|) / (4 L l_rod). With rho the distance from A_i to
    # the in-plane projection Q_i' and alpha the angle at A_i of the triangle (A_i, E_i, Q_i'),
    # sqrt(D) = 4 L rho sin(alpha) and |d_i . E_i'| = L rho sin(alpha) (law of sines), so at a
    # solution this is exactly the inverse-type measure |d_i . E_i'| / (l_arm l_rod).
    signed = jnp.where(disc >= 0, sqrt_disc, -safe_sqrt(-disc)) / (4.0 * l_arm * l_rod)
    return theta, cos_theta, sin_theta, signed


def _ik_status(robot: Delta, theta: Array, signed: Array, valid: Array) -> Array:
    _, _, _, _, lo, hi = _params(robot, theta.dtype)
    rtol = singular_rtol(theta.dtype)
    margin = jnp.minimum(jnp.minimum(signed[..., 0], signed[..., 1]), signed[..., 2])
    margin_sq = jnp.sign(margin) * margin * margin  # D / (4 l_arm l_rod)^2, signed
    out_of_limits = _any3((theta < lo) | (theta > hi))
    return jnp.where(
        ~valid,
        Status.INVALID_INPUT,
        jnp.where(
            margin_sq < -rtol,
            Status.UNREACHABLE,
            jnp.where(
                margin_sq <= rtol,
                Status.SINGULAR,
                jnp.where(out_of_limits, Status.OUT_OF_LIMITS, Status.OK),
            ),
        ),
    ).astype(STATUS_DTYPE)


def _reduced_residual(p, planes, rod: tuple[Array, Array]) -> tuple[Array, Array, Array]:
    """The distance constraints, rows 2 and 3 taken relative to row 1 (length units).

    With the sphere centres ``C_i`` (``p`` at distance ``l_rod`` from each), ``d = p - C_1``,
    ``e_i = C_i - C_1`` and the constraints ``r_i = (|p - C_i|^2 - l_rod^2) / (2 l_rod)``::

        r_1          = (|d|^2 - l_rod^2) / (2 l_rod)
        r_i - r_1    = (|e_i|^2 / 2 - d . e_i) / l_rod          (i = 2, 3: linear in p)

    Newton's iterates are invariant under a constant invertible recombination of the
    equations, so this system has the same iterates as ``r`` itself; its two linear rows cut
    the arithmetic of each trip by ~30 % (operations counted in the compiled loop).
    ``planes = (C_1, e_2, e_3, |e_2|^2 / 2, |e_3|^2 / 2)``
    as components (``jaxkin.newton``); ``rod = (l_rod^2, 1 / l_rod)``: multiplications only in
    the loop (XLA does not fold a division by a runtime geometry value).
    """
    l_rod_sq, inv_l_rod = rod
    centre, e_2, e_3, half_sq_2, half_sq_3 = planes
    d = [p[k] - centre[k] for k in range(3)]
    r_1 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - l_rod_sq) * (0.5 * inv_l_rod)
    r_2 = (half_sq_2 - (d[0] * e_2[0] + d[1] * e_2[1] + d[2] * e_2[2])) * inv_l_rod
    r_3 = (half_sq_3 - (d[0] * e_3[0] + d[1] * e_3[1] + d[2] * e_3[2])) * inv_l_rod
    return r_1, r_2, r_3


def _cos_sin(theta: Array) -> tuple[tuple[Array, ...], tuple[Array, ...]]:
    """``(cos theta_i, sin theta_i)`` of the three actuators as components, computed once.

    Stored once (``computed_once``): XLA would otherwise evaluate them in every loop that reads
    them. A stored stack computes each row on its own, so the rows use ``cos_alone`` and
    ``sin_alone`` (one polynomial each, absolute accuracy, which is what a centre needs).
    Measured at batch 1e6, float64 (best of 21, interleaved): the Newton FK 1.12x faster than
    with XLA's cos/sin and 1.2x than with ``sincos`` rows; the closed form 1.16x faster than
    with ``sincos`` rows.
    """
    angles = [theta[..., i] for i in range(3)]
    rows = computed_once(jnp.stack([cos_alone(t) for t in angles] + [sin_alone(t) for t in angles]))
    return tuple(rows[:3]), tuple(rows[3:])


def _centre_components(robot: Delta, theta: Array, cos_sin=None) -> tuple[tuple[Array, ...], ...]:
    """The sphere centres ``C_i = E_i - r_platform u_i`` as components ``C[i][k]`` (chain i,
    coordinate k), batch-shaped: ``p`` lies at distance ``l_rod`` from each.

    ``cos_sin``: ``_cos_sin(theta)`` when the caller has it already.
    """
    r_base, r_platform, l_arm, _, _, _ = _params(robot, theta.dtype)
    cos_theta, sin_theta = _cos_sin(theta) if cos_sin is None else cos_sin
    out = []
    for i in range(3):
        radial = r_base - r_platform + l_arm * cos_theta[i]
        out.append((radial * _UX[i], radial * _UY[i], -l_arm * sin_theta[i]))
    return tuple(out)


def _default_guess(robot: Delta, centres: tuple[tuple[Array, ...], ...]) -> Array:
    """Centroid of the sphere centres, lowered by ``sqrt(max(l_rod^2 - spread, l_rod^2/4))``."""
    l_rod = jnp.asarray(robot.l_rod, centres[0][0].dtype)
    mean = [(centres[0][k] + centres[1][k] + centres[2][k]) / 3.0 for k in range(3)]
    spread = (
        sum(
            (c[0] - mean[0]) * (c[0] - mean[0]) + (c[1] - mean[1]) * (c[1] - mean[1])
            for c in centres
        )
        / 3.0
    )
    drop = jnp.sqrt(jnp.maximum(l_rod * l_rod - spread, 0.25 * l_rod * l_rod))
    return jnp.stack([mean[0], mean[1], mean[2] - drop], axis=-1)


def _fk_newton(
    robot: Delta, theta: Array, guess: Array | None, tol: float, max_iter: int, cos_sin=None
):
    """Newton on ``_reduced_residual``; every reported field refers to the original ``r``.

    The loop stops at ``max|r_reduced| <= tol * scale / 2``, which bounds the original
    ``max|r| = max(|r_1|, |r_1 + (r_i - r_1)|)`` by ``tol * scale``. ``residual``,
    ``conditioning`` (Hadamard ratio of ``J = [p - C_i]_i``), ``converged`` and ``status``
    are then recomputed at the returned ``p`` for ``r`` itself.
    """
    dtype = theta.dtype
    centres = _centre_components(robot, theta, cos_sin)
    if guess is None:
        guess = jax.lax.stop_gradient(_default_guess(robot, centres))
    scale = jnp.asarray(robot.l_arm, dtype) + jnp.asarray(robot.l_rod, dtype)
    l_rod = jnp.asarray(robot.l_rod, dtype)
    rod = (l_rod * l_rod, 1.0 / l_rod)
    centre = centres[0]
    e_2, e_3 = ([c[k] - centre[k] for k in range(3)] for c in centres[1:])
    half_sq = [0.5 * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) for e in (e_2, e_3)]
    planes = (centre, e_2, e_3, *half_sq)
    sol = newton.solve(
        _reduced_residual, guess, planes, rod, tol=0.5 * tol, scale=scale, max_iter=max_iter
    )
    # The original system at the returned p (no gradient flows through these diagnostics).
    x = jax.lax.stop_gradient(sol.x)
    d = [x[..., k] - centre[k] for k in range(3)]
    r_1, r_2, r_3 = _reduced_residual(tuple(x[..., k] for k in range(3)), planes, rod)
    residual = jnp.maximum(jnp.abs(r_1), jnp.maximum(jnp.abs(r_1 + r_2), jnp.abs(r_1 + r_3)))
    rows = [d, [d[k] - e_2[k] for k in range(3)], [d[k] - e_3[k] for k in range(3)]]
    conditioning = newton.hadamard_ratio_components(rows)
    # Each of the four outputs below would otherwise recompute both from the centres.
    residual, conditioning = computed_once(jnp.stack([residual, conditioning]))
    converged = residual <= tol * scale
    status = jnp.where(
        conditioning <= singular_rtol(dtype),
        Status.SINGULAR,
        jnp.where(converged, Status.OK, Status.NOT_CONVERGED),
    ).astype(STATUS_DTYPE)
    return dataclasses.replace(
        sol, converged=converged, residual=residual, conditioning=conditioning, status=status
    )


def _sphere_intersection(robot: Delta, theta: Array):
    """Closed-form FK: lower and upper solutions, the circumcentre, ``n`` and the status parts.

    Written on components (batch-shaped arrays per coordinate), which XLA fuses into one loop;
    stacked ``(..., 3)`` cross products ran ~2x slower at 1e6 points.
    """
    # The barrier materialises the centres once: otherwise XLA recomputes their sin/cos in
    # every output's fusion (lower, upper, status), measured 3-4x slower.
    (c1, c2, c3) = jax.lax.optimization_barrier(_centre_components(robot, theta))
    l_rod = jnp.asarray(robot.l_rod, theta.dtype)
    a = [c2[k] - c1[k] for k in range(3)]
    b = [c3[k] - c1[k] for k in range(3)]
    n = _cross3(a, b)
    aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2]
    nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
    rtol = singular_rtol(theta.dtype)
    collinear = nn <= rtol * aa * bb  # sin(angle(a, b))^2 <= sqrt(eps)
    inv_two_nn = 0.5 / jnp.where(collinear, 1.0, nn)
    offset = _cross3([aa * b[k] - bb * a[k] for k in range(3)], n)
    offset = [v * inv_two_nn for v in offset]
    centre = [c1[k] + offset[k] for k in range(3)]  # circumcentre O of the sphere centres
    flip = jnp.where(n[2] > 0, -1.0, 1.0)  # orient n downward (n_z <= 0)
    n = [v * flip for v in n]
    height_sq = l_rod * l_rod - (offset[0] ** 2 + offset[1] ** 2 + offset[2] ** 2)  # |O p|^2
    h = safe_sqrt(height_sq * (2.0 * inv_two_nn))
    w = height_sq / (l_rod * l_rod)
    lower = jnp.stack([centre[k] + h * n[k] for k in range(3)], axis=-1)
    upper = jnp.stack([centre[k] - h * n[k] for k in range(3)], axis=-1)
    return lower, upper, jnp.stack(centre, -1), jnp.stack(n, -1), w, collinear


def _cross3(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


# ---------------------------------------------------------------------------------- rates


def _constraint_jacobians(robot: Delta, p, cos_theta, sin_theta):
    """Per chain ``i``: ``d_i = D_i - E_i`` (row i of ``J_p``), ``d_i . E_i'`` (``J_theta``),
    ``d_i . E_i''`` and ``E_i'``, all as components (batch-shaped arrays, see ``jaxkin.newton``).

    ``p``: the platform position as three components; ``cos_theta``, ``sin_theta``: three each.
    With ``R_i = r_base - r_platform + l_arm cos th_i`` (the module docstring's frame)::

        d_i = p - R_i u_i + l_arm sin th_i e_z,
        E_i' = -l_arm (sin th_i u_i + cos th_i e_z),   E_i'' = -(E_i - A_i),
        d_i . E_i'  = -l_arm (sin th_i (d_i . u_i) + cos th_i d_iz),
        d_i . E_i'' = -l_arm (cos th_i (d_i . u_i) - sin th_i d_iz).

    Component form, not stacked ``(..., 3, 3)`` arrays: the stacked rates measured 3-4x the cost
    of the positions at batch 1e6 (XLA on CPU runs small minor axes as slow strided loops).
    """
    r_base, r_platform, l_arm, _, _, _ = _params(robot, p[0].dtype)
    d, jt, d_dd, d_elbow = [], [], [], []
    for i in range(3):
        c, s = cos_theta[i], sin_theta[i]
        reach = r_base - r_platform + l_arm * c
        d_i = (p[0] - reach * _UX[i], p[1] - reach * _UY[i], p[2] + l_arm * s)
        radial = d_i[0] * _UX[i] + d_i[1] * _UY[i]  # d_i . u_i
        d.append(d_i)
        jt.append(-l_arm * (s * radial + c * d_i[2]))
        d_dd.append(-l_arm * (c * radial - s * d_i[2]))
        d_elbow.append((-l_arm * s * _UX[i], -l_arm * s * _UY[i], -l_arm * c))
    return d, jt, d_dd, d_elbow


def _components(x: Array) -> tuple[Array, Array, Array]:
    return x[..., 0], x[..., 1], x[..., 2]


def _dot3(u, v) -> Array:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _ik_rates_analytic(robot, p: Jet, theta: Array, cos_sin, ok: Array) -> Jet:
    """``J_theta theta_dot = J_p p_dot`` row by row, and its time derivative for theta_ddot."""
    d, jt, d_dd, d_elbow = _constraint_jacobians(
        robot, _components(p.p), _components(cos_sin[0]), _components(cos_sin[1])
    )
    p_dot, p_ddot = _components(p.v), _components(p.a)
    theta_dot, theta_ddot = [], []
    for i in range(3):
        inv_jt = 1.0 / jnp.where(ok, jt[i], 1.0)
        rate = _dot3(d[i], p_dot) * inv_jt
        d_dot = [p_dot[k] - d_elbow[i][k] * rate for k in range(3)]
        rhs = _dot3(d[i], p_ddot) + _dot3(d_dot, d_dot) - d_dd[i] * rate * rate
        theta_dot.append(jnp.where(ok, rate, 0.0))
        theta_ddot.append(jnp.where(ok, rhs * inv_jt, 0.0))
    return Jet(theta, jnp.stack(theta_dot, -1), jnp.stack(theta_ddot, -1))


def _fk_rates_analytic(robot, theta: Jet, p: Array, ok: Array, cos_sin) -> Jet:
    """``J_p p_dot = J_theta theta_dot`` and its time derivative, solved per sample."""
    d, jt, d_dd, d_elbow = _constraint_jacobians(robot, _components(p), *cos_sin)
    theta_dot, theta_ddot = _components(theta.v), _components(theta.a)
    p_dot = newton.solve_components(d, tuple(jt[i] * theta_dot[i] for i in range(3)))
    # Read by the three p_ddot loops: stored once, not recomputed (a solve each) by each.
    p_dot = tuple(computed_once(jnp.stack(p_dot)))
    rhs = []
    for i in range(3):
        d_dot = [p_dot[k] - d_elbow[i][k] * theta_dot[i] for k in range(3)]
        rhs.append(
            jt[i] * theta_ddot[i] + d_dd[i] * theta_dot[i] * theta_dot[i] - _dot3(d_dot, d_dot)
        )
    p_ddot = newton.solve_components(d, tuple(rhs))
    zero = [jnp.where(ok, v, 0.0) for v in (*p_dot, *p_ddot)]
    return Jet(p, jnp.stack(zero[:3], -1), jnp.stack(zero[3:], -1))


# -------------------------------------------------------------------------------- kernels


def _sanitise(x: Jet, fill: Array, rates: bool = True) -> tuple[Jet, Array]:
    """Double-where, step 1: replace non-finite elements by ``fill`` (position) and 0 (rates).

    Without rates, ``x.v`` and ``x.a`` are ``None`` (positions only, nothing else allocated).
    """
    valid = _finite3(x.p)
    if rates:
        valid = valid & _finite3(x.v) & _finite3(x.a)
    vc = valid[..., None]
    p = jnp.where(vc, x.p, fill)
    if not rates:
        return Jet(p, None, None), valid
    return Jet(p, jnp.where(vc, x.v, 0.0), jnp.where(vc, x.a, 0.0)), valid


def _home(robot: Delta, dtype) -> Array:
    r_base, r_platform, l_arm, l_rod, _, _ = _params(robot, dtype)
    reach = r_base - r_platform + l_arm
    z = -safe_sqrt(l_rod * l_rod - reach * reach)
    return jnp.stack([0.0 * z, 0.0 * z, jnp.where(z < 0, z, -l_rod)])


def _ik_impl(robot: Delta, p: Jet, branch: str, method: str, rates: bool) -> IKResult:
    p, valid = _sanitise(p, _home(robot, p.p.dtype), rates)

    if method == "analytic" or not rates:
        theta, cos_theta, sin_theta, signed = _ik_position(robot, p.p, branch)
        status = _ik_status(robot, theta, signed, valid)
        if rates:
            ok = _rates_ok(status)
            theta_jet = _ik_rates_analytic(robot, p, theta, (cos_theta, sin_theta), ok)
        else:
            theta_jet = Jet.constant(theta)
    else:

        def position(x):
            theta, _, _, signed = _ik_position(robot, x, branch)
            return theta, signed

        theta_j, signed_j = lift(position)(p)
        status = _ik_status(robot, theta_j.p, signed_j.p, valid)
        okc = _rates_ok(status)[..., None]
        theta_jet = Jet(theta_j.p, jnp.where(okc, theta_j.v, 0.0), jnp.where(okc, theta_j.a, 0.0))
        signed = signed_j.p
    margin = jnp.where(valid, jnp.clip(jnp.min(signed, axis=-1), -1.0, 1.0), -1.0)
    return IKResult(theta_jet, status, margin)


def _rates_ok(status: Array) -> Array:
    # Rates are defined where the position is solved and the relevant Jacobian is regular.
    return (status == Status.OK) | (status == Status.OUT_OF_LIMITS)


def _fk_impl(
    robot, theta: Jet, guess, tol: float, max_iter: int, method: str, rates: bool
) -> FKResult:
    dtype = theta.p.dtype
    theta, valid = _sanitise(theta, jnp.zeros((3,), dtype), rates)
    cos_sin = _cos_sin(theta.p)  # shared by the guess, the Newton setup and the rates
    if guess is None:
        guess_valid = valid
    else:
        guess = jnp.broadcast_to(guess, theta.p.shape)
        guess_valid = all_finite(guess)
        # A non-finite guess makes the element INVALID_INPUT (below): any finite start will do,
        # and a constant one (the home pose) needs no per-element work.
        home = _home(robot, dtype)
        guess = jax.lax.stop_gradient(jnp.where(guess_valid[..., None], guess, home))

    def position(th):
        return _fk_newton(robot, th, guess, tol, max_iter)

    if method == "analytic" or not rates:
        sol = _fk_newton(robot, theta.p, guess, tol, max_iter, cos_sin)
    else:

        def position_tuple(th):
            sol = position(th)
            return tuple(getattr(sol, f.name) for f in dataclasses.fields(sol))

        lifted = lift(position_tuple)(theta)
        x, converged, iterations, residual, conditioning, status = lifted
        sol = newton.NewtonResult(x, converged, iterations, residual.p, conditioning.p, status)
    _, _, _, _, lo, hi = _params(robot, dtype)
    out_of_limits = _any3((theta.p < lo) | (theta.p > hi))
    rtol = singular_rtol(dtype)
    direct_singular = sol.conditioning * sol.conditioning <= rtol
    status = jnp.where(
        ~(valid & guess_valid),
        Status.INVALID_INPUT,
        jnp.where(
            sol.status != Status.OK,
            sol.status,
            jnp.where(
                direct_singular,
                Status.SINGULAR,
                jnp.where(out_of_limits, Status.OUT_OF_LIMITS, Status.OK),
            ),
        ),
    ).astype(STATUS_DTYPE)
    ok = _rates_ok(status)
    if not rates:
        p_jet = Jet(sol.x, None, None)  # at rest: zero rates added by _fk_chunked or fk
    elif method == "analytic":
        p_jet = _fk_rates_analytic(robot, theta, sol.x, ok, cos_sin)
    else:
        okc = ok[..., None]
        x = sol.x
        p_jet = Jet(x.p, jnp.where(okc, x.v, 0.0), jnp.where(okc, x.a, 0.0))
    return FKResult(p_jet, sol.converged, sol.iterations, sol.residual, sol.conditioning, status)


def _fk_closed_form_impl(robot: Delta, theta: Array) -> ClosedFormFKResult:
    valid = _finite3(theta)
    theta = jnp.where(valid[..., None], theta, 0.0)
    lower, upper, centre, _, w, collinear = _sphere_intersection(robot, theta)
    rtol = singular_rtol(theta.dtype)
    _, _, _, _, lo, hi = _params(robot, theta.dtype)
    out_of_limits = _any3((theta < lo) | (theta > hi))
    status = jnp.where(
        ~valid,
        Status.INVALID_INPUT,
        jnp.where(
            collinear,
            Status.SINGULAR,
            jnp.where(
                w < -rtol,
                Status.UNREACHABLE,
                jnp.where(
                    w <= rtol,
                    Status.SINGULAR,
                    jnp.where(out_of_limits, Status.OUT_OF_LIMITS, Status.OK),
                ),
            ),
        ),
    ).astype(STATUS_DTYPE)
    del centre
    return ClosedFormFKResult(lower, upper, status)


def _branch_impl(robot: Delta, theta: Array, p: Array) -> Array:
    _, _, centre, n, _, _ = _sphere_intersection(robot, theta)
    side = jnp.sum((p - centre) * n, -1)  # n points downward
    return jnp.where(side >= 0, LOWER, UPPER).astype(STATUS_DTYPE)


def _singularity_impl(robot: Delta, p: Array, theta: Array) -> SingularityResult:
    valid = all_finite(p) & all_finite(theta)
    p = jnp.where(valid[..., None], p, _home(robot, p.dtype))
    theta = jnp.where(valid[..., None], theta, 0.0)
    _, _, l_arm, l_rod, _, _ = _params(robot, p.dtype)
    d, jt, _, _ = _constraint_jacobians(robot, _components(p), *_cos_sin(theta))
    inverse = jnp.minimum(jnp.minimum(jnp.abs(jt[0]), jnp.abs(jt[1])), jnp.abs(jt[2]))
    inverse = inverse / (l_arm * l_rod)
    direct = jnp.abs(_dot3(d[0], _cross3(d[1], d[2]))) / (l_rod * l_rod * l_rod)
    rtol = singular_rtol(p.dtype)
    status = jnp.where(
        ~valid,
        Status.INVALID_INPUT,
        jnp.where(
            (inverse * inverse <= rtol) | (direct * direct <= rtol), Status.SINGULAR, Status.OK
        ),
    ).astype(STATUS_DTYPE)
    return SingularityResult(inverse, direct, status)


def _fk_chunked(
    robot: Delta,
    theta: Jet,
    guess,
    tol: float,
    max_iter: int,
    method: str,
    rates: bool,
    zero_rates: bool,
) -> FKResult:
    """The FK kernel; ``zero_rates``: at rest, write the zero rates here (else ``fk`` adds them)."""
    # The whole kernel runs on cache-sized chunks (jaxkin._chunks): 1.6-1.8x at batch 1e6.
    batch = theta.p.shape[:-1]
    if guess is not None:
        guess = jnp.broadcast_to(guess, theta.p.shape)

    def solve_chunk(chunk):
        return _fk_impl(robot, *chunk, tol, max_iter, method, rates)

    result = _chunks.map_chunks(solve_chunk, (theta, guess), batch)
    if rates or not zero_rates:
        return result
    return dataclasses.replace(result, p=Jet.constant(result.p.p))


# At rest (plain angles), ``fk`` makes the zero rates itself above this batch size, as one
# array shared by v and a: a kernel output cannot alias another, and writing both cost ~8 % of
# the FK at batch 1e6. Below it the kernel writes them: the extra eager call cost more
# (batch 1: 80 us per call in the kernel, 150 us outside; measured float64).
_SHARED_ZEROS_MIN = 1 << 16


def _frozen(robot: Delta) -> Delta | None:
    """The robot with Python-float fields when every field is a concrete scalar, else None."""
    values = [getattr(robot, name) for name in _DELTA_FIELDS]
    if not all(_is_number(v) and np.ndim(v) == 0 for v in values):
        return None
    return _delta_unflatten(None, [float(v) for v in values])


def _jit(
    fn: Callable[..., Any],
    static_argnames: tuple[str, ...] = (),
    batched_argnames: tuple[str, ...] = (),
) -> Callable[..., Any]:
    """``jax.jit(fn)`` that compiles a concrete geometry in as constants.

    A geometry of Python numbers is a static argument (one compilation per robot, cached):
    XLA then folds it into the kernel, which measured 1.4x faster for the Newton FK at batch
    1e6 than passing it as runtime data. A traced or batched geometry (gradients with respect
    to the design, ``vmap`` over robots) takes the dynamic path.

    With ``batched_argnames``, large batches are split across host threads
    (``jaxkin._threads``) and the call takes the batch shape as the keyword ``batch``.
    """
    if batched_argnames:
        dynamic = _threads.PartsJit(fn, static_argnames, batched_argnames)
        static = _threads.PartsJit(fn, ("robot", *static_argnames), batched_argnames)
    else:
        dynamic = jax.jit(fn, static_argnames=static_argnames)
        static = jax.jit(fn, static_argnames=("robot", *static_argnames))

    @functools.wraps(fn)
    def call(robot: Delta, *args: Any, **kwargs: Any) -> Any:
        frozen = _frozen(robot)
        if frozen is None:
            return dynamic(robot, *args, **kwargs)
        return static(frozen, *args, **kwargs)

    call._cache_size = static._cache_size  # for tests (both jits share one cache)
    call._static = static  # for tests: the concrete-geometry kernel (a PartsJit when split)
    return call


_ik_jit = _jit(_ik_impl, ("branch", "method", "rates"))
# The Newton loop runs on one core per program (jaxkin._threads): split large batches.
_fk_jit = _jit(
    _fk_chunked, ("tol", "max_iter", "method", "rates", "zero_rates"), ("theta", "guess")
)
_fk_closed_form_jit = _jit(_fk_closed_form_impl)
_branch_jit = _jit(_branch_impl)
_singularity_jit = _jit(_singularity_impl)


# --------------------------------------------------------------------------------- public


def _check_robot(robot: Any) -> Delta:
    if not isinstance(robot, Delta):
        raise ValueError(f"robot must be a jaxkin.delta.Delta, got {type(robot).__name__}")
    return robot


def _dtype(*xs: Any) -> Any:
    return jnp.result_type(*xs, float)


def ik(robot: Delta, p: Jet | ArrayLike, branch: str = "out", method: str = "analytic") -> IKResult:
    """Actuator angles (and rates) for platform positions.

    Args:
        robot: the geometry.
        p: platform centre, shape ``(..., 3)``: a ``Jet`` (position, velocity, acceleration) or
            a plain array (taken at rest).
        branch: ``"out"`` (elbow-out, elbows farther from the z axis; default) or ``"in"``.
        method: ``"analytic"`` (constraint Jacobians) or ``"autodiff"`` (``jaxkin.lift``).

    Returns:
        ``IKResult`` with ``theta`` (Jet, ``(..., 3)``), ``status`` and ``margin`` (``(...)``).

    Raises:
        ValueError: unknown branch/method, last axis not 3, or ``robot`` not a ``Delta``.
    """
    robot = _check_robot(robot)
    branch = _validate.choice(branch, "branch", BRANCHES)
    method = _validate.choice(method, "method", METHODS)
    if isinstance(p, Jet):
        p = _validate.as_jet(p, "p", coords=3)
        return _ik_jit(robot, p.astype(_dtype(p.p)), branch, method, True)
    # Positions only: no rate arrays are built or passed (the result has zero rates).
    p = _as_coords(p, "p")
    return _ik_jit(robot, Jet(p, None, None), branch, method, False)


def fk(
    robot: Delta,
    theta: Jet | ArrayLike,
    guess: ArrayLike | None = None,
    tol: float | None = None,
    max_iter: int = 30,
    method: str = "analytic",
) -> FKResult:
    """Platform position (and rates) from actuator angles by batched Newton-Raphson.

    A large batch (two or more parts of 2^15 elements) called outside ``jit`` runs as one part
    per host thread (``jaxkin.set_num_threads``; the same values, see ``jaxkin._threads``).

    Args:
        robot: the geometry.
        theta: actuator angles, shape ``(..., 3)``: a ``Jet`` or a plain array (at rest).
        guess: initial platform positions, broadcastable to ``(..., 3)`` (warm start, e.g. the
            previous trajectory sample); ``None`` for the default guess below the elbows
            (module docstring), which converges to the lower (hanging) assembly.
        tol: converged where ``max_i |r_i| <= tol * (l_arm + l_rod)``; ``None`` for
            ``max(1e-12, 8 eps(dtype))``: 1e-12 in float64, 9.5e-7 in float32 (1e-12 is below
            float32 resolution).
        max_iter: maximum number of Newton updates.
        method: ``"analytic"`` rates (constraint Jacobians) or ``"autodiff"`` (``jaxkin.lift``
            through ``lax.custom_root``).

    Returns:
        ``FKResult`` (``p`` Jet ``(..., 3)``, ``converged``, ``iterations``, ``residual``,
        ``conditioning``, ``status``).

    Raises:
        ValueError: bad shapes, ``tol <= 0``, ``max_iter < 1``, unknown method.
    """
    robot = _check_robot(robot)
    method = _validate.choice(method, "method", METHODS)
    rates = isinstance(theta, Jet)
    if rates:
        theta = _validate.as_jet(theta, "theta", coords=3)
    else:
        theta = Jet(_as_coords(theta, "theta"), None, None)
    if tol is not None and not (isinstance(tol, int | float) and math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a positive finite float or None, got {tol!r}")
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise ValueError(f"max_iter must be a positive int, got {max_iter!r}")
    dtype = _dtype(theta.p)
    if tol is None:
        tol = max(1e-12, 8.0 * float(jnp.finfo(dtype).eps))
    if guess is not None:
        guess = jnp.asarray(guess, dtype)
        if guess.ndim == 0 or guess.shape[-1] != 3:
            raise ValueError(f"guess: expected shape (..., 3), got {tuple(guess.shape)}")
        shape = _validate.batch_shape({"theta": theta.shape[:-1], "guess": guess.shape[:-1]})
        theta = jax.tree.map(lambda x: jnp.broadcast_to(x, (*shape, 3)), theta)
    theta = jax.tree.map(lambda x: x.astype(dtype), theta)
    zeros_here = not rates and math.prod(theta.shape[:-1]) >= _SHARED_ZEROS_MIN
    batch = theta.shape[:-1]
    result = _fk_jit(
        robot, theta, guess, float(tol), max_iter, method, rates, not zeros_here, batch=batch
    )
    if not zeros_here:
        return result
    return dataclasses.replace(result, p=Jet.constant(result.p.p))


def fk_closed_form(robot: Delta, theta: ArrayLike) -> ClosedFormFKResult:
    """Platform position by three-sphere intersection (both assemblies), shape ``(..., 3)``."""
    robot = _check_robot(robot)
    theta = _as_coords(theta, "theta")
    return _fk_closed_form_jit(robot, theta)


def which_branch(robot: Delta, theta: ArrayLike, p: ArrayLike) -> Array:
    """Which assembly ``p`` is: ``LOWER`` (0, below the plane of the sphere centres) or
    ``UPPER`` (1), e.g. to report which branch Newton converged to; shape ``(...)``."""
    robot = _check_robot(robot)
    theta = _as_coords(theta, "theta")
    p = _as_coords(p, "p")
    _validate.batch_shape({"theta": theta.shape[:-1], "p": p.shape[:-1]})
    dtype = _dtype(theta, p)
    return _branch_jit(robot, theta.astype(dtype), p.astype(dtype))


def singularity(
    robot: Delta, p: ArrayLike, theta: ArrayLike | None = None, branch: str = "out"
) -> SingularityResult:
    """Inverse- and direct-type singularity measures at ``(p, theta)``, shape ``(...)``.

    ``theta`` defaults to ``ik(robot, p, branch).theta.p``. See the module docstring for the
    normalisation (both measures in [0, 1], 0 at the singularity).
    """
    robot = _check_robot(robot)
    p = _as_coords(p, "p")
    if theta is None:
        theta = ik(robot, p, branch=branch).theta.p
    theta = _as_coords(theta, "theta")
    shape = _validate.batch_shape({"p": p.shape[:-1], "theta": theta.shape[:-1]})
    dtype = _dtype(p, theta)
    p = jnp.broadcast_to(p, (*shape, 3)).astype(dtype)
    theta = jnp.broadcast_to(theta, (*shape, 3)).astype(dtype)
    return _singularity_jit(robot, p, theta)


def _as_coords(x: ArrayLike, name: str) -> Array:
    x = jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.inexact):
        x = x.astype(jnp.result_type(float))
    if x.ndim == 0 or x.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., 3), got {tuple(x.shape)}")
    return x


def workspace(
    robot: Delta,
    bounds: tuple[tuple[float, float], tuple[float, float], tuple[float, float]] | None = None,
    resolution: float = 1.0,
    branch: str = "out",
    chunk_size: int = 1 << 18,
    dtype: Any = None,
    progress: bool | None = None,
):
    """Voxel sweep of the reachable workspace (see ``jaxkin.workspace.sweep``).

    ``bounds`` defaults to the paper's box for this robot: ``x, y`` in ``[-R, R]`` with
    ``R = r_base - r_platform + l_arm + l_rod`` (the maximum horizontal reach) and ``z`` in
    ``[-0.9 R, 0.9 R]`` (for the paper's robot: [-50, 50]^2 x [-45, 45] cm, 101 x 101 x 91 =
    928,291 voxels at 1 cm, as ERRATA explains). A voxel is reachable where ``ik`` gives
    ``OK`` or ``SINGULAR`` (the position is solved; the boundary itself is singular).
    """
    from . import workspace as _workspace

    robot = _check_robot(robot)
    if bounds is None:
        reach = float(robot.r_base) - float(robot.r_platform)
        reach += float(robot.l_arm) + float(robot.l_rod)
        bounds = ((-reach, reach), (-reach, reach), (-0.9 * reach, 0.9 * reach))

    def status_of(points: Array) -> Array:
        return ik(robot, points, branch=branch).status

    return _workspace.sweep(
        status_of,
        bounds,
        resolution,
        chunk_size=chunk_size,
        dtype=dtype,
        progress=progress,
        reachable=(Status.OK, Status.SINGULAR),
    )


__all__ = [
    "BRANCHES",
    "LOWER",
    "METHODS",
    "UPPER",
    "ClosedFormFKResult",
    "Delta",
    "FKResult",
    "IKResult",
    "SingularityResult",
    "fk",
    "fk_closed_form",
    "ik",
    "singularity",
    "which_branch",
    "workspace",
]
