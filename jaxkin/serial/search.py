"""The IK search of a chain (``jaxkin.ik`` of a ``serial.Chain``).

In units of the chain's size and in the body frame, per element:

* projected Levenberg-Marquardt: the step of ``serial._step`` with ``mu = LM_WEIGHT |V|^2``
  (Yamashita and Fukushima; quadratic also near singular poses) and every iterate projected
  onto the joint limits (a revolute joint outside them first tries the 2 pi turn that lands
  inside; continuous joints wrap to [-pi, pi)): Kanzow, Yamashita and Fukushima (J. Comput.
  Appl. Math. 172, 2004) prove local quadratic convergence to a solution inside the box. A
  joint at a limit that the descent direction ``J^T V`` pushes outward leaves the step (its
  column zeroed: the active set of projected Newton methods, [Bertsekas 1982]). Joints come
  back within the limits (but for ``OUT_OF_LIMITS``); prismatic coordinates are lengths in
  units of the chain's size like every other length, so a change of unit changes nothing;
* restarts, one after the other, ``max_iter`` updates each, from the starts of
  ``serial._starts`` (the nearest pose of a fixed table, the middle of the limits,
  the other groups' nearest, then seeds spread over the limits); the first run that meets the
  tolerances ends the element's search; after the last, ``FREE_RUNS`` unbounded runs (from
  the best iterate, then from the element's first starts): one that meets the tolerances
  within the limits solves the element (``OK``); ``OUT_OF_LIMITS`` only when every one meets
  them outside the limits (the evidence that none lies within them), else ``NOT_CONVERGED``.
  ``UNREACHABLE``: the target lies beyond ``chain.reach()``. A batch larger than
  ``QUEUE_SLOTS`` runs as a work queue (``_batching.work_queue``): that many lanes
  iterate, and a lane whose target has ended takes the next one (the same updates, so the same
  results, as in step);
* ``OK`` only where ``angle(R^T R_d) <= orientation_tol`` and ``|p_d - p| <= position_tol``,
  evaluated at the returned joints; ``INVALID_INPUT`` for NaN or inf in the target or its
  rates, or a rotation block that is not a rotation (``serial._step.rigid_target``). A pose
  given in a less precise dtype than the chain's (float32 targets of a float64 chain) is
  checked in its own dtype and made the nearest rotation in the chain's at the boundary
  (``Chain.work_target``), so it meets the same tolerances as one given in the chain's;
* rates from the target's body twist, ``q_dot = J_b^+ V_b``, ``q_ddot = J_b^+ (V_b_dot -
  J_b_dot q_dot)`` (minimum-norm for a redundant chain, least squares for one with fewer than
  six joints), a Jacobian-based margin, and implicit derivatives (``dq = J_b^+ dV_b``);
* a chain whose targets are points (``target_kind == "point"``; the chain robot passes them
  as poses of identity rotation) drives the position error ``p_bd = R^T (p_d - p)`` alone to
  zero with the body Jacobian's linear rows (``_residual``, the one place the residual is
  formed): ``OK`` on ``|p_d - p| <= position_tol``, rates ``q_dot = J_p^+ p_dot`` with
  ``J_p = R J_b[3:]`` the tip origin's Jacobian in the base frame.

The IK along sampled paths (``Chain.ik_path_kernel``) is ``serial.track``'s; it runs this search
on a path's first sample.

Every function here is pure and traceable (``solve`` is the kernel the chain robot compiles);
the chain is read through its numeric fields, ``follows`` and ``joint_kinds`` only.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .. import _batching, _validate, lie
from .._numerics import all_finite, eps, isotropy, safe_sqrt
from .._validate import is_concrete
from ..jet import Jet
from ..result import IKResult
from ..robot import options
from ..status import STATUS_DTYPE, Status
from . import _kinematics, _starts, _step
from ._starts import Box

__all__ = [
    "BLOCK",
    "COMPILER_OPTIONS",
    "FREE_RUNS",
    "LM_WEIGHT",
    "QUEUE_SLOTS",
    "Budget",
    "ChainIKOptions",
    "solve",
]

# Levenberg-Marquardt damping ``mu = LM_WEIGHT |V|^2``: any positive weight keeps
# Yamashita-Fukushima's quadratic convergence; 1e-3 needed 3-5x fewer updates than 1 from far
# starts (1,000 UR5 / Panda poses within the limits).
LM_WEIGHT = 1e-3
# Lanes of the work queue: batches up to this size run every target in step; larger ones keep
# this many iterating and refill them as targets end (1e3-1e4 UR5 / Panda poses: 32-64 lanes
# fastest, 4-7x the batch in step).
QUEUE_SLOTS = 32
# Targets per compiled call of a batch (``Chain.ik_policy``): every batch size of two or more
# runs as blocks of this size, so one compilation serves them all; each block is a work queue
# of ``QUEUE_SLOTS`` lanes.
BLOCK = 8 * QUEUE_SLOTS
# Unbounded runs after the bounded ones of an element that none solved: the first from the best
# iterate, the others from its first starts. One that meets the tolerances within the limits
# solves the element; ``OUT_OF_LIMITS`` needs every one to meet them, each outside the limits.
FREE_RUNS = 4
# XLA options of the compiled search (``CompilePolicy.compiler_options``): the CPU's older
# per-kernel code generation and LLVM at -O1 compile its few hundred small kernels in about
# half the time of the defaults, at the same speed of the search (docs/performance.md).
COMPILER_OPTIONS: tuple = (
    ("xla_cpu_use_fusion_emitters", False),
    ("xla_backend_optimization_level", 1),
)

_TWO_PI = 2.0 * np.pi


def _tolerance(value: Any, name: str) -> Any:
    """A positive finite tolerance as a float, or None; traced values pass (not user input)."""
    if value is None or not is_concrete(value):
        return value
    if isinstance(value, bool | str | bytes) or np.ndim(value) != 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    number = float(value)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return number


@options(dynamic=("position_tol", "orientation_tol"))
class ChainIKOptions:
    """Options of a chain's IK (``jaxkin.ik(chain, pose, **options)``).

    Attributes:
        restarts: runs per element at most (>= 1), before the unbounded run.
        max_iter: updates per run (>= 1).
        warm_iter: updates of a path sample's Newton iterations from the prediction, and of
            its retry along intermediate targets (the planner's IK along paths,
            ``serial.track``).
        path_lanes: solutions of a path's first sample followed along it side by side, the
            best kept (``serial.track``).
        position_tol: length units; None for ``max(1e-10, 1000 eps) * chain.length_scale()``.
            A new value compiles nothing new.
        orientation_tol: rad; None for ``max(1e-10, 1000 eps)`` (``eps`` of the work dtype;
            a float32 pose of a float64 chain is made a rotation in float64 first,
            ``Chain.work_target``).
        use_limits: respect the chain's position limits (False: search without them).
    """

    restarts: int = 64
    max_iter: int = 12
    warm_iter: int = 20
    path_lanes: int = 16
    position_tol: float | None = None
    orientation_tol: float | None = None
    use_limits: bool = True

    def __post_init__(self) -> None:
        for name in ("restarts", "max_iter", "warm_iter", "path_lanes"):
            object.__setattr__(self, name, _validate.count(getattr(self, name), name))
        for name in ("position_tol", "orientation_tol"):
            object.__setattr__(self, name, _tolerance(getattr(self, name), name))
        if not isinstance(self.use_limits, bool):
            object.__setattr__(self, "use_limits", bool(self.use_limits))


@dataclasses.dataclass(frozen=True)
class Budget:
    """The static shape of a search (hashable: a compilation key).

    Attributes:
        max_iter: updates per run.
        runs: runs per element at most, before the unbounded run.
        warm_iter: updates per attempt of a path sample (``track.solve_paths``).
        slots: lanes of the work queue (``QUEUE_SLOTS``); a batch of at most this many
            elements iterates in step.
        lanes: solutions of a path's first sample followed along it (``track.solve_paths``).
    """

    max_iter: int
    runs: int
    warm_iter: int
    slots: int = QUEUE_SLOTS
    lanes: int = 1


@dataclasses.dataclass(frozen=True)
class _Runs:
    """What every update of one search reads (closed over by its loops).

    Attributes:
        unit: the chain in units of its size.
        seeds: ``(runs, n)`` starts of the later runs.
        box: the joint box (units of the chain).
        tol_rot, tol_pos: the tolerances (rad; units of the chain).
        max_iter, runs: as ``Budget``.
        free_runs: unbounded runs after the last bounded one (with limits only).
    """

    unit: Any
    seeds: Array
    box: Box
    tol_rot: Array
    tol_pos: Array
    max_iter: int
    runs: int
    free_runs: int = 1


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Lane:
    """The search state of one element (or of every element of a batch in step).

    Attributes:
        q: the iterate ``(..., n)``.
        run: the run it belongs to (int32; from ``runs`` on: the unbounded runs).
        k: updates so far in this run (int32).
        best_q, best: the iterate of least error ``|omega| + |p_bd|`` so far and that error.
        outside: unbounded runs so far that met the tolerances outside the limits (int32).
        outside_q: the first such solution.
    """

    q: Array
    run: Array
    k: Array
    best_q: Array
    best: Array
    outside: Array
    outside_q: Array


@dataclasses.dataclass(frozen=True)
class _Outcome:
    """One update of every lane: the next ``lane``; which lanes ``ended``; for those, their
    joints ``q`` and status ``code``."""

    lane: _Lane
    ended: Array
    q: Array
    code: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _InStep:
    """The ``lax.while_loop`` state of a batch iterated in step.

    Attributes:
        lane: every element's search state.
        done: ended (or preset: invalid, unreachable), ``(...)``.
        status: the status codes so far, ``(...)``.
        steps: updates taken (int32 scalar).
    """

    lane: _Lane
    done: Array
    status: Array
    steps: Array


@dataclasses.dataclass(frozen=True)
class _Prepared:
    """A batch's targets made safe and put in units of the chain (``_prepare``).

    Attributes:
        safe: the target Jet with non-finite elements replaced by the identity at rest.
        goal: ``safe.p`` with its translation divided by ``scale``, ``(..., 4, 4)``.
        unit: the chain in units of its size; ``g``: ``q_unit = g q`` per coordinate.
        scale: the chain's ``length_scale()``.
        box: the joint box (units of the chain).
        status: preset codes (``INVALID_INPUT``, ``UNREACHABLE``, else ``NOT_CONVERGED``).
        done: preset elements (invalid or unreachable).
        tol_rot, tol_pos: the tolerances (rad; units of the chain).
        seeds: ``(runs, n)`` seeds.
        lower, upper: the limits of the coordinates in the chain's own units (``-inf``/``inf``
            without ``use_limits``).
    """

    safe: Jet
    goal: Array
    unit: Any
    g: Array
    scale: Array
    box: Box
    status: Array
    done: Array
    tol_rot: Array
    tol_pos: Array
    seeds: Array
    lower: Array
    upper: Array


def _body_twists(target: Jet) -> tuple[Array, Array]:
    """The target's body twist ``V = vee(T^-1 T_dot)`` and its time derivative
    ``vee(T^-1 T_ddot - (T^-1 T_dot)^2)``, rows ``(omega, v)``, each ``(..., 6)``."""
    inverse = lie.se3_inverse(target.p)
    x = inverse @ target.v
    y = inverse @ target.a - x @ x
    twist, rate = lie.se3_vee(x), lie.se3_vee(y)
    return twist, rate


def _in_units(chain: Any, scale: Array) -> tuple[Any, Array, Array]:
    """The chain in units of its size (lengths / ``scale``), the factors ``g`` of the
    coordinates (``q_unit = g q``) and the mask of prismatic coordinates (whose joints slide)."""
    sliding = jnp.all(chain.screws[:, :3] == 0, axis=-1)
    onto = jnp.asarray(_kinematics.follow_matrix(chain), chain.screws.dtype)
    prismatic = onto.T @ sliding.astype(chain.screws.dtype) > 0
    f = jnp.where(sliding, 1.0 / scale, 1.0)  # theta_unit = f theta
    g = jnp.where(prismatic, 1.0 / scale, 1.0)
    unit = copy.copy(chain)  # the same chain with new numbers (no validation: traced values)
    for name, value in (
        ("screws", chain.screws.at[:, 3:].multiply(jnp.where(sliding, 1.0, 1.0 / scale)[:, None])),
        ("home", chain.home.at[:3, 3].divide(scale)),
        ("multiplier", chain.multiplier * f / g[np.asarray(chain.follows)]),
        ("offset", chain.offset * f),
        ("lower", chain.lower * g),
        ("upper", chain.upper * g),
    ):
        object.__setattr__(unit, name, value)
    return unit, g, prismatic


def _turned(q: Array, box: Box, lower: Array, upper: Array) -> Array:
    """``q`` with every revolute joint outside ``[lower, upper]`` turned by the multiple of
    2 pi that brings it inside, where one does (the one nearest the range's middle: the only
    one when the range is shorter than 2 pi); continuous joints wrapped to [-pi, pi)."""
    middle = jnp.where(jnp.isfinite(lower) & jnp.isfinite(upper), 0.5 * (lower + upper), 0.0)
    turned = q - _TWO_PI * jnp.round((q - middle) / _TWO_PI)
    outside = (q < lower) | (q > upper)
    q = jnp.where(box.revolute & outside & (turned >= lower) & (turned <= upper), turned, q)
    return jnp.where(box.continuous, q - _TWO_PI * jnp.floor((q + np.pi) / _TWO_PI), q)


def _projected(q: Array, box: Box, lower: Array, upper: Array) -> Array:
    """The projection onto ``[lower, upper]`` after the 2 pi turns of ``_turned``."""
    return jnp.clip(_turned(q, box, lower, upper), lower, upper)


def _project(q: Array, box: Box) -> Array:
    return _projected(q, box, box.lower, box.upper)


def _residual(chain: Any, q: Array, target: Array, fk: tuple | None = None):
    """The residual the search drives to zero, the Jacobian rows of the same residual, the
    rotation and the position errors. A pose target: the body twist ``log(T^-1 T_d)``
    ``(..., 6)`` and the body Jacobian ``(..., 6, n)``; a point target
    (``chain.target_kind == "point"``, the target a pose whose translation is the point):
    ``p_bd = R^T (p_d - p)`` ``(..., 3)`` and the body Jacobian's linear rows (``R^T p_dot``),
    no rotation error. ``fk``: ``(R, p, J_b)`` at ``q`` when already computed."""
    rot, p, jac = _kinematics.fk_and_jacobian(chain, q, "body", looped=True) if fk is None else fk
    twist, p_bd = _step.body_twist(rot, p, target)
    err_pos = _step.norm3(p_bd)
    if chain.target_kind == "point":
        return jnp.stack(p_bd, axis=-1), jac[..., 3:, :], jnp.zeros_like(err_pos), err_pos
    return jnp.stack(twist, axis=-1), jac, _step.norm3(twist[:3]), err_pos


def _task_jacobian(chain: Any, q: Array) -> Array:
    """The Jacobian the rates are solved with: the body Jacobian ``(..., 6, n)`` (pose
    targets), or the tip origin's ``(..., 3, n)`` in the base frame, ``R J_b[3:]`` (points)."""
    rot, _, jac = _kinematics.fk_and_jacobian(chain, q, "body", looped=True)
    return rot @ jac[..., 3:, :] if chain.target_kind == "point" else jac


