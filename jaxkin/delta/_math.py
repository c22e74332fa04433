"""The Delta's kit: its frame, constants and the pieces every Delta kernel shares.

Frame (the paper's figures are not available; the convention is stated in
``docs/conventions.md``): origin at the centre of the fixed platform, z up, the moving platform
below it (z < 0). Chain i (i = 1, 2, 3) has its actuator axis at ``A_i = r_base u_i`` with
``u_i = (cos phi_i, sin phi_i, 0)``, ``phi_i = -90 + 120 (i - 1)`` degrees (chain 1 in the YZ
plane on the -y side, counter-clockwise seen from +z). ``theta_i = 0`` with the arm horizontal
and radially outward, positive *downward*: the elbow is
``E_i = A_i + l_arm (cos theta_i u_i - sin theta_i e_z)``. The platform does not rotate; its
joint i is at ``D_i = p + r_platform u_i`` and the parallelogram keeps ``|D_i - E_i| = l_rod``.
The sphere centres ``C_i = E_i - r_platform u_i`` are the points ``p`` keeps at ``l_rod``.

Every function here reads a robot by its fields alone (``r_base``, ``r_platform``, ``l_arm``,
``l_rod``, ``theta_min``, ``theta_max``): this module sits below the kernels and the ``Delta``
class (``jaxkin.delta.robot``) and imports neither.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from .. import _validate
from .._execute import WHOLE, Kernel, Policy
from .._geometry import concrete_scalars
from .._numerics import computed_once, safe_sqrt
from .._trig import cos_alone, sin_alone
from ..jet import Jet
from ..status import Status

__all__ = [
    "BRANCHES",
    "FAR",
    "FIELDS",
    "JOINT_NAMES",
    "METHODS",
    "UX",
    "UY",
    "any3",
    "as_coords",
    "centre_components",
    "components",
    "constant_geometry_kernel",
    "cos_sin",
    "dot3",
    "far_away",
    "finite3",
    "float_dtype",
    "frozen",
    "home",
    "in_own_units",
    "params",
    "radial",
    "rates_ok",
    "sanitise",
]

DeltaRobot = Any  # a delta.Delta: the class sits above its kernels, which read its fields

BRANCHES = ("out", "in")
METHODS = ("analytic", "autodiff")
JOINT_NAMES = ("theta1", "theta2", "theta3")
FIELDS = ("r_base", "r_platform", "l_arm", "l_rod", "theta_min", "theta_max")

# Radial unit vectors u_i = (cos phi_i, sin phi_i), phi_i = -90, 30, 150 degrees.
_SQRT3_2 = math.sqrt(3.0) / 2.0

UX = (0.0, _SQRT3_2, -_SQRT3_2)

UY = (-1.0, 0.5, 0.5)


def any3(x: Array) -> Array:
    """``any`` over a last axis of size 3, written elementwise: XLA on CPU runs reductions over
    a tiny minor axis as separate slow loops, elementwise ORs fuse with their producers."""
    return x[..., 0] | x[..., 1] | x[..., 2]


def finite3(x: Array) -> Array:
    """True where all three entries of the last axis are finite."""
    return ~any3(~jnp.isfinite(x))


def radial(dtype) -> tuple[Array, Array]:
    """The x and y components of the three radial unit vectors ``u_i``, ``(3,)`` each."""
    return jnp.asarray(UX, dtype), jnp.asarray(UY, dtype)


def params(robot: DeltaRobot, dtype) -> tuple[Array, ...]:
    """The robot's fields (``FIELDS`` order) as scalars of ``dtype``."""
    return tuple(jnp.asarray(getattr(robot, f), dtype) for f in FIELDS)


def cos_sin(theta: Array) -> tuple[tuple[Array, ...], tuple[Array, ...]]:
    """``(cos theta_i, sin theta_i)`` of the three actuators as components, computed once.

    Stored once (``computed_once``): XLA would otherwise evaluate them in every loop that reads
    them. A stored stack computes each row on its own, so the rows use ``cos_alone`` and
    ``sin_alone`` (one polynomial each, absolute accuracy, which is what a centre needs).
    """
    angles = [theta[..., i] for i in range(3)]
    rows = computed_once(jnp.stack([cos_alone(t) for t in angles] + [sin_alone(t) for t in angles]))
    return tuple(rows[:3]), tuple(rows[3:])


def centre_components(
    robot: DeltaRobot, theta: Array, cosines=None
) -> tuple[tuple[Array, ...], ...]:
    """The sphere centres ``C_i = E_i - r_platform u_i`` as components ``C[i][k]`` (chain i,
    coordinate k), batch-shaped: ``p`` lies at distance ``l_rod`` from each.

    ``cosines``: ``cos_sin(theta)`` when the caller has it already.
    """
    r_base, r_platform, l_arm, _, _, _ = params(robot, theta.dtype)
    cos_theta, sin_theta = cos_sin(theta) if cosines is None else cosines
    out = []
    for i in range(3):
        reach = r_base - r_platform + l_arm * cos_theta[i]
        out.append((reach * UX[i], reach * UY[i], -l_arm * sin_theta[i]))
    return tuple(out)


