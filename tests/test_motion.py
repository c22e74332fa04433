"""jaxkin.motion: the joint space, the speed bound, certified and discrete edges, worlds per
problem, the MotionBenchMaker reader, and plans on small robots re-checked densely.

The planner's programs take tens of seconds to compile; the tests that plan are in the slow
tier, the default tier checks the pieces (each a small program or host code)."""

from __future__ import annotations

import dataclasses
import importlib.util
import io
import sys
import tarfile
import textwrap
import types
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import collision, delta, motion, scara, serial
from jaxkin.motion import bound as mbound
from jaxkin.motion import collider, edges, repair
from jaxkin.motion.space import joint_space

ROOT = Path(__file__).resolve().parents[1]
# the planner's sizes in the tests: small programs
SMALL = dict(lanes=2, capacity=256, path_points=32, spline_states=256, grid=64)


# ----------------------------------------------------------------------------- joint space
def test_continuous_joints_take_the_short_way_round():
    space = joint_space(serial.Planar2R(1.0, 0.8)).astype(jnp.float64)
    a, b = jnp.array([3.0, 0.0]), jnp.array([-3.0, 0.5])
    step = np.asarray(space.step(a, b))
    assert np.allclose(step, [2 * np.pi - 6.0, 0.5], atol=1e-12)
    path = jnp.stack([a, space.canonical(a + step)])
    unwrapped = np.asarray(space.unwrap(path))
    assert np.allclose(unwrapped[1], [3.0 + 2 * np.pi - 6.0, 0.5], atol=1e-12)


def test_the_nearest_node_is_the_brute_force_one_for_every_tree_size():
    """The search's nearest neighbour (coordinate-major trees, a scan compiled per size
    class, wrapped joints) against NumPy's brute force over the live nodes, for trees in
    each size class and lanes that need no answer."""
    from jaxkin.motion import search

    space = joint_space(serial.Planar2R(1.0, 0.8)).astype(jnp.float64)  # both joints wrap
    rng = np.random.default_rng(3)
    cap, w = 512, 4
    nodes = rng.uniform(-np.pi, np.pi, (2, 2, 2, cap))  # (teams, trees, n, N)
    team, grow = np.array([0, 0, 1, 1]), np.array([0, 1, 1, 0])
    target = rng.uniform(-np.pi, np.pi, (w, 2))
    nearest = jax.jit(lambda *args: search._nearest(args[0], team, *args[1:]))
    for sizes in ([5, 40, 1, 64], [65, 3, 200, 10], [300, 512, 2, 7]):
        size = np.array(sizes)
        need = np.array([True, True, False, True])
        near, q = nearest(jnp.asarray(nodes), grow, size, target, space, need)
        for i in np.flatnonzero(need):
            tree = nodes[team[i], grow[i], :, : size[i]].T
            step = np.mod(tree - target[i] + np.pi, 2 * np.pi) - np.pi
            want = int(np.argmin(np.sum(step * step, -1)))
            assert int(near[i]) == want
            assert np.allclose(np.asarray(q[i]), tree[want], atol=0)


def test_nearby_sample_streams_are_independent_and_uniform():
    """The search's samples of seeds 0 and 7 share no draws (they were once the same draws
    shifted by seven indices), and each stream is uniform: mean and a 16-bin histogram of
    2^16 draws within five standard deviations."""
    from jaxkin.motion.planner import _stream
    from jaxkin.motion.space import hashed_uniform

    index = jnp.arange(2**16, dtype=jnp.uint32)
    draws = {
        s: np.asarray(hashed_uniform(jnp.uint32(_stream(s)), index, jnp.float64)) for s in (0, 7)
    }
    shared = np.intersect1d(draws[0], draws[7]).size
    assert shared < 600  # 2^32 pairs over 2^24 values: about 256 equal by chance
    for u in draws.values():
        assert np.all((u >= 0) & (u < 1))
        assert abs(u.mean() - 0.5) < 5 * np.sqrt(1 / 12 / u.size)
        counts = np.bincount((u * 16).astype(int), minlength=16)
        expect = u.size / 16
        assert np.all(np.abs(counts - expect) < 5 * np.sqrt(expect))


def test_prismatic_joints_count_in_units_of_the_robots_size():
    limits = scara.JointLimits(np.array([-2.0, -2.0, 0.0]), np.array([2.0, 2.0, 150.0]))
    robot = scara.Scara(150.0, 80.0, 50.0, limits=limits)
    space = joint_space(robot)
    assert np.allclose(space.weight, [1.0, 1.0, 1.0 / float(robot.length_scale())])
    assert np.all(space.continuous == 0)


def test_a_prismatic_joint_without_limits_is_refused_naming_it():
    with pytest.raises(ValueError, match="'l3'"):
        joint_space(scara.Scara(150.0, 80.0, 50.0))


# ----------------------------------------------------------------------------- speed bound
def _displacement(robot, body, q0, dq, steps=257):
    """The largest path length of any primitive point along ``q0 + t dq`` (dense)."""
    links = np.asarray(body.sphere_link + body.capsule_link)
    pts = np.concatenate(
        [np.asarray(body.sphere_center).reshape(-1, 3), np.asarray(body.capsule_a).reshape(-1, 3)]
    )
    t = np.linspace(0.0, 1.0, steps)[:, None, None]
    q = jnp.asarray(q0[None] + t * dq[None])
    poses = np.asarray(robot.link_poses(q))[..., links, :, :]
    placed = np.einsum("tbpij,pj->tbpi", poses[..., :3, :3], pts) + poses[..., :3, 3]
    return np.linalg.norm(np.diff(placed, axis=0), axis=-1).sum(0)  # (B, P)


