"""Angle and distance of planar vectors with their time derivatives (seed 000, Figs. 2-3).

Both take ``Jet``s of shape ``(..., 2)`` and return a scalar ``Jet`` (batch shape) and a boolean
``defined`` mask. Where the quantity is undefined (zero vector, coincident points) the Jet holds
zeros and ``defined`` is False; nothing is NaN and gradients stay finite.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from ._numerics import safe_div, safe_sqrt
from .jet import Jet


def angle(vec: Jet) -> tuple[Jet, Array]:
    """Angle ``theta`` of a planar vector with the +X axis, with its first two rates.

    Seed 000 Fig. 2, corrected (ERRATA seed 000 items 1-3): one formula for every quadrant::

        theta      = atan2(y, x)                      in (-pi, pi]; y = 0, x < 0 gives +pi
        theta_dot  = (x y' - y x') / r2               r2 = x^2 + y^2
        theta_ddot = ((x y'' - y x'') r2 - (x y' - y x') 2 (x x' + y y')) / r2^2

    Args:
        vec: Jet of shape ``(..., 2)``.

    Returns:
        ``(theta, defined)``: a Jet of batch shape and a mask, False for the zero vector
        (then theta, theta_dot and theta_ddot are 0).
    """
    x, y = vec.p[..., 0], vec.p[..., 1]
    x_dot, y_dot = vec.v[..., 0], vec.v[..., 1]
    x_ddot, y_ddot = vec.a[..., 0], vec.a[..., 1]
    r2 = x * x + y * y
    defined = r2 > 0
    # Fig. 2 puts y = 0, x < 0 at +pi: map -0.0 to +0.0 so atan2 agrees.
    y_pos = jnp.where(y == 0, 0.0, y)
    theta = jnp.arctan2(jnp.where(defined, y_pos, 0.0), jnp.where(defined, x, 1.0))
    cross = x * y_dot - y * x_dot
    theta_dot = safe_div(cross, r2)
    theta_ddot = safe_div(
        (x * y_ddot - y * x_ddot) * r2 - cross * 2.0 * (x * x_dot + y * y_dot), r2 * r2
    )
    return Jet(theta, theta_dot, theta_ddot), defined


def distance(a: Jet, b: Jet) -> tuple[Jet, Array]:
    """Distance ``l = |B - A|`` between two planar points, with its first two rates.

    Seed 000 Fig. 3 (correct as printed), with ``d = B - A``::

        l      = sqrt(d . d)
        l_dot  = (d . d') / l
        l_ddot = ((d' . d' + d . d'') l - (d . d') l_dot) / l^2

    Args:
        a, b: Jets of shape ``(..., 2)`` (broadcastable).

    Returns:
        ``(l, defined)``: a Jet of batch shape and a mask, False where A = B (then the rates
        are 0: they do not exist there).
    """
    d, d_dot, d_ddot = b.p - a.p, b.v - a.v, b.a - a.a
    l = safe_sqrt(jnp.sum(d * d, axis=-1))
    defined = l > 0
    d_dot_d = jnp.sum(d * d_dot, axis=-1)
    l_dot = safe_div(d_dot_d, l)
    l_ddot = safe_div(
        (jnp.sum(d_dot * d_dot, axis=-1) + jnp.sum(d * d_ddot, axis=-1)) * l - d_dot_d * l_dot,
        l * l,
    )
    return Jet(l, l_dot, l_ddot), defined
