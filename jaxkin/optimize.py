"""Trajectory optimisation through the IK kernels: per-guess L-BFGS (or any optax method).

A trajectory is a Bezier curve in task space: ``p(s) = sum_i B_i(s) P_i`` with Bernstein
polynomials ``B_i`` of degree ``K - 1`` and ``s = t / duration``. The end control points are
``start`` and ``goal`` (with ``rest_to_rest`` the second and second-to-last too, so the path
starts and ends at rest); the interior points are the parameters. Rates are exact derivatives
of the basis, so the IK kernels receive an exact ``Jet``.

Every guess is optimised on its own (``jax.vmap`` of one guess's update): each has its own
L-BFGS history and line search (the default, ``LBFGS()``, optax's ``lbfgs`` with a zoom line
search), or its own Adam moments. The loop runs compiled (``lax.while_loop``) until every guess
has stopped: its gradient norm is below ``gtol * (1 + |f|)`` or its cost changed by less than
``ftol`` relatively in a step (``converged``), or ``steps`` were taken. The parameters are the
interior points in units of the robot's size.

Costs are ``cost(TrajectorySample) -> (B,)``. Terms: ``acceleration``, ``jerk``,
``limit_penalty``, ``unreachable_penalty``, ``SingularityBarrier(threshold)`` and
``Obstacles(...)`` (spheres and boxes kept clear of the robot's links by a safety distance);
``compose`` weighs them. Costs and methods are described by value (frozen dataclasses; a
cost's weights, thresholds and obstacle positions are array data), so a new start, goal,
guess, weight or obstacle position reuses the compilation; only a new *structure* compiles.
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
import optax
from jax import Array
from jax.typing import ArrayLike

from . import _batching, _processes, _validate, plan
from ._numerics import safe_norm
from ._progress import bar, is_active
from .jet import Jet
from .robot import Robot, as_robot, fk, ik

__all__ = [
    "DEFAULT_COST",
    "LBFGS",
    "Adam",
    "Obstacles",
    "OptimizationResult",
    "SingularityBarrier",
    "Sum",
    "TrajectorySample",
    "acceleration",
    "bezier_basis",
    "bezier_path",
    "compose",
    "jerk",
    "limit_penalty",
    "optimize",
    "singularity_barrier",
    "straight_line_guess",
    "unreachable_penalty",
]

PROGRESS_BLOCK = 50  # optimiser steps per compiled call when a progress bar is shown


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
    return SingularityBarrier(_validate.positive_number(threshold, "threshold"))


def _box_distance(points: Array, centres: Array, half: Array) -> Array:
    """Signed distance from points ``(..., d)`` to axis-aligned boxes ``(m, d)``: ``(..., m)``."""
    offset = jnp.abs(points[..., None, :] - centres) - half
    outside = safe_norm(jnp.maximum(offset, 0.0))
    inside = jnp.minimum(jnp.max(offset, axis=-1), 0.0)
    return outside + inside


def _segment_sphere_distance(a: Array, b: Array, centres: Array, radii: Array) -> Array:
    """Distance from segments ``a -> b`` ``(..., d)`` to spheres minus their radii: ``(..., m)``."""
    ab = (b - a)[..., None, :]
    ac = centres - a[..., None, :]
    length_sq = jnp.sum(ab * ab, axis=-1)
    t = jnp.clip(jnp.sum(ac * ab, -1) / jnp.where(length_sq > 0, length_sq, 1.0), 0.0, 1.0)
    nearest = a[..., None, :] + t[..., None] * ab
    return safe_norm(nearest - centres) - radii


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
        spheres = _segment_sphere_distance(
            a, b, self.sphere_centres.astype(dtype), self.sphere_radii.astype(dtype)
        )
        t = jnp.linspace(0.0, 1.0, self.box_samples, dtype=dtype)[:, None]
        points = a[..., None, :] + t * (b - a)[..., None, :]
        boxes = jnp.min(
            _box_distance(
                points, self.box_centres.astype(dtype), self.box_half_extents.astype(dtype)
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
        weights.append(np.asarray(weight))
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


# ------------------------------------------------------------------ methods
@dataclasses.dataclass(frozen=True)
class LBFGS:
    """L-BFGS per guess (``optax.lbfgs``: ``memory`` pairs, a zoom line search of at most
    ``linesearch_steps`` evaluations). The default method."""

    memory: int = 10
    linesearch_steps: int = 20

    def transformation(self) -> optax.GradientTransformationExtraArgs:
        # A quasi-Newton step starts its line search at 1 ("one"), not at the last step length.
        search = optax.scale_by_zoom_linesearch(
            max_linesearch_steps=self.linesearch_steps, initial_guess_strategy="one"
        )
        return optax.lbfgs(memory_size=self.memory, linesearch=search)


@dataclasses.dataclass(frozen=True)
class Adam:
    """Adam per guess with a step of ``learning_rate`` (in units of the robot's size)."""

    learning_rate: float = 1e-2

    def transformation(self) -> optax.GradientTransformationExtraArgs:
        return optax.with_extra_args_support(optax.adam(self.learning_rate))


# ------------------------------------------------------------------ the path
def bezier_basis(n_ctrl: int, n_samples: int) -> np.ndarray:
    """Bernstein basis and its first two derivatives in ``s``: shape ``(3, n_samples, n_ctrl)``.

    ``B_i(s) = C(K-1, i) s^i (1 - s)^(K-1-i)`` at ``s = linspace(0, 1, n_samples)``; the
    derivatives use ``B'_{i,n} = n (B_{i-1,n-1} - B_{i,n-1})`` (host-side setup, float64).
    """

    def bernstein(degree: int, s: np.ndarray) -> np.ndarray:
        i = np.arange(degree + 1)
        coef = np.array([math.comb(degree, k) for k in i], float)
        return coef * s[:, None] ** i * (1.0 - s[:, None]) ** (degree - i)

    def derivative(values: np.ndarray, degree: int) -> np.ndarray:
        padded = np.pad(values, ((0, 0), (1, 1)))
        return degree * (padded[:, :-1] - padded[:, 1:])

    s = np.linspace(0.0, 1.0, n_samples)
    n = n_ctrl - 1
    b0 = bernstein(n, s)
    b1 = derivative(bernstein(n - 1, s), n) if n >= 1 else np.zeros_like(b0)
    b2 = derivative(derivative(bernstein(n - 2, s), n - 1), n) if n >= 2 else np.zeros_like(b0)
    return np.stack([b0, b1, b2])


def _full_controls(interior: Array, start: Array, goal: Array, rest_to_rest: bool) -> Array:
    batch = interior.shape[:-2]
    ends = [jnp.broadcast_to(x, (*batch, 1, x.shape[-1])) for x in (start, goal)]
    if rest_to_rest:
        ends = [jnp.concatenate([e, e], axis=-2) for e in ends]
    return jnp.concatenate([ends[0], interior, ends[1]], axis=-2)


def bezier_path(controls: Array, basis: Array, duration: float) -> Jet:
    """Jet of the Bezier path, shape ``(..., T, d)``, from controls ``(..., K, d)``."""
    p = jnp.einsum("tk,...kc->...tc", basis[0], controls)
    v = jnp.einsum("tk,...kc->...tc", basis[1], controls) / duration
    a = jnp.einsum("tk,...kc->...tc", basis[2], controls) / duration**2
    return Jet(p, v, a)


def straight_line_guess(
    start: ArrayLike, goal: ArrayLike, n_interior: int, n_guesses: int = 1, noise=0.0, seed=0
) -> np.ndarray:
    """Interior control points on the segment start-goal, plus Gaussian noise: (B, K-2, d)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    s = np.linspace(0.0, 1.0, n_interior + 2)[1:-1, None]
    line = start + s * (goal - start)
    rng = np.random.default_rng(seed)
    return line + noise * rng.normal(size=(n_guesses, n_interior, start.shape[-1]))


# ------------------------------------------------------------------ the result
@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class OptimizationResult:
    """Result of ``optimize``.

    Attributes:
        controls: all Bezier control points (ends included), shape ``(B, K, d)``.
        path: Jet of the optimised paths, shape ``(B, T, d)``.
        cost: the final cost of each guess, shape ``(B,)``.
        history: the cost of each guess before every step and after the last, ``(steps + 1,
            B)`` (held constant once a guess has stopped).
        converged: each guess met a stopping rule (gradient norm or cost change), ``(B,)``.
        iterations: steps taken by each guess, ``(B,)``.
        grad_norm: the final gradient norm (with respect to the interior points in units of the
            robot's size), ``(B,)``.
        best: the index of the best guess: the feasible one of least cost (or of least cost if
            none is feasible), an ``int32`` scalar.
        evaluation: ``plan.Evaluation`` of the optimised paths.

    With several devices (one process or many, ``jax.distributed``) every array is global,
    split along the guess axis (``history`` along its second axis; replicated when B is not a
    multiple of ``jax.device_count()``), and ``best`` is the global index on every process.
    """

    controls: Array
    path: Jet
    cost: Array
    history: Array
    converged: Array
    iterations: Array
    grad_norm: Array
    best: Array
    evaluation: plan.Evaluation


def _sample(robot, controls, basis, duration, dt, limits, branch) -> TrajectorySample:
    path = bezier_path(controls, basis, duration)
    res = ik(robot, path, branch)
    dt = jnp.asarray(dt, controls.dtype)
    return TrajectorySample(res.q, res.status, res.margin, dt, limits, path, robot)


@dataclasses.dataclass(frozen=True)
class _Static:
    """Everything that shapes the compiled loop (hashable)."""

    method: Any
    cost: Any  # the cost itself when it is not array data, else None
    cost_treedef: Any
    branch: Any
    rest_to_rest: bool
    steps: int


def _objective(x: Array, data: dict, static: _Static) -> Array:
    """One guess's cost at interior points ``x`` ``(K', d)`` in units of the robot's size."""
    cost = static.cost
    if cost is None:
        cost = jax.tree.unflatten(static.cost_treedef, data["cost"])
    interior = (x * data["scale"])[None]
    controls = _full_controls(interior, data["start"], data["goal"], static.rest_to_rest)
    sample = _sample(
        data["robot"],
        controls,
        data["basis"],
        data["duration"],
        data["dt"],
        data["limits"],
        static.branch,
    )
    return cost(sample)[0]


def _transformation(method: Any) -> Any:
    if isinstance(method, LBFGS | Adam):
        return method.transformation()
    return optax.with_extra_args_support(method)


@functools.partial(jax.jit, static_argnames="static")
def _start(x: Array, data: dict, static: _Static):
    """The loop's initial carry for guesses ``x`` ``(B, K', d)``."""
    value_and_grad = jax.value_and_grad(_objective)
    f, g = jax.vmap(lambda xb: value_and_grad(xb, data, static))(x)
    state = jax.vmap(_transformation(static.method).init)(x)
    batch = x.shape[0]
    history = jnp.broadcast_to(f, (static.steps + 1, batch))
    done = ~jnp.isfinite(f)
    zeros = jnp.zeros(batch, jnp.int32)
    return (x, state, f, g, done, jnp.zeros(batch, bool), zeros, jnp.int32(0), history)


@functools.partial(jax.jit, static_argnames="static")
def _run(carry, data: dict, stop: Array, static: _Static):
    """Steps until every guess has stopped, ``static.steps`` were taken, or step ``stop``."""
    tx = _transformation(static.method)
    value_and_grad = jax.value_and_grad(_objective)
    gtol, ftol = data["gtol"], data["ftol"]

    def one_step(x, state, f, g):
        def value_fn(y):
            return _objective(y, data, static)

        updates, state = tx.update(g, state, x, value=f, grad=g, value_fn=value_fn)
        x = optax.apply_updates(x, updates)
        if isinstance(static.method, LBFGS):
            # the line search evaluated the accepted point already: reuse, not re-trace
            f_new = optax.tree_utils.tree_get(state, "value")
            g_new = optax.tree_utils.tree_get(state, "grad")
        else:
            f_new, g_new = value_and_grad(x, data, static)
        return x, state, f_new, g_new

    def cond(carry):
        done, step = carry[4], carry[7]
        return (step < jnp.minimum(stop, static.steps)) & ~jnp.all(done)

    def body(carry):
        x, state, f, g, done, converged, iterations, step, history = carry
        x_new, state_new, f_new, g_new = jax.vmap(one_step)(x, state, f, g)
        good = jnp.isfinite(f_new) & jnp.all(jnp.isfinite(g_new), axis=(-2, -1))
        take = ~done & good

        def choose(new, old):
            mask = take.reshape(take.shape + (1,) * (jnp.ndim(new) - 1))
            return jnp.where(mask, new, old)

        x, state, f_next, g = jax.tree.map(
            choose, (x_new, state_new, f_new, g_new), (x, state, f, g)
        )
        grad_norm = jnp.sqrt(jnp.sum(g * g, axis=(-2, -1)))
        change = jnp.abs(f - f_next) <= ftol * jnp.maximum(jnp.abs(f), jnp.abs(f_next))
        met = take & ((grad_norm <= gtol * (1.0 + jnp.abs(f_next))) | change)
        iterations = iterations + take.astype(jnp.int32)
        converged = converged | met
        done = done | met | ~good
        history = history.at[step + 1].set(f_next)
        return (x, state, f_next, g, done, converged, iterations, step + 1, history)

    carry = jax.lax.while_loop(cond, body, carry)
    return carry


def optimize(
    robot: Robot,
    start: ArrayLike,
    goal: ArrayLike,
    interior: ArrayLike,
    duration: float = 1.0,
    n_samples: int = 100,
    optimizer: Any = None,
    steps: int = 500,
    cost: CostTerm = DEFAULT_COST,
    branch: Any = None,
    limits: plan.Limits | None = None,
    rest_to_rest: bool = False,
    space: str = "task",
    gtol: float | None = None,
    ftol: float | None = None,
    progress: bool | None = None,
) -> OptimizationResult:
    """Optimise B trajectories from ``start`` to ``goal`` at once, each guess on its own.

    Args:
        robot: any robot of the protocol whose targets are points (``robot.target``).
        start, goal: end points, shape ``robot.target.shape`` (``space="task"``), or joint
            vectors ``(n_joints,)`` (``space="joint"``: their forward kinematics).
        interior: initial interior control points, shape ``(B, K', d)`` or ``(K', d)``; every
            guess must be finite (a ``ValueError`` names the guesses that are not). Host data
            (the same on every process), or a global ``jax.Array`` split along the guesses:
            with several devices each runs its own guesses' loop.
        duration: motion time; ``n_samples`` samples are taken uniformly in [0, duration].
        optimizer: ``LBFGS()`` (default) or ``Adam(...)`` (described by value: no new
            compilation), or any optax transformation (a new object compiles anew: keep one).
        steps: the most steps a guess takes.
        cost: ``cost(TrajectorySample) -> (B,)``; default ``DEFAULT_COST``. A ``compose``-d
            cost's weights, thresholds and obstacles are data; a plain function is static.
        branch: the branch held along the path (None: the default).
        limits: ``plan.Limits`` for limit penalties and the final evaluation.
        rest_to_rest: also fix the second and second-to-last control points.
        space: ``"task"`` or ``"joint"`` (the meaning of ``start`` and ``goal``).
        gtol, ftol: stopping rules per guess: ``|grad| <= gtol (1 + |f|)`` or a relative cost
            change ``<= ftol`` in one step; None for ``max(1e-7, 1000 eps)`` and
            ``max(1e-10, 8 eps)`` (float64: 1e-7 and 1e-10, which reach the optimum of the
            benchmark problems to 1e-8 relative; float32: 1.2e-4 and 9.5e-7).
        progress: show a progress bar (default: only when stderr is a terminal).

    Returns:
        ``OptimizationResult``.

    Raises:
        ValueError: a robot whose targets are not points, shapes that do not match, non-finite
            start, goal or guesses, or bad numeric options (each named).
    """
    robot = as_robot(robot)
    if not robot.target.is_point:
        raise ValueError(
            f"optimize needs a robot whose targets are points; {type(robot).__name__}'s are "
            f"{robot.target.name}s"
        )
    branch = robot.check_branch(branch)
    dims = robot.target.shape[0]
    if space not in ("task", "joint"):
        raise ValueError(f"space must be 'task' or 'joint', got {space!r}")
    start = jnp.asarray(start, float)
    goal = jnp.asarray(goal, float)
    want = (robot.n_joints,) if space == "joint" else (dims,)
    for name, x in (("start", start), ("goal", goal)):
        if x.shape != want:
            raise ValueError(f"{name}: expected shape {want} ({space} space), got {x.shape}")
        if not bool(jnp.all(jnp.isfinite(x))):
            raise ValueError(f"{name} must be finite, got {np.asarray(x)}")
    if space == "joint":
        start, goal = (fk(robot, x).x.p for x in (start, goal))
    interior = jnp.asarray(interior, float)
    if interior.ndim == 2:
        interior = interior[None]
    if interior.ndim != 3 or interior.shape[-1] != dims or interior.shape[1] < 1:
        raise ValueError(
            f"interior: expected shape (B, K', {dims}) with K' >= 1, got {interior.shape}"
        )
    bad = np.concatenate(
        [
            start + np.flatnonzero(~np.all(np.isfinite(rows), axis=(1, 2)))
            for start, rows in _processes.local_rows(interior)
        ]
    )
    if not _processes.fetchable(interior):  # split over processes: every process must raise
        bad = np.unique(_processes.allgather_rows(bad))
    if bad.size:
        raise ValueError(
            f"interior: initial guess(es) {bad.tolist()} hold NaN or inf (every guess must be "
            "finite: a NaN would come back as NaN controls)"
        )
    for name, value, low in (("n_samples", n_samples, 3), ("steps", steps, 0)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name} must be an int >= {low}, got {value!r}")
    epsilon = float(jnp.finfo(interior.dtype).eps)
    gtol = max(1e-7, 1000 * epsilon) if gtol is None else gtol
    ftol = max(1e-10, 8 * epsilon) if ftol is None else ftol
    duration, gtol, ftol = (
        _validate.nonnegative_number(value, name)
        for name, value in (("duration", duration), ("gtol", gtol), ("ftol", ftol))
    )
    if not duration > 0:
        raise ValueError(f"duration must be positive, got {duration!r}")
    method = LBFGS() if optimizer is None else optimizer
    n_ctrl = interior.shape[1] + 2 + (2 if rest_to_rest else 0)
    dtype = interior.dtype
    basis = jnp.asarray(bezier_basis(n_ctrl, n_samples), dtype)
    dt = duration / (n_samples - 1)
    limits = plan.robot_limits(robot, limits)
    leaves, treedef = jax.tree.flatten(cost)
    is_data = all(isinstance(leaf, jax.Array | np.ndarray | float | int) for leaf in leaves)
    static = _Static(
        method,
        None if is_data else cost,
        treedef if is_data else None,
        branch,
        bool(rest_to_rest),
        steps,
    )
    scale = jnp.asarray(robot.length_scale(), dtype)
    data = dict(
        robot=robot,
        start=start.astype(dtype),
        goal=goal.astype(dtype),
        basis=basis,
        duration=jnp.asarray(duration, dtype),
        dt=jnp.asarray(dt, dtype),
        limits=limits,
        cost=[jnp.asarray(leaf, dtype) for leaf in leaves] if is_data else [],
        scale=scale,
        gtol=jnp.asarray(gtol, dtype),
        ftol=jnp.asarray(ftol, dtype),
    )

    def run(guesses: Array) -> tuple:
        """The guesses ``(b, K', d)`` of one device optimised, per-guess results leading."""
        carry = _start(guesses / scale, data, static)
        block = min(steps, PROGRESS_BLOCK) if is_active(progress) else steps
        with bar(steps, "optimize", enabled=progress) as meter:
            done_steps = 0
            while done_steps < steps:
                carry = _run(carry, data, jnp.int32(done_steps + block), static)
                reached = int(carry[7])
                meter.update(reached - done_steps)
                if reached < done_steps + block:  # every guess has stopped
                    break
                done_steps = reached
        x, _, f, g, _, converged, iterations, step, history = carry
        history = jnp.where(jnp.arange(steps + 1)[:, None] > step, f, history)
        controls = _full_controls(x * scale, data["start"], data["goal"], rest_to_rest)
        path = bezier_path(controls, basis, duration)
        grad_norm = jnp.sqrt(jnp.sum(g * g, axis=(-2, -1)))
        return controls, path, f, history.T, converged, iterations, grad_norm

    # A guess's steps never depend on the others' (a stopped guess is held), so each device
    # runs its own guesses' loop to its own end.
    controls, path, f, history, converged, iterations, grad_norm = _batching.map_candidates(
        run, interior, interior.shape[0], name="interior"
    )
    history = history.T
    evaluation = plan.evaluate(robot, path, limits=limits, branch=branch, dt=dt)
    ranked = jnp.where(evaluation.feasible, f, jnp.inf)
    best = jnp.where(jnp.any(evaluation.feasible), jnp.argmin(ranked), jnp.argmin(f))
    return OptimizationResult(
        controls,
        path,
        f,
        history,
        converged,
        iterations,
        grad_norm,
        best.astype(jnp.int32),
        evaluation,
    )