def _task_jacobian_rate(chain: Any, rot: Array, jac_theta: Array, q_dot: Array) -> Array:
    """The time derivative of ``_task_jacobian`` along ``q_dot`` ``(..., n)``, from the body
    Jacobian of the path joints ``jac_theta`` ``(..., 6, m)`` and the tip rotation ``rot``.

    With ``T = E_1 ... E_m M`` the body Jacobian's column ``i``, ``J_i = Ad(G_i^-1) S_i`` with
    ``G_i = E_i ... E_m M``, moves with the later joints only (``dG_i / dtheta_j = G_i [J_j]``
    for ``j > i``): ``dJ_i / dtheta_j = ad(J_i) J_j`` for ``j > i``, 0 for ``j <= i``, with
    ``ad((w, v)) (w', v') = (w x w', w x v' + v x w')``. So ``J_i_dot = ad(J_i) sum_{j > i}
    J_j theta_dot_j``, ``theta_dot = c q_dot[k]``; a point target's ``R J_v`` has the rate
    ``R (omega_b x J_v + J_v_dot)``, ``omega_b = J_w q_dot``. No loop over the joints: the
    search's program keeps one forward kinematics less."""
    follows = np.asarray(chain.follows)
    theta_dot = q_dot[..., follows] * chain.multiplier
    weighted = jac_theta * theta_dot[..., None, :]
    suffix = jnp.flip(jnp.cumsum(jnp.flip(weighted, -1), axis=-1), -1)  # sum_{j >= i}
    later = jnp.concatenate([suffix[..., 1:], jnp.zeros_like(suffix[..., :1])], -1)
    w, v = jac_theta[..., :3, :], jac_theta[..., 3:, :]
    w_later, v_later = later[..., :3, :], later[..., 3:, :]
    rate = jnp.concatenate(
        [
            jnp.cross(w, w_later, axis=-2),
            jnp.cross(w, v_later, axis=-2) + jnp.cross(v, w_later, axis=-2),
        ],
        axis=-2,
    )
    rate = _kinematics.couple(chain, rate)
    if chain.target_kind != "point":
        return rate
    jac = _kinematics.couple(chain, jac_theta)
    omega = jnp.einsum("...ij,...j->...i", jac[..., :3, :], q_dot)
    turning = jnp.cross(omega[..., :, None], jac[..., 3:, :], axis=-2)
    return rot @ (turning + rate[..., 3:, :])


