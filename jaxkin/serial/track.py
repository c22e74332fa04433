"""The chain IK along sampled paths (``Chain.ik_path_kernel``): several solutions of the
first sample followed along the path at once, the best kept.

In units of the chain's size (``search._prepare``), for targets ``G_t``, ``t = 0 ... T - 1``,
with body twists ``V_t`` and their rates ``A_t`` (``search._body_twists``; a point target: the
tip origin's velocity and acceleration in the base frame):

* **Lanes.** ``K = ChainIKOptions.path_lanes`` joint vectors per path follow it side by side:
  the first sample's solution of the IK search (``search.solve``'s, lane 0), then the other
  starts of ``_starts.first_starts`` and the search's seeds, which the first sample's Newton
  iterations below take onto ``G_0`` (with the sub-step homotopy of a retry from their own
  pose). With ``seed`` (a path solved in windows) one lane starts at it.
* **Rates.** At joints ``q`` the rates are those of the weighted least-norm solution
  [Chan and Dubey 1995]: ``q_dot = W^-1/2 (J W^-1/2)^+ V``, ``q_ddot = W^-1/2 (J W^-1/2)^+ (A -
  J_dot q_dot)``, with ``J`` the body Jacobian (a point: the tip origin's, base frame) and
  ``W = diag(w_j)``, ``w_j = (u_j - l_j)^2 / (4 (u_j - q_j)(q_j - l_j))`` (1 at the middle of
  the limits ``[l_j, u_j]``, growing without bound towards them: a joint near a limit moves
  less; 1 for a joint without limits or a revolute one whose range is a turn or more). A
  redundant chain's velocity also moves, in the weighted null space of ``J``, towards the
  middle of its limits [Liegeois 1977]: ``q_dot += z - W^-1/2 (J W^-1/2)^+ J z``,
  ``z_j = -NULL_GAIN s c_j`` with ``c_j = 2 (q_j - m_j) / (u_j - l_j)`` (0 for the
  unweighted joints) and ``s = max_j |q_dot_j|`` of the least-norm velocity (so a target at
  rest keeps the joints at rest, and the motion per unit of path does not depend on its
  timing); ``J q_dot = V`` still. For a chain with no more joints than target rows the
  weights and ``z`` change nothing (``J`` square or the least-squares solution unique). The
  returned rates are these, those of the lane kept (``search._finish``'s ``given``).
* **Time.** The kernel is given no sampling period: each step's ``dt`` is estimated from the
  targets, ``dt = <xi, M> / <M, M>`` with ``xi = log(G_prev^-1 G_t)`` (the step's body twist)
  and ``M = (V_prev + V_t) / 2`` (0 at rest).
* **Prediction and correction** (``_follow``): from the last accepted sample ``(q, q_dot,
  q_ddot)``, Newton's iterations (damped as the search's, ``search.LM_WEIGHT``; weighted as the
  rates; each revolute step at most ``MAX_STEP``) start at ``q + dt q_dot + dt^2 q_ddot / 2``.
  A redundant chain's iterate is also pulled, in the null space of ``J``, towards the step the
  rates predict (the planner's, below): ``dq <- y + (J W^-1/2)^+ ... (V - J y)``, ``y = E - (q -
  q_prev)`` [collocation: the trapezoid rule with its end correction, Hairer, Norsett and
  Wanner 1993, II.7], until ``|dq_j| <= SETTLE_RTOL reach_j`` or for ``SETTLE_ITER`` updates.
* **Continuity.** A solution is accepted unless its step is one the rates do not explain, the
  test of ``plan.unexplained_steps`` with ``JUMP_RTOL`` (stricter than the planner's 0.5)::

      E = dt (q_dot_prev + q_dot) / 2 + dt^2 (q_ddot_prev - q_ddot) / 12
      |q - q_prev - E|_j > JUMP_RTOL reach_j + sqrt(eps) (|q_j| + |q_prev_j| + 1)

  with ``reach_j = dt (|q_dot_prev| + |q_dot|)_j / 2 + dt^2 (|q_ddot_prev| + |q_ddot|)_j / 12``.
  A step that jumps, or Newton's that does not converge within ``warm_iter`` updates, is tried
  again from ``q_prev`` along ``SUBSTEPS`` intermediate targets ``G_prev exp(h(s))``, ``h`` the
  cubic Hermite curve in the twist coordinates of the step with end slopes ``dt V_prev``,
  ``dt V_t`` (a homotopy along the target's own motion), ``SUBSTEP_ITER`` updates each.
* **Choice.** A lane fails at the first sample it does not solve, whose step jumps, where its
  joints leave their limits (its range over the path, after the whole turns of revolute
  joints that fit it best: ``_room``; the planner moves a path by whole turns likewise) or
  where a speed exceeds the chain's velocity limit. Per path the lane that fails last wins,
  among those the one with the most room to the limits; its joints come back turned into the
  limits sample by sample (``search._turned``), ``OK`` where they meet the tolerances within
  the limits, ``OUT_OF_LIMITS`` where they meet them outside, ``NOT_CONVERGED`` where Newton's
  iterations did not (the joints of the lane's last solution).

Every lane iterates in step with the others (a ``lax.while_loop`` per sample inside a
``lax.scan`` over the samples): one compiled program for every path length of a shape.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .. import lie
from .._numerics import eps, safe_sqrt
from ..jet import Jet
from ..result import IKResult
from ..status import STATUS_DTYPE, Status
from . import _kinematics, _starts, _step, search

__all__ = [
    "DIRECT_ITER",
    "JUMP_RTOL",
    "MAX_STEP",
    "NULL_GAIN",
    "SETTLE_ITER",
    "SETTLE_RTOL",
    "SUBSTEPS",
    "SUBSTEP_ITER",
    "solve_paths",
]

# A step is a jump when it misses the rates' prediction by this fraction of their reach
# (the planner's test with a margin below its 0.5, so that an accepted step passes it).
JUMP_RTOL = 0.4
# A retried step: this many intermediate targets, this many updates each.
SUBSTEPS = 8
SUBSTEP_ITER = 2
# Updates of a sample's first attempt (from the prediction) before it is retried.
DIRECT_ITER = 8
# The largest move of a revolute joint in one update (rad).
MAX_STEP = 0.5
# A redundant chain's null-space pull settles within this fraction of the reach, or stops
# after this many updates (then Newton's alone).
SETTLE_RTOL = 0.05
SETTLE_ITER = 5

# Runs of the first sample's search for every lane but the first (which has the whole budget).
LANE_RUNS = 3
# Lanes whose first joints are this close (rad, or units of the chain) are one.
DUPLICATE_TOL = 1e-6
# The largest weight of a joint's speed (at or beyond a limit).
WEIGHT_CAP = 250.0
# A redundant chain's null-space motion away from the limits: at most this fraction of the
# largest joint speed the target's motion asks for (0 at rest).
NULL_GAIN = 0.5

_TWO_PI = 2.0 * np.pi


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Lanes:
    """Every lane's state, ``(B, K, ...)``.

    Attributes:
        q, q_dot, q_ddot: joints (turned as returned: ``search._turned``) and rates at its
            last accepted sample, ``(B, K, n)``; ``u``: those joints unwrapped along the lane.
        reached: the tip pose at ``q`` ``(B, K, 4, 4)``.
        vel, acc: that sample's target twist and rate ``(B, K, r)``.
        low, high: the joints' range over the accepted samples ``(B, K, n)``.
        fail: the first failing sample (int32; ``_NEVER`` for none).
        t: the sample being solved (int32; ``T`` once the path is done).
        x: the iterate ``(B, K, n)``; ``fresh``: to be replaced by the prediction first.
        k: updates so far in this attempt (int32); ``retried``: on the sub-step attempt.
    """

    q: Array
    u: Array
    q_dot: Array
    q_ddot: Array
    reached: Array
    vel: Array
    acc: Array
    low: Array
    high: Array
    fail: Array
    t: Array
    x: Array
    fresh: Array
    k: Array
    retried: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Loop:
    """The ``lax.while_loop`` state: the lanes, every lane's joints and rates ``(B, K, T,
    n)`` and status ``(B, K, T)`` per sample so far, and the updates taken (int32 scalar)."""

    lanes: _Lanes
    q: Array
    q_dot: Array
    q_ddot: Array
    code: Array
    steps: Array


_NEVER = np.iinfo(np.int32).max


def _weights_scale(q: Array, box: Any) -> Array:
    """``W^-1/2`` ``(..., n)`` of the weighted least-norm rates (module docstring)."""
    finite = jnp.isfinite(box.lower) & jnp.isfinite(box.upper)
    span = jnp.where(finite, box.upper - box.lower, 1.0)
    weighted = finite & ~(box.revolute & (span >= _TWO_PI))
    lower = jnp.where(weighted, box.lower, -1.0)
    upper = jnp.where(weighted, box.upper, 1.0)
    # At or beyond a limit the weight is capped (WEIGHT_CAP: the joint moves, slowly).
    inside = jnp.maximum((upper - q) * (q - lower), span * span / (4.0 * WEIGHT_CAP))
    return jnp.where(weighted, jax.lax.rsqrt(span * span / (4.0 * inside)), 1.0)


def _weighted_step(jac: Array, rhs: Array, damping: Array, floor: float, scale: Array) -> Array:
    """``_step.damped_step_looped`` of the columns scaled by ``scale`` (``W^-1/2``), scaled
    back: the damped weighted least-norm step (unweighted when ``n <= r``)."""
    if jac.shape[-1] <= jac.shape[-2]:
        return _step.damped_step_looped(jac, rhs, damping, floor)
    return scale * _step.damped_step_looped(jac * scale[..., None, :], rhs, damping, floor)


def _centred(q: Array, box: Any) -> Array:
    """``(..., n)``: each joint's offset from the middle of its limits in half ranges, ``2 (q_j
    - m_j) / (u_j - l_j)`` (0 for the joints ``_weights_scale`` leaves unweighted)."""
    finite = jnp.isfinite(box.lower) & jnp.isfinite(box.upper)
    span = jnp.where(finite, box.upper - box.lower, 1.0)
    weighted = finite & ~(box.revolute & (span >= _TWO_PI))
    middle = jnp.where(weighted, 0.5 * (box.lower + box.upper), 0.0)
    return jnp.where(weighted, 2.0 * (q - middle) / span, 0.0)


def _rates(unit: Any, box: Any, x: Array, kin: tuple, vel: Array, acc: Array) -> tuple:
    """The joint rates ``(q_dot, q_ddot)`` ``(..., n)`` at joints ``x`` (module docstring):
    ``kin`` the residual's Jacobian, the tip rotation and the joints' body Jacobian there;
    a redundant chain's with the null-space motion ``z`` away from its limits."""
    jac, rot, jac_theta = kin
    dtype = x.dtype
    scale = _weights_scale(x, box)
    zero = jnp.zeros(x.shape[:-1], dtype)
    v_rhs, _ = _rate_rows(unit, rot, jac_theta, vel, acc, jnp.zeros_like(x))
    q_dot = _weighted_step(jac, v_rhs, zero, eps(dtype), scale)
    if jac.shape[-1] > jac.shape[-2]:
        speed = jnp.max(jnp.abs(q_dot), axis=-1, keepdims=True)
        z = -NULL_GAIN * speed * _centred(x, box)
        back = _weighted_step(jac, jnp.einsum("...ij,...j->...i", jac, z), zero, eps(dtype), scale)
        q_dot = q_dot + z - back
    _, a_rhs = _rate_rows(unit, rot, jac_theta, vel, acc, q_dot)
    q_ddot = _weighted_step(jac, a_rhs, zero, eps(dtype), scale)
    return q_dot, q_ddot


