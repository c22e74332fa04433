"""Bidirectional RRT-Connect inside one compiled program: teams of lanes, many problems.

RRT-Connect [Kuffner & LaValle 2000] grows a tree from the start and one from the goals (all
goal configurations are roots of the second tree) and alternates two moves:

- EXTEND tree ``a`` toward a uniform sample: from its nearest node, a step of at most
  ``range`` (``space.distance``) checked as one edge (``edges``); the good part becomes a
  new node if it advances at least ``range / 8`` (or reaches the sample);
- CONNECT the other tree toward that new node: the same steps, repeated while they advance;
  reaching it joins the trees (a path). When a move is trapped the trees swap roles.

Dynamic domains [Yershova et al. 2005]: a node from which an EXTEND hit an obstacle keeps a
radius (``domain``, VAMP's RRT-Connect does the same), and a sample farther than it from its
nearest node is dropped before any state is checked (the lane draws again in the next
iteration): the samples that would only grow edges into the obstacles around a node stop
costing edges, which shortens the long searches of cluttered scenes.

The search is one ``lax.while_loop`` over fixed-capacity trees in arrays (``capacity`` nodes
per tree, brute-force nearest neighbours, parents as indices). Its unit of work is a *lane*:
one of these moves after the other, each an edge that the loop checks ``chunk`` states per
iteration (``edges``: coarse to fine, so a colliding edge usually settles in its first
round). The ``W`` lanes' states go through the collision kernel together, ``W x chunk`` per
iteration; a lane whose edge settles makes its move and starts its next edge in the next
iteration, so lanes never wait for one another and no state is checked twice.

A *team* of ``team`` lanes grows one pair of trees (each lane its own samples and moves: a
team advances one RRT-Connect ``team`` edges at a time); ``W / team`` teams work at once.
Teams take problems from a queue: when a team's problem is solved (by it or by another team)
or its budget is spent, the team takes the next problem, or, when the queue is empty, joins an
unsolved one with trees of its own (an independent restart: parallel RRTs whose first success
wins, which shortens the heavy tail of a single RRT's running time). A team whose tree is
full restarts its problem.

The settled edges of a problem's own team (the one that took it from the queue) count toward
its ``max_iterations`` (the teams that join it are extra attempts); a problem that spends them
is reported ``NO_PATH``. A solved lane's path (start tree root to the junction, then the goal
tree back to its root) is written to its problem's row of ``(B, P, n)`` waypoints; a path of
more than ``P`` waypoints is dropped and the team restarts.

In certified mode every node keeps its distances (``collider.clearances``, known from the
state that became the node, or given for the roots): an edge starting there needs no check
of its first state.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ..status import NamedStatusRepr
from . import collider
from .edges import (
    EdgeState,
    absorb,
    good_fraction,
    round_states,
    settled,
    start_edges,
)
from .space import JointSpace
from .status import MotionStatus

__all__ = ["SearchConfig", "SearchResult", "search_kernel"]

_EXTEND, _CONNECT = 0, 1


@dataclasses.dataclass(frozen=True)
class SearchConfig:
    """Static sizes and choices of the search (hashable; one compilation per value).

    Attributes:
        lanes: ``W``, moves in flight per iteration.
        team: lanes that grow one pair of trees (``W`` a multiple of it).
        capacity: nodes per tree (a multiple of 64, or less than 64).
        slots: ``S``, intervals per edge (``S + 1`` states).
        chunk: states checked per lane per iteration.
        path_points: ``P``, waypoints per returned path.
        mode: ``"certified"`` or ``"discrete"`` (``edges``).
        shared_world: every problem has the same world (passed without a problem axis).
    """

    lanes: int = 4
    team: int = 4
    capacity: int = 1024
    slots: int = 32
    chunk: int = 8
    path_points: int = 128
    mode: str = "certified"
    shared_world: bool = True

    @property
    def teams(self) -> int:
        return self.lanes // self.team


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SearchResult(NamedStatusRepr):
    """Per problem ``(B,)``: ``status`` (``MotionStatus``: ``SOLVED`` or ``NO_PATH``; the
    statuses given in ``status_in`` kept), ``path (B, P, n)`` (waypoints, unwrapped; rows
    past ``count`` repeat the last one), ``count`` (waypoints), ``iterations`` (edges the
    search settled for it); ``loops`` ``()``, the iterations of the search's loop."""

    status_fields: ClassVar = {"status": MotionStatus}

    status: Array
    path: Array
    count: Array
    iterations: Array
    loops: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Teams:
    problem: Array  # (T,) int32, -1: idle
    nodes: Array  # (T, 2, n, N): coordinate-major (the nearest-neighbour scan's layout)
    parent: Array  # (T, 2, N) int32
    count: Array  # (T, 2) int32
    clear: Array  # (T, 2, N, R): each node's distances (certified; R = 0 discrete)
    domain: Array  # (T, 2, N): each node's dynamic domain (inf until an EXTEND from it fails)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Lanes:
    mode: Array  # (W,) int32
    a: Array  # (W,) int32: the tree EXTEND grows; CONNECT grows 1 - a
    target: Array  # (W, n): CONNECT's target (a node of tree a)
    target_index: Array  # (W,) int32
    grow: Array  # (W,) int32: the tree the edge in flight grows
    near: Array  # (W,) int32: the node it starts from
    reaches: Array  # (W,) bool: it reaches its target if good to its end
    length: Array  # (W,) its requested length
    fresh: Array  # (W,) bool: the lane starts a new edge this iteration
    edge: EdgeState  # (W, ...)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class _Problems:
    done: Array  # (B,) bool
    status: Array  # (B,) int8
    path: Array  # (B, P, n)
    count: Array  # (B,) int32
    iterations: Array  # (B,) int32: edges settled for it (every team)
    spent: Array  # (B,) int32: edges its own team settled (the budget)
    owner: Array  # (B,) int32: the team that took it from the queue (-1: none yet)
    head: Array  # () int32: next queued problem


