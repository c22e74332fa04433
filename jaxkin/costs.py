"""Cost terms of trajectory optimisation, apart from the optimiser's loop (``optimize``).

A cost is ``cost(TrajectorySample) -> (B,)``: it sees the IK of B candidate paths (joint
``Jet``, statuses, margins), the limits, the path itself and the robot. Terms (per candidate,
``dt`` the sample spacing, sums over samples ``t`` and joints)::

    acceleration         sum_t |q_ddot|^2 dt
    jerk                 sum_t |jerk|^2 dt,  jerk by forward differences of q_ddot
    limit_penalty        sum_t excess^2  (how far q, |q_dot|, |q_ddot| pass their limits)
    unreachable_penalty  sum_t max(0, -margin)^2
    SingularityBarrier   sum_t (max(0, threshold - margin) / threshold)^2
    Obstacles            sum_t sum_links sum_obstacles (max(0, safety - distance) / safety)^2

``compose`` weighs them into a ``Sum``. Costs are described by value (frozen dataclasses; a
cost's weights, thresholds and obstacle positions are array data), so a new weight or
obstacle position reuses the optimiser's compilation; only a new *structure* compiles.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from . import _validate, plan
from .collision import distance as sd
from .jet import Jet

__all__ = [
    "DEFAULT_COST",
    "CostTerm",
    "Obstacles",
    "SingularityBarrier",
    "Sum",
    "TrajectorySample",
    "acceleration",
    "compose",
    "jerk",
    "limit_penalty",
    "singularity_barrier",
    "unreachable_penalty",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class TrajectorySample:
    """What a cost term sees: the IK of B candidate paths of T samples.

    Attributes:
        q: Jet of joint coordinates, shape ``(B, T, n)``.
        status: ``int8`` statuses, shape ``(B, T)``.
        margin: singularity margin, shape ``(B, T)``.
        dt: sample spacing (scalar).
        limits: ``plan.Limits``.
        path: Jet of the end-effector path, shape ``(B, T, d)``.
        robot: the robot (for terms that need its links).
    """

    q: Jet
    status: Array
    margin: Array
    dt: Array
    limits: plan.Limits
    path: Jet
    robot: Any


CostTerm = Callable[[TrajectorySample], Array]


def acceleration(sample: TrajectorySample) -> Array:
    """``sum_t |q_ddot|^2 dt`` per candidate (``plan`` calls it integrated_acceleration)."""
    return jnp.sum(sample.q.a**2, axis=(-2, -1)) * sample.dt


def jerk(sample: TrajectorySample) -> Array:
    """``sum_t |jerk|^2 dt`` per candidate, jerk by forward differences of q_ddot."""
    return jnp.sum(plan.jerk(sample.q, sample.dt) ** 2, axis=(-2, -1)) * sample.dt


def limit_penalty(sample: TrajectorySample) -> Array:
    """``sum_t excess^2`` where ``excess`` is how far q, |q_dot|, |q_ddot| pass their limits."""
    return jnp.sum(plan.limit_excess(sample.q, sample.limits) ** 2, axis=-1)


def unreachable_penalty(sample: TrajectorySample) -> Array:
    """``sum_t max(0, -margin)^2``: the margin is negative outside the workspace."""
    return jnp.sum(jax.nn.relu(-sample.margin) ** 2, axis=-1)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SingularityBarrier:
    """``sum_t (max(0, threshold - margin) / threshold)^2`` per candidate.

    Attributes:
        threshold: the margin below which the barrier acts (> 0; array data).
    """

    threshold: Any

    def __call__(self, sample: TrajectorySample) -> Array:
        threshold = jnp.asarray(self.threshold, sample.margin.dtype)
        return jnp.sum((jax.nn.relu(threshold - sample.margin) / threshold) ** 2, axis=-1)


def singularity_barrier(threshold: float) -> SingularityBarrier:
    """``SingularityBarrier(threshold)``, checking ``threshold > 0``."""
    threshold = _validate.positive_number(threshold, "threshold")
    return SingularityBarrier(float(threshold))


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Obstacles:
    """Spheres and axis-aligned boxes to keep the robot's links clear of, as a cost term.

    Per candidate: ``sum_t sum_links sum_obstacles (max(0, safety - distance) / safety)^2``,
    where ``distance`` is the signed distance from a link segment (``robot.link_segments``:
    capsules along the links, the end point included) to an obstacle's surface: exact for
    spheres, and over ``box_samples`` points along each segment for boxes. Every field is
    array data, so obstacles can move between calls without a new compilation.

    Attributes:
        sphere_centres: ``(S, d)`` (``d`` the target's position dimension); ``(0, d)`` for none.
        sphere_radii: ``(S,)``.
        box_centres: ``(Bx, d)``.
        box_half_extents: ``(Bx, d)`` (half the box's side lengths).
        safety: the clearance sought, in length units (> 0).
    """

    sphere_centres: Any
    sphere_radii: Any
    box_centres: Any
    box_half_extents: Any
    safety: Any
    box_samples: int = dataclasses.field(default=8, metadata=dict(static=True))

    @classmethod
    def create(
        cls,
        spheres: tuple[ArrayLike, ArrayLike] | None = None,
        boxes: tuple[ArrayLike, ArrayLike] | None = None,
        safety: float = 1.0,
        dims: int = 3,
    ) -> Obstacles:
        """``spheres=(centres (S, d), radii (S,))``, ``boxes=(centres (Bx, d), half_extents
        (Bx, d))``, ``safety`` in length units.

        Raises:
            ValueError: shapes that do not match, non-finite values, radii or half extents
                that are negative, or a safety distance that is not positive.
        """
        safety = _validate.positive_number(safety, "safety")
        arrays = []
        for name, pair, size_shape in (("spheres", spheres, ()), ("boxes", boxes, (dims,))):
            if pair is None:
                centres, sizes = np.zeros((0, dims)), np.zeros((0, *size_shape))
            else:
                centres, sizes = (np.asarray(x, dtype=float) for x in pair)
            if centres.ndim != 2 or centres.shape[1] != dims:
                raise ValueError(
                    f"{name}: centres must have shape (m, {dims}), got {centres.shape}"
                )
            want = (centres.shape[0], *size_shape)
            if sizes.shape != want:
                raise ValueError(f"{name}: sizes must have shape {want}, got {sizes.shape}")
            if not (np.all(np.isfinite(centres)) and np.all(np.isfinite(sizes))):
                raise ValueError(f"{name}: centres and sizes must be finite")
            if np.any(sizes < 0):
                raise ValueError(f"{name}: sizes must be >= 0, got {sizes}")
            arrays += [centres, sizes]
        return cls(*(jnp.asarray(x) for x in arrays), jnp.asarray(float(safety)))

    def distances(self, segments: Array) -> Array:
        """Signed distances ``(..., S + Bx)`` from segments ``(..., 2, d)`` to every obstacle."""
        a, b = segments[..., 0, :], segments[..., 1, :]
        dtype = segments.dtype
        spheres = sd.point_segment(
            self.sphere_centres.astype(dtype), a[..., None, :], b[..., None, :]
        ) - self.sphere_radii.astype(dtype)
        t = jnp.linspace(0.0, 1.0, self.box_samples, dtype=dtype)[:, None]
        points = a[..., None, :] + t * (b - a)[..., None, :]
        boxes = jnp.min(
            sd.point_box(
                points[..., None, :],
                self.box_centres.astype(dtype),
                None,
                self.box_half_extents.astype(dtype),
            ),
            axis=-2,
        )
        return jnp.concatenate([spheres, boxes], axis=-1)

    def __call__(self, sample: TrajectorySample) -> Array:
        segments = sample.robot.link_segments(sample.q.p, sample.path.p)
        safety = jnp.asarray(self.safety, segments.dtype)
        gap = jax.nn.relu(safety - self.distances(segments)) / safety
        return jnp.sum(gap * gap, axis=(-3, -2, -1))


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Sum:
    """``sum_i weights[i] * terms[i](sample)``; the weights are array data, the terms static
    (plain functions, or pytrees such as ``SingularityBarrier`` and ``Obstacles`` whose own
    fields are data: pass those in ``data_terms``)."""

    weights: tuple
    data_terms: tuple
    terms: tuple = dataclasses.field(metadata=dict(static=True))

    def __call__(self, sample: TrajectorySample) -> Array:
        total = 0.0
        data = iter(self.data_terms)
        for weight, term in zip(self.weights, self.terms, strict=True):
            fn = next(data) if term is None else term
            total = total + jnp.asarray(weight, sample.margin.dtype) * fn(sample)
        return total


def compose(*weighted_terms: tuple[float, CostTerm]) -> Sum:
    """The weighted sum of ``(weight, term)`` pairs, described by value (a new weight or
    threshold reuses the compilation)."""
    weights, data_terms, terms = [], [], []
    for weight, term in weighted_terms:
        weight = _validate.finite_number(weight, "compose: weights")
        # NumPy, not a device array: importing jaxkin must not start JAX before jax.distributed
        weights.append(np.asarray(float(weight)))
        if jax.tree_util.all_leaves([term]):
            terms.append(term)  # a plain function: part of the structure
        else:
            data_terms.append(term)
            terms.append(None)
    return Sum(tuple(weights), tuple(data_terms), tuple(terms))


DEFAULT_COST = compose(
    (1.0, acceleration), (100.0, SingularityBarrier(0.05)), (1e6, unreachable_penalty)
)
"""Smooth joint motion, kept away from singularities, and (dominant) inside the workspace."""
