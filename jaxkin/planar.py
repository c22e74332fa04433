"""Angle and distance of planar vectors with their time derivatives [Noriega, Figs. 2-3].

The public functions take ``Jet``s of shape ``(..., 2)`` and return a scalar ``Jet`` (batch
shape) and a boolean ``defined`` mask. Where the quantity is undefined (zero vector, coincident
points) the Jet holds zeros and ``defined`` is False; nothing is NaN and gradients stay finite.

The component-wise forms (``angle_rates``, ``length_rates``) take separate x/y arrays: kernels
such as the dyad work on components throughout, which lets XLA fuse the whole computation into
few loops (a ``(..., 2)`` layout splits it into many).
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from ._numerics import safe_div, safe_sqrt
from ._trig import atan2
from .jet import Jet

__all__ = [
    "angle",
    "angle_rates",
    "distance",
    "length_rates",
    "link_end_rates",
]


def angle_rates(
    x: Array,
    y: Array,
    x_dot: Array,
    y_dot: Array,
    x_ddot: Array,
    y_ddot: Array,
    inv_r2: Array | None = None,
) -> tuple[Array, Array]:
    """``(theta_dot, theta_ddot)`` of ``theta = atan2(y, x)``; 0 for the zero vector.

    ``inv_r2``: ``1 / (x^2 + y^2)`` (0 for the zero vector) when the caller already has it.

    [Noriega, Fig. 2], corrected (docs/errata.md), one formula for every quadrant::

        theta_dot  = (x y' - y x') / r2                                   r2 = x^2 + y^2
        theta_ddot = ((x y'' - y x'') r2 - (x y' - y x') 2 (x x' + y y')) / r2^2
    """
    if inv_r2 is None:
        inv_r2 = safe_div(1.0, x * x + y * y)
    theta_dot = (x * y_dot - y * x_dot) * inv_r2
    theta_ddot = ((x * y_ddot - y * x_ddot) - 2.0 * theta_dot * (x * x_dot + y * y_dot)) * inv_r2
    return theta_dot, theta_ddot


def length_rates(
    x: Array,
    y: Array,
    x_dot: Array,
    y_dot: Array,
    x_ddot: Array,
    y_ddot: Array,
    inv_l: Array | None = None,
) -> tuple[Array, Array, Array]:
    """``(l, l_dot, l_ddot)`` of ``l = |(x, y)|``; the rates are 0 where ``l = 0``.

    ``inv_l``: ``1 / l`` (0 where ``l = 0``) when the caller already has it.

    [Noriega, Fig. 3] (correct as printed), with ``d = (x, y)``::

        l_dot  = (d . d') / l
        l_ddot = ((d' . d' + d . d'') l - (d . d') l_dot) / l^2
    """
    if inv_l is None:
        l = safe_sqrt(x * x + y * y)
        inv_l = safe_div(1.0, l)
    else:
        l = (x * x + y * y) * inv_l
    d_dot_d = x * x_dot + y * y_dot
    l_dot = d_dot_d * inv_l
    l_ddot = x_dot * x_dot + y_dot * y_dot + x * x_ddot + y * y_ddot - d_dot_d * l_dot * inv_l
    return l, l_dot, l_ddot * inv_l


def link_end_rates(
    length: Array, cos_phi: Array, sin_phi: Array, phi_dot: Array, phi_ddot: Array
) -> tuple[Array, Array, Array, Array]:
    """Velocity and acceleration of ``length (cos phi, sin phi)``, a link of constant length
    turning at ``phi_dot``, ``phi_ddot`` [Noriega, eqs. 7-8 without the base point's rates]::

        v = length phi_dot (-sin phi, cos phi)
        a = length (phi_ddot (-sin phi, cos phi) - phi_dot^2 (cos phi, sin phi))

    Returns ``(v_x, v_y, a_x, a_y)``, component-wise like the inputs.
    """
    v_x = -(length * sin_phi * phi_dot)
    v_y = length * cos_phi * phi_dot
    a_x = -(length * (cos_phi * phi_dot * phi_dot + sin_phi * phi_ddot))
    a_y = length * (cos_phi * phi_ddot - sin_phi * phi_dot * phi_dot)
    return v_x, v_y, a_x, a_y


def _components(jet: Jet) -> tuple[Array, ...]:
    return tuple(arr[..., k] for arr in (jet.p, jet.v, jet.a) for k in (0, 1))


def angle(vec: Jet) -> tuple[Jet, Array]:
    """Angle ``theta`` of a planar vector with the +X axis, with its first two rates.

    ``theta = atan2(y, x)`` in (-pi, pi]; ``y = 0, x < 0`` gives +pi (Fig. 2), also for
    ``y = -0.0``. Rates as in ``angle_rates``.

    Args:
        vec: Jet of shape ``(..., 2)``.

    Returns:
        ``(theta, defined)``: a Jet of batch shape and a mask, False for the zero vector
        (then theta, theta_dot and theta_ddot are 0).
    """
    x, y, x_dot, y_dot, x_ddot, y_ddot = _components(vec)
    defined = (x * x + y * y) > 0
    y_pos = jnp.where(y == 0, 0.0, y)  # -0.0 -> +0.0 so atan2 gives +pi on the -X axis
    theta = atan2(jnp.where(defined, y_pos, 0.0), jnp.where(defined, x, 1.0))
    theta_dot, theta_ddot = angle_rates(x, y, x_dot, y_dot, x_ddot, y_ddot)
    return Jet(theta, theta_dot, theta_ddot), defined


def distance(a: Jet, b: Jet) -> tuple[Jet, Array]:
    """Distance ``l = |B - A|`` between two planar points, with its first two rates.

    Args:
        a, b: Jets of shape ``(..., 2)`` (broadcastable).

    Returns:
        ``(l, defined)``: a Jet of batch shape and a mask, False where A = B (then the rates
        are 0: they do not exist there).
    """
    l, l_dot, l_ddot = length_rates(*_components(Jet(b.p - a.p, b.v - a.v, b.a - a.a)))
    return Jet(l, l_dot, l_ddot), l > 0