def _argmin_last(x: Array) -> Array:
    """The index of the smallest entry along the last axis (its first, for ties) as two plain
    minimums, of the values and of the indices where the smallest sits: reduces XLA
    vectorises on the CPU (a reduce that carries the index is a scalar loop there)."""
    m = jnp.min(x, axis=-1, keepdims=True)
    index = jnp.arange(x.shape[-1], dtype=jnp.int32)
    return jnp.min(jnp.where(x == m, index, jnp.int32(x.shape[-1] - 1)), axis=-1)


# tree sizes the nearest-neighbour scan is compiled for (each a branch; the smallest that
# holds every tree searched runs): young trees, the usual ones, full capacity
_SCAN_SIZES = (64, 256)


def _nearest(
    nodes: Array, team: np.ndarray, grow: Array, size: Array, target: Array, space, need: Array
):
    """Per lane the nearest node ``(W,)`` of its team's tree ``grow`` (nodes coordinate-major,
    ``(T, 2, n, N)``: every distance one vectorised pass over the nodes) to ``target (W,
    n)``, and its configuration ``(W, n)``. Only lanes ``need`` are answered (the others get
    node 0); the scan covers the first ``K`` nodes of the smallest of ``_SCAN_SIZES`` and
    ``N`` that holds their trees (none when no lane needs it)."""
    cap = nodes.shape[-1]
    tj = jnp.asarray(team, jnp.int32)
    sizes = sorted({k for k in _SCAN_SIZES if k < cap} | {cap})

    def scan(k: int):
        def run() -> Array:
            trees = nodes[..., :k][tj, grow]  # (W, n, K)
            step = space.wrap(trees - target[:, :, None], axis=-2) * space.weight[:, None]
            d2 = sum(step[:, j] * step[:, j] for j in range(step.shape[1]))  # (W, K)
            d2 = jnp.where(jnp.arange(k)[None, :] < size[:, None], d2, jnp.inf)
            return _argmin_last(d2)

        return run

    largest = jnp.max(jnp.where(need, size, 0))
    branch = jnp.where(jnp.any(need), 1 + jnp.searchsorted(jnp.asarray(sizes), largest), 0)

    def skip() -> Array:
        return jnp.zeros(grow.shape, jnp.int32)

    near = jax.lax.switch(branch, [skip, *(scan(k) for k in sizes)])
    return near, nodes[tj, grow, :, near]


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
    k, idx, out = jax.lax.while_loop(cond, body, (jnp.int32(0), start.astype(jnp.int32), out))
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