@pytest.mark.parametrize(
    "robot",
    [
        serial.Planar3R(1.0, 0.7, 0.4, link_radius=0.05),
        serial.Anthropomorphic(0.3, 0.25, 0.2, link_radius=0.02),
        scara.Scara(
            150.0,
            80.0,
            50.0,
            link_radius=4.0,
            limits=scara.JointLimits(np.array([-2.0, -2.0, 0.0]), np.array([2.0, 2.0, 120.0])),
        ),
    ],
    ids=["planar3r", "anthropomorphic", "scara"],
)
def test_the_speed_bound_is_proved_and_holds_on_random_steps(robot):
    """Every primitive's path length along random steps is within its row's bound."""
    body, pairs = collider.prepare(robot)
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    assert bound.proved
    space = joint_space(robot)
    rng = np.random.default_rng(0)
    q0 = space.lower + rng.uniform(size=(64, robot.n_joints)) * (space.upper - space.lower)
    dq = rng.normal(size=q0.shape) * 0.5 / np.asarray(space.weight)
    moved = _displacement(robot, body, q0, dq)
    prims, _ = mbound.part_speeds(bound, jnp.asarray(dq))
    capped = np.asarray(prims)[:, : moved.shape[1]]
    # the dense path length is a lower bound of the motion: within the bound, and the bound
    # not loose by more than the sqrt(n) of summing joints
    assert np.all(moved <= capped * (1 + 1e-9) + 1e-12)
    assert np.max(moved / np.maximum(capped, 1e-12)) > 0.2


@pytest.mark.slow
def test_a_closed_chain_gets_a_sampled_bound():
    robot = delta.Delta.paper()
    body, pairs = collider.prepare(robot)
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    assert not bound.proved
    assert np.all(np.isfinite(np.asarray(bound.rows)))


# ----------------------------------------------------------------------------- edges
def _planar_scene():
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.05)
    world = collision.World.create(
        spheres=collision.Spheres.create([[1.2, 0.6, 0.0], [-0.2, 1.3, 0.0]], [0.25, 0.2])
    )
    return robot, world


def _evaluators(robot, world, mode):
    body, pairs = collider.prepare(robot)

    def evaluate(q):
        if mode == "discrete":
            return collider.free(robot, body, pairs, q, world)
        return collider.clearances(robot, body, pairs, q, world)

    return body, pairs, evaluate


def test_rake_order_visits_every_state_coarse_first():
    order = edges.rake_order(32)
    assert sorted(order.tolist()) == list(range(33))
    assert order[:3].tolist() == [0, 32, 16]


@pytest.mark.slow
def test_a_grazing_edge_slips_between_discrete_states_and_is_caught_certified():
    """The tip of the arm sweeps past a small ball: between two of the coarse discrete states
    it touches the ball (a dense check finds the contact), the discrete edge check misses it,
    the certified one does not certify the edge past it."""
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.01)
    a = np.array([0.0, 0.0])
    d = np.array([1.0, 0.0])  # joint 1 sweeps 1 rad
    body, pairs = collider.prepare(robot)
    # a ball just reached by the tip at t = 0.53 (between the states t = 0.5 and 0.5625)
    tip = 1.8 * np.array([np.cos(0.53), np.sin(0.53), 0.0])
    world = collision.World.create(spheres=collision.Spheres.create([tip * 1.012], 0.012))
    dense = np.linspace(0.0, 1.0, 4001)[:, None] * d + a
    assert np.any(np.asarray(collision.check(robot, dense, world).collides))
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    rows = mbound.speed_rows(bound, body)
    space = joint_space(robot)
    tol, resolution = jnp.asarray(1e-12), jnp.asarray(16.0)
    out = {}
    for mode in edges.MODES:
        _, _, evaluate = _evaluators(robot, world, mode)
        check = jax.jit(
            lambda a, d, e=evaluate, m=mode: edges.edge_check(
                e, rows, a, d, 16, 8, m, tol, resolution, space
            )
        )
        out[mode] = float(check(jnp.asarray(a[None]), jnp.asarray(d[None]))[0])
    assert out["discrete"] == 1.0  # the 17 states miss the ball
    assert out["certified"] < 0.53  # certified only up to before the contact


@pytest.mark.slow
def test_a_found_edge_that_slips_through_is_planned_again_with_certified_edges(monkeypatch):
    """The straight motion from start to goal sweeps the tip past a small ball between two
    states of the resolution: the search at the resolution takes it (discrete mode returns
    it, and a dense check finds the contact); certified mode finds that its edge cannot be
    certified, plans that edge again with certified edges and returns a path free under the
    dense check."""
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.01)
    tip = 1.8 * np.array([np.cos(0.53), np.sin(0.53), 0.0])
    world = collision.World.create(spheres=collision.Spheres.create([tip * 1.012], 0.012))
    start, goal = np.array([0.0, 0.0]), np.array([1.0, 0.0])
    options = dict(SMALL, period=None, range=2.0, resolution=16.0, simplify=False)
    discrete = motion.plan(robot, start, world, goal=goal, mode="discrete", **options)
    assert motion.status_names(discrete.status).tolist() == ["SOLVED"]
    assert int(discrete.path_count[0]) == 2  # the straight edge
    assert _dense_free(robot, world, discrete.path[0, :2]) < 0
    certified = motion.plan(robot, start, world, goal=goal, mode="certified", **options)
    assert motion.status_names(certified.status).tolist() == ["SOLVED"]
    # the edge planned again alone, the problem not searched again whole
    assert certified.seconds["edges_searched_again"] == 1
    assert certified.seconds["searched_again"] == 0 and bool(certified.certified[0])
    path = certified.path[0, : int(certified.path_count[0])]
    assert _dense_free(robot, world, path) > 0
    # an edge's own problem with too small a budget: the problem is searched again whole
    monkeypatch.setattr(motion.planner, "REPAIR_BUDGET", 10**9)
    whole = motion.plan(robot, start, world, goal=goal, mode="certified", **options)
    assert motion.status_names(whole.status).tolist() == ["SOLVED"]
    assert whole.seconds["edges_searched_again"] == 1 and whole.seconds["searched_again"] == 1
    assert whole.seconds["retried"] == motion.planner.RETRIES  # each found the same edge
    assert _dense_free(robot, world, whole.path[0, : int(whole.path_count[0])]) > 0


