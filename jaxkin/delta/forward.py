"""The Delta's forward kinematics: batched Newton-Raphson [Cardona, eqs. 8-16] and closed form.

Newton: unknown ``p`` (the platform does not rotate, so only the position part of eq. 8
remains), residuals ``r_i(p) = (|p - C_i|^2 - l_rod^2) / (2 l_rod)`` (length units, about
``|D_i - E_i| - l_rod`` near the solution), the 3x3 Jacobian by forward-mode autodiff and an
explicit solve, per-element convergence in one ``lax.while_loop`` (``jaxkin.newton``) on
cache-sized chunks of the batch, and large batches in one part per CPU core
(``jaxkin._batching``); converged where ``max|r| <= tol * (l_arm + l_rod)``. The loop solves the
equivalent system ``(r_1, r_2 - r_1, r_3 - r_1)``, whose last two rows are linear in ``p`` (the
same iterates). The default initial guess is the centroid of the sphere centres lowered by
``sqrt(max(l_rod^2 - spread, l_rod^2 / 4))``, so Newton lands on the lower (hanging) assembly;
``guess`` warm-starts it (e.g. from the previous sample of a trajectory). Derivatives through
the solution come from the implicit function theorem (``lax.custom_root``).

Closed form (three-sphere intersection): ``a = C_2 - C_1``, ``b = C_3 - C_1``, ``n = a x b``,
the circumcentre ``O = C_1 + ((|a|^2 b - |b|^2 a) x n) / (2 |n|^2)`` and ``p = O +/- h n`` with
``h^2 = (l_rod^2 - |O - C_1|^2) / |n|^2``: ``x`` is the lower solution, ``x_upper`` its mirror.

Statuses. Newton: ``INVALID_INPUT`` (non-finite theta or guess), ``SINGULAR`` (direct-type, see
``jaxkin.delta.jacobians``), ``NOT_CONVERGED`` (including theta for which the mechanism cannot be
assembled: the closed form tells), ``OUT_OF_LIMITS``, ``OK``. Closed form, with ``w`` the squared
sine of the rods' elevation above the plane of the centres: ``INVALID_INPUT``, ``UNREACHABLE``
(``w < -sqrt(eps)``: no common point; ``x`` is then the circumcentre), ``SINGULAR`` (collinear
centres or ``|w| <= sqrt(eps)``), ``OUT_OF_LIMITS``, ``OK``. Rates are 0 where not OK.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from jax import Array

from .. import _batching, newton
from .._numerics import all_finite, computed_once, safe_sqrt, singular_rtol
from ..jet import Jet, lift
from ..lie import cross_soa
from ..result import FKResult, SolverResult
from ..status import STATUS_DTYPE, Status
from ._math import (
    DeltaRobot,
    any3,
    centre_components,
    constant_geometry_kernel,
    cos_sin,
    finite3,
    home,
    in_own_units,
    params,
    rates_ok,
    sanitise,
)
from .jacobians import fk_rates
from .options import DeltaFKOptions

__all__ = [
    "LOWER",
    "UPPER",
    "ClosedFormFKResult",
    "NewtonFKResult",
    "branch_jit",
    "closed_form_jit",
    "fk_guess_jit",
    "fk_kernel",
]

LOWER = 0

UPPER = 1


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class NewtonFKResult(FKResult):
    """Forward kinematics by Newton-Raphson.

    Attributes:
        x: Jet of the platform centre, shape ``(..., 3)``.
        status: ``int8`` codes, shape ``(...)``.
        converged: shape ``(...)``.
        iterations: Newton updates applied, ``int32``, shape ``(...)``.
        residual: ``max_i |r_i|`` (length units, see the module docstring), shape ``(...)``.
        conditioning: direct-type singularity measure at ``x`` (Jacobian Hadamard ratio).
    """

    converged: Array
    iterations: Array
    residual: Array
    conditioning: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class ClosedFormFKResult(SolverResult):
    """Forward kinematics by three-sphere intersection.

    Attributes:
        x: lower solution (the physical one for a hanging Delta), shape ``(..., 3)``.
        x_upper: the mirror solution, shape ``(..., 3)``.
        status: ``int8`` codes, shape ``(...)``.
    """

    x: Array
    x_upper: Array
    status: Array


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


def _default_guess(robot: DeltaRobot, centres: tuple[tuple[Array, ...], ...]) -> Array:
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
    robot: DeltaRobot, theta: Array, guess: Array | None, tol: float, max_iter: int, cosines=None
):
    """Newton on ``_reduced_residual``; every reported field refers to the original ``r``.

    The loop stops at ``max|r_reduced| <= tol * scale / 2``, which bounds the original
    ``max|r| = max(|r_1|, |r_1 + (r_i - r_1)|)`` by ``tol * scale``. ``residual``,
    ``conditioning`` (Hadamard ratio of ``J = [p - C_i]_i``), ``converged`` and ``status``
    are then recomputed at the returned ``p`` for ``r`` itself.
    """
    dtype = theta.dtype
    centres = centre_components(robot, theta, cosines)
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


def _fk_impl(
    robot, theta: Jet, guess, tol: float, max_iter: int, method: str, rates: bool
) -> NewtonFKResult:
    dtype = theta.p.dtype
    robot, scale = in_own_units(robot)
    scale = jnp.asarray(scale, dtype)
    if guess is not None:
        guess = guess * (1.0 / scale)
    theta, valid = sanitise(theta, jnp.zeros((3,), dtype), rates)
    cosines = cos_sin(theta.p)  # shared by the guess, the Newton setup and the rates
    if guess is None:
        guess_valid = valid
    else:
        guess = jnp.broadcast_to(guess, theta.p.shape)
        guess_valid = all_finite(guess)
        # A non-finite guess makes the element INVALID_INPUT (below): any finite start will do,
        # and a constant one (the home pose) needs no per-element work.
        rest = home(robot, dtype)
        guess = jax.lax.stop_gradient(jnp.where(guess_valid[..., None], guess, rest))

    def position(th):
        return _fk_newton(robot, th, guess, tol, max_iter)

    if method == "analytic" or not rates:
        sol = _fk_newton(robot, theta.p, guess, tol, max_iter, cosines)
    else:

        def position_tuple(th):
            sol = position(th)
            return tuple(getattr(sol, f.name) for f in dataclasses.fields(sol))

        lifted = lift(position_tuple)(theta)
        x, converged, iterations, residual, conditioning, status = lifted
        sol = newton.NewtonResult(x, converged, iterations, residual.p, conditioning.p, status)
    _, _, _, _, lo, hi = params(robot, dtype)
    out_of_limits = any3((theta.p < lo) | (theta.p > hi))
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
    ok = rates_ok(status)
    if not rates:
        p_jet = Jet.positions(sol.x)  # at rest: zero rates added by _fk_chunked or fk
    elif method == "analytic":
        p_jet = fk_rates(robot, theta, sol.x, ok, cosines)
    else:
        okc = ok[..., None]
        x = sol.x
        p_jet = Jet(x.p, jnp.where(okc, x.v, 0.0), jnp.where(okc, x.a, 0.0))
    p_jet = Jet(*(None if x is None else x * scale for x in (p_jet.p, p_jet.v, p_jet.a)))
    return NewtonFKResult(
        p_jet, status, sol.converged, sol.iterations, sol.residual * scale, sol.conditioning
    )


def _sphere_intersection(robot: DeltaRobot, theta: Array):
    """Closed-form FK: lower and upper solutions, the circumcentre, ``n`` and the status parts.

    Written on components (batch-shaped arrays per coordinate), which XLA fuses into one loop;
    stacked ``(..., 3)`` cross products ran slower.
    """
    # The barrier materialises the centres once: otherwise XLA recomputes their sin/cos in
    # every output's fusion (lower, upper, status).
    (c1, c2, c3) = jax.lax.optimization_barrier(centre_components(robot, theta))
    l_rod = jnp.asarray(robot.l_rod, theta.dtype)
    a = [c2[k] - c1[k] for k in range(3)]
    b = [c3[k] - c1[k] for k in range(3)]
    n = cross_soa(a, b)
    aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2]
    nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2]
    rtol = singular_rtol(theta.dtype)
    collinear = nn <= rtol * aa * bb  # sin(angle(a, b))^2 <= sqrt(eps)
    inv_two_nn = 0.5 / jnp.where(collinear, 1.0, nn)
    offset = cross_soa([aa * b[k] - bb * a[k] for k in range(3)], n)
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


def _fk_closed_form_impl(robot: DeltaRobot, theta: Array) -> ClosedFormFKResult:
    robot, scale = in_own_units(robot)
    valid = finite3(theta)
    theta = jnp.where(valid[..., None], theta, 0.0)
    lower, upper, centre, _, w, collinear = _sphere_intersection(robot, theta)
    scale = jnp.asarray(scale, theta.dtype)
    lower, upper = lower * scale, upper * scale
    rtol = singular_rtol(theta.dtype)
    _, _, _, _, lo, hi = params(robot, theta.dtype)
    out_of_limits = any3((theta < lo) | (theta > hi))
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


def _branch_impl(robot: DeltaRobot, theta: Array, p: Array) -> Array:
    robot, scale = in_own_units(robot)
    p = p * (1.0 / jnp.asarray(scale, p.dtype))
    _, _, centre, n, _, _ = _sphere_intersection(robot, theta)
    side = jnp.sum((p - centre) * n, -1)  # n points downward
    return jnp.where(side >= 0, LOWER, UPPER).astype(STATUS_DTYPE)


def _fk_chunked(
    robot: DeltaRobot,
    theta: Jet,
    guess,
    tol: float,
    max_iter: int,
    method: str,
    rates: bool,
    zero_rates: bool,
) -> NewtonFKResult:
    """The FK kernel; ``zero_rates``: at rest, write the zero rates here (else ``fk`` adds them)."""
    # Cache-sized chunks: the Newton loop's state stays in cache.
    batch = theta.p.shape[:-1]
    if guess is not None:
        guess = jnp.broadcast_to(guess, theta.p.shape)

    def solve_chunk(chunk):
        return _fk_impl(robot, *chunk, tol, max_iter, method, rates)

    result = _batching.map_chunks(solve_chunk, (theta, guess), batch)
    if rates or not zero_rates:
        return result
    return dataclasses.replace(result, x=Jet.constant(result.x.p))


# Warm-started FK (``jaxkin.delta.fk`` with a guess): the Newton loop runs on one core per
# program, so large batches are split across host threads.
fk_guess_jit = constant_geometry_kernel(
    _fk_chunked,
    ("tol", "max_iter", "method", "rates", "zero_rates"),
    {"theta": 1, "guess": 1},
)
closed_form_jit = constant_geometry_kernel(_fk_closed_form_impl)
branch_jit = constant_geometry_kernel(_branch_impl)


def fk_kernel(
    robot: DeltaRobot, theta: Jet, options: DeltaFKOptions, rates: bool
) -> NewtonFKResult:
    """The robot protocol's FK kernel (``Delta.fk_kernel``): Newton from the default guess;
    at rest no rate is read or written (the pipeline writes the zero rates)."""
    tol = options.tolerance(theta.dtype)
    theta = theta if rates else Jet.positions(theta.p)
    return _fk_chunked(
        robot, theta, None, tol, options.max_iter, options.method, rates, zero_rates=False
    )
