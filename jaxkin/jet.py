"""``Jet``: position, velocity and acceleration of a quantity, and ``lift``.

A ``Jet`` carries a trajectory's second-order Taylor data at one instant: ``p`` (value),
``v = dp/dt`` and ``a = d2p/dt2``, all of the same shape. Leading axes are batch axes; the last
axis holds the coordinates where there is one (``(..., 2)`` for a planar point).

``lift(f)`` turns a position-level function ``y = f(x)`` into a Jet-level one by the chain
rule, computed with forward-mode autodiff (nested ``jax.jvp``)::

    y_dot  = Df(x)[x_dot]
    y_ddot = Df(x)[x_ddot] + D2f(x)[x_dot, x_dot]

Both come out of one nested ``jvp``: the outer jvp differentiates ``(x, t) -> Df(x)[t]`` along
``(x_dot, x_ddot)``. This works through ``lax.custom_root`` and ``while_loop``-free code alike.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

__all__ = [
    "Jet",
    "lift",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Jet:
    """Position ``p``, velocity ``v`` and acceleration ``a`` of one quantity.

    Attributes:
        p: value, shape ``(..., *coords)``.
        v: first time derivative, same shape as ``p``.
        a: second time derivative, same shape as ``p``.
    """

    p: Array
    v: Array
    a: Array

    @classmethod
    def constant(cls, p: ArrayLike) -> Jet:
        """A quantity at rest: zero velocity and acceleration."""
        p = jnp.asarray(p)
        if not jnp.issubdtype(p.dtype, jnp.inexact):
            p = p.astype(jnp.result_type(float))
        zeros = jnp.zeros_like(p)
        return cls(p, zeros, zeros)

    @classmethod
    def positions(cls, p: Array) -> Jet:
        """Positions alone, their rates not computed (``None``): a kernel's intermediate when
        its caller asked for no rates (``rates=False``), never a result."""
        return cls(p, None, None)  # type: ignore[arg-type]  # the rates are left out

    @classmethod
    def of(cls, p: ArrayLike, v: ArrayLike | None = None, a: ArrayLike | None = None) -> Jet:
        """Build a Jet from arrays, filling missing rates with zeros and sharing one dtype."""
        # host data converted on the host and put once: no eager program compiled per process
        given = [x for x in (p, v, a) if x is not None]
        dtype = jnp.result_type(
            *(x if isinstance(x, jax.Array) else np.asarray(x) for x in given), float
        )

        def put(x: Any) -> Array:
            if isinstance(x, jax.Array):
                return jnp.asarray(x, dtype)
            return jax.device_put(np.asarray(x, dtype))

        p = put(p)
        v = put(np.zeros(p.shape, dtype)) if v is None else put(v)
        a = put(np.zeros(p.shape, dtype)) if a is None else put(a)
        return cls(p, v, a)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.p.shape)

    @property
    def dtype(self) -> Any:
        return self.p.dtype

    def __getitem__(self, index: Any) -> Jet:
        """Index all three arrays alike, e.g. ``jet[..., 0]`` for the x coordinate."""
        return Jet(self.p[index], self.v[index], self.a[index])

    def astype(self, dtype: Any) -> Jet:
        """The same Jet in ``dtype`` (no copy, and no dispatch, when it already is)."""
        if all(x.dtype == dtype for x in (self.p, self.v, self.a)):
            return self
        return Jet(self.p.astype(dtype), self.v.astype(dtype), self.a.astype(dtype))

    def map(self, fn: Callable[[Array], Array]) -> Jet:
        """Apply the same *linear* map to p, v and a (e.g. a reshape or a selection)."""
        return Jet(fn(self.p), fn(self.v), fn(self.a))

    @staticmethod
    def stack(jets: list[Jet], axis: int = -1) -> Jet:
        """Stack Jets along a new axis (default: a new last, coordinate axis)."""
        return Jet(
            jnp.stack([j.p for j in jets], axis),
            jnp.stack([j.v for j in jets], axis),
            jnp.stack([j.a for j in jets], axis),
        )


def _to_jet_if_float(y: Array, y_dot: Array, y_ddot: Array) -> Jet | Array:
    # Integer and boolean outputs (status codes, masks) have float0 tangents: keep the value.
    if jnp.issubdtype(jnp.asarray(y).dtype, jnp.inexact):
        return Jet(y, y_dot, y_ddot)
    return y


def lift(f: Callable[..., Any]) -> Callable[..., Any]:
    """Lift a position-level function to Jets by forward-mode autodiff.

    Every positional argument that is a ``Jet`` is differentiated along its ``v`` and ``a``;
    every other argument is a constant. Floating outputs come back as ``Jet``s, integer and
    boolean outputs (statuses, masks) unchanged, in the same pytree structure as ``f``'s output.

    Example::

        lifted = lift(lambda x: jnp.sin(x))
        y = lifted(Jet.of(x, x_dot, x_ddot))  # y.v == cos(x) x_dot, ...
    """

    @functools.wraps(f)
    def lifted(*args: Any) -> Any:
        is_jet = [isinstance(x, Jet) for x in args]
        jets = [x for x in args if isinstance(x, Jet)]
        positions = tuple(j.p for j in jets)
        velocities = tuple(j.v for j in jets)
        accelerations = tuple(j.a for j in jets)

        def at(*ps: Array) -> Any:
            it = iter(ps)
            return f(*[next(it) if jet else x for x, jet in zip(args, is_jet, strict=True)])

        def value_and_rate(ps: tuple[Array, ...], vs: tuple[Array, ...]) -> Any:
            return jax.jvp(at, ps, vs)

        (y, y_dot), (_, y_ddot) = jax.jvp(
            value_and_rate, (positions, velocities), (velocities, accelerations)
        )
        return jax.tree.map(_to_jet_if_float, y, y_dot, y_ddot)

    return lifted