def _update(
    runs: _Runs, goal: Array, starts: Array, lane: _Lane, done: Array, quota: Array | None = None
) -> _Outcome:
    """One projected Levenberg-Marquardt update of every lane. ``starts`` ``(..., S, n)``: the
    lane's first ``S`` runs' starts, projected onto the box as ``runs.seeds`` are (``_search``);
    ``done``: lanes that take no part; ``quota`` ``(...)``: bounded runs after which a lane
    ends unsolved (None: ``runs.runs``, then the unbounded runs)."""
    box, q = runs.box, lane.q
    one = jnp.asarray(1.0, q.dtype)
    bounded = jnp.any(jnp.isfinite(box.lower) | jnp.isfinite(box.upper))
    free_runs = jnp.where(bounded, runs.free_runs, 0)
    last = runs.runs - 1 + free_runs  # the unbounded runs come last

    twist, jac, err_rot, err_pos = _residual(runs.unit, q, goal)
    free = lane.run >= runs.runs
    turned = _turned(q, box, box.lower, box.upper)
    within = jnp.all((turned >= box.lower) & (turned <= box.upper), axis=-1)
    hit = (err_rot <= runs.tol_rot) & (err_pos <= runs.tol_pos)
    solved = hit & within
    # A run that meets the tolerances outside the limits ends (counted if unbounded).
    escaped = ~done & hit & ~within
    counted = escaped & free
    outside = lane.outside + counted.astype(jnp.int32)
    outside_q = jnp.where((counted & (lane.outside == 0))[..., None], q, lane.outside_q)
    score = err_rot + err_pos
    improve = ~done & ~free & (score < lane.best)
    best_q = jnp.where(improve[..., None], q, lane.best_q)
    best = jnp.where(improve, score, lane.best)
    spent = (lane.k >= runs.max_iter) | escaped
    final = lane.run >= last if quota is None else (lane.run >= last) | (lane.run >= quota - 1)
    ended = ~done & (solved | (spent & final))
    # OUT_OF_LIMITS only when every unbounded run met the tolerances, each outside the limits.
    excluded = (free_runs > 0) & (outside >= free_runs)
    code = jnp.where(
        solved, Status.OK, jnp.where(excluded, Status.OUT_OF_LIMITS, Status.NOT_CONVERGED)
    ).astype(STATUS_DTYPE)
    # Levenberg-Marquardt damping mu = LM_WEIGHT |V|^2 (the floor 16 eps trace keeps it defined).
    error_sq = jnp.sum(twist * twist, axis=-1)
    damping = safe_sqrt(LM_WEIGHT * error_sq)
    # A joint held at a limit by the descent direction J^T V is left out of the step (its
    # column zeroed), so the others make up for it (an active set, as projected Newton
    # methods [Bertsekas 1982]); a step that projection would cut is not taken.
    descent = jnp.einsum("...ki,...k->...i", jac, twist)
    held = ((q <= box.lower) & (descent < 0)) | ((q >= box.upper) & (descent > 0))
    held = held & ~free[..., None]
    jac = jnp.where(held[..., None, :], 0.0, jac)
    step = _step.damped_step_looped(jac, twist, damping, 16 * eps(q.dtype))
    moved = q + _step.limited(step, box.revolute, one)
    # The unbounded runs project onto no limits: only their continuous joints wrap.
    lo = jnp.where(free[..., None], -jnp.inf, box.lower)
    hi = jnp.where(free[..., None], jnp.inf, box.upper)
    moved = _projected(moved, box, lo, hi)
    following = lane.run + 1
    own = starts.shape[-2]
    # Bounded runs start from the element's own starts, then the shared seeds; the unbounded
    # ones from the best iterate, then from the element's own starts again.
    pick = jnp.where(following < runs.runs, following, following - runs.runs - 1)
    mine = jnp.take_along_axis(starts, jnp.clip(pick, 0, own - 1)[..., None, None], -2)
    shared = jnp.take(runs.seeds, jnp.minimum(following, runs.runs - 1), axis=0)
    mine_first = (following < own) | (following > runs.runs)
    restart = jnp.where(mine_first[..., None], mine[..., 0, :], shared)  # projected (_search)
    restart = jnp.where((following == runs.runs)[..., None], best_q, restart)
    q_next = jnp.where(spent[..., None], restart, moved)
    q_end = jnp.where(solved[..., None], turned, jnp.where(excluded[..., None], outside_q, best_q))
    run = jnp.where(spent & ~done, following, lane.run)
    k = jnp.where(spent, 0, lane.k + 1)
    lane = _Lane(q_next, run, k, best_q, best, outside, outside_q)
    return _Outcome(lane, ended, q_end, code)