@pytest.mark.slow
def test_a_problem_whose_edge_is_not_planned_again_is_searched_again_at_the_resolution(
    monkeypatch,
):
    """A found path whose bad edge cannot be planned again alone (here: every edge of the
    first search's paths reported bad, and their paths found again reported not to fit) is
    searched again at the resolution with the seed's next stream of samples, and that path,
    certified as found, is returned: no search whole with certified edges."""
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.01)
    world = collision.World.create(spheres=collision.Spheres.create([[0.0, 0.0, 1.0]], 0.05))
    start, goal = np.array([-2.0, 1.0]), np.array([-1.0, 2.0])
    options = dict(SMALL, period=None, range=2.0, resolution=16.0, simplify=False)
    real, calls = repair.bad_edges, []

    def first_search_all_bad(count, good, solved):
        calls.append(len(calls))
        return real(count, good & (len(calls) > 1), solved)

    def nothing_fits(*args):
        path, count, failed = splice(*args)
        return path, count, np.ones_like(failed)

    splice = repair.splice
    monkeypatch.setattr(motion.planner.repair, "bad_edges", first_search_all_bad)
    monkeypatch.setattr(motion.planner.repair, "splice", nothing_fits)
    out = motion.plan(robot, start, world, goal=goal, mode="certified", **options)
    assert motion.status_names(out.status).tolist() == ["SOLVED"]
    assert out.seconds["edges_searched_again"] >= 1
    assert out.seconds["retried"] == 1 and out.seconds["searched_again"] == 0
    assert bool(out.certified[0]) and len(calls) == 2
    assert _dense_free(robot, world, out.path[0, : int(out.path_count[0])]) > 0


@pytest.mark.slow
def test_edges_planned_again_in_a_batch_of_parts_keep_each_part_as_its_problems_alone(
    monkeypatch,
):
    """Five problems in parts of two, one world per problem, two of them the grazing straight
    edge: each part's rows equal a call with its problems alone (its bad edges planned again
    among its own), and every returned path is free under the dense check."""
    monkeypatch.setattr(motion.planner, "PART_PROBLEMS", 2)
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.01)
    tip = 1.8 * np.array([np.cos(0.53), np.sin(0.53), 0.0])
    world = collision.World.create(spheres=collision.Spheres.create([tip * 1.012], 0.012))
    starts = np.array([[0.0, 0.0], [-2.0, 1.0], [0.0, 0.0], [2.5, -1.0], [-1.0, -2.0]])
    goals = np.array([[1.0, 0.0], [-1.0, 2.0], [1.0, 0.0], [1.5, -2.0], [-2.5, -1.0]])
    options = dict(SMALL, period=None, range=2.0, resolution=16.0, simplify=False)
    worlds = [world] * 5
    whole = motion.plan(robot, starts, worlds, goal=goals, **options)
    assert motion.status_names(whole.status).tolist() == ["SOLVED"] * 5
    assert whole.seconds["edges_searched_again"] >= 2
    for first in (0, 2, 4):
        rows = slice(first, first + 2)
        alone = motion.plan(robot, starts[rows], worlds[rows], goal=goals[rows], **options)
        for field in ("status", "path", "path_count", "iterations"):
            assert np.array_equal(getattr(whole, field)[rows], getattr(alone, field)), field
    for i in range(5):
        assert _dense_free(robot, world, whole.path[i, : int(whole.path_count[i])]) > 0


def _spline_check_by_hand(knots, s, slopes, count, q, param, piece, dist, placed, rows, tol):
    """Certified mode's spline check written out state by state in NumPy from its docstring:
    each state's ball from its own clearances and the speed bound of the three pieces around
    it (the Bezier control points of ``dq/ds``), cut at their outer ends; the prefix walked in
    order; a piece is bad when one of its states lies past the prefix."""
    pieces = knots.shape[0] - 1
    h = np.diff(s)
    vmax = np.zeros((pieces, knots.shape[1]))
    for k in range(count - 1):
        y0, y1, m0, m1 = knots[k], knots[k + 1], slopes[k], slopes[k + 1]
        control = [m0, 3.0 * (y1 - y0) / h[k] - m0 - m1, m1]
        vmax[k] = np.max(np.abs(control), axis=0)
    span = s[count - 1]
    t = param / span
    good_to, reach = 0.0, -np.inf
    for i in range(t.size):
        k = piece[i]
        speeds = np.abs(np.max(vmax[max(k - 1, 0) : k + 2], axis=0) * span) @ rows.T
        safe = np.where(speeds > 0, speeds, 1.0)
        ratios = np.where(speeds > 0, np.maximum(dist[i] - tol, 0.0) / safe, 2.0)
        free = bool(placed[i]) and bool(np.all(dist[i] > 0))
        radius = min(float(np.min(ratios)), 2.0) if free else 0.0
        lo, hi = s[max(k - 1, 0)] / span, s[min(k + 2, count - 1)] / span
        left, right = min(radius, t[i] - lo), min(radius, hi - t[i])
        if not free or (i > 0 and not t[i] - left < reach):
            break
        good_to, reach = t[i], max(reach, t[i] + right)
    bad = np.zeros(pieces, bool)
    bad[piece[t > good_to]] = True
    return bad


