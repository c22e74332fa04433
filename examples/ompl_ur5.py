"""OMPL plans a UR5 around obstacles with jaxkin as its collision checker (RRT-Connect).

The UR5 of ``examples/ur5.urdf`` (no ``<collision>`` elements: its body is the skeleton of
capsules from each link's origin to its child joints', 5 cm thick, ``with_link_radius``) must
swing from one side of a wall to the other over a table, among a post and a ball. OMPL's
RRT-Connect (PyPI ``ompl``, the ``ompl`` extra) searches the joint box; jaxkin answers its
state validity queries (``collision.collides``, the verdict alone, world and self-collision)
and, through a ``MotionValidator`` subclass, its motion queries: ``checkMotion(s1, s2)``
validates the whole edge in one compiled call (``collision.validate_motions`` with the verdict
alone, 32 states per unit of joint distance). Both go through compiled handles
(``jaxkin.compiled``), made before the planner's clock starts: a query is one call of a
compiled program, with no other work; run as a script, the example first turns on
``jaxkin.enable_low_latency()``, so that each query runs in the calling thread as one compiled
function. The path found is then re-checked edge by edge, every edge in one call.

Run: ``python examples/ompl_ur5.py [--output-dir DIR] [--seed N]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

import jaxkin
from jaxkin import collision, serial

jax.config.update("jax_enable_x64", True)  # an application choice; the library never sets it

URDF = Path(__file__).resolve().parent / "ur5.urdf"
RESOLUTION = 32.0  # states per unit of joint distance (rad)
SAMPLES = 128  # state slots per edge: one compilation for every edge up to 3.9 rad long
START = np.array([-1.2, -1.2, 1.6, -1.9, -1.57, 0.0])
GOAL = np.array([1.2, -1.2, 1.6, -1.9, -1.57, 0.0])


def make_robot() -> serial.Chain:
    return serial.from_urdf(URDF, "tool0").with_link_radius(0.05)


def make_world() -> collision.World:
    """A table top (the half-space z <= -0.06 under the base), a wall in front of the arm
    between START and GOAL, a post and a ball."""
    return collision.World.create(
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [-0.06]),
        boxes=collision.Boxes.create(center=[[0.55, 0.0, 0.15]], half_extents=[[0.12, 0.05, 0.15]]),
        capsules=collision.Capsules.create([[-0.5, -0.5, -0.1]], [[-0.5, -0.5, 0.6]], 0.06),
        spheres=collision.Spheres.create([[0.0, 0.6, 0.7]], 0.1),
    )


class JaxkinMotionValidator:
    """Builds the OMPL ``MotionValidator`` subclass (OMPL imported lazily: an optional extra)."""

    def __new__(cls, si, edge, n_joints):
        from ompl import base as ob

        # The class must not refer to si: OMPL holds the validator, so a class that did would
        # tie si to itself through C++ (a cycle Python's collector cannot see, which nanobind
        # reports as leaked instances at exit).
        class Validator(ob.MotionValidator):
            def __init__(self, information):
                super().__init__(information)
                self.edges = 0

            def checkMotion(self, s1, s2, *last_valid):
                a = np.array([[s1[i] for i in range(n_joints)]])
                b = np.array([[s2[i] for i in range(n_joints)]])
                self.edges += 1
                return bool(edge(a, b).valid[0])

        return Validator(si)


def compiled_checks(robot, world):
    """The planner's two queries compiled once: one state ``(6,)`` (the verdict) and one edge
    ``(1, 6)`` to ``(1, 6)`` (``SAMPLES`` states at ``RESOLUTION``)."""
    state = jaxkin.compiled(collision.collides, robot, world, batch=(), dtype=np.float64)
    edge = jaxkin.compiled(
        collision.validate_motions,
        robot,
        world,
        RESOLUTION,
        SAMPLES,
        batch=1,
        clearance=False,
        dtype=np.float64,
    )
    return state, edge


def plan(robot, world, start, goal, seed: int, budget: float = 20.0, checks=None):
    """RRT-Connect from ``start`` to ``goal`` (``checks``: ``compiled_checks``, made here
    when None); returns the path ``(K, 6)`` (None if none) and the number of state and
    motion queries."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LOG_WARN)
    ou.RNG.setSeed(seed)
    state_check, edge_check = compiled_checks(robot, world) if checks is None else checks
    n = robot.n_joints
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    lower, upper = np.asarray(robot.lower), np.asarray(robot.upper)
    for i in range(n):
        bounds.setLow(i, float(max(lower[i], -np.pi)))
        bounds.setHigh(i, float(min(upper[i], np.pi)))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    si = setup.getSpaceInformation()
    states = {"n": 0}

    def is_valid(state) -> bool:
        states["n"] += 1
        q = np.array([state[i] for i in range(n)])
        return not bool(state_check(q).collides)

    setup.setStateValidityChecker(is_valid)
    validator = JaxkinMotionValidator(si, edge_check, n)
    si.setMotionValidator(validator)
    begin, end = space.allocState(), space.allocState()
    for i in range(n):
        begin[i], end[i] = float(start[i]), float(goal[i])
    setup.setStartAndGoalStates(begin, end)
    setup.setPlanner(og.RRTConnect(si))
    # a condition polled by the planner itself: OMPL's timed one runs a thread of its own
    deadline = time.perf_counter() + budget
    stop = ob.PlannerTerminationCondition(lambda: time.perf_counter() > deadline)
    if not setup.solve(stop) or not setup.haveExactSolutionPath():
        return None, states["n"], validator.edges
    path = setup.getSolutionPath()
    waypoints = np.array(
        [[path.getState(k)[i] for i in range(n)] for k in range(path.getStateCount())]
    )
    return waypoints, states["n"], validator.edges


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    parser.add_argument("--seed", type=int, default=1, help="OMPL's random seed")
    args = parser.parse_args(argv)
    jaxkin.enable_compilation_cache()  # compiled programs kept for the next run
    robot, world = make_robot(), make_world()
    checks = compiled_checks(robot, world)  # compiled outside the planner's time budget
    ends = collision.check(robot, np.stack([START, GOAL]), world)
    print(f"start and goal clearances: {np.round(np.asarray(ends.clearance), 3)} m")
    # the first call compiles (outside the planner's time budget); the planner's reuse it
    straight = collision.validate_motions(
        robot, START[None], GOAL[None], world, RESOLUTION, samples=SAMPLES
    )
    print(
        f"straight joint-space line valid: {bool(straight.valid[0])} "
        f"(first collision at t = {float(straight.fraction[0]):.3f})"
    )
    begin = time.perf_counter()
    waypoints, n_states, n_edges = plan(robot, world, START, GOAL, args.seed, checks=checks)
    seconds = time.perf_counter() - begin
    if waypoints is None:
        print("RRT-Connect: no path found")
        return 1
    print(
        f"RRT-Connect: path of {len(waypoints)} waypoints in {seconds:.2f} s "
        f"({n_states} state checks, {n_edges} motion checks)"
    )
    again = collision.validate_motions(robot, waypoints[:-1], waypoints[1:], world, RESOLUTION)
    print(
        f"every edge re-checked in one call: {int(np.sum(again.valid))} of {len(again.valid)} "
        f"valid, smallest clearance {float(np.min(again.clearance)):.3f} m"
    )
    args.output_dir.mkdir(parents=True, exist_ok=True)
    np.savetxt(
        args.output_dir / "ompl_ur5_path.csv",
        waypoints,
        delimiter=",",
        header=",".join(robot.joint_names),
        comments="",
    )
    return 0


if __name__ == "__main__":
    jaxkin.enable_low_latency()  # before JAX's first computation: each query runs inline
    raise SystemExit(main())
