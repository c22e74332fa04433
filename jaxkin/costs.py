"""Cost terms of trajectory optimisation, apart from the optimiser's loop (``optimize``).

A cost is ``cost(TrajectorySample) -> (B,)``: it sees the IK of B candidate paths (joint
``Jet``, statuses, margins), the limits, the path itself and the robot. Terms (per candidate,
``dt`` the sample spacing, sums over samples ``t`` and joints)::

    acceleration         sum_t |q_ddot|^2 dt
    jerk                 sum_t |jerk|^2 dt,  jerk by forward differences of q_ddot
    limit_penalty        sum_t excess^2  (how far q, |q_dot|, |q_ddot| pass their limits)
    unreachable_penalty  sum_t max(0, -margin)^2
    SingularityBarrier   sum_t (max(0, threshold - margin) / threshold)^2
    Obstacles            sum_t sum_primitives (max(0, safety - nearest distance) / safety)^2
                         (the robot's collision body, exact signed distances; optionally
                         its self-collision pairs)

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

from . import _validate, collision, plan
from .jet import Jet
from .status import NamedStatusRepr

__all__ = [
    "DEFAULT_COST",
    "CostTerm",
    "Obstacles",
    "SingularityBarrier",
    "Sum",
    "TrajectorySample",
    "acceleration",
    "bind",
    "compose",
    "jerk",
    "limit_penalty",
    "singularity_barrier",
    "unreachable_penalty",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class TrajectorySample(NamedStatusRepr):
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
    """Obstacles to keep the robot's body clear of, and optionally the body clear of itself,
    as a cost term.

    Per candidate: ``sum_t sum_p (max(0, safety - min_o d(p, o)) / safety)^2`` over the
    robot's primitives ``p`` (its collision body, ``robot.collision_body()`` placed by
    ``robot.link_poses``) and their nearest obstacle ``o`` of the world
    (``collision.nearest_obstacles``), with ``d`` the exact signed distance of
    ``collision.distance`` (spheres, capsules, oriented boxes, half-spaces), plus,
    with ``self_collision``, the same barrier on each of the robot's self-collision link pairs
    (``robot.self_collision_pairs()``, the smallest distance of the pair). Every field but the
    structure is array data, so obstacles can move between calls without a new compilation.

    Attributes:
        world: a ``collision.World`` (3-D; a planar robot's obstacles are placed in its plane,
            z = 0, with boxes as tall as needed).
        safety: the clearance sought, in length units (> 0).
        body, pairs: the robot's body and self-collision pairs, computed on the host: by
            ``create(robot=...)``, or by ``optimize`` (``bind``) from the robot it is given.
            None when unbound: the cost then reads the body from the robot it sees, which
            works only where that body can be built from traced geometry (the SCARA, the
            Delta and the arms; not a URDF chain, whose mesh covers are computed on the host).
    """

    world: collision.World
    safety: Any
    body: Any = None
    pairs: Any = None
    self_collision: bool = dataclasses.field(default=False, metadata=dict(static=True))

    @classmethod
    def create(
        cls,
        spheres: tuple[ArrayLike, ArrayLike] | None = None,
        boxes: tuple[ArrayLike, ArrayLike] | None = None,
        safety: float = 1.0,
        dims: int = 3,
        world: collision.World | None = None,
        robot: Any = None,
        self_collision: bool = False,
    ) -> Obstacles:
        """``spheres=(centres (S, d), radii (S,))``, ``boxes=(centres (Bx, d), half_extents
        (Bx, d))`` (axis-aligned) with ``d = dims`` (2 for a planar robot: in the plane z =
        0), and/or a ``collision.World`` of any obstacles; ``safety`` in length units;
        ``robot`` binds the cost to that robot's body now (else ``optimize`` binds it to the
        robot it optimises); ``self_collision`` adds the robot's self-collision pairs.

        Raises:
            ValueError: shapes that do not match, non-finite values, radii or half extents
                that are negative, or a safety distance that is not positive.
        """
        safety = _validate.positive_number(safety, "safety")
        if dims not in (2, 3):
            raise ValueError(f"dims must be 2 or 3, got {dims!r}")
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
        sphere_c, sphere_r, box_c, box_h = arrays
        if dims == 2:  # the plane z = 0; a box reaches past any in-plane depth along z
            sphere_c = np.concatenate([sphere_c, np.zeros((len(sphere_c), 1))], axis=1)
            tall = np.full((len(box_h), 1), 1e3 * (1.0 + float(np.max(box_h, initial=0.0))))
            box_c = np.concatenate([box_c, np.zeros((len(box_c), 1))], axis=1)
            box_h = np.concatenate([box_h, tall], axis=1)
        if world is not None and not isinstance(world, collision.World):
            raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
        extra = collision.World.create(
            spheres=collision.Spheres.create(sphere_c, sphere_r),
            boxes=collision.Boxes.create(box_c, half_extents=box_h),
        )
        merged = extra
        if world is not None:
            merged = jax.tree.map(
                lambda a, b: jnp.concatenate([a, b.astype(a.dtype)]), world, extra
            )
        term = cls(merged, jnp.asarray(float(safety)), None, None, bool(self_collision))
        return term if robot is None else term.bind(robot)

    def bind(self, robot: Any) -> Obstacles:
        """This term with ``robot``'s body and self-collision pairs (host side,
        ``collision.prepare``, cached on the robot); unchanged when already bound."""
        if self.body is not None:
            return self
        body, pairs = collision.prepare(robot, self.self_collision)
        return dataclasses.replace(self, body=body, pairs=pairs)

    def _barrier(self, distance: Array, safety: Array) -> Array:
        gap = jax.nn.relu(safety - distance) / safety
        return gap * gap

    def __call__(self, sample: TrajectorySample) -> Array:
        robot = sample.robot
        q = sample.q.p
        dtype = q.dtype
        body, pairs = self.body, self.pairs
        if body is None:  # unbound: the robot's own, from its (traced) geometry
            body = robot.collision_body()
            if self.self_collision:
                pairs = collision.SelfPairs.create(body, robot.self_collision_pairs())
        body, world = body.astype(dtype), self.world.astype(dtype)
        spheres, capsules = body.place(robot.link_poses(q).astype(dtype))
        safety = jnp.asarray(self.safety, dtype)
        total = jnp.zeros(q.shape[:-2], dtype)
        for nearest in collision.nearest_obstacles(spheres, capsules, world):
            total = total + jnp.sum(self._barrier(nearest.distance, safety), axis=(-2, -1))
        if self.self_collision and pairs is not None and pairs.link_pairs:
            d = collision.self_distances(spheres, capsules, pairs)
            total = total + jnp.sum(self._barrier(d, safety), axis=(-2, -1))
        return total


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
        total: Any = 0.0  # a float until the first term
        data = iter(self.data_terms)
        for weight, term in zip(self.weights, self.terms, strict=True):
            fn = next(data) if term is None else term
            total = total + jnp.asarray(weight, sample.margin.dtype) * fn(sample)
        return total


def bind(cost: Any, robot: Any) -> Any:
    """``cost`` with every ``Obstacles`` term in it (itself, or the data terms of a ``Sum``)
    bound to ``robot``'s body and self-collision pairs, computed on the host (``optimize``
    calls it before tracing: a URDF chain's body cannot be built inside the trace); any other
    cost is returned as it is."""
    if isinstance(cost, Obstacles):
        return cost.bind(robot)
    if isinstance(cost, Sum):
        return dataclasses.replace(
            cost, data_terms=tuple(bind(term, robot) for term in cost.data_terms)
        )
    return cost


def compose(*weighted_terms: tuple[float, CostTerm]) -> Sum:
    """The weighted sum of ``(weight, term)`` pairs, described by value (a new weight or
    threshold reuses the compilation)."""
    weights: list[np.ndarray] = []
    data_terms: list[CostTerm] = []
    terms: list[CostTerm | None] = []
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
    (1.0, acceleration),
    (100.0, SingularityBarrier(0.05)),
    (1e6, unreachable_penalty),
    (1e6, limit_penalty),
)
"""Smooth joint motion, kept away from singularities, and (dominant) inside the workspace and
the joint limits (the robot's own, ``robot.joint_limits()``, unless the caller's are tighter)."""
