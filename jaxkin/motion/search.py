"""Bidirectional RRT-Connect inside one compiled program, many lanes, many problems.

RRT-Connect [Kuffner & LaValle 2000] grows a tree from the start and one from the goals (all
goal configurations are roots of the second tree) and alternates two moves:

- EXTEND tree ``a`` toward a uniform sample: from its nearest node, a step of at most
  ``range`` (``space.distance``) checked as one edge (``edges.edge_prefix``); the good prefix
  becomes a new node if it advances at least ``range / 8`` (or reaches the sample);
- CONNECT the other tree toward that new node: the same steps, repeated while they advance;
  reaching it joins the trees (a path). When a move is trapped the trees swap roles.

The search is one ``lax.while_loop`` over fixed-capacity trees in arrays (``capacity`` nodes
per tree, brute-force nearest neighbours over the nodes, parents as indices). Its unit of work
is a *lane*: one RRT-Connect on one problem, advancing one edge per loop iteration; ``W``
lanes run side by side in every iteration (their edges' states go through the collision
kernel together), so that one iteration checks ``W x (S + 1)`` states. Lanes take problems
from a queue: when a lane's problem is solved (by it or by another lane) or its budget is
spent, the lane takes the next problem, or, when the queue is empty, joins an unsolved one as
an independent restart (parallel RRTs whose first success wins, which shortens the heavy tail
of a single RRT's running time). One problem with ``W`` lanes is ``W`` parallel restarts; 700
problems with ``W`` lanes are a work queue: no lane idles while a problem is open, and no
problem waits for the slowest one. A lane whose tree is full restarts its problem.

Every lane-iteration counts toward its problem's ``max_iterations``; a problem that spends them
is reported ``NO_PATH``. A solved lane's path (start tree root to the junction, then the goal
tree back to its root) is written to its problem's row of ``(B, P, n)`` waypoints; a path of
more than ``P`` waypoints is dropped and the lane restarts.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from jax import Array

from ..status import NamedStatusRepr
from . import collider
from .bound import MotionBound
from .edges import edge_check
from .space import JointSpace
from .status import MotionStatus

__all__ = ["SearchConfig", "SearchResult", "search_kernel"]

_EXTEND, _CONNECT = 0, 1
_BLOCK = 64  # nodes per block of the nearest-neighbour scan


@dataclasses.dataclass(frozen=True)
class SearchConfig:
    """Static sizes and choices of the search (hashable; one compilation per value).

    Attributes:
        lanes: ``W``, RRT-Connects advanced per iteration.
        capacity: nodes per tree.
        slots: ``S``, intervals per edge (``S + 1`` states).
        path_points: ``P``, waypoints per returned path.
        mode: ``"certified"`` or ``"discrete"`` (``edges``).
        shared_world: every problem has the same world (passed without a problem axis).
    """

    lanes: int = 8
    capacity: int = 1024
    slots: int = 32
    path_points: int = 256
    mode: str = "certified"
    shared_world: bool = True


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SearchResult(NamedStatusRepr):
    """Per problem ``(B,)``: ``status`` (``MotionStatus``: ``SOLVED`` or ``NO_PATH``; the
    statuses given in ``status_in`` kept), ``path (B, P, n)`` (waypoints, unwrapped; rows
    past ``count`` repeat the last one), ``count`` (waypoints), ``iterations`` (lane
    iterations spent)."""

    status_fields: ClassVar = {"status": MotionStatus}

    status: Array
    path: Array
    count: Array
    iterations: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Lanes:
    problem: Array  # (W,) int32
    nodes: Array  # (W, 2, N, n)
    parent: Array  # (W, 2, N) int32
    count: Array  # (W, 2) int32
    mode: Array  # (W,) int32
    a: Array  # (W,) int32: the tree EXTEND grows; CONNECT grows 1 - a
    target: Array  # (W, n): CONNECT's target (a node of tree a)
    target_index: Array  # (W,) int32


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Problems:
    done: Array  # (B,) bool
    status: Array  # (B,) int8
    path: Array  # (B, P, n)
    count: Array  # (B,) int32
    iterations: Array  # (B,) int32
    head: Array  # () int32: next queued problem


def _reset(lanes: _Lanes, need: Array, problem: Array, starts, goals, goal_count, replica):
    """Lanes ``need`` start problem ``problem``: tree 0 the start, tree 1 the goals; first a
    CONNECT of the start tree toward goal ``replica % goal_count`` (the straight line)."""
    start = starts[problem]  # (W, n)
    goal = goals[problem]  # (W, G, n)
    g = goals.shape[1]
    # only the roots are written: nodes past a tree's count are never read
    roots = (
        jnp.where(need[:, None], start, lanes.nodes[:, 0, 0]),
        jnp.where(need[:, None, None], goal, lanes.nodes[:, 1, :g]),
    )
    z = jnp.zeros((), jnp.int32)
    nodes = jax.lax.dynamic_update_slice(lanes.nodes, roots[0][:, None, None], (z, z, z, z))
    nodes = jax.lax.dynamic_update_slice(nodes, roots[1][:, None], (z, z + 1, z, z))
    # the roots' parents (-1), for the lanes that start over only
    old_roots = lanes.parent[:, :, :g]
    parent = jax.lax.dynamic_update_slice(
        lanes.parent, jnp.where(need[:, None, None], -1, old_roots).astype(jnp.int32), (z, z, z)
    )
    count = jnp.stack([jnp.ones_like(problem), goal_count[problem]], -1).astype(jnp.int32)
    pick = (replica % jnp.maximum(goal_count[problem], 1)).astype(jnp.int32)
    target = jnp.take_along_axis(goal, pick[:, None, None], 1)[:, 0]

    def sel(new, old):
        return jnp.where(need.reshape(need.shape + (1,) * (old.ndim - 1)), new, old)

    return _Lanes(
        sel(problem, lanes.problem),
        nodes,
        parent,
        sel(count, lanes.count),
        sel(jnp.full_like(lanes.mode, _CONNECT), lanes.mode),
        sel(jnp.ones_like(lanes.a), lanes.a),
        sel(target, lanes.target),
        sel(pick, lanes.target_index),
    )


def _assign(lanes: _Lanes, probs: _Problems, queue: Array, starts, goals, goal_count, replica):
    """Lanes whose problem is closed take the next queued one, or join an open one."""
    need = (lanes.problem < 0) | probs.done[jnp.maximum(lanes.problem, 0)]
    rank = jnp.cumsum(need) - 1
    queued = probs.head + rank
    from_queue = need & (queued < queue.shape[0])
    take = queue[jnp.clip(queued, 0, queue.shape[0] - 1)]
    # helpers: the open problems, in index order, shared round-robin
    open_ = ~probs.done
    n_open = jnp.sum(open_)
    spare = rank - (queue.shape[0] - probs.head)
    # the k-th open problem, k = spare mod n_open (a one-hot over problems: no sort)
    k = jnp.mod(spare, jnp.maximum(n_open, 1))
    nth = (jnp.cumsum(open_) - 1)[None, :] == k[:, None]
    helper = jnp.argmax(nth & open_[None, :], axis=1)
    problem = jnp.where(from_queue, take, jnp.where(need & (n_open > 0), helper, lanes.problem))
    moved = need & (from_queue | (n_open > 0))
    head = jnp.minimum(probs.head + jnp.sum(need), queue.shape[0])
    # a problem taken from the queue is open already (the caller queues open problems only)
    lanes = _reset(lanes, moved, problem.astype(jnp.int32), starts, goals, goal_count, replica)
    return lanes, dataclasses.replace(probs, head=head.astype(jnp.int32))


def _nearest(nodes: Array, grow: Array, size: Array, target: Array, space: JointSpace):
    """Per lane the nearest node of tree ``grow`` to ``target``: blocks of ``_BLOCK`` nodes
    up to the largest tree (a loop whose length follows the trees, not the capacity)."""
    w, _, cap, n = nodes.shape
    size_b = min(_BLOCK, cap)  # the capacity is a multiple of it (MotionOptions)
    blocks = (jnp.max(size).astype(jnp.int32) + size_b - 1) // size_b

    def body(k, best):
        d_best, i_best, q_best = best
        start = (k * size_b).astype(jnp.int32)
        zero = jnp.zeros((), jnp.int32)
        block = jax.vmap(
            lambda t, g: jax.lax.dynamic_slice(
                t, (g.astype(jnp.int32), start, zero), (1, size_b, n)
            )[0]
        )(nodes, grow)  # (W, block, n)
        index = start + jnp.arange(size_b)
        d = space.distance(block, target[:, None, :])
        d = jnp.where(index[None] < size[:, None], d, jnp.inf)
        j = jnp.argmin(d, -1)
        dj = jnp.take_along_axis(d, j[:, None], 1)[:, 0]
        better = dj < d_best
        qj = jnp.take_along_axis(block, j[:, None, None], 1)[:, 0]
        return (
            jnp.where(better, dj, d_best),
            jnp.where(better, (start + j).astype(jnp.int32), i_best),
            jnp.where(better[:, None], qj, q_best),
        )

    init = (jnp.full((w,), jnp.inf, nodes.dtype), jnp.zeros((w,), jnp.int32), nodes[:, 0, 0])
    _, near, q_near = jax.lax.fori_loop(0, blocks, body, init)
    return near, q_near


def _walk(parent: Array, start: Array, points: int) -> tuple[Array, Array]:
    """Node indices from ``start`` up to its root ``(P,)`` (``-1`` past it) and their count."""

    def body(carry):
        k, idx, out = carry
        out = jnp.where(jnp.arange(points) == k, idx, out)
        return k + 1, parent[idx], out

    def cond(carry):
        k, idx, _ = carry
        return (idx >= 0) & (k < points)

    out = jnp.full((points,), -1, jnp.int32)
    k, idx, out = jax.lax.while_loop(cond, body, (jnp.int32(0), start, out))
    return out, jnp.where(idx >= 0, points + 1, k)  # too deep: more than P


def _join(nodes, parent, a, ia, ib, space: JointSpace, points: int) -> tuple[Array, Array]:
    """The path of one lane: start root -> junction (tree 0), junction -> goal root (tree 1);
    ``ia`` in tree ``a``, ``ib`` in tree ``1 - a`` are the junction (the same configuration)."""
    i0 = jnp.where(a == 0, ia, ib)
    i1 = jnp.where(a == 0, ib, ia)
    w0, k0 = _walk(parent[0], i0, points)  # junction -> start root
    w1, k1 = _walk(parent[1], i1, points)  # junction -> goal root
    total = k0 + k1 - 1  # the junction once
    # waypoint m: m < k0 -> w0[k0 - 1 - m]; else w1[m - k0 + 1]
    m = jnp.arange(points)
    from0 = m < k0
    idx0 = w0[jnp.clip(k0 - 1 - m, 0, points - 1)]
    idx1 = w1[jnp.clip(m - k0 + 1, 0, points - 1)]
    q = jnp.where(from0[:, None], nodes[0][jnp.maximum(idx0, 0)], nodes[1][jnp.maximum(idx1, 0)])
    last = jnp.clip(total - 1, 0, points - 1)
    q = jnp.where((m < total)[:, None], q, q[last])
    return space.unwrap(q), total


def search_kernel(
    robot: Any,
    body: Any,
    pairs: Any,
    world: Any,
    space: JointSpace,
    bound: MotionBound,
    starts: Array,
    goals: Array,
    goal_count: Array,
    status_in: Array,
    queue: Array,
    key: Array,
    range_: Array,
    max_iterations: Array,
    max_loops: Array,
    tol: Array,
    config: SearchConfig,
) -> SearchResult:
    """Plan ``B`` problems (module docstring).

    Args:
        robot, body, pairs: the robot and ``collider.prepare``'s body and pairs.
        world: one ``World`` (``config.shared_world``) or one per problem (leading axis B).
        space, bound: ``space.joint_space`` and ``bound.motion_bound`` (arrays).
        starts: ``(B, n)``; goals ``(B, G, n)`` with ``goal_count (B,)`` valid ones first.
        status_in: ``(B,)`` ``MotionStatus``: problems not ``SOLVED`` (invalid start or goals)
            are not searched and keep it.
        queue: ``(Q,)`` int32, the problems to search in order (those with ``SOLVED`` in
            ``status_in``).
        key: a PRNG key; range_: the step (``space.distance``); max_iterations: lane
            iterations per problem; max_loops: loop iterations in all; tol: rounding
            tolerance of the certified mode (length).
        config: ``SearchConfig`` (static).
    """
    dtype = starts.dtype
    b, n = starts.shape
    w, cap, p = config.lanes, config.capacity, config.path_points
    replica = jnp.arange(w, dtype=jnp.int32)
    lanes = _Lanes(
        jnp.zeros((w,), jnp.int32),
        jnp.zeros((w, 2, cap, n), dtype),
        jnp.full((w, 2, cap), -1, jnp.int32),
        jnp.ones((w, 2), jnp.int32),
        jnp.zeros((w,), jnp.int32),
        jnp.zeros((w,), jnp.int32),
        jnp.zeros((w, n), dtype),
        jnp.zeros((w,), jnp.int32),
    )
    searched = status_in == MotionStatus.SOLVED
    probs = _Problems(
        ~searched,
        jnp.where(searched, MotionStatus.NO_PATH, status_in).astype(jnp.int8),
        jnp.broadcast_to(starts[:, None], (b, p, n)),
        jnp.where(searched, 0, 1).astype(jnp.int32),
        jnp.zeros((b,), jnp.int32),
        jnp.int32(0),
    )
    # every lane starts idle (problem -1): the first step hands the problems out
    lanes = dataclasses.replace(lanes, problem=jnp.full((w,), -1, jnp.int32))
    idle_all = jnp.all(probs.done)

    def evaluate(problem):
        """``states (W, T, n) ->`` ``edges.edge_check``'s triple, against each lane's world."""

        def run(wd, q):
            if config.mode == "discrete":
                return None, None, collider.free(robot, body, pairs, q, wd)
            return collider.clearances(robot, body, pairs, q, wd)

        if config.shared_world:
            return lambda q: run(world, q)
        lane_world = jax.tree.map(lambda x: x[jnp.maximum(problem, 0)], world)
        return lambda q: jax.vmap(run)(lane_world, q)

    def check(problem, a, delta):
        return edge_check(evaluate(problem), bound, a, delta, config.slots, config.mode, tol)

    def step(carry):
        loop, lanes, probs = carry
        lanes, probs = _assign(lanes, probs, queue, starts, goals, goal_count, replica + loop)
        k = jax.random.fold_in(key, loop)
        sample = space.sample(k, (w,))
        grow = jnp.where(lanes.mode == _EXTEND, lanes.a, 1 - lanes.a)  # (W,)
        target = jnp.where((lanes.mode == _EXTEND)[:, None], sample, lanes.target)
        size = jnp.take_along_axis(lanes.count, grow[:, None], 1)[:, 0]
        near, q_near = _nearest(lanes.nodes, grow, size, target, space)
        delta = space.step(q_near, target)
        length = space.norm(delta)
        scale = jnp.minimum(1.0, range_ / jnp.maximum(length, 1e-30))
        delta = delta * scale[:, None]
        reaches = scale >= 1.0
        t_good = check(lanes.problem, q_near, delta)
        advance = t_good * length * scale
        # EXTEND keeps a step of at least range / 8 (no crowd of tiny nodes); CONNECT any
        # step, so that it can close in on a target near an obstacle (its edges shorten,
        # their states get denser, the certified balls then cover them)
        least = jnp.where(lanes.mode == _EXTEND, range_ / 8, range_ * 1e-3)
        added = (t_good > 0) & ((advance >= least) | (t_good >= 1.0))
        reached = added & reaches & (t_good >= 1.0)
        q_new = space.canonical(q_near + t_good[:, None] * delta)
        full = size >= cap
        added = added & ~full
        # write the node (one-hot selects: no scatter in the loop body)
        slot = jnp.minimum(size, cap - 1)

        def put(tree_nodes, tree_parent, t, i, q, par, ok):
            zero = jnp.zeros((), jnp.int32)
            t, i = t.astype(jnp.int32), i.astype(jnp.int32)
            old_q = jax.lax.dynamic_slice(tree_nodes, (t, i, zero), (1, 1, n))[0, 0]
            old_p = jax.lax.dynamic_slice(tree_parent, (t, i), (1, 1))[0, 0]
            row = jnp.where(ok, q, old_q)
            pr = jnp.where(ok, par, old_p).astype(jnp.int32)
            tree_nodes = jax.lax.dynamic_update_slice(tree_nodes, row[None, None], (t, i, zero))
            tree_parent = jax.lax.dynamic_update_slice(tree_parent, pr[None, None], (t, i))
            return tree_nodes, tree_parent

        nodes, parent = jax.vmap(put)(lanes.nodes, lanes.parent, grow, slot, q_new, near, added)
        count = lanes.count + ((jnp.arange(2)[None, :] == grow[:, None]) & added[:, None]).astype(
            jnp.int32
        )
        extend = lanes.mode == _EXTEND
        a_before = lanes.a
        solved = ~extend & reached & ~probs.done[lanes.problem]
        # EXTEND: added -> CONNECT toward the new node; else swap. CONNECT: keep going while
        # it advances; trapped -> EXTEND on the swapped trees.
        mode = jnp.where(
            extend,
            jnp.where(added, _CONNECT, _EXTEND),
            jnp.where(added & ~reached, _CONNECT, _EXTEND),
        ).astype(jnp.int32)
        a = jnp.where(extend & added, lanes.a, jnp.where(mode == _EXTEND, 1 - lanes.a, lanes.a))
        new_target = jnp.where((extend & added)[:, None], q_new, lanes.target)
        new_index = jnp.where(extend & added, slot, lanes.target_index)
        lanes = _Lanes(
            lanes.problem,
            nodes,
            parent,
            count,
            mode,
            a.astype(jnp.int32),
            new_target,
            new_index.astype(jnp.int32),
        )

        def record(probs):
            paths, totals = jax.vmap(
                lambda nd, pa, aa, ia, ib: _join(nd, pa, aa, ia, ib, space, p)
            )(lanes.nodes, lanes.parent, a_before, lanes.target_index, slot)
            ok = solved & (totals <= p)
            same = lanes.problem[:, None] == lanes.problem[None, :]
            earlier = jnp.tril(jnp.ones((w, w), bool), -1)
            winner = ok & ~jnp.any(same & earlier & ok[None, :], axis=1)
            # problem b takes the path of its winning lane, if any: a (B, W) one-hot
            of = winner[None, :] & (lanes.problem[None, :] == jnp.arange(b)[:, None])
            has = jnp.any(of, axis=1)
            lane = jnp.argmax(of, axis=1)
            path = jnp.where(has[:, None, None], paths[lane], probs.path)
            cnt = jnp.where(has, totals[lane].astype(jnp.int32), probs.count)
            st = jnp.where(has, jnp.int8(MotionStatus.SOLVED), probs.status)
            done = probs.done | has
            return dataclasses.replace(probs, path=path, count=cnt, status=st, done=done), ok

        probs, ok = jax.lax.cond(jnp.any(solved), record, lambda pr: (pr, solved), probs)
        # budgets: every open lane's iteration counts for its problem
        working = ~probs.done[lanes.problem]
        on = (lanes.problem[None, :] == jnp.arange(b)[:, None]) & working[None, :]
        iters = probs.iterations + jnp.sum(on, axis=1, dtype=jnp.int32)
        spent = iters >= max_iterations
        probs = dataclasses.replace(probs, iterations=iters, done=probs.done | spent)
        # a full tree, or a solved path too long for P, restarts the lane's problem
        restart = (full | (solved & ~ok)) & ~probs.done[lanes.problem]
        lanes = _reset(lanes, restart, lanes.problem, starts, goals, goal_count, replica + loop)
        return loop + 1, lanes, probs

    def cond(carry):
        loop, _, probs = carry
        return (loop < max_loops) & ~jnp.all(probs.done)

    carry = (jnp.int32(0), lanes, probs)
    carry = jax.lax.cond(idle_all, lambda c: c, lambda c: jax.lax.while_loop(cond, step, c), carry)
    probs = carry[2]
    return SearchResult(probs.status, probs.path, probs.count, probs.iterations)