def test_certified_spline_check_gives_each_state_its_own_speed_bound():
    """``simplify.spline_check`` in certified mode against ``_spline_check_by_hand`` on random
    splines in the planar scene, several of which pass close to the balls (a ball computed
    with another state's speed bound would cover what it does not)."""
    from jaxkin.motion import simplify

    robot, world = _planar_scene()
    body, pairs, evaluate = _evaluators(robot, world, "certified")
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    rows = np.asarray(mbound.speed_rows(bound, body))
    space = joint_space(robot)
    tol, count, states = 1e-12, 5, 96
    check = simplify.Checker(
        evaluate, space, jnp.asarray(rows), "certified", jnp.asarray(tol), jnp.asarray(32.0), 8
    )

    @jax.jit
    def run(knots):
        s = simplify.chord_parameters(knots, count, space)
        slopes = simplify.spline_slopes(knots, s, count)
        q, param, piece, enough = simplify._spline_states(
            knots, s, slopes, count, states, space, 32.0, "certified"
        )
        bad = simplify.spline_check(check, knots, s, slopes, count, states)
        return bad, s, slopes, q, param, piece, enough, *evaluate(q)

    rng = np.random.default_rng(11)
    some_bad = 0
    for _ in range(24):
        knots = np.zeros((8, 2))
        # steps alternately short and long: sharp turns, pieces of very different speeds
        steps = rng.normal(size=(count, 2)) * np.array([0.03, 0.9, 0.03, 0.9, 0.03])[:, None]
        knots[:count] = rng.uniform(-np.pi, np.pi, 2) + np.cumsum(steps, axis=0)
        knots[count:] = knots[count - 1]
        bad, s, slopes, q, param, piece, enough, dist, placed = (
            np.asarray(x) for x in run(jnp.asarray(knots))
        )
        assert bool(enough)
        expected = _spline_check_by_hand(
            knots, s, slopes, count, q, param, piece, dist, placed, rows, tol
        )
        assert np.array_equal(bad, expected)
        some_bad += bool(np.any(expected[: count - 1]))
    assert 3 <= some_bad <= 21  # splines that hit or graze the balls, and free ones


def test_bad_edges_are_spliced_out_for_the_paths_found_between_their_ends():
    """``repair``: the bad edges of solved problems in order; each replaced by the path found
    between its ends (the expected paths written out by hand); a problem with an edge not
    found, or whose path would overflow its buffer, is left as it was and reported."""
    p = 6
    path = np.zeros((3, p, 1))
    path[0, :3, 0] = [0.0, 1.0, 2.0]
    path[1, :4, 0] = [0.0, 10.0, 20.0, 30.0]
    path[2, :3, 0] = [5.0, 6.0, 7.0]
    count = np.array([3, 4, 3])
    for row in range(3):
        path[row, count[row] :] = path[row, count[row] - 1]
    good = np.ones((3, p - 1), bool)
    good[0, 1] = good[1, 0] = good[1, 2] = good[2, 0] = False
    good[0, 4] = False  # past the path's last edge: not an edge
    solved = np.array([True, True, True])
    problem, edge = repair.bad_edges(count, good, solved)
    assert problem.tolist() == [0, 1, 1, 2] and edge.tolist() == [1, 0, 2, 0]
    sub_path = np.zeros((4, p, 1))
    sub_path[0, :3, 0] = [1.0, 1.5, 2.0]
    sub_path[1, :4, 0] = [0.0, 3.0, 6.0, 10.0]
    sub_path[2, :3, 0] = [20.0, 25.0, 30.0]
    sub_path[3, :5, 0] = [5.0, 5.2, 5.4, 5.6, 6.0]
    sub_count = np.array([3, 4, 3, 5])
    out, new_count, failed = repair.splice(
        path, count, problem, edge, sub_path, sub_count, np.array([True, True, True, True])
    )
    # problem 1 would need 4 + 2 + 1 = 7 waypoints: left as it was
    assert new_count.tolist() == [4, 4, 6] and failed.tolist() == [False, True, False]
    assert out[0, :, 0].tolist() == [0.0, 1.0, 1.5, 2.0, 2.0, 2.0]
    assert np.array_equal(out[1], path[1])
    assert out[2, :, 0].tolist() == [5.0, 5.2, 5.4, 5.6, 6.0, 7.0]
    b_count = np.array([3, 3, 3])  # problem 1 shorter: everything fits
    b_path = path.copy()
    b_path[1, 3:] = 20.0
    good_b = good.copy()
    good_b[1, 2] = True
    problem, edge = repair.bad_edges(b_count, good_b, solved)
    assert problem.tolist() == [0, 1, 2] and edge.tolist() == [1, 0, 0]
    pick = [0, 1, 3]
    out, new_count, failed = repair.splice(
        b_path, b_count, problem, edge, sub_path[pick], sub_count[pick], np.array([1, 1, 0], bool)
    )
    assert new_count.tolist() == [4, 5, 3] and failed.tolist() == [False, False, True]
    assert out[1, :, 0].tolist() == [0.0, 3.0, 6.0, 10.0, 20.0, 20.0]
    assert np.array_equal(out[2], b_path[2])


def test_certified_prefixes_are_free_under_a_dense_check():
    robot, world = _planar_scene()
    body, pairs, evaluate = _evaluators(robot, world, "certified")
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    rows = mbound.speed_rows(bound, body)
    space = joint_space(robot)
    tol, resolution = jnp.asarray(1e-12), jnp.asarray(32.0)
    rng = np.random.default_rng(1)
    a = rng.uniform(-np.pi, np.pi, (64, 2))
    ok = ~np.asarray(collision.check(robot, a, world).collides)
    a = a[ok]
    d = rng.normal(size=a.shape) * 0.8
    check = jax.jit(
        lambda a, d: edges.edge_check(
            evaluate, rows, a, d, 32, 8, "certified", tol, resolution, space
        )
    )
    t_good = np.asarray(check(jnp.asarray(a), jnp.asarray(d)))
    assert np.any(t_good >= 1.0) and np.any(t_good < 1.0)
    s = np.linspace(0.0, 1.0, 2001)
    states = a[:, None] + (s[None, :, None] * t_good[:, None, None]) * d[:, None]
    clearance = np.asarray(collision.check(robot, states, world).clearance)
    assert np.min(clearance) > 0