def _fresh(q: Array) -> _Lane:
    """The state of elements about to start their first run at ``q``."""
    zeros = jnp.zeros(q.shape[:-1], jnp.int32)
    return _Lane(q, zeros, zeros, q, jnp.full(q.shape[:-1], jnp.inf, q.dtype), zeros, q)


def _search(
    runs: _Runs,
    target: Array,
    starts: Array,
    done: Array,
    status: Array,
    slots: int | None,
    quota: Array | None = None,
) -> tuple[Array, Array]:
    """Projected Levenberg-Marquardt with restarts (module docstring), in units of the chain.

    ``target`` ``(..., 4, 4)``; ``starts`` ``(..., S, n)`` each element's first ``S`` runs'
    starts (``runs.seeds`` the later runs', rows below ``S`` unused); ``done``/``status``
    preset elements (invalid, unreachable); ``quota`` ``(...)`` (int32, or None): the bounded
    runs after which an element ends unsolved (``_update``). Every element iterates in step
    until the last has ended, or, with more elements than ``slots``, as a work queue of
    ``slots`` lanes. Returns
    ``(q, status)``: ``OK``, ``OUT_OF_LIMITS``, ``NOT_CONVERGED`` or the preset status.
    """
    per_element = (runs.runs + runs.free_runs) * (runs.max_iter + 1) + 2
    # Every start projected once, here: the loop's restarts take them as they are.
    starts = _project(starts, runs.box)
    runs = dataclasses.replace(runs, seeds=_project(runs.seeds, runs.box))
    batch = starts.shape[:-2]
    size = math.prod(batch)
    if slots is not None and size > slots:
        flat = (target.reshape(size, 4, 4), starts.reshape(size, *starts.shape[-2:]))
        quota = None if quota is None else jnp.broadcast_to(quota, batch).ravel()
        q, status = _queued(runs, *flat, done.ravel(), status.ravel(), slots, per_element, quota)
        return q.reshape(*batch, -1), status.reshape(batch)

    def body(state: _InStep) -> _InStep:
        out = _update(runs, target, starts, state.lane, state.done, quota)
        status = jnp.where(out.ended, out.code, state.status)
        q = jnp.where(
            state.done[..., None], state.lane.q, jnp.where(out.ended[..., None], out.q, out.lane.q)
        )
        lane = dataclasses.replace(out.lane, q=q)
        return _InStep(lane, state.done | out.ended, status, state.steps + 1)

    def cond(state: _InStep) -> Array:
        return (state.steps < per_element) & jnp.any(~state.done)

    init = _InStep(_fresh(starts[..., 0, :]), done, status, jnp.int32(0))
    final = jax.lax.while_loop(cond, body, init)
    return final.lane.q, final.status