def components(x: Array) -> tuple[Array, Array, Array]:
    """The three coordinates of ``(..., 3)`` as batch-shaped arrays."""
    return x[..., 0], x[..., 1], x[..., 2]


def dot3(u, v) -> Array:
    """Dot product of two vectors given as components."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def sanitise(x: Jet, fill: Array, rates: bool = True) -> tuple[Jet, Array]:
    """Double-where, step 1: replace non-finite elements by ``fill`` (position) and 0 (rates).

    Without rates, ``x.v`` and ``x.a`` are ``None`` (positions only, nothing else allocated).
    """
    valid = finite3(x.p)
    if rates:
        valid = valid & finite3(x.v) & finite3(x.a)
    vc = valid[..., None]
    p = jnp.where(vc, x.p, fill)
    if not rates:
        return Jet.positions(p), valid
    return Jet(p, jnp.where(vc, x.v, 0.0), jnp.where(vc, x.a, 0.0)), valid


def home(robot: DeltaRobot, dtype) -> Array:
    """The platform position with every arm horizontal (``theta = 0``), ``(3,)``: a finite
    point substituted for invalid input."""
    r_base, r_platform, l_arm, l_rod, _, _ = params(robot, dtype)
    reach = r_base - r_platform + l_arm
    z = -safe_sqrt(l_rod * l_rod - reach * reach)
    return jnp.stack([0.0 * z, 0.0 * z, jnp.where(z < 0, z, -l_rod)])


def in_own_units(robot: DeltaRobot) -> tuple[DeltaRobot, Any]:
    """The robot with its lengths divided by ``l_arm + l_rod``, and that scale.

    The kernels work in these units, so no square or product of rates over- or underflows
    whatever the scale of the robot and its targets; lengths are scaled back on output.
    """
    scale = robot.l_arm + robot.l_rod
    lengths = [robot.r_base, robot.r_platform, robot.l_arm, robot.l_rod]
    fields = [x / scale for x in lengths] + [robot.theta_min, robot.theta_max]
    fields.append(robot.link_radius / scale)
    return jax.tree.unflatten(jax.tree.structure(robot), fields), scale


# Beyond this many robot sizes from the base a point is unreachable: tested before any square.
FAR = 1e6


def far_away(p: Array) -> Array:
    """True where a point (in the robot's own units, ``(..., 3)``) is beyond ``FAR``."""
    return ~(
        (jnp.abs(p[..., 0]) <= FAR) & (jnp.abs(p[..., 1]) <= FAR) & (jnp.abs(p[..., 2]) <= FAR)
    )


def rates_ok(status: Array) -> Array:
    """Where rates are defined: the position is solved and the relevant Jacobian is regular."""
    return (status == Status.OK) | (status == Status.OUT_OF_LIMITS)


def frozen(robot: DeltaRobot) -> DeltaRobot | None:
    """The robot with Python-float fields when every field is a concrete scalar, else None."""
    values = concrete_scalars(robot, (*FIELDS, "link_radius"))
    if values is None:
        return None
    return jax.tree.unflatten(jax.tree.structure(robot), list(values))


def constant_geometry_kernel(
    fn: Callable[..., Any],
    static: tuple[str, ...] = (),
    batched: dict[str, int] | None = None,
) -> Callable[..., Any]:
    """A ``Kernel`` of ``fn`` that compiles a concrete geometry in as constants.

    A geometry of Python numbers is a static argument (one compilation per robot, cached), so
    XLA folds it into the kernel; a traced or batched geometry (gradients with respect to the
    design, ``vmap`` over robots) takes the dynamic path.

    With ``batched`` (argument name -> core axes), small batches are padded and large ones
    split across host threads (``Policy(pad=True, threads=True)``), and the call takes the
    batch shape as the keyword ``batch``.
    """
    policy = Policy(pad=True, threads=True) if batched else WHOLE
    dynamic = Kernel(fn, static=static, batched=batched, policy=policy)
    constant = Kernel(fn, static=("robot", *static), batched=batched, policy=policy)

    @functools.wraps(fn)
    def call(robot: DeltaRobot, *args: Any, **kwargs: Any) -> Any:
        concrete = frozen(robot)
        if concrete is None:
            return dynamic(robot, *args, **kwargs)
        return constant(concrete, *args, **kwargs)

    return call


def float_dtype(*xs: Any) -> Any:
    """The floating dtype of the inputs (float for integers)."""
    return jnp.result_type(*xs, float)


def as_coords(x: ArrayLike, name: str) -> Array:
    """``x`` as a float array of shape ``(..., 3)``; ``ValueError`` naming ``name`` if not."""
    x = _validate.as_float(x)
    if x.ndim == 0 or x.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., 3), got {tuple(x.shape)}")
    return x