@pytest.mark.slow
def test_gap_rounds_spend_states_only_where_the_balls_leave_gaps():
    """``edges.gap_states``' rounds: an edge far from the obstacles is certified by its first
    round (the coarse balls overlap), and on random edges the certified prefix is at least
    the one every state known gives (the uniform rounds), never longer than is free."""
    robot, world = _planar_scene()
    body, pairs, evaluate = _evaluators(robot, world, "certified")
    bound = mbound.motion_bound(robot, body, pairs.link_pairs)
    rows = jnp.asarray(mbound.speed_rows(bound, body))
    space = joint_space(robot)
    tol, resolution, slots, chunk = jnp.asarray(1e-12), jnp.asarray(32.0), 32, 8

    def start(a, d):
        a_clear = evaluate(a[:, None, :])[0][:, 0]
        return edges.start_edges(a, d, a_clear, rows, slots, "certified", tol, resolution, space)

    # the arm folded away from both balls, a short sweep of the elbow
    edge = start(jnp.array([[-2.0, 2.4]]), jnp.array([[0.0, 0.05]]))
    j, wanted = edges.gap_states(edge, slots, chunk)
    assert bool(wanted[0]) and int(j[0, 0]) == slots  # the end state first
    edge = edges.absorb(edge, j, evaluate(edges.states_at(edge, j, slots)), "certified", tol, False)
    assert not bool(edges.gap_states(edge, slots, chunk)[1][0])  # settled after one round
    assert int(jnp.sum(edge.known)) <= 1 + chunk
    assert float(edges.good_fraction(edge, slots, "certified")[0][0]) == 1.0

    rng = np.random.default_rng(3)
    a = rng.uniform(-np.pi, np.pi, (96, 2))
    a = a[~np.asarray(collision.check(robot, a, world).collides)]
    d = rng.normal(size=a.shape) * 0.8
    a, d = jnp.asarray(a), jnp.asarray(d)
    gap = np.asarray(
        jax.jit(
            lambda a, d: edges.edge_check(
                evaluate, rows, a, d, slots, chunk, "certified", tol, resolution, space
            )
        )(a, d)
    )
    every = start(a, d)
    j = jnp.broadcast_to(jnp.arange(slots + 1), (a.shape[0], slots + 1))
    every = edges.absorb(
        every, j, evaluate(edges.states_at(every, j, slots)), "certified", tol, False
    )
    uniform = np.asarray(edges.good_fraction(every, slots, "certified")[0])
    assert np.all(gap >= uniform - 1e-12) and np.any(gap < 1.0) and np.any(gap >= 1.0)
    s = np.linspace(0.0, 1.0, 801)
    states = a[:, None] + (s[None, :, None] * gap[:, None, None]) * d[:, None]
    assert np.min(np.asarray(collision.check(robot, states, world).clearance)) > 0