def _queued(runs: _Runs, target, starts, done, status, slots: int, per_element: int, quota=None):
    """``_search`` as a work queue (``_batching.work_queue``) over flat ``(B, ...)`` elements
    (``starts`` projected; ``quota`` ``(B,)`` or None, as ``_search``'s). Each element gets
    the same updates as in step (the same starts and seeds), so the same results."""
    size = starts.shape[0]

    def fresh(slot: Array) -> _Lane:
        return _fresh(starts[jnp.minimum(slot, size - 1), 0])

    def step(slot: Array, lane: _Lane):
        i = jnp.minimum(slot, size - 1)
        preset = done[i] | (slot >= size)  # invalid, unreachable, or idle
        out = _update(runs, target[i], starts[i], lane, preset, None if quota is None else quota[i])
        # A preset element ends at once with its preset status and its start.
        finished = out.ended | (preset & (slot < size))
        q_out = jnp.where(out.ended[..., None], out.q, starts[i, 0])
        code = jnp.where(out.ended, out.code, status[i])
        return out.lane, finished, (q_out, code)

    limit = (-(-size // slots) + 1) * per_element
    initial = (starts[:, 0], status)
    return _batching.work_queue(step, fresh, initial, size, slots, limit)


def _prepare(chain: Any, target: Jet, tols: tuple[Array, Array], use_limits, runs: int):
    """Units, limits, the preset statuses (invalid, unreachable), the tolerances in units of
    the chain and the ``runs`` seeds of a batch (``_Prepared``)."""
    dtype = target.dtype
    flat = jnp.concatenate(
        [x.reshape(*x.shape[:-2], 16) for x in (target.p, target.v, target.a)], -1
    )
    finite = all_finite(flat) & _step.rigid_target(target.p)
    safe = Jet(
        jnp.where(finite[..., None, None], target.p, jnp.eye(4, dtype=dtype)),
        jnp.where(finite[..., None, None], target.v, 0.0),
        jnp.where(finite[..., None, None], target.a, 0.0),
    )
    scale = jnp.asarray(chain.length_scale(), dtype)
    unit, g, prismatic = _in_units(chain, scale)
    n = chain.n_joints
    if use_limits:
        lower, upper = unit.lower, unit.upper
        own = (chain.lower, chain.upper)
    else:
        lower, upper = jnp.full(n, -jnp.inf, dtype), jnp.full(n, jnp.inf, dtype)
        own = (lower, upper)
    continuous = jnp.asarray([k == "continuous" for k in chain.joint_kinds])
    box = Box(lower, upper, ~prismatic, continuous)
    goal = safe.p.at[..., :3, 3].divide(scale)
    centre, radius = unit.reach()
    distance = safe_sqrt(jnp.sum((goal[..., :3, 3] - centre) ** 2, axis=-1))
    tol_rot, tol_pos = tols[0], tols[1] / scale
    unreachable = finite & (distance > radius + tol_pos)
    status = jnp.where(finite, Status.NOT_CONVERGED, Status.INVALID_INPUT)
    status = jnp.where(unreachable, Status.UNREACHABLE, status).astype(STATUS_DTYPE)
    seeds = _starts.seeds(box, runs, dtype)
    return _Prepared(
        safe,
        goal,
        unit,
        g,
        scale,
        box,
        status,
        ~finite | unreachable,
        tol_rot,
        tol_pos,
        seeds,
        *own,
    )


def _runs(prep: _Prepared, max_iter: int, runs: int) -> _Runs:
    return _Runs(
        prep.unit, prep.seeds, prep.box, prep.tol_rot, prep.tol_pos, max_iter, runs, FREE_RUNS
    )


@jax.custom_jvp
def _solution(q: Array, unit: Any, goal: Array, ok: Array) -> Array:
    """The search's solution ``q`` ``(..., n)`` (units of the chain) as a function of the chain
    ``unit`` and the goal ``(..., 4, 4)``: its value is ``q``; its derivatives are the
    implicit ones of a solution (``_solution_jvp``), zero where not ``ok``. The search itself
    is not differentiated, and a call that is not differentiated computes nothing here."""
    return q


@_solution.defjvp
def _solution_jvp(primals: tuple, tangents: tuple) -> tuple[Array, Array]:
    """One Newton step at the solution, ``dq = J^+ V`` with ``V`` the residual
    (``_residual``: ``log(T(q)^-1 T_d)``, or ``p_bd`` for a point), differentiated in the
    chain and the goal at fixed ``q``: ``q_dot = J^+ V_dot``, the derivative of the solution
    of ``V(q, chain, goal) = 0`` (the residual is zero there up to the tolerances; its own
    derivative through ``J^+`` is kept, as differentiating the step gives). Where not ``ok``
    the goal is the reached pose itself (a finite step) and the derivative zero."""
    q, unit, goal, ok = primals
    _, unit_dot, goal_dot, _ = tangents
    zero = jnp.zeros((), q.dtype)

    def newton_step(unit: Any, goal: Array) -> Array:
        fk = _kinematics.fk_and_jacobian(unit, q, "body", looped=True)
        reached = lie.from_rotation_translation(fk[0], fk[1])
        toward = jnp.where(ok[..., None, None], goal, reached)
        residual, jac, _, _ = _residual(unit, q, toward, fk)
        return _step.damped_step_looped(jac, residual, zero, eps(q.dtype))

    _, dq_dot = jax.jvp(newton_step, (unit, goal), (unit_dot, goal_dot))
    return q, jnp.where(ok[..., None], dq_dot, 0.0)


def _finish(
    prep: _Prepared,
    goal: Array,
    q_unit: Array,
    status: Array,
    rates: bool,
    given: tuple[Array, Array] | None = None,
) -> IKResult:
    """Joint rates, margins and implicit derivatives at the solutions (module docstring);
    ``given``: the rates ``(q_dot, q_ddot)`` in the chain's units (``serial.track``'s), used
    in place of the least-norm ones."""
    unit, g, scale, target = prep.unit, prep.g, prep.scale, prep.safe
    dtype = q_unit.dtype
    ok = status == Status.OK
    point = unit.target_kind == "point"
    q_unit = _solution(jax.lax.stop_gradient(q_unit), unit, goal, ok)
    rot, p, jac_theta = _kinematics.screws_fk_and_jacobian(
        unit.screws, unit.home, _kinematics.angles(unit, q_unit), "body", looped=True
    )
    jac = _kinematics.couple(unit, jac_theta)
    _, _, err_rot, err_pos = _residual(unit, q_unit, goal, (rot, p, jac))
    jac = rot @ jac[..., 3:, :] if point else jac
    floor = eps(dtype)
    zero = jnp.zeros((), dtype)
    rows = jnp.concatenate([jnp.ones(3, dtype), jnp.full(3, 1.0 / scale, dtype)])
    solved_outside = status == Status.OUT_OF_LIMITS
    if rates:
        # A point target's twists are (0, p_dot), (0, p_ddot) (base-frame axes): keep v.
        velocity, acceleration = (x[..., 3:] if point else x for x in _body_twists(target))
        rows = rows[3:] if point else rows
        if given is None:
            q_dot = _step.damped_step_looped(jac, velocity * rows, zero, floor)
            jac_rate = _task_jacobian_rate(unit, rot, jac_theta, q_dot)
            drift = jnp.einsum("...ij,...j->...i", jac_rate, q_dot)
            q_ddot = _step.damped_step_looped(jac, acceleration * rows - drift, zero, floor)
        else:
            q_dot, q_ddot = given
        okc = ok[..., None]
    q = q_unit / g
    # Back in the chain's units a joint at its limit may pass it by an ulp: moved back (values
    # only), but for OUT_OF_LIMITS.
    inside = jnp.clip(q, prep.lower, prep.upper)
    q = q + jax.lax.stop_gradient(jnp.where(solved_outside[..., None], q, inside) - q)
    if rates:
        q_jet = Jet(q, jnp.where(okc, q_dot / g, 0.0), jnp.where(okc, q_ddot / g, 0.0))
    else:
        q_jet = Jet.constant(q)
    error = jnp.minimum(err_rot + err_pos, 1.0)
    solved = ok | (status == Status.OUT_OF_LIMITS)
    margin = jnp.where(solved, isotropy(jac), -error)
    margin = jnp.where(status == Status.INVALID_INPUT, -1.0, margin)
    return IKResult(q_jet, status, margin.astype(dtype))


def solve(
    chain: Any,
    target: Jet,
    tols: tuple[Array, Array],
    budget: Budget,
    use_limits: bool,
    rates: bool,
) -> IKResult:
    """The search (module docstring) for targets ``(..., 4, 4)``, a Jet in the chain's dtype.

    ``tols`` the ``(rotation, position)`` tolerances (rad, length); ``use_limits`` False
    searches without the chain's position limits; ``rates`` False skips the joint rates
    (zero)."""
    prep = _prepare(chain, target, tols, use_limits, budget.runs)
    runs = _runs(prep, budget.max_iter, budget.runs)
    starts = _starts.first_starts(prep.unit, prep.goal, prep.box, prep.seeds)
    q, status = _search(runs, prep.goal, starts, prep.done, prep.status, budget.slots)
    return _finish(prep, prep.goal, q, status, rates)