def _room(low: Array, high: Array, box: Any) -> Array:
    """Per lane ``(...)``: the least distance over joints from the range ``[low, high]``
    ``(..., n)`` to the limits, after the whole turns of each revolute joint that centre it;
    negative where it does not fit, ``inf`` without limits or samples."""
    finite = jnp.isfinite(box.lower) & jnp.isfinite(box.upper)
    middle = jnp.where(finite, 0.5 * (box.lower + box.upper), 0.0)
    some = high >= low
    centre = jnp.where(some, 0.5 * (low + high), 0.0)
    turns = jnp.where(finite & box.revolute, jnp.round((middle - centre) / _TWO_PI), 0.0)
    shift = _TWO_PI * turns
    room = jnp.minimum(low + shift - box.lower, box.upper - high - shift)
    return jnp.min(jnp.where(some, room, jnp.inf), axis=-1)


def _rate_rows(unit: Any, rot: Array, jac_theta: Array, vel: Array, acc: Array, q_dot: Array):
    """The right-hand sides ``(V, A - J_dot q_dot)`` whose solutions with the residual's
    Jacobian are the rates: a pose's body twists as they are; a point's base-frame velocity
    and acceleration turned into the tip frame (the residual's rows, ``R^T J_p``)."""
    rate = search._task_jacobian_rate(unit, rot, jac_theta, q_dot)
    rest = acc - jnp.einsum("...ij,...j->...i", rate, q_dot)
    if unit.target_kind != "point":
        return vel, rest
    rot_t = jnp.swapaxes(rot, -1, -2)
    turn = lambda x: jnp.einsum("...ij,...j->...i", rot_t, x)  # noqa: E731
    return turn(vel), turn(rest)