# ----------------------------------------------------------------------------- worlds
def test_padding_worlds_changes_no_clearance():
    """Worlds of every kind, each lacking some kind another has, stacked: every kind padded to
    a multiple of the bucket, every clearance as in the world alone."""
    robot, _ = _planar_scene()
    w1 = collision.World.create(
        spheres=collision.Spheres.create([[1.2, 0.6, 0.0]], 0.25),
        boxes=collision.Boxes.create([[0.0, -1.0, 0.0]], [[0.3, 0.1, 0.1]]),
    )
    w2 = collision.World.create(
        spheres=collision.Spheres.create([[1.2, 0.6, 0.0], [-0.3, 1.2, 0.0]], [0.25, 0.1]),
        cylinders=collision.Cylinders.create([[-1.0, -0.4, 0.0]], 0.2, 0.3, axis=[1.0, 0.0, 1.0]),
    )
    w3 = collision.World.create(
        capsules=collision.Capsules.create([[0.5, -1.2, 0.0]], [[0.9, -1.0, 0.0]], 0.1)
    )
    stacked = collider.stack_worlds([w1, w2, w3])
    bucket = collision.OBSTACLE_BUCKET
    assert stacked.spheres.radius.shape == (3, bucket)
    assert stacked.capsules.radius.shape == (3, bucket)
    assert stacked.boxes.half_extents.shape == (3, bucket, 3)
    assert stacked.cylinders.radius.shape == (3, bucket)
    assert stacked.halfspaces.offset.shape == (3, 0)
    q = np.random.default_rng(2).uniform(-np.pi, np.pi, (50, 2))
    for i, w in enumerate((w1, w2, w3)):
        padded = jax.tree.map(lambda x, i=i: x[i], stacked)
        got = np.asarray(collision.check(robot, q, padded).clearance)
        want = np.asarray(collision.check(robot, q, w).clearance)
        assert np.allclose(got, want, rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------- MotionBenchMaker
SCENE = textwrap.dedent(
    """\
    name: ""
    world:
      collision_objects:
        - id: table
          primitives:
            - type: box
              dimensions: [1.0, 0.5, 0.1]
          primitive_poses:
            - position: [0.5, 0, 0.2]
              orientation: [0, 0, 0.7071067811865476, 0.7071067811865476]
        - id: can
          pose: {position: [0, 0, 1.0], orientation: [0, 0, 0, 1]}
          primitives:
            - type: cylinder
              dimensions: [0.2, 0.05]
          primitive_poses:
            - position: [0.1, 0, 0]
              orientation: [0.7071067811865476, 0, 0, 0.7071067811865476]
        - id: ball
          primitives: [{type: sphere, dimensions: [0.1]}]
          primitive_poses: [{position: [0, 1, 0], orientation: [0, 0, 0, 1]}]
    """
)


def _mbm_module():
    spec = importlib.util.spec_from_file_location(
        "mbm_problems", ROOT / "benchmarks/mbm_problems.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


REQUEST = textwrap.dedent(
    """\
    group_name: arm
    start_state:
      joint_state:
        name: [a, b, finger]
        position: [0.1, -0.2, 0.04]
    goal_constraints:
      - joint_constraints:
          - {joint_name: b, position: 0.5}
          - {joint_name: a, position: -1.5}
    """
)


def test_the_mbm_reader_pairs_scenes_and_requests(tmp_path):
    pytest.importorskip("yaml")
    mbm = _mbm_module()
    archive = tmp_path / "problems.tar.bz2"
    with tarfile.open(archive, "w:bz2") as tar:
        for name, text in [
            ("problems/box_robot/scene0002.yaml", SCENE),
            ("problems/box_robot/request0002.yaml", REQUEST),
            ("problems/cage_robot/scene0001.yaml", SCENE.replace("0.5, 0, 0.2", "0.5, 0, 0.3")),
            ("problems/cage_robot/request0001.yaml", REQUEST),
        ]:
            data = text.encode()
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    sets = mbm.read_problems(archive, ("a", "b"))
    assert sorted(sets) == ["box", "cage"]
    (p,) = sets["box"]
    assert p.index == 2 and np.allclose(p.start, [0.1, -0.2]) and np.allclose(p.goal, [-1.5, 0.5])
    cage = sets["cage"][0].world
    assert np.allclose(cage.boxes.center, [[0.5, 0.0, 0.3]])
    assert len(cage.cylinders) == 1 and np.allclose(cage.cylinders.axis, [[0.0, -1.0, 0.0]])
    with pytest.raises(ValueError, match="missing"):
        mbm.read_problems(archive, ("a", "c"))


# ----------------------------------------------------------------------------- options
def test_options_name_what_is_wrong():
    robot, world = _planar_scene()
    with pytest.raises(ValueError, match="mode"):
        motion.MotionOptions(mode="fast")
    with pytest.raises(ValueError, match="grid"):
        motion.MotionOptions(grid=16, path_points=32)
    for bad in (0.0, -1.0, float("nan"), "4", True):
        with pytest.raises(ValueError, match="domain"):
            motion.MotionOptions(domain=bad)
    assert motion.MotionOptions(domain=float("inf")).domain == float("inf")
    assert motion.MotionOptions().team is None and motion.MotionOptions(lanes=4, team=8).team == 8
    for bad in (0, 2.0, True, "4"):
        with pytest.raises(ValueError, match="team"):
            motion.MotionOptions(team=bad)
    with pytest.raises(ValueError, match="multiple of team"):
        motion.MotionOptions(lanes=6, team=4)
    with pytest.raises(ValueError, match="exactly one"):
        motion.plan(robot, [0.0, 0.0], world)
    with pytest.raises(ValueError, match="start"):
        motion.plan(robot, [0.0, 0.0, 0.0], world, goal=[1.0, 0.0])
    assert "SOLVED" in motion.describe(0)


# ----------------------------------------------------------------------------- plans
def _dense_free(robot, world, knots, steps=64):
    """Every straight edge between the knots checked at ``steps`` states per 0.1 rad."""
    out = []
    for a, b in zip(knots[:-1], knots[1:], strict=True):
        k = max(2, int(np.ceil(np.linalg.norm(b - a) * steps * 10)))
        out.append(a + np.linspace(0.0, 1.0, k)[:, None] * (b - a))
    states = np.concatenate(out)
    return float(np.min(np.asarray(collision.check(robot, states, world).clearance)))


@pytest.mark.slow
@pytest.mark.parametrize("mode", edges.MODES)
def test_a_planar_arm_plans_around_obstacles(mode):
    robot, world = _planar_scene()
    start, goal = np.array([0.0, 0.3]), np.array([2.5, 0.4])
    small = dict(SMALL, mode=mode)
    result = motion.plan(robot, start, world, goal=goal, **small)
    assert result.status[0] == motion.MotionStatus.SOLVED
    k = int(result.path_count[0])
    path = result.path[0, :k]
    assert np.allclose(path[0], start)
    space = joint_space(robot)
    assert float(space.distance(jnp.asarray(path[-1]), jnp.asarray(goal))) < 1e-9
    assert _dense_free(robot, world, path) > 0
    simple = result.simplified[0, : int(result.simplified_count[0])]
    assert _dense_free(robot, world, simple) > 0
    assert bool(result.certified[0]) == (mode == "certified")
    traj = result.trajectory
    n_valid = int(traj.count[0])
    q = np.asarray(traj.q.p[0, :n_valid])
    assert np.allclose(q[0], start, atol=1e-9)
    # the last sample is within one period of the end, where the arm comes to rest
    assert float(space.distance(jnp.asarray(q[-1]), jnp.asarray(goal))) < 1e-3
    # the timed trajectory is free too (densely along its samples)
    assert float(np.min(np.asarray(collision.check(robot, q, world).clearance))) > 0
    # the same shapes again: nothing compiles
    kernels = [motion.planner._search_jit, motion.planner._simplify_jit]
    kernels += [motion.planner._certify_jit] if mode == "certified" else []
    before = [k.jitted._cache_size() for k in kernels]
    motion.plan(robot, start + 0.01, world, goal=goal, **small)
    assert [k.jitted._cache_size() for k in kernels] == before


@pytest.mark.slow
def test_many_problems_each_keep_their_own_simplified_path():
    """More problems than a simplification group (sorted by waypoint count, simplified in
    groups, put back): each problem's simplified path runs from its own start to its own
    goal, free under a dense check."""
    robot, world = _planar_scene()
    rng = np.random.default_rng(4)
    q = rng.uniform(-np.pi, np.pi, (200, 2))
    q = q[~np.asarray(collision.check(robot, q, world).collides)]
    b = motion.planner.SIMPLIFY_GROUP + 3
    starts, goals = q[:b], q[b : 2 * b]
    result = motion.plan(robot, starts, world, goal=goals, **SMALL, period=None)
    space = joint_space(robot)
    for i in range(b):
        assert result.status[i] == motion.MotionStatus.SOLVED
        simple = result.simplified[i, : int(result.simplified_count[i])]
        assert float(space.distance(jnp.asarray(simple[0]), jnp.asarray(starts[i]))) < 1e-9
        assert float(space.distance(jnp.asarray(simple[-1]), jnp.asarray(goals[i]))) < 1e-9
        assert _dense_free(robot, world, simple) > 0


@pytest.mark.slow
def test_a_large_batch_plans_in_parts_each_as_its_problems_alone(monkeypatch):
    """Parts of ``PART_PROBLEMS`` problems (4 here; the last part filled with copies of its
    last problem, never searched) on two host threads: each part's rows equal a call with
    its problems alone, one world per problem; and one thread gives the same as two."""
    from jaxkin import _batching

    monkeypatch.setattr(motion.planner, "PART_PROBLEMS", 4)
    robot, world = _planar_scene()
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (200, 2))
    q = q[~np.asarray(collision.check(robot, q, world).collides)]
    b = 9
    starts, goals = q[:b].copy(), q[b : 2 * b]
    starts[5] = [0.6, 0.0]  # the forearm in the first ball
    worlds = [world] * b
    options = dict(SMALL, period=None)
    monkeypatch.setattr(_batching, "_requested", 2)
    whole = motion.plan(robot, starts, worlds, goal=goals, **options)
    assert whole.seconds["parts"] > 0
    names = motion.status_names(whole.status).tolist()
    assert names == ["SOLVED"] * 5 + ["INVALID_START"] + ["SOLVED"] * 3
    for first in (0, 4, 8):
        rows = slice(first, first + 4)
        alone = motion.plan(robot, starts[rows], worlds[rows], goal=goals[rows], **options)
        for field in ("status", "path", "path_count", "simplified", "simplified_count"):
            assert np.array_equal(getattr(whole, field)[rows], getattr(alone, field)), field
    simple = whole.simplified[8, : int(whole.simplified_count[8])]
    assert _dense_free(robot, world, simple) > 0
    monkeypatch.setattr(_batching, "_requested", 1)
    serial_run = motion.plan(robot, starts, worlds, goal=goals, **options)
    assert np.array_equal(serial_run.simplified, whole.simplified)


@pytest.mark.slow
def test_teams_that_join_a_problem_do_not_spend_its_budget():
    """The arm's upper link is held in a pocket between two balls, the goal outside it: no
    path. Four teams of one lane, one problem: the three that join it are extra attempts, so
    the problem ends NO_PATH when its own team has settled max_iterations edges, with about
    four times as many settled in all (they once shared the budget and ended it at 1x)."""
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.05)
    centres = [[0.5 * np.cos(a), 0.5 * np.sin(a), 0.0] for a in (0.6, -0.6)]
    world = collision.World.create(spheres=collision.Spheres.create(centres, 0.12))
    start, goal = np.array([0.0, 0.3]), np.array([2.5, 0.4])
    assert not np.any(np.asarray(collision.check(robot, np.stack([start, goal]), world).collides))
    budget = 150
    options = dict(SMALL, lanes=4, team=1, max_iterations=budget, period=None, simplify=False)
    result = motion.plan(robot, start, world, goal=goal, **options)
    assert motion.status_names(result.status).tolist() == ["NO_PATH"]
    assert int(result.iterations[0]) >= 3 * budget


