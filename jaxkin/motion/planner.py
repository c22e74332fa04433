"""``motion.plan``: from a start to goals among obstacles, then short, smooth and timed.

One call plans ``B`` problems (a start each; goals as joint configurations, or as targets the
inverse kinematics turns into collision-free configurations, ``goals.ik_goals``) in a world
shared by all or one world per problem:

1. host checks: finite input (else ``INVALID_INPUT``), a start within the limits and free
   (else ``INVALID_START``), at least one free goal within the limits (else ``INVALID_GOAL``,
   or ``UNREACHABLE_GOAL`` for targets);
2. the search (``search.search_kernel``, one compiled program: RRT-Connect lanes over a queue
   of problems), returning each solved problem's path. In certified mode the search checks
   its edges at the resolution (as in discrete mode, a few states each), then every edge of
   each found path is certified (``_certified_paths``: for a kinematic tree by enclosures of
   its pieces at the resolution, cut in two where they touch, ``swept``; otherwise by
   clearance balls, states where they leave gaps); an edge that is not (it grazes an
   obstacle between two states, or passes too close to be certified) is planned again
   alone with certified edges, from its first waypoint to its second, and its path replaces
   it (``repair``); a problem where that fails is searched again at the resolution with the
   seed's next streams of samples (``RETRIES``, another path, certified as found), and
   where those fail too, whole with certified edges;
3. the simplification (``simplify.simplify_kernel``, one compiled program over the problems:
   shortcuts, then a natural cubic spline re-checked, or the shortcut polygon; in certified
   mode the shortcuts and the spline's pieces are certified by ``swept`` as well);
4. the time-optimal timing of the result within the joints' speed and acceleration limits
   (TOPP-RA, ``jaxkin.timing.retime``) sampled every ``period``: a spline is followed as it is,
   the polygon with a stop at each corner (its pieces ``q = y0 + (3 tau^2 - 2 tau^3)(y1 -
   y0)``: straight, at rest at both ends).

Every compiled program is a pure kernel run as a ``jaxkin._execute.Kernel`` at module level
(with the collision checks' XLA options, ``collider.COMPILER_OPTIONS``); a repeated call
with the same shapes (problems, goals per problem, obstacles per kind within their buckets)
and options compiles nothing new.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .. import _batching, timing
from .._execute import Kernel, Policy, kernel
from .._execute.latency import small_loops_in_one_function
from .._splines import hermite
from ..collision import World
from ..status import NamedStatusRepr, Status
from . import collider, repair, swept
from .bound import motion_bound, speed_rows
from .edges import MODES, edge_check, path_edges_good
from .goals import ik_goals
from .search import SearchConfig, SearchResult, search_kernel
from .simplify import SHORTCUTS, Checker, Simplified, chord_parameters, simplify_kernel
from .space import JointSpace, joint_space
from .status import MotionStatus

__all__ = ["MotionOptions", "MotionPlan", "plan", "plan_kernels"]


_AT_LEAST_ONE = ("lanes", "team", "chunk", "goals_per_target", "max_iterations")


@dataclasses.dataclass(frozen=True)
class MotionOptions:
    """Options of ``plan`` (each also a keyword of ``plan``).

    Attributes:
        mode: ``"certified"`` (default: nothing slips through; the paths of a search at
            the resolution certified edge by edge, an edge that is not planned again with
            certified edges: module docstring) or
            ``"discrete"`` (states ``1 / resolution`` apart, as VAMP and OMPL).
        range: the longest edge the search adds (joint distance, ``space`` module).
        domain: the dynamic domain [Yershova et al. 2005], in ranges: once an EXTEND from a
            node hits an obstacle, samples farther than ``domain * range`` from it (as their
            nearest node) are drawn again (``math.inf``: no domain; VAMP's RRT-Connect uses
            4 joint-space units at the Panda's range of 1).
        resolution: states per unit of joint distance in discrete mode (VAMP's 32).
        lanes: moves (edges) in flight per iteration of the search (``search``).
        team: lanes that grow one RRT-Connect (``lanes`` a multiple of it: ``lanes / team``
            RRTs at once, each problem one, idle ones restarting open problems); None: all
            the lanes for one problem, teams of ``gcd(lanes, 4)`` for several (measured best
            for each: ``docs/performance.md``).
        chunk: states checked per lane per iteration (``edges``).
        capacity: nodes per tree.
        max_iterations: edges a problem's own team settles before ``NO_PATH`` (teams that
            join it once the queue is empty are extra attempts: ``search``).
        path_points: waypoints per path buffer.
        simplify: shortcut and smooth the path.
        spline_states: states that check the spline (discrete mode, and certified mode
            for a robot without a curvature bound: ``swept``).
        period: control period of the sampled trajectory (the limits' time unit); None: no
            timing.
        grid: grid points of the timing per path.
        velocity, acceleration: joint limits of the timing, ``(n,)``; None: the robot's
            (``joint_limits``), a missing acceleration limit taken as 4 times the speed limit
            (full speed in a quarter of the time unit), a missing speed limit as 1 per time
            unit (rad, or the robot's size for a prismatic joint).
        goals_per_target: goal configurations kept per target (IK goals).
        seed: of the search's random samples.
    """

    mode: str = "certified"
    range: float = 1.0
    domain: float = 4.0
    resolution: float = 32.0
    lanes: int = 8
    team: int | None = None
    chunk: int = 8
    capacity: int = 1024
    max_iterations: int = 40000
    path_points: int = 128
    simplify: bool = True
    spline_states: int = 512
    period: float | None = 0.01
    grid: int = 200
    velocity: Any = None
    acceleration: Any = None
    goals_per_target: int = 4
    seed: int = 0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {self.mode!r}")
        for name in ("range", "resolution"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        for name in (
            "lanes",
            "team",
            "chunk",
            "capacity",
            "max_iterations",
            "path_points",
            "spline_states",
            "grid",
            "goals_per_target",
        ):
            value = getattr(self, name)
            if name == "team" and value is None:
                continue
            if (
                isinstance(value, bool)
                or not isinstance(value, int)
                or value < 2 - (name in _AT_LEAST_ONE)
            ):
                raise ValueError(
                    f"{name} must be a positive integer (>= 2 for sizes), got {value!r}"
                )
        if self.team is not None and self.lanes % min(self.team, self.lanes):
            raise ValueError(f"lanes ({self.lanes}) must be a multiple of team ({self.team})")
        if self.grid < self.path_points:
            # every knot is a grid point of the timing
            raise ValueError(
                f"grid ({self.grid}) must be at least path_points ({self.path_points})"
            )
        if self.capacity % min(64, self.capacity):
            raise ValueError(f"capacity must be below 64 or a multiple of 64, got {self.capacity}")
        if self.period is not None and not (
            isinstance(self.period, int | float) and math.isfinite(self.period) and self.period > 0
        ):
            raise ValueError(f"period must be a positive number or None, got {self.period!r}")
        if not (
            isinstance(self.domain, int | float)
            and not isinstance(self.domain, bool)
            and self.domain > 0
        ):
            raise ValueError(f"domain must be a positive number or math.inf, got {self.domain!r}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool):
            raise ValueError(f"seed must be an int, got {self.seed!r}")


@dataclasses.dataclass(frozen=True)
class MotionPlan(NamedStatusRepr):
    """The result of ``plan`` per problem (NumPy, leading axis ``B``).

    Attributes:
        status: ``int8`` ``MotionStatus`` codes ``(B,)``.
        path: the search's path ``(B, P, n)``; ``path_count (B,)`` waypoints (rows past it
            repeat the last one); unwrapped for continuous joints.
        simplified: the shortcut polygon or the spline's knots ``(B, P, n)``,
            ``simplified_count (B,)``; ``smooth (B,)`` True where the spline passed its check
            (then the trajectory follows the spline through these knots, else the polygon).
        goal: the goal configuration reached ``(B, n)``.
        iterations: lane iterations the search spent ``(B,)``.
        certified: ``(B,)`` the path and its smoothing were certified (certified mode with a
            proved speed bound, ``bound.MotionBound.proved``).
        trajectory: ``timing.RetimedTrajectory`` sampled every ``period`` (None without a
            period): ``q`` a Jet ``(B, T, n)``, ``valid``, ``count``; ``duration (B,)``.
        timing_status: ``jaxkin.Status`` of the timing ``(B,)`` (``OK``, ``UNTIMEABLE``).
        seconds: wall time of the stages of this call (``"search"``, ``"simplify"``,
            ``"timing"``), each program run to completion (compilation included on a first
            call); a batch of more than ``PART_PROBLEMS`` runs in parts at once on the host
            threads: then ``"search"`` and ``"simplify"`` are summed over the parts and
            ``"parts"`` is the wall time of both stages. ``"search"`` includes the
            certification of the found paths and the second searches (certified mode):
            ``"edges_searched_again"`` counts the edges planned again alone,
            ``"retried"`` the searches again at the resolution with another stream of
            samples, ``"searched_again"`` the problems searched again whole with certified
            edges; ``"loops"`` the search loops' iterations.
    """

    status_fields: ClassVar = {"status": MotionStatus, "timing_status": Status}

    status: np.ndarray
    path: np.ndarray
    path_count: np.ndarray
    simplified: np.ndarray
    simplified_count: np.ndarray
    smooth: np.ndarray
    goal: np.ndarray
    iterations: np.ndarray
    certified: np.ndarray
    trajectory: Any
    duration: np.ndarray
    timing_status: np.ndarray
    seconds: dict = dataclasses.field(default_factory=dict)

    @property
    def solved(self) -> np.ndarray:
        return self.status == MotionStatus.SOLVED


# ------------------------------------------------------------------------ compiled kernels
def _evaluator(robot, body, pairs, world, mode):
    """``states (..., n) ->`` ``free`` (discrete) or ``(dist, placed)`` (certified)."""

    def run(q):
        if mode == "discrete":
            return collider.free(robot, body, pairs, q, world)
        return collider.clearances(robot, body, pairs, q, world)

    return run


def _piece_touches(robot, body, pairs, world):
    """``(qa, qb, grow) ->`` whether each piece's enclosure touches (``collider``)."""

    def touches(qa, qb, grow):
        return collider.piece_touches(robot, body, pairs, qa, qb, grow, world)

    return touches


def _roots_kernel(robot, body, pairs, world, starts, goals, mode, shared_world):
    """Per problem: whether the start ``(B,)`` and the goals ``(B, G)`` are free, and their
    distances ``(B, 1 + G, R)`` (certified mode; ``R = 0`` discrete)."""

    def one(wd, start, goal):
        q = jnp.concatenate([start[None], goal])
        out = _evaluator(robot, body, pairs, wd, mode)(q)
        if mode == "discrete":
            return out, jnp.zeros((q.shape[0], 0), q.dtype)
        dist, placed = out
        return placed & jnp.all(dist > 0, -1), dist

    axes = (None if shared_world else 0, 0, 0)
    free, clear = jax.vmap(one, in_axes=axes)(world, starts, goals)
    return free[:, 0], free[:, 1:], clear


def _per_path(one, world, path, count, shared_world, group):
    """``one(world, path (P, n), count)`` for every problem ``(B, P, n)``, ``group`` problems
    at a time (a ``vmap`` within a group, a loop over the groups): the loops of a ``vmap`` run
    as long as its longest element, so a group of similar paths (``plan`` sorts them by
    waypoint count) wastes little, where one ``vmap`` of every problem runs each as long as
    the hardest."""
    if path.shape[0] <= group:
        return jax.vmap(one, in_axes=(None if shared_world else 0, 0, 0))(world, path, count)
    if shared_world:
        return jax.lax.map(lambda x: one(world, *x), (path, count), batch_size=group)
    return jax.lax.map(lambda x: one(*x), (world, path, count), batch_size=group)


def _simplify_all(
    robot,
    body,
    pairs,
    world,
    space,
    rows,
    path,
    count,
    tol,
    resolution,
    bound,
    slots,
    chunk,
    mode,
    states,
    shared_world,
    group,
):
    """``simplify_kernel`` for every problem ``(B, P, n)``, ``group`` problems at a time
    (``_per_path``); in certified mode with a curvature bound (``bound``, a ``MotionBound``)
    the shortcuts and the spline certified by ``swept``."""

    curvature = bound.curvature

    def one(wd, p, c):
        evaluate = _evaluator(robot, body, pairs, wd, mode)
        touches = _piece_touches(robot, body, pairs, wd)

        def certify_straight(a, delta):
            # first pieces at the resolution: the longest shortcut spans SHORTCUTS + 1 edges
            return swept.edges_certified(
                touches,
                curvature,
                space,
                a,
                delta,
                resolution,
                tol,
                slots,
                SWEPT_CHUNK,
                SHORTCUT_LEVELS,
            )

        def certify_spline(knots, s, slopes, k):
            return swept.spline_certified(
                touches,
                bound.prims,
                curvature,
                space,
                knots,
                s,
                slopes,
                k,
                resolution,
                tol,
                SPLINE_SLOTS,
                SWEPT_CHUNK,
            )

        swept_ok = mode != "discrete" and curvature is not None
        straight = certify_straight if swept_ok else None
        curved = certify_spline if swept_ok else None
        check = Checker(evaluate, space, rows, mode, tol, resolution, chunk, straight, curved)
        return simplify_kernel(check, p, c, slots, states)

    return _per_path(one, world, path, count, shared_world, group)


def _certified_paths(
    robot,
    body,
    pairs,
    world,
    space,
    rows,
    path,
    count,
    tol,
    curvature,
    resolution,
    slots,
    chunk,
    shared_world,
    group,
):
    """Per problem and edge ``(B, P - 1)``: the edge of its path ``(B, P, n)`` is certified,
    ``group`` problems at a time (``_per_path``). With a ``curvature`` bound (a kinematic
    tree): by enclosures of its pieces (``swept``: ``slots`` first pieces at most, cut in two
    where they touch); else by clearance balls (``edges.path_edges_good``, ``CERTIFY_SLOTS``
    times ``slots`` intervals, the states placed where the balls are small)."""

    def one(wd, p, c):
        if curvature is not None:
            touches = _piece_touches(robot, body, pairs, wd)

            def swept_good(a, delta):
                good = swept.edges_certified(
                    touches, curvature, space, a, delta, resolution, tol, slots, SWEPT_CHUNK
                )
                return good.astype(a.dtype)

            return path_edges_good(swept_good, space, p, c, SWEPT_EDGES)
        evaluate = _evaluator(robot, body, pairs, wd, "certified")

        def edge_good(a, delta):
            return edge_check(
                evaluate,
                rows,
                a,
                delta,
                CERTIFY_SLOTS * slots,
                chunk,
                "certified",
                tol,
                resolution,
                space,
            )

        return path_edges_good(edge_good, space, p, c, CERTIFY_EDGES)

    return _per_path(one, world, path, count, shared_world, group)


SIMPLIFY_GROUP = 8  # problems simplified together (_simplify_all)
# a found edge (at most a range long, its search's slots) certified with this many times its
# slots, this many states per round (_certified_paths): balls of a few millimetres fit
CERTIFY_SLOTS = 32
CERTIFY_CHUNK = 32
CERTIFY_EDGES = 4  # edges of a path certified at once
SWEPT_EDGES = 8  # edges of a path whose pieces share a stack (_certified_paths, swept)
SWEPT_CHUNK = 64  # pieces checked per step (swept)
# cuts of a shortcut's pieces (swept): a shortcut that passes within about a millimetre of an
# obstacle is not taken rather than cut finer (a found path's edges get swept.LEVELS)
SHORTCUT_LEVELS = 4
SPLINE_SLOTS = 32  # first pieces of a spline's piece at most (swept)
# searches again at the resolution, each with the seed's next stream of samples, of a problem
# whose found path has an edge that neither certifies nor is planned again alone, before its
# search whole with certified edges (plan)
RETRIES = 2
PART_PROBLEMS = 64  # problems per part of a large batch (one search's queue), plan
TEAM = 4  # lanes per team for several problems (MotionOptions.team None)


def _rows(tree: Any, rows: np.ndarray) -> Any:
    """The rows ``rows`` of every leaf of ``tree`` (a world or results with a problem axis)."""
    return jax.tree.map(lambda leaf: leaf[rows], tree)


def _join(parts: list[Any], take: list[np.ndarray]) -> Any:
    """The parts' results as one (NumPy) batch: the rows ``take[k]`` of part ``k`` in turn;
    a scalar per part (the search's loop count) becomes one entry per part."""

    def leaf(*values: Any) -> np.ndarray:
        host = [np.asarray(v) for v in values]
        if host[0].ndim == 0:
            return np.stack(host)
        return np.concatenate([v[t] for v, t in zip(host, take, strict=True)])

    return jax.tree.map(leaf, *parts)


def _rows_of(results: Any, rows: np.ndarray) -> Any:
    """The rows ``rows`` of every leaf of NumPy results with a problem axis (``_join``),
    scalars as they are."""
    return jax.tree.map(lambda leaf: leaf if np.ndim(leaf) == 0 else leaf[rows], results)


def _with_rows(base: Any, rows: np.ndarray, other: Any) -> Any:
    """``base`` (NumPy results with a problem axis) with its rows ``rows`` replaced by the
    rows of ``other`` (in order); scalars kept from ``base``."""

    def leaf(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        if x.ndim == 0:
            return x
        out = np.array(x)
        out[rows] = y
        return out

    return jax.tree.map(leaf, base, other)


@dataclasses.dataclass
class _Problems:
    """Host side, one row per problem: ``starts (B, n)``, ``goals (B, G, n)``, ``goal_count
    (B,)``, ``root_clear (B, 1 + G, R)`` (certified distances of the start and goals),
    ``status (B,)`` (``SOLVED``: to search), ``world_rows (B,)`` (the world of each, a row of
    the stacked worlds), ``budget`` (edges per problem, ``MotionOptions.max_iterations``)."""

    starts: np.ndarray
    goals: np.ndarray
    goal_count: np.ndarray
    root_clear: np.ndarray
    status: np.ndarray
    world_rows: np.ndarray
    budget: int = 0


def _edge_problems(
    problems: _Problems, problem: np.ndarray, a: np.ndarray, b: np.ndarray, budget: int
) -> _Problems:
    """The problems from ``a (m, n)`` to ``b (m, n)`` in the worlds of ``problems``' rows
    ``problem (m,)`` (``repair``), the goal repeated in every goal slot, a budget of
    ``budget / REPAIR_BUDGET`` edges; their distances (``root_clear``) to be filled."""
    g = problems.goals.shape[1]
    m = problem.size
    return _Problems(
        np.array(a),
        np.repeat(np.asarray(b)[:, None], g, axis=1),
        np.ones(m, np.int32),
        np.zeros((m, *problems.root_clear.shape[1:]), problems.root_clear.dtype),
        np.full(m, int(MotionStatus.SOLVED), np.int8),
        problems.world_rows[problem],
        max(1, budget // REPAIR_BUDGET),
    )


# a bad edge's own problem gets this fraction of a problem's budget: a repair that fails
# spends all it gets, and its problem is then searched again (RETRIES)
REPAIR_BUDGET = 32


# the collision loops inside the search and the simplification run their bodies 2-5x faster
# with the CPU's older fusion emitters (collider.COMPILER_OPTIONS)
# Reductions as XLA's own loops, not library calls (YNNPACK fusions), which would keep the
# search's loop from running as one compiled function (jaxkin.enable_low_latency)
_POLICY = Policy(
    pad=False,
    compiler_options=(*collider.COMPILER_OPTIONS, ("xla_cpu_experimental_ynn_fusion_type", "")),
)
_search_jit = Kernel(search_kernel, static=("config",), policy=_POLICY)
_roots_jit = Kernel(_roots_kernel, static=("mode", "shared_world"), policy=_POLICY)
_simplify_jit = Kernel(
    _simplify_all,
    static=("slots", "chunk", "mode", "states", "shared_world", "group"),
    policy=_POLICY,
)


_certify_jit = Kernel(
    _certified_paths, static=("slots", "chunk", "shared_world", "group"), policy=_POLICY
)


def plan_kernels():
    """The compiled programs ``(search, simplify)`` (for benchmarks that time them apart)."""
    return _search_jit, _simplify_jit


# ------------------------------------------------------------------------ host side
def _as_array(x: Any, name: str) -> np.ndarray:
    try:
        out = np.array(x, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name}: expected real numbers, got {type(x).__name__}") from error
    return out


def _worlds(world: Any, b: int) -> tuple[Any, bool]:
    """The world of every problem, or the worlds stacked (``collider.stack_worlds``), each kind
    in whole buckets (a world within its buckets compiles nothing new)."""
    if isinstance(world, World):
        if world.batched():
            raise ValueError("world: expected a collision.World without batch axes")
        return world.bucketed(), True
    if isinstance(world, list | tuple):
        if len(world) != b:
            raise ValueError(f"world: {len(world)} worlds for {b} problems")
        return collider.stack_worlds(list(world)), False
    raise ValueError(
        f"world: expected a collision.World or one per problem, got {type(world).__name__}"
    )


def _limits(
    robot: Any, options: MotionOptions, space: JointSpace, n: int
) -> tuple[np.ndarray, np.ndarray]:
    limits = robot.joint_limits()
    v = np.asarray(limits.velocity if options.velocity is None else options.velocity, float)
    v = np.broadcast_to(v, (n,)).copy()
    scale = 1.0 / np.asarray(space.weight, float)
    v = np.where(np.isfinite(v), v, scale)
    a = np.asarray(
        limits.acceleration if options.acceleration is None else options.acceleration, float
    )
    a = np.broadcast_to(a, (n,)).copy()
    a = np.where(np.isfinite(a), a, 4.0 * v)
    if np.any(v <= 0) or np.any(a <= 0):
        raise ValueError("velocity and acceleration limits must be positive")
    return v, a


@kernel(static=("grid",))
def _joint_paths(
    knots: Array, s: Array, slopes: Array, count: Array, grid: int
) -> timing.JointPath:
    """The ``JointPath`` grid ``(B, grid)`` of each spline (every knot a grid point, the
    other points shared among the pieces in proportion to their parameter length)."""

    def one(knots, s, slopes, count):
        p = knots.shape[0]
        live = jnp.arange(p - 1) < count - 1
        h = jnp.where(live, jnp.diff(s), 0.0)
        total = jnp.maximum(jnp.sum(h), 1e-30)
        inner = grid - 1 - (count - 1)
        share = jnp.where(live, 1.0 + jnp.floor(h / total * inner), 0.0)
        share = share.at[jnp.maximum(count - 2, 0)].add(grid - 1 - jnp.sum(share))
        ends = jnp.cumsum(share)
        k = jnp.arange(grid)
        piece = jnp.clip(jnp.searchsorted(ends, k, side="right"), 0, p - 2)
        piece = jnp.where(k >= grid - 1, jnp.maximum(count - 2, 0), piece)
        begin = ends[piece] - share[piece]
        tau = jnp.where(k >= grid - 1, 1.0, (k - begin) / jnp.maximum(share[piece], 1.0))
        hp = jnp.where(h[piece] > 0, h[piece], 1.0)[:, None]
        y0, y1 = knots[piece], knots[piece + 1]
        m0, m1 = slopes[piece], slopes[piece + 1]
        q, dq, ddq = hermite(y0, m0, y1, m1, hp, tau[:, None])
        param = s[piece] + tau * jnp.where(live[piece], h[piece], 0.0)
        # a path of one point (start = goal): a strictly increasing grid at rest
        param = jnp.where(count > 1, param, k.astype(param.dtype))
        return param, q, dq, ddq

    param, q, dq, ddq = jax.vmap(one)(knots, s, slopes, count)
    return timing.JointPath(param, q, dq, ddq)


@dataclasses.dataclass(frozen=True)
class _Prepared:
    """Host side, once per robot: its body and self pairs, its joint space (NumPy and in the
    planner's dtype), its speed bound and rows (``bound.speed_rows``), its size, its joint
    limits (NumPy)."""

    body: Any
    pairs: Any
    space_np: JointSpace
    space: JointSpace
    bound: Any
    rows: Array
    scale: float
    lower: np.ndarray
    upper: np.ndarray

    def within(self, q: np.ndarray) -> np.ndarray:
        """Per configuration ``q`` ``(..., n)``: every joint within its closed range (host)."""
        return np.all((q >= self.lower) & (q <= self.upper), axis=-1)


def _prepare(robot: Any, dtype: Any) -> _Prepared:
    """``_Prepared`` of ``robot`` in ``dtype``, cached on the robot."""
    cached = robot.__dict__.get("_motion_prepared", {})
    key = np.dtype(dtype).name
    if key in cached:
        return cached[key]
    body, pairs = collider.prepare(robot, True)
    space = joint_space(robot)
    bound = motion_bound(robot, body, pairs.link_pairs).astype(dtype)
    rows = jax.device_put(np.asarray(speed_rows(bound, body), dtype))
    scale = float(np.asarray(robot.length_scale()))
    limits = robot.joint_limits()
    lower, upper = (np.asarray(x, float) for x in (limits.lower, limits.upper))
    prepared = _Prepared(body, pairs, space, space.astype(dtype), bound, rows, scale, lower, upper)
    object.__setattr__(robot, "_motion_prepared", {**cached, key: prepared})
    return prepared


def plan(
    robot: Any,
    start: Any,
    world: Any,
    goal: Any = None,
    target: Any = None,
    options: MotionOptions | None = None,
    **option_values: Any,
) -> MotionPlan:
    """Plan motions from ``start`` to ``goal`` configurations or ``target`` poses (module
    docstring).

    Args:
        robot: a robot of the protocol with a collision body.
        start: ``(n,)`` or ``(B, n)`` joint configurations (robot units).
        world: a ``collision.World`` shared by every problem, or a list of ``B`` worlds.
        goal: joint configurations ``(n,)``, ``(B, n)`` or ``(B, G, n)`` (several goals per
            problem: the plan reaches one of them).
        target: instead of ``goal``, targets of the robot's IK (``robot.target``:
            ``(*target)`` or ``(B, *target)``).
        options: ``MotionOptions``; or its fields as keywords.

    Returns:
        ``MotionPlan`` (NumPy arrays).

    Raises:
        ValueError: neither or both of ``goal`` and ``target``, shapes that do not match the
            robot, a bad world or option (naming it).
    """
    if options is None:
        options = MotionOptions(**option_values)
    elif option_values:
        options = dataclasses.replace(options, **option_values)
    if not isinstance(options, MotionOptions):
        raise ValueError(f"options: expected MotionOptions, got {type(options).__name__}")
    for method in ("collision_body", "link_poses", "joint_limits"):
        if not callable(getattr(robot, method, None)):
            raise ValueError(
                f"robot: expected a jaxkin robot with {method}(), got {type(robot).__name__}"
            )
    if (goal is None) == (target is None):
        raise ValueError("give exactly one of goal (joint configurations) and target (IK targets)")
    n = robot.n_joints
    starts = _as_array(start, "start")
    if starts.ndim not in (1, 2) or starts.shape[-1] != n:
        raise ValueError(f"start: expected shape (n,) or (B, n) with n = {n}, got {starts.shape}")
    starts = starts.reshape(-1, n)
    b = starts.shape[0]
    dtype = jnp.result_type(float)
    prep = _prepare(robot, dtype)
    body, pairs, space = prep.body, prep.pairs, prep.space
    worlds, shared = _worlds(world, b)
    worlds = worlds.astype(dtype)

    def put(x: Any, kind: Any = None) -> np.ndarray:
        # host arrays go to the compiled programs as they are (a device_put costs more)
        return np.asarray(x, dtype if kind is None else kind)

    def free_fn(q: np.ndarray) -> np.ndarray:
        if shared:
            return np.asarray(_free_jit(robot, body, pairs, put(q), worlds))
        return np.asarray(_free_batched_jit(robot, body, pairs, put(q), worlds))

    finite_start = np.all(np.isfinite(starts), -1)
    starts_safe = np.where(np.isfinite(starts), starts, 0.0)
    inside = prep.within(starts_safe)
    if target is not None:
        shape = tuple(robot.target.shape)
        t = _as_array(target, "target")
        if t.shape == shape:
            t = np.broadcast_to(t, (b, *shape))
        if t.shape != (b, *shape):
            raise ValueError(f"target: expected shape {shape} or ({b}, *{shape}), got {t.shape}")
        finite_goal = np.all(np.isfinite(t.reshape(b, -1)), -1)
        goals, ik_count = ik_goals(
            robot,
            np.where(np.isfinite(t), t, 0.0),
            starts_safe,
            space,
            free_fn,
            options.goals_per_target,
        )
        solution = np.arange(goals.shape[1])[None, :] < ik_count[:, None]
        no_goal = MotionStatus.UNREACHABLE_GOAL
    else:
        g = _as_array(goal, "goal")
        if g.shape == (n,):
            g = np.broadcast_to(g, (b, 1, n))
        elif g.ndim == 2 and g.shape == (b, n):
            g = g[:, None]
        if g.ndim != 3 or g.shape[0] != b or g.shape[2] != n:
            raise ValueError(
                f"goal: expected shape (n,), (B, n) or (B, G, n) with B = {b}, n = {n}, "
                f"got {g.shape}"
            )
        finite_goal = np.all(np.isfinite(g), (-1, -2))
        goals = np.where(np.isfinite(g), g, 0.0)
        solution = np.ones(goals.shape[:2], bool)
        no_goal = MotionStatus.INVALID_GOAL
    seconds = {}
    clock = time.perf_counter()
    mode = options.mode
    start_free, goal_free, root_clear = _roots_jit(
        robot, body, pairs, worlds, put(starts_safe), put(goals), mode=mode, shared_world=shared
    )
    good = solution & prep.within(goals) & np.asarray(goal_free, bool)
    # the free goals first (a stable order), their distances alike
    order = np.argsort(~good, axis=1, kind="stable")
    goals = np.take_along_axis(goals, order[..., None], 1)
    root_clear = np.asarray(root_clear)
    root_clear = np.concatenate(
        [root_clear[:, :1], np.take_along_axis(root_clear[:, 1:], order[..., None], 1)], 1
    )
    goal_count = np.sum(good, 1).astype(np.int32)
    status = np.full(b, int(MotionStatus.SOLVED), np.int8)
    status = np.where(goal_count == 0, int(no_goal), status)
    start_ok = inside & np.asarray(start_free, bool)
    status = np.where(~start_ok, int(MotionStatus.INVALID_START), status)
    status = np.where(~(finite_start & finite_goal), int(MotionStatus.INVALID_INPUT), status)
    status = status.astype(np.int8)
    tol = 64.0 * float(jnp.finfo(dtype).eps) * (1.0 + prep.scale)
    slots = max(2, math.ceil(options.range * options.resolution))
    lanes = options.lanes
    # one problem: all lanes in one team; several: teams of TEAM (MotionOptions.team)
    team = min(options.team or (lanes if b == 1 else math.gcd(lanes, TEAM)), lanes)
    size = min(b, PART_PROBLEMS)
    # certified mode: a search at the resolution first, its paths then certified edge by edge
    # (_certified_paths), and only the problems whose path is not are searched again with
    # certified edges
    lazy = mode == "certified"

    def config(search_mode: str) -> SearchConfig:
        return SearchConfig(
            lanes,
            team,
            options.capacity,
            slots,
            options.chunk,
            options.path_points,
            search_mode,
            shared,
        )

    rounds = -(-slots // options.chunk)

    def scalars(max_iterations: int, attempt: int = 0) -> tuple:
        """The search's scalar arguments for a budget of ``max_iterations`` edges, the
        stream of samples of the seed's ``attempt``-th search (0: the first)."""
        # a safety cap: the teams share the queue's budgets, and the last problem's own team
        # settles at least one edge per lane every `rounds` iterations
        budget = int(max_iterations) * rounds
        max_loops = budget * size // lanes + budget // team + 4 * size + 16
        return (
            put(_stream(options.seed + attempt), np.uint32),
            put(options.range),
            put(options.domain * options.range),
            put(options.resolution),
            put(max_iterations, np.int32),
            put(min(max_loops, 2**31 - 1), np.int32),
            put(tol),
        )

    problems = _Problems(
        starts_safe, goals, goal_count, root_clear, status, np.arange(b), options.max_iterations
    )

    def part_worlds_of(p: _Problems, rows: np.ndarray) -> Any:
        if shared:
            return worlds
        if size == b and np.array_equal(p.world_rows[rows], np.arange(b)):
            return worlds  # the whole batch in one part, in order (no copy)
        return _rows(worlds, p.world_rows[rows])

    def search_args(
        p: _Problems,
        rows: np.ndarray,
        search_mode: str,
        part_status: np.ndarray,
        queue: Any,
        attempt: int = 0,
    ) -> tuple:
        """The search's arguments for the problems ``rows`` of ``p`` (a part)."""
        clear = p.root_clear[rows]
        return (
            robot,
            body,
            pairs,
            part_worlds_of(p, rows),
            space,
            prep.rows,
            put(p.starts[rows]),
            put(p.goals[rows]),
            put(p.goal_count[rows], np.int32),
            put(clear if search_mode == "certified" else clear[..., :0]),
            put(part_status, np.int8),
            put(queue, np.int32),
            *scalars(p.budget, attempt),
        )

    def checked_paths(part_worlds: Any, path: Any, count: Any) -> tuple:
        """The leading arguments of the programs that check paths (certify, simplify)."""
        return (robot, body, pairs, part_worlds, space, prep.rows, path, count, put(tol))

    def search(
        p: _Problems, rows: np.ndarray, search_mode: str, attempt: int = 0
    ) -> tuple[Any, ...]:
        """Search the problems ``rows`` of ``p`` (a part of equal size: a repeated last row is
        a copy, never searched) with edges checked in ``search_mode`` (``attempt``: which
        stream of samples, ``scalars``); whether each edge of each path is certified
        (``lazy``, discrete search: checked after it, in its time; else True); the
        seconds."""
        clock = time.perf_counter()
        copy = np.zeros(size, bool)
        copy[1:] = rows[1:] == rows[:-1]
        part_status = np.where(copy, int(MotionStatus.INVALID_INPUT), p.status[rows])
        queue = np.flatnonzero(part_status == MotionStatus.SOLVED).astype(np.int32)
        if queue.size == 0:
            queue = np.zeros(1, np.int32)  # nothing to search: the loop never runs
        found: SearchResult = _search_jit(
            *search_args(p, rows, search_mode, part_status, queue, attempt),
            config=config(search_mode),
        )
        good = np.ones((size, options.path_points - 1), bool)
        if lazy and search_mode == "discrete":
            good = _certify_jit(
                *checked_paths(part_worlds_of(p, rows), found.path, found.count),
                prep.bound.curvature,
                put(options.resolution),
                slots=slots,
                chunk=CERTIFY_CHUNK,
                shared_world=shared,
                group=min(1 if small_loops_in_one_function() else SIMPLIFY_GROUP, size),
            )
        jax.block_until_ready((found, good))
        return found, good, time.perf_counter() - clock

    def simplify(found: SearchResult, rows: np.ndarray) -> tuple[Simplified, float]:
        """Shortcut and smooth the paths of the problems ``rows`` (a part, ``_simplify_all``)
        or take their polygons; the seconds."""
        clock = time.perf_counter()
        path, count = found.path[rows], found.count[rows]
        if not options.simplify:
            simple = _polygon_jit(path, count, space)
            return jax.block_until_ready(simple), time.perf_counter() - clock
        part_worlds = part_worlds_of(problems, rows)
        # more problems than a group: similar paths together (_simplify_all), the problems
        # sorted by waypoint count; one at a time when each loop runs as one function (its
        # steps then cost no hand-off to amortise over a group)
        group = min(1 if small_loops_in_one_function() else SIMPLIFY_GROUP, size)
        order = np.argsort(count, kind="stable")
        sort = size > group
        pick = order if sort else slice(None)
        simple = _simplify_jit(
            *checked_paths(
                _rows(part_worlds, order) if sort and not shared else part_worlds,
                put(path[pick]),
                put(count[pick], np.int32),
            ),
            put(options.resolution),
            prep.bound,
            slots=(SHORTCUTS + 1) * slots,
            # certified shortcuts place their states in the balls' gaps: wider rounds, fewer
            chunk=options.chunk if mode == "discrete" else max(options.chunk, CERTIFY_CHUNK),
            mode=mode,
            states=options.spline_states,
            shared_world=shared,
            group=group,
        )
        simple = _rows(simple, np.argsort(order)) if sort else simple
        return jax.block_until_ready(simple), time.perf_counter() - clock

    # a large batch in parts of equal size on the host threads (each part's programs run on
    # one core); the parts depend on the batch size alone, so results do not depend on the
    # machine
    def in_parts(run: Any, groups: list[np.ndarray]) -> tuple[list[Any], list[np.ndarray]]:
        """``run(part)`` for each group of problems as a part of ``size`` (filled with copies
        of its last problem), on the host threads; the rows of each part to keep."""
        parts = [g[np.minimum(np.arange(size), g.size - 1)] for g in groups]
        return _batching.run_parts(run, parts), [np.arange(g.size) for g in groups]

    def search_all(
        p: _Problems, groups: list[np.ndarray], search_mode: str, attempt: int = 0
    ) -> tuple:
        """``search`` of each group (``in_parts``), joined (NumPy, the groups' rows in turn);
        the edges certified, the seconds summed over the parts, the loops' iterations."""
        done, take = in_parts(lambda part: search(p, part, search_mode, attempt), groups)
        found, good = (_join([part[k] for part in done], take) for k in (0, 1))
        loops = int(np.sum(found.loops))
        found = dataclasses.replace(found, loops=np.int64(loops))
        return found, good, float(sum(part[2] for part in done)), loops

    checked = time.perf_counter() - clock  # the starts' and goals' checks belong to the search
    groups = [np.arange(k, min(k + size, b)) for k in range(0, b, size)]
    # the second search compiles beside the first call's (not when a path first fails)
    compiling = (
        _compile_second_search(
            search_args(
                problems,
                np.minimum(np.arange(size), b - 1),
                "certified",
                np.full(size, int(MotionStatus.INVALID_INPUT)),
                np.zeros(1, np.int32),
            ),
            config("certified"),
        )
        if lazy
        else None
    )
    found, good, searching, loops = search_all(problems, groups, "discrete" if lazy else mode)
    if compiling is not None:
        compiling.join()
    problem, edge = repair.bad_edges(found.count, good, found.status == MotionStatus.SOLVED)
    failed = np.zeros(b, bool)
    if problem.size:
        # each bad edge a problem of its own (certified edges, a smaller budget), each part's
        # edges together: a part's results depend on it alone
        ends = found.path[problem, edge], found.path[problem, edge + 1]
        edges_p = _edge_problems(problems, problem, *ends, options.max_iterations)
        sub_groups = [
            chunk
            for g in groups
            for rows in [np.flatnonzero(np.isin(problem, g))]
            for chunk in np.array_split(rows, -(-rows.size // size) or 1)
            if chunk.size
        ]

        def root_and_search(part: np.ndarray) -> tuple[Any, ...]:
            free_start, free_goal, clear = _roots_jit(
                robot,
                body,
                pairs,
                part_worlds_of(edges_p, part),
                put(edges_p.starts[part]),
                put(edges_p.goals[part]),
                mode="certified",
                shared_world=shared,
            )
            edges_p.root_clear[part] = np.asarray(clear)
            # an end the certified check does not find free: that edge's problem is not searched
            free = np.asarray(free_start) & np.asarray(free_goal)[:, 0]
            edges_p.status[part] = np.where(free, edges_p.status[part], int(MotionStatus.NO_PATH))
            return search(edges_p, part, "certified")

        done, take = in_parts(root_and_search, sub_groups)
        sub = _join([part[0] for part in done], take)
        searching += float(sum(part[2] for part in done))
        loops += int(np.sum(sub.loops))
        back = np.argsort(np.concatenate(sub_groups))  # the bad edges' order
        path, count, failed = repair.splice(
            found.path,
            found.count,
            problem,
            edge,
            sub.path[back],
            sub.count[back],
            sub.status[back] == MotionStatus.SOLVED,
        )
        iterations = np.array(found.iterations)
        np.add.at(iterations, problem, sub.iterations[back])
        found = dataclasses.replace(found, path=path, count=count, iterations=iterations)
    # a problem whose edges could not all be planned again: searched again at the resolution
    # with the seed's next streams of samples (another path, certified as found: RETRIES),
    # then whole with certified edges, each part's own together
    retried = 0
    for attempt in range(1, RETRIES + 1) if lazy else ():
        retry_groups = [g[failed[g]] for g in groups if np.any(failed[g])]
        if not retry_groups:
            break
        retry_rows = np.concatenate(retry_groups)
        found_r, good_r, searching_r, loops_r = search_all(
            problems, retry_groups, "discrete", attempt
        )
        searching, loops, retried = (
            searching + searching_r,
            loops + loops_r,
            retried + retry_rows.size,
        )
        solved_r = found_r.status == MotionStatus.SOLVED
        ok = solved_r & ~np.isin(np.arange(retry_rows.size), repair.bad_edges(
            found_r.count, good_r, solved_r)[0])  # fmt: skip
        # the earlier searches' edges count too
        found_r = dataclasses.replace(
            found_r, iterations=found_r.iterations + found.iterations[retry_rows]
        )
        found = _with_rows(found, retry_rows[ok], _rows_of(found_r, np.flatnonzero(ok)))
        failed[retry_rows[ok]] = False
    again_groups = [g[failed[g]] for g in groups if np.any(failed[g])]
    again = np.concatenate(again_groups) if again_groups else np.zeros(0, int)
    if again.size:
        found_2, _, searching_2, loops_2 = search_all(problems, again_groups, "certified")
        # the first search's edges count too
        found_2 = dataclasses.replace(
            found_2, iterations=found_2.iterations + found.iterations[again]
        )
        found = _with_rows(found, again, found_2)
        searching, loops = searching + searching_2, loops + loops_2
    done, take = in_parts(lambda part: simplify(found, part), groups)
    simple = _join([part[0] for part in done], take)
    seconds["search"] = checked + searching
    seconds["simplify"] = float(sum(part[1] for part in done))
    seconds["parts"] = time.perf_counter() - clock
    seconds["loops"] = loops
    seconds["edges_searched_again"] = int(problem.size)
    seconds["searched_again"] = int(again.size)
    seconds["retried"] = retried
    status = found.status
    solved = status == MotionStatus.SOLVED
    clock = time.perf_counter()
    path_np, count_np = found.path, found.count
    goal_reached = path_np[np.arange(b), np.maximum(count_np - 1, 0)]
    trajectory, duration, timing_status = None, np.zeros(b), np.zeros(b, np.int8)
    if options.period is not None:
        v, a = _limits(robot, options, prep.space_np, n)
        jp = _joint_paths(simple.path, simple.knots_s, simple.slopes, simple.count, options.grid)
        timed = timing.retime(jp, put(v), put(a))
        duration = np.where(solved, np.asarray(timed.duration), 0.0)
        timing_status = np.asarray(timed.status)
        trajectory = timing.sample(
            jp,
            timed,
            options.period,
            num=int(np.floor(np.max(duration, initial=0.0) / options.period)) + 1,
        )
    seconds["timing"] = time.perf_counter() - clock
    return MotionPlan(
        status=status.astype(np.int8),
        path=path_np,
        path_count=count_np,
        simplified=np.asarray(simple.path),
        simplified_count=np.asarray(simple.count),
        smooth=np.asarray(simple.smooth) & solved,
        goal=goal_reached,
        iterations=np.asarray(found.iterations),
        certified=solved & (mode == "certified") & prep.bound.proved,
        trajectory=trajectory,
        duration=duration,
        timing_status=timing_status,
        seconds=seconds,
    )


_SECOND_SEARCHES: set = set()  # the second searches compiled (_compile_second_search)


def _compile_second_search(args: tuple, config: SearchConfig) -> threading.Thread | None:
    """A thread that compiles certified mode's second search for these arguments' shapes
    (running it with nothing to search), once per process; None when done before."""
    leaves, tree = jax.tree.flatten(args)
    key = (tree, config, tuple((np.shape(x), str(getattr(x, "dtype", type(x)))) for x in leaves))
    if key in _SECOND_SEARCHES:
        return None
    _SECOND_SEARCHES.add(key)
    thread = threading.Thread(
        target=lambda: jax.block_until_ready(_search_jit(*args, config=config)), daemon=True
    )
    thread.start()
    return thread


def _stream(number: int) -> int:
    """The sample stream of an option's integer (mixed by the golden-ratio increment)."""
    return (number * 0x9E3779B9 + 0x7F4A7C15) & 0xFFFFFFFF


@kernel
def _polygon_jit(path: Array, count: Array, space: JointSpace) -> Simplified:
    """The path as it is (no simplification): its polygon, chord parameters."""
    s = jax.vmap(lambda p, c: chord_parameters(p, c, space))(path, count)
    return Simplified(path, count, s, jnp.zeros_like(path), jnp.zeros(count.shape, bool))


def _free_kernel(robot, body, pairs, q, world):
    return collider.free(robot, body, pairs, q, world)


def _free_batched_kernel(robot, body, pairs, q, world):
    return jax.vmap(lambda qq, wd: collider.free(robot, body, pairs, qq, wd))(q, world)


_free_jit = Kernel(_free_kernel, policy=_POLICY)
_free_batched_jit = Kernel(_free_batched_kernel, policy=_POLICY)