def _step_time(xi: Array, v_prev: Array, vel: Array) -> Array:
    """The estimated time of a step ``(...)``: ``<xi, M> / <M, M>``, ``M`` the mean twist
    (module docstring), 0 at rest."""
    mean = 0.5 * (v_prev + vel)
    norm = jnp.sum(mean * mean, -1)
    tiny = jnp.finfo(xi.dtype).tiny
    return jnp.maximum(jnp.sum(xi * mean, -1) / jnp.maximum(norm, tiny), 0.0)


def _at(x: Array, t: Array) -> Array:
    """``x`` ``(B, T, ...)`` at each lane's sample ``t`` ``(B, K)``: ``(B, K, ...)``."""
    index = t.reshape(*t.shape, *([1] * (x.ndim - 2)))
    return jnp.take_along_axis(x[:, None], index[:, :, None], axis=2)[:, :, 0]


def _follow(runs: Any, targets: tuple, lanes: _Lanes, warm_iter: int, v_max: Array) -> _Loop:
    """Every lane along the samples (module docstring), each at its own pace: an update
    moves every lane that has not ended by one Newton step of its own sample, and a lane
    whose sample ends goes on to its next one. ``targets``: ``(goal, vel, acc, valid)``, each
    ``(B, T, ...)``."""
    box, unit = runs.box, runs.unit
    goals, vels, accs, valids = targets
    size = goals.shape[1]
    dtype = lanes.q.dtype
    point = unit.target_kind == "point"
    redundant = unit.n_joints > (3 if point else 6)
    floor_rel = float(np.sqrt(eps(dtype)))
    substeps = SUBSTEPS * SUBSTEP_ITER
    max_step = jnp.asarray(MAX_STEP, dtype)
    per_sample = 2 * DIRECT_ITER + substeps + 2

    def body(loop: _Loop) -> _Loop:
        ln = loop.lanes
        t = jnp.minimum(ln.t, size - 1)
        goal, vel, acc, valid = (_at(x, t) for x in (goals, vels, accs, valids))
        alive = ln.fail == _NEVER
        # Lanes that have failed stop, but for those that failed last once none is alive
        # (the one kept then is one of them).
        latest = jnp.max(ln.fail, axis=-1, keepdims=True)
        others = ~jnp.any(alive, axis=-1, keepdims=True) & (ln.fail == latest)
        active = (ln.t < size) & (alive | others)
        skip = active & ~valid
        active = active & valid
        prev = ln.reached
        if point:  # the step of the tip origin, base frame
            xi = goal[..., :3, 3] - prev[..., :3, 3]
        else:
            xi = lie.se3_log(lie.se3_inverse(prev) @ goal)
        dt = jnp.where(ln.t == 0, 0.0, _step_time(xi, ln.vel, vel))[..., None]
        guess = ln.q + dt * ln.q_dot + 0.5 * dt * dt * ln.q_ddot
        # Iterates turned as the joints returned are, so that a path solved in windows,
        # warm-started from the joints returned, repeats the whole path's values.
        x = search._turned(jnp.where(ln.fresh[..., None], guess, ln.x), box, box.lower, box.upper)
        # The target: the sample's, or an intermediate one of a retry (a Hermite curve).
        s = jnp.where(ln.retried, (ln.k // SUBSTEP_ITER + 1) / SUBSTEPS, 1.0)
        last = s >= 1
        s = jnp.minimum(s, 1.0).astype(dtype)[..., None]
        h = (s**3 - 2 * s**2 + s) * dt * ln.vel + (3 - 2 * s) * s**2 * xi
        h = h + (s**3 - s**2) * dt * vel
        if point:
            partial = goal.at[..., :3, 3].set(prev[..., :3, 3] + h)
        else:
            partial = prev @ lie.se3_exp(h)
        target = jnp.where(last[..., None, None], goal, partial)
        angles = _kinematics.angles(unit, x)
        rot, p, jac_theta = _kinematics.screws_fk_and_jacobian(
            unit.screws, unit.home, angles, "body", looped=True
        )
        jac = _kinematics.couple(unit, jac_theta)
        twist, jac_res, err_rot, err_pos = search._residual(unit, x, target, (rot, p, jac))
        scale = _weights_scale(x, box)
        q_dot, q_ddot = _rates(unit, box, x, (jac_res, rot, jac_theta), vel, acc)
        moved = x - ln.q
        moved = jnp.where(box.revolute, moved - _TWO_PI * jnp.round(moved / _TWO_PI), moved)
        predicted = dt * (ln.q_dot + q_dot) / 2 + dt * dt * (ln.q_ddot - q_ddot) / 12
        reach = dt * (jnp.abs(ln.q_dot) + jnp.abs(q_dot)) / 2
        reach = reach + dt * dt * (jnp.abs(ln.q_ddot) + jnp.abs(q_ddot)) / 12
        floor = floor_rel * (jnp.abs(x) + jnp.abs(ln.q) + 1.0)
        # A redundant chain: pulled in the null space towards the predicted step.
        settling = ln.k < jnp.where(ln.retried, substeps, 0) + SETTLE_ITER
        pulled = last & settling & (ln.t > 0) if redundant else jnp.zeros_like(last)
        pull = jnp.where(pulled[..., None], predicted - moved, 0.0)
        rest = twist - jnp.einsum("...ij,...j->...i", jac_res, pull)
        damping = safe_sqrt(search.LM_WEIGHT * jnp.sum(twist * twist, -1))
        step = pull + _weighted_step(jac_res, rest, damping, 16 * eps(dtype), scale)
        met = (err_rot <= runs.tol_rot) & (err_pos <= runs.tol_pos) & last
        settled = jnp.all(jnp.abs(step) <= SETTLE_RTOL * reach + floor, axis=-1)
        hit = met & (settled | ~pulled)
        off = jnp.abs(moved - predicted) > JUMP_RTOL * reach + floor
        jump = jnp.any(off, axis=-1) & (ln.t > 0)
        spent = ln.k >= jnp.where(ln.retried, substeps + DIRECT_ITER, DIRECT_ITER)
        retry = active & ~ln.retried & ((hit & jump) | (~hit & spent))
        end = active & ~retry & (hit | spent)
        # The sample ends: accepted where it met the tolerances.
        ok = end & hit
        okn = ok[..., None]
        u = jnp.where(okn, ln.u + moved, ln.u)
        low = jnp.where(okn, jnp.minimum(ln.low, u), ln.low)
        high = jnp.where(okn, jnp.maximum(ln.high, u), ln.high)
        fits = _room(low, high, box) >= 0
        fast = jnp.any(jnp.abs(q_dot) > v_max, axis=-1)
        failed = end & alive & (~hit | jump | ~fits | fast)
        q_new = jnp.where(okn, x, ln.q)
        step_q = x + _step.limited(step, box.revolute, max_step)
        # The first sample's iterates stay within the limits (as the search's).
        step_q = jnp.where((ln.t == 0)[..., None], search._project(step_q, box), step_q)
        x_next = jnp.where(retry[..., None], ln.q, jnp.where(active[..., None], step_q, x))
        ended = end | skip
        lanes = _Lanes(
            q=q_new,
            u=u,
            q_dot=jnp.where(okn, q_dot, ln.q_dot),
            q_ddot=jnp.where(okn, q_ddot, ln.q_ddot),
            reached=jnp.where(ok[..., None, None], lie.from_rotation_translation(rot, p), prev),
            vel=jnp.where(okn, vel, ln.vel),
            acc=jnp.where(okn, acc, ln.acc),
            low=low,
            high=high,
            fail=jnp.where(failed, ln.t, ln.fail),
            t=ln.t + ended.astype(jnp.int32),
            x=x_next,
            fresh=jnp.where(ended, True, ln.fresh & ~active),
            k=jnp.where(ended | retry, 0, ln.k + active.astype(jnp.int32)),
            retried=jnp.where(ended, False, ln.retried | retry),
        )
        # Each ended lane's joints and status at its sample (others dropped: index T).
        b, k = np.indices(ln.t.shape)
        at = (b, k, jnp.where(ended, ln.t, size))
        code = jnp.where(ok, Status.OK, Status.NOT_CONVERGED).astype(STATUS_DTYPE)
        return _Loop(
            lanes,
            loop.q.at[at].set(q_new, mode="drop"),
            loop.q_dot.at[at].set(jnp.where(okn, q_dot, 0.0), mode="drop"),
            loop.q_ddot.at[at].set(jnp.where(okn, q_ddot, 0.0), mode="drop"),
            loop.code.at[at].set(code, mode="drop"),
            loop.steps + 1,
        )

    def cond(loop: _Loop) -> Array:
        ln = loop.lanes
        alive = ln.fail == _NEVER
        latest = jnp.max(ln.fail, axis=-1, keepdims=True)
        others = ~jnp.any(alive, axis=-1, keepdims=True) & (ln.fail == latest)
        going = (ln.t < size) & (alive | others)
        return jnp.any(going) & (loop.steps < size * per_sample)

    shape = lanes.fail.shape
    q_all = jnp.zeros((*shape, size, lanes.q.shape[-1]), dtype)
    code_all = jnp.full((*shape, size), Status.NOT_CONVERGED, STATUS_DTYPE)
    start = _Loop(lanes, q_all, q_all, q_all, code_all, jnp.int32(0))
    return jax.lax.while_loop(cond, body, start)


def _first_lanes(prep: Any, runs: Any, budget: Any, count: int) -> Array:
    """``(..., K, n)`` starts of the lanes: the first sample's solutions of the search from
    ``K`` starts (those of ``_starts.first_starts``, then the seeds), lane ``k`` starting with
    the ``k``-th and going on through the others; lane 0 with the search's whole budget, the
    others with ``LANE_RUNS`` runs (an unsolved lane starts from its best iterate)."""
    first = prep.goal[..., 0, :, :]
    near = _starts.first_starts(prep.unit, first, prep.box, prep.seeds)
    batch = first.shape[:-2]
    seeds = jnp.broadcast_to(prep.seeds[1:], (*batch, *prep.seeds[1:].shape))
    pool = jnp.concatenate([near, seeds], -2)[..., :count, :]
    count = pool.shape[-2]
    order = (np.arange(count)[:, None] + np.arange(count)[None, :]) % count
    starts = pool[..., order, :]  # lane k: pool[k], pool[k + 1], ...
    quota = jnp.asarray(np.where(np.arange(count) == 0, runs.runs, LANE_RUNS), jnp.int32)
    every = (*batch, count)
    solved, _ = search._search(
        runs,
        jnp.broadcast_to(first[..., None, :, :], (*every, 4, 4)),
        starts,
        jnp.broadcast_to(prep.done[..., :1], every),
        jnp.broadcast_to(prep.status[..., :1], every),
        budget.slots,
        quota,
    )
    return solved


def solve_paths(
    chain: Any,
    path: Jet,
    tols: tuple[Array, Array],
    budget: Any,
    use_limits: bool,
    seed: Array | None = None,
) -> IKResult:
    """The IK along sampled paths ``(..., T, 4, 4)`` (module docstring), with rates.

    ``budget``: ``search.Budget`` (``lanes`` lanes, ``warm_iter`` updates per sample and
    attempt; the first sample's search ``max_iter`` and ``runs``). ``seed`` ``(..., n)``: the
    joints (the chain's units) of the last solved sample before the first, for a path solved
    in windows: one lane then starts there (None: ``budget.lanes`` lanes from the first
    sample's solutions)."""
    prep = search._prepare(chain, path, tols, use_limits, budget.runs)
    runs = search._runs(prep, budget.max_iter, budget.runs)
    box, dtype, n = prep.box, prep.g.dtype, chain.n_joints
    batch, size = prep.goal.shape[:-3], prep.goal.shape[-3]
    if seed is None:
        q0 = _first_lanes(prep, runs, budget, budget.lanes)
    else:
        # One lane from the seed, the others its duplicates (idle): the same shapes as the
        # whole path's, whose values a path solved in windows repeats to the last bit.
        q0 = jnp.asarray(seed, dtype) * prep.g
        q0 = jnp.broadcast_to(q0[..., None, :], (*batch, budget.lanes, n))
    count = q0.shape[-2]
    q0 = search._turned(q0.reshape(-1, count, n), box, box.lower, box.upper)
    # A lane that starts where an earlier one does (whole turns aside) takes no part.
    apart = q0[:, :, None, :] - q0[:, None, :, :]
    apart = jnp.where(box.revolute, apart - _TWO_PI * jnp.round(apart / _TWO_PI), apart)
    same = jnp.max(jnp.abs(apart), axis=-1) <= DUPLICATE_TOL
    duplicate = jnp.any(same & jnp.asarray(np.tri(count, k=-1, dtype=bool)), axis=-1)
    rot, p = _kinematics.fk_rp(prep.unit, q0, looped=True)
    point = chain.target_kind == "point"
    big = jnp.asarray(jnp.finfo(dtype).max, dtype)
    zeros = jnp.zeros((*q0.shape[:2], 3 if point else 6), dtype)
    ints = jnp.zeros(q0.shape[:2], jnp.int32)
    start = _Lanes(
        q=q0,
        u=q0,
        q_dot=jnp.zeros_like(q0),
        q_ddot=jnp.zeros_like(q0),
        reached=lie.from_rotation_translation(rot, p),
        vel=zeros,
        acc=zeros,
        low=jnp.full_like(q0, big),
        high=jnp.full_like(q0, -big),
        fail=jnp.where(duplicate, -1, _NEVER),
        t=ints,
        x=q0,
        fresh=ints == 0,
        k=ints,
        retried=ints != 0,
    )
    vel, acc = search._body_twists(prep.safe)
    rows = jnp.concatenate([jnp.ones(3, dtype), jnp.full(3, 1.0 / prep.scale, dtype)])
    vel, acc = vel * rows, acc * rows
    if point:  # (0, p_dot) of an identity rotation: the base-frame velocity
        vel, acc = vel[..., 3:], acc[..., 3:]
    targets = tuple(
        x.reshape(-1, size, *x.shape[len(batch) + 1 :]) for x in (prep.goal, vel, acc, ~prep.done)
    )
    v_max = chain.velocity.astype(dtype) * prep.g
    v_max = v_max if use_limits else jnp.full(n, jnp.inf, dtype)
    end = _follow(runs, targets, start, budget.warm_iter, v_max)
    # The lane that fails last, then the one with the most room to the limits.
    lanes = end.lanes
    room = _room(lanes.low, lanes.high, box)
    latest = jnp.max(lanes.fail, axis=-1, keepdims=True)
    choice = jnp.argmax(jnp.where(lanes.fail == latest, room, -jnp.inf), axis=-1)
    code = jnp.take_along_axis(end.code, choice[:, None, None], axis=1)[:, 0]
    q, q_dot, q_ddot = (
        jnp.take_along_axis(x, choice[:, None, None, None], axis=1)[:, 0].reshape(*batch, size, n)
        for x in (end.q, end.q_dot, end.q_ddot)
    )
    code = code.reshape(*batch, size)
    code = jnp.where(prep.done, prep.status, code)
    turned = search._turned(q, box, box.lower, box.upper)
    within = jnp.all((turned >= box.lower) & (turned <= box.upper), axis=-1)
    solved = code == Status.OK
    code = jnp.where(solved & ~within, Status.OUT_OF_LIMITS, code).astype(STATUS_DTYPE)
    return search._finish(prep, prep.goal, turned, code, True, (q_dot, q_ddot))