@pytest.mark.slow
def test_invalid_problems_get_their_status():
    robot, world = _planar_scene()
    inside = np.array([0.6, 0.0])  # the forearm in the first ball
    starts = np.array([[0.0, 0.3], inside, [np.nan, 0.0], [0.0, 0.3]])
    goals = np.array([[2.5, 0.4], [2.5, 0.4], [2.5, 0.4], inside])
    result = motion.plan(robot, starts, world, goal=goals, **SMALL, period=None)
    names = motion.status_names(result.status).tolist()
    assert names == ["SOLVED", "INVALID_START", "INVALID_INPUT", "INVALID_GOAL"]


@pytest.mark.slow
def test_a_target_point_becomes_collision_free_ik_goals():
    """Both elbow solutions of the planar arm are candidate goals; the plan reaches one whose
    tip is on the target."""
    import jaxkin

    robot, world = _planar_scene()
    target = np.array([-0.9, 0.9])
    start = np.array([0.0, 0.3])
    result = motion.plan(robot, start, world, target=target, **SMALL, period=None)
    assert result.status[0] == motion.MotionStatus.SOLVED
    tip = np.asarray(jaxkin.fk(robot, result.goal[0]).x.p)
    assert np.allclose(tip[:2], target, atol=1e-9)
    far = np.array([3.0, 0.0])
    unreachable = motion.plan(robot, start, world, target=far, **SMALL, period=None)
    assert unreachable.status[0] == motion.MotionStatus.UNREACHABLE_GOAL