def _fresh_lanes(lanes: _Lanes, need: Array, team_size: int, goals_of: Array, count_of: Array):
    """Lanes ``need`` (their team starts over) begin anew: lane ``i`` of a team CONNECTs the
    start toward goal ``i`` while ``i`` is below the goal count (the straight lines first),
    the others EXTEND the start tree (even lanes) or the goal tree (odd lanes)."""
    w = need.shape[0]
    i = jnp.asarray(np.arange(w) % team_size, jnp.int32)
    connect = i < count_of
    pick = jnp.minimum(i, jnp.maximum(count_of - 1, 0))
    target = jnp.take_along_axis(goals_of, pick[:, None, None], 1)[:, 0]

    def sel(new, old):
        return jnp.where(need.reshape(need.shape + (1,) * (old.ndim - 1)), new, old)

    return dataclasses.replace(
        lanes,
        mode=sel(jnp.where(connect, _CONNECT, _EXTEND).astype(jnp.int32), lanes.mode),
        a=sel(jnp.where(connect, 1, i % 2).astype(jnp.int32), lanes.a),
        target=sel(target, lanes.target),
        target_index=sel(pick, lanes.target_index),
        fresh=lanes.fresh | need,
    )


def search_kernel(
    robot: Any,
    body: Any,
    pairs: Any,
    world: Any,
    space: JointSpace,
    rows: Array,
    starts: Array,
    goals: Array,
    goal_count: Array,
    root_clear: Array,
    status_in: Array,
    queue: Array,
    stream: Array,
    range_: Array,
    domain: Array,
    resolution: Array,
    max_iterations: Array,
    max_loops: Array,
    tol: Array,
    config: SearchConfig,
) -> SearchResult:
    """Plan ``B`` problems (module docstring).

    Args:
        robot, body, pairs: the robot and ``collider.prepare``'s body and pairs.
        world: one ``World`` (``config.shared_world``) or one per problem (leading axis B).
        space: ``space.joint_space`` (arrays); rows: the speed rows ``(R, n)``
            (``bound.speed_rows``; certified mode).
        starts: ``(B, n)``; goals ``(B, G, n)`` with ``goal_count (B,)`` valid ones first.
        root_clear: ``(B, 1 + G, R)`` the distances of the start and the goals
            (``collider.clearances``; certified mode, ``R = 0`` in discrete mode).
        status_in: ``(B,)`` ``MotionStatus``: problems not ``SOLVED`` (invalid start or goals)
            are not searched and keep it.
        queue: ``(Q,)`` int32, the problems to search in order (those with ``SOLVED`` in
            ``status_in``).
        stream: ``uint32``, which stream of samples (``space.sample_hashed``); range_: the
            step (``space.distance``); domain: the dynamic domain's radius of a node an
            EXTEND from which failed (``inf``: none); resolution: states per unit
            of joint distance (discrete mode); max_iterations: edges per problem (its own team's);
            max_loops: loop iterations in all; tol: rounding tolerance of the certified mode.
        config: ``SearchConfig`` (static).
    """
    dtype = starts.dtype
    b, n = starts.shape
    g = goals.shape[1]
    w, k, cap, p = config.lanes, config.team, config.capacity, config.path_points
    t_count = config.teams
    slots, chunk, mode = config.slots, config.chunk, config.mode
    r = root_clear.shape[-1]
    team_of = np.arange(w) // k  # static
    rows = rows.astype(dtype)

    teams = _Teams(
        jnp.full((t_count,), -1, jnp.int32),
        jnp.zeros((t_count, 2, n, cap), dtype),
        jnp.full((t_count, 2, cap), -1, jnp.int32),
        jnp.ones((t_count, 2), jnp.int32),
        jnp.zeros((t_count, 2, cap, r), dtype),
        jnp.full((t_count, 2, cap), jnp.inf, dtype),
    )
    zeros_n = jnp.zeros((w, n), dtype)
    empty_edges = start_edges(
        zeros_n, zeros_n, jnp.zeros((w, r), dtype), rows, slots, mode, tol, resolution, space
    )
    lanes = _Lanes(
        jnp.zeros((w,), jnp.int32),
        jnp.zeros((w,), jnp.int32),
        zeros_n,
        jnp.zeros((w,), jnp.int32),
        jnp.zeros((w,), jnp.int32),
        jnp.zeros((w,), jnp.int32),
        jnp.zeros((w,), bool),
        jnp.zeros((w,), dtype),
        jnp.zeros((w,), bool),
        empty_edges,
    )
    searched = status_in == MotionStatus.SOLVED
    probs = _Problems(
        ~searched,
        jnp.where(searched, MotionStatus.NO_PATH, status_in).astype(jnp.int8),
        jnp.broadcast_to(starts[:, None], (b, p, n)),
        jnp.where(searched, 0, 1).astype(jnp.int32),
        jnp.zeros((b,), jnp.int32),
        jnp.zeros((b,), jnp.int32),
        jnp.full((b,), -1, jnp.int32),
        jnp.int32(0),
    )
    idle_all = jnp.all(probs.done)

    def evaluate(problem_of_team: Array, states: Array) -> Any:
        """``states (W, chunk, n)`` against each lane's world: ``free`` or ``(dist,
        placed)``."""

        def run(wd, q):
            if mode == "discrete":
                return collider.free(robot, body, pairs, q, wd)
            return collider.clearances(robot, body, pairs, q, wd)

        if config.shared_world:
            return run(world, states)
        team_world = jax.tree.map(lambda x: x[jnp.maximum(problem_of_team, 0)], world)
        out = jax.vmap(run)(team_world, states.reshape(t_count, k * chunk, n))
        return jax.tree.map(lambda x: x.reshape((w, chunk, *x.shape[2:])), out)

    def restart(teams: _Teams, lanes: _Lanes, need: Array, problem: Array):
        """Teams ``need`` start ``problem`` over: tree 0 the start, tree 1 the goals."""
        q0 = starts[problem]  # (T, n)
        goal = goals[problem]  # (T, G, n)
        clear = root_clear[problem]  # (T, 1 + G, R)
        z = jnp.zeros((), jnp.int32)
        # only the roots are written: nodes past a tree's count are never read
        roots0 = jnp.where(need[:, None], q0, teams.nodes[:, 0, :, 0])  # (T, n)
        roots1 = jnp.where(need[:, None, None], goal, jnp.swapaxes(teams.nodes[:, 1, :, :g], 1, 2))
        nodes = jax.lax.dynamic_update_slice(teams.nodes, roots0[:, None, :, None], (z, z, z, z))
        nodes = jax.lax.dynamic_update_slice(
            nodes, jnp.swapaxes(roots1, 1, 2)[:, None], (z, z + 1, z, z)
        )
        c0 = jnp.where(need[:, None], clear[:, 0], teams.clear[:, 0, 0])
        c1 = jnp.where(need[:, None, None], clear[:, 1:], teams.clear[:, 1, :g])
        cl = jax.lax.dynamic_update_slice(teams.clear, c0[:, None, None], (z, z, z, z))
        cl = jax.lax.dynamic_update_slice(cl, c1[:, None], (z, z + 1, z, z))
        old_roots = teams.parent[:, :, :g]
        parent = jax.lax.dynamic_update_slice(
            teams.parent, jnp.where(need[:, None, None], -1, old_roots).astype(jnp.int32), (z,) * 3
        )
        old_domains = teams.domain[:, :, :g]
        domains = jax.lax.dynamic_update_slice(
            teams.domain, jnp.where(need[:, None, None], jnp.inf, old_domains), (z,) * 3
        )
        count = jnp.stack([jnp.ones_like(problem), goal_count[problem]], -1).astype(jnp.int32)
        teams = _Teams(
            jnp.where(need, problem, teams.problem).astype(jnp.int32),
            nodes,
            parent,
            jnp.where(need[:, None], count, teams.count),
            cl,
            domains,
        )
        lane_need = need[team_of]
        lane_problem = jnp.maximum(teams.problem[team_of], 0)
        lanes = _fresh_lanes(lanes, lane_need, k, goals[lane_problem], goal_count[lane_problem])
        return teams, lanes

    def assign(teams: _Teams, lanes: _Lanes, probs: _Problems):
        """Teams whose problem is closed take the next queued one, or join an open one."""
        need = (teams.problem < 0) | probs.done[jnp.maximum(teams.problem, 0)]
        rank = jnp.cumsum(need) - 1
        queued = probs.head + rank
        from_queue = need & (queued < queue.shape[0])
        take = queue[jnp.clip(queued, 0, queue.shape[0] - 1)]
        # helpers: the open problems, in index order, shared round-robin
        open_ = ~probs.done
        n_open = jnp.sum(open_)
        spare = rank - (queue.shape[0] - probs.head)
        # the k-th open problem, k = spare mod n_open (a one-hot over problems: no sort)
        kth = jnp.mod(spare, jnp.maximum(n_open, 1))
        nth = (jnp.cumsum(open_) - 1)[None, :] == kth[:, None]
        helper = jnp.argmax(nth & open_[None, :], axis=1)
        problem = jnp.where(from_queue, take, jnp.where(need & (n_open > 0), helper, teams.problem))
        moved = need & (from_queue | (n_open > 0))
        head = jnp.minimum(probs.head + jnp.sum(need), queue.shape[0])
        owned = jnp.where(from_queue, take, b)  # out of bounds: dropped
        owner = probs.owner.at[owned].set(jnp.arange(t_count, dtype=jnp.int32), mode="drop")
        teams, lanes = restart(teams, lanes, moved, problem.astype(jnp.int32))
        return teams, lanes, dataclasses.replace(probs, head=head.astype(jnp.int32), owner=owner)

    def step(carry):
        loop, teams, lanes, probs = carry
        teams, lanes, probs = jax.lax.cond(
            jnp.any((teams.problem < 0) | probs.done[jnp.maximum(teams.problem, 0)]),
            assign,
            lambda t, ln, pr: (t, ln, pr),
            teams,
            lanes,
            probs,
        )
        # ---- fresh lanes start their next edge
        sample = space.sample_hashed(stream, loop, w)
        extend = lanes.mode == _EXTEND
        grow = jnp.where(extend, lanes.a, 1 - lanes.a)
        target = jnp.where(extend[:, None], sample, lanes.target)
        size = teams.count[team_of, grow]
        near, q_near = _nearest(teams.nodes, team_of, grow, size, target, space, lanes.fresh)
        delta = space.step(q_near, target)
        length = space.norm(delta)
        # dynamic domain: a sample beyond its nearest node's domain is dropped (the lane
        # draws again next iteration; its edge of no length is checked and not counted)
        dropped = lanes.fresh & extend & (length > teams.domain[team_of, grow, near])
        scale = jnp.minimum(1.0, range_ / jnp.maximum(length, 1e-30))
        delta = jnp.where(dropped[:, None], 0.0, delta * scale[:, None])
        a_clear = teams.clear[team_of, grow, near]
        new = start_edges(q_near, delta, a_clear, rows, slots, mode, tol, resolution, space)
        fresh = lanes.fresh

        def sel(x, y):
            return jnp.where(fresh.reshape(fresh.shape + (1,) * (x.ndim - 1)), x, y)

        edge = jax.tree.map(sel, new, lanes.edge)
        lanes = dataclasses.replace(
            lanes,
            grow=sel(grow, lanes.grow),
            near=sel(near, lanes.near),
            reaches=sel(scale >= 1.0, lanes.reaches),
            length=sel(jnp.where(dropped, 0.0, length * scale), lanes.length),
        )
        # ---- one round of every lane's edge
        states, j = round_states(edge, slots, chunk, mode)
        edge = absorb(edge, j, evaluate(teams.problem, states), mode, tol, keep_clear=r > 0)
        done_edge = settled(edge, slots, chunk, mode)
        t_good, end = good_fraction(edge, slots, mode)
        # ---- settled lanes make their move
        lane_problem = jnp.maximum(teams.problem[team_of], 0)
        live = done_edge & ~dropped & (teams.problem[team_of] >= 0) & ~probs.done[lane_problem]
        extend = lanes.mode == _EXTEND
        advance = t_good * lanes.length
        # EXTEND keeps a step of at least range / 8 (no crowd of tiny nodes); CONNECT any
        # step, so that it can close in on a target near an obstacle (its edges shorten,
        # their states get denser, the certified balls then cover them)
        least = jnp.where(extend, range_ / 8, range_ * 1e-3)
        added = live & (t_good > 0) & ((advance >= least) | (t_good >= 1.0))
        reached = added & lanes.reaches & (t_good >= 1.0)
        fraction = jnp.where(end >= 0, jnp.maximum(end, 0) / slots, 0.0).astype(dtype)
        q_new = space.canonical(edge.a + fraction[:, None] * edge.delta)
        # slots of the new nodes: a team's lanes adding to one tree take consecutive slots
        same = (team_of[:, None] == team_of[None, :]) & (lanes.grow[:, None] == lanes.grow[None, :])
        earlier = jnp.asarray(np.tril(np.ones((w, w), bool), -1))
        rank = jnp.sum(same & earlier & added[None, :], axis=1, dtype=jnp.int32)
        slot = teams.count[team_of, lanes.grow] + rank
        full = added & (slot >= cap)
        added = added & ~full
        reached = reached & ~full
        write = jnp.where(added, slot, cap)  # out of bounds: dropped
        tj = jnp.asarray(team_of, jnp.int32)
        nodes = teams.nodes.at[tj, lanes.grow, :, write].set(q_new, mode="drop")
        parent = teams.parent.at[tj, lanes.grow, write].set(lanes.near, mode="drop")
        # an EXTEND that hit an obstacle bounds its node's domain; a new node has none
        tight = live & extend & (t_good < 1.0)
        bounded = jnp.where(tight, domain, teams.domain[tj, lanes.grow, lanes.near])
        domains = teams.domain.at[tj, lanes.grow, lanes.near].min(bounded)
        domains = domains.at[tj, lanes.grow, write].set(jnp.inf, mode="drop")
        clear = teams.clear
        if r:
            row = jnp.take_along_axis(edge.clear, jnp.maximum(end, 0)[:, None, None], 1)[:, 0]
            clear = clear.at[tj, lanes.grow, write].set(row, mode="drop")
        grown = jnp.zeros((t_count, 2), jnp.int32).at[tj, lanes.grow].add(added.astype(jnp.int32))
        teams = dataclasses.replace(
            teams,
            nodes=nodes,
            parent=parent,
            clear=clear,
            domain=domains,
            count=teams.count + grown,
        )
        solved = live & ~extend & reached
        # EXTEND: added -> CONNECT toward the new node; else swap. CONNECT: keep going while
        # it advances; trapped -> EXTEND on the swapped trees.
        next_mode = jnp.where(
            extend,
            jnp.where(added, _CONNECT, _EXTEND),
            jnp.where(added & ~reached, _CONNECT, _EXTEND),
        ).astype(jnp.int32)
        swap = jnp.where(next_mode == _EXTEND, 1 - lanes.a, lanes.a)
        a_new = jnp.where(extend & added, lanes.a, swap)
        a_before = lanes.a
        lanes = dataclasses.replace(
            lanes,
            mode=jnp.where(live, next_mode, lanes.mode),
            a=jnp.where(live, a_new, lanes.a).astype(jnp.int32),
            target=jnp.where((live & extend & added)[:, None], q_new, lanes.target),
            target_index=jnp.where(live & extend & added, slot, lanes.target_index).astype(
                jnp.int32
            ),
            fresh=done_edge | dropped,
            edge=edge,
        )

        def record(probs):
            paths, totals = jax.vmap(
                lambda t, aa, ia, ib: _join(
                    jnp.swapaxes(teams.nodes[t], 1, 2), teams.parent[t], aa, ia, ib, space, p
                )
            )(tj, a_before, lanes.target_index, slot)
            ok = solved & (totals <= p)
            same_p = lane_problem[:, None] == lane_problem[None, :]
            winner = ok & ~jnp.any(same_p & earlier & ok[None, :], axis=1)
            # problem b takes the path of its winning lane, if any: a (B, W) one-hot
            of = winner[None, :] & (lane_problem[None, :] == jnp.arange(b)[:, None])
            has = jnp.any(of, axis=1)
            lane = jnp.argmax(of, axis=1)
            path = jnp.where(has[:, None, None], paths[lane], probs.path)
            cnt = jnp.where(has, totals[lane].astype(jnp.int32), probs.count)
            st = jnp.where(has, jnp.int8(MotionStatus.SOLVED), probs.status)
            done = probs.done | has
            return dataclasses.replace(probs, path=path, count=cnt, status=st, done=done), ok

        probs, ok = jax.lax.cond(jnp.any(solved), record, lambda pr: (pr, solved), probs)
        # budgets: the settled edges of a problem's own team (the teams that join it from an
        # empty queue are extra attempts: they do not shorten its own)
        on = (lane_problem[None, :] == jnp.arange(b)[:, None]) & live[None, :]
        own = on & (jnp.asarray(team_of, jnp.int32)[None, :] == probs.owner[:, None])
        iters = probs.iterations + jnp.sum(on, axis=1, dtype=jnp.int32)
        spent = probs.spent + jnp.sum(own, axis=1, dtype=jnp.int32)
        out = spent >= max_iterations
        probs = dataclasses.replace(probs, iterations=iters, spent=spent, done=probs.done | out)
        # a full tree, or a solved path too long for P, restarts the team's problem
        bad = full | (solved & ~ok)
        again = jnp.zeros((t_count,), bool).at[tj].max(bad)
        again = again & ~probs.done[jnp.maximum(teams.problem, 0)] & (teams.problem >= 0)
        teams, lanes = jax.lax.cond(
            jnp.any(again),
            lambda t, ln: restart(t, ln, again, jnp.maximum(t.problem, 0)),
            lambda t, ln: (t, ln),
            teams,
            lanes,
        )
        return loop + 1, teams, lanes, probs

    def cond(carry):
        loop, _, _, probs = carry
        return (loop < max_loops) & ~jnp.all(probs.done)

    carry = (jnp.int32(0), teams, lanes, probs)
    carry = jax.lax.cond(idle_all, lambda c: c, lambda c: jax.lax.while_loop(cond, step, c), carry)
    probs = carry[3]
    return SearchResult(probs.status, probs.path, probs.count, probs.iterations, carry[0])