@pytest.mark.slow
def test_the_motion_command_writes_a_timed_trajectory(tmp_path):
    pytest.importorskip("yaml")
    from jaxkin import cli

    scene_file = tmp_path / "scene.yaml"
    scene_file.write_text(
        "world:\n  collision_objects:\n    - id: ball\n"
        "      primitives: [{type: sphere, dimensions: [0.25]}]\n"
        "      primitive_poses: [{position: [1.2, 0.6, 0.0], orientation: [0, 0, 0, 1]}]\n"
    )
    out = tmp_path / "motion.csv"
    argv = [
        "motion",
        "planar-2r",
        "--l1",
        "1",
        "--l2",
        "0.8",
        "--link-radius",
        "0.05",
        "--from",
        "0,0.3",
        "--to",
        "2.5,0.4",
        "--world",
        str(scene_file),
        "-o",
        str(out),
    ]
    assert cli.main(argv) == 0
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    header = out.read_text().splitlines()[0].split(",")
    assert header[:3] == ["t", "q1", "q2"] and table.shape[1] == 7
    assert np.allclose(table[0, 1:3], [0.0, 0.3]) and np.all(np.diff(table[:, 0]) > 0)
    robot = serial.Planar2R(1.0, 0.8, link_radius=0.05)
    world = collision.read_moveit_scene(scene_file)
    assert not np.any(np.asarray(collision.check(robot, table[:, 1:3], world).collides))
    assert cli.main([*argv[:-6], "--to", "2.5", "--world", str(scene_file), "-o", str(out)]) == 2


def test_the_motion_command_passes_its_seed_and_names_it_when_no_path(
    tmp_path, monkeypatch, capsys
):
    """``--seed`` reaches ``motion.plan`` (a stand-in that records it and finds no path), and
    the error of a search that ran out of budget says another seed searches again."""
    from jaxkin import cli

    seen = {}

    def no_path(robot, start, world, goal=None, **options):
        seen.update(options)
        # the command reads only the status of a plan that found nothing
        return types.SimpleNamespace(status=np.array([motion.MotionStatus.NO_PATH], np.int8))

    monkeypatch.setattr(motion, "plan", no_path)
    world_file = tmp_path / "world.json"
    world_file.write_text('{"units": "m", "spheres": [{"center": [1.2, 0.6, 0], "radius": 0.25}]}')
    argv = ["motion", "planar-2r", "--l1", "1", "--l2", "0.8", "--from", "0,0.3", "--to"]
    argv += ["2.5,0.4", "--world", str(world_file), "-o", str(tmp_path / "m.csv"), "--seed", "5"]
    assert cli.main(argv) == 2
    assert seen["seed"] == 5
    assert "another --seed" in capsys.readouterr().err
    assert not (tmp_path / "m.csv").exists()


def test_spline_slopes_and_compaction_against_scipy_and_numpy():
    """The simplification's natural cubic spline slopes (its own Thomas solver) equal SciPy's
    ``CubicSpline(bc_type="natural")`` derivative at the knots to 1e-14 relative (a strictly
    diagonally dominant system: the two solvers differ by a few ulp, 3e-16 measured), the
    first ``count`` knots of a padded array; the rows past ``count`` are zero. ``kept_order`` lists
    the kept indices in order (NumPy's ``flatnonzero``) and valid indices past them, for
    masks with none, some and all kept."""
    from scipy.interpolate import CubicSpline

    from jaxkin.motion import simplify

    rng = np.random.default_rng(7)
    for count in (3, 4, 9, 16):
        s = np.concatenate([[0.0], np.cumsum(rng.uniform(0.1, 2.0, 15))])
        knots = rng.normal(size=(16, 7))
        got = np.asarray(simplify.spline_slopes(jnp.asarray(knots), jnp.asarray(s), count))
        want = CubicSpline(s[:count], knots[:count], bc_type="natural")(s[:count], 1)
        scale = np.max(np.abs(want))
        np.testing.assert_allclose(got[:count], want, rtol=0, atol=1e-14 * scale)
        assert np.all(got[count:] == 0.0)
    for keep in (np.zeros(9, bool), rng.uniform(size=9) < 0.5, np.ones(9, bool)):
        order = np.asarray(simplify.kept_order(jnp.asarray(keep), 12))
        kept = np.flatnonzero(keep)
        np.testing.assert_array_equal(order[: kept.size], kept)
        assert np.all((order >= 0) & (order < 9))


@pytest.mark.slow  # the fast tier is near its 5 minutes
def test_spline_pieces_that_may_leave_the_joint_limits_are_bad():
    """``within_limits`` against SciPy's natural spline sampled densely: a piece it passes
    stays within the box at 201 samples (Bezier hull), every piece that leaves the box at a
    sample is refused, and a continuous joint has no box."""
    from scipy.interpolate import CubicSpline

    from jaxkin.motion import simplify

    space = joint_space(serial.Planar2R(1.0, 0.8)).astype(jnp.float64)
    box = dict(lower=jnp.array([-1.0, -1.0]), upper=jnp.array([1.0, 1.0]))
    space = dataclasses.replace(space, continuous=jnp.zeros(2), **box)
    rng = np.random.default_rng(5)
    passed = left = 0
    leaving = None
    for _ in range(40):
        knots = rng.uniform(-1.0, 1.0, (6, 2))
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(knots, axis=0), axis=1))])
        slopes = simplify.spline_slopes(jnp.asarray(knots), jnp.asarray(s), 6)
        inside = np.asarray(
            simplify.within_limits(space, jnp.asarray(knots), jnp.asarray(s), slopes, 6)
        )
        spline = CubicSpline(s, knots, bc_type="natural")
        for k in range(5):
            q = spline(np.linspace(s[k], s[k + 1], 201))
            out = np.any(np.abs(q) > 1.0 + 1e-12)
            assert not (inside[k] and out)
            passed += bool(inside[k])
            left += bool(out)
            if out:
                leaving = (jnp.asarray(knots), jnp.asarray(s), slopes)
    assert passed and left  # both kinds among the pieces
    free = dataclasses.replace(space, continuous=jnp.array([1.0, 1.0]))
    assert np.all(np.asarray(simplify.within_limits(free, *leaving, 6)))
