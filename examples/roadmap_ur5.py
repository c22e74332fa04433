"""A batched roadmap for the UR5: every sample and every edge checked in a few compiled calls.

A probabilistic roadmap built the batched way: draw N random configurations of the UR5 of
``examples/ur5.urdf`` (its skeleton body, 5 cm thick) within [-pi, pi] per joint, keep the
valid ones with one ``collision.check`` call, join each to its k nearest neighbours in joint
space, validate all those edges with one ``collision.validate_motions`` call (32 states per
unit of joint distance), and find the shortest path from START to GOAL on the graph of valid
edges (scipy's Dijkstra). The scene is the one of ``examples/ompl_ur5.py``: a table, a wall
between START and GOAL, a post and a ball.

Run: ``python examples/roadmap_ur5.py [--output-dir DIR] [--samples N] [--neighbours K]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

from jaxkin import collision, serial

jax.config.update("jax_enable_x64", True)  # an application choice; the library never sets it

URDF = Path(__file__).resolve().parent / "ur5.urdf"
RESOLUTION = 32.0
START = np.array([-1.2, -1.2, 1.6, -1.9, -1.57, 0.0])
GOAL = np.array([1.2, -1.2, 1.6, -1.9, -1.57, 0.0])


def make_world() -> collision.World:
    return collision.World.create(
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [-0.06]),
        boxes=collision.Boxes.create(center=[[0.55, 0.0, 0.15]], half_extents=[[0.12, 0.05, 0.15]]),
        capsules=collision.Capsules.create([[-0.5, -0.5, -0.1]], [[-0.5, -0.5, 0.6]], 0.06),
        spheres=collision.Spheres.create([[0.0, 0.6, 0.7]], 0.1),
    )


def main(argv: list[str] | None = None) -> int:
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=Path("."), help="where files go")
    parser.add_argument("--samples", type=int, default=512, help="random configurations")
    parser.add_argument("--neighbours", type=int, default=8, help="edges per node")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    robot = serial.from_urdf(URDF, "tool0").with_link_radius(0.05)
    world = make_world()
    rng = np.random.default_rng(args.seed)

    begin = time.perf_counter()
    samples = rng.uniform(-np.pi, np.pi, (args.samples, robot.n_joints))
    free = ~np.asarray(collision.check(robot, samples, world).collides)
    nodes = np.concatenate([START[None], GOAL[None], samples[free]])
    print(f"nodes: {len(nodes)} ({int(free.sum())} of {args.samples} samples free)")

    k = min(args.neighbours, len(nodes) - 1)
    gaps = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    near = np.argsort(gaps, axis=1)[:, :k]
    i = np.repeat(np.arange(len(nodes)), k)
    j = near.ravel()
    pairs = np.unique(np.stack([np.minimum(i, j), np.maximum(i, j)], -1), axis=0)  # once each
    edges = collision.validate_motions(
        robot, nodes[pairs[:, 0]], nodes[pairs[:, 1]], world, RESOLUTION
    )
    valid = np.asarray(edges.valid)
    print(f"edges: {int(valid.sum())} of {len(pairs)} valid, validated in one call")

    a, b = pairs[valid, 0], pairs[valid, 1]
    weights = gaps[a, b]
    graph = csr_matrix(
        (np.concatenate([weights, weights]), (np.concatenate([a, b]), np.concatenate([b, a]))),
        shape=(len(nodes), len(nodes)),
    )
    distance, previous = dijkstra(graph, indices=0, return_predecessors=True)
    seconds = time.perf_counter() - begin
    if not np.isfinite(distance[1]):
        print(f"no path from START to GOAL on the roadmap ({seconds:.2f} s)")
        return 1
    route = [1]
    while route[-1] != 0:
        route.append(int(previous[route[-1]]))
    waypoints = nodes[route[::-1]]
    print(
        f"shortest path: {len(waypoints)} waypoints, joint distance {distance[1]:.3f} rad "
        f"({seconds:.2f} s with compilation)"
    )
    again = collision.validate_motions(robot, waypoints[:-1], waypoints[1:], world, RESOLUTION)
    print(f"path re-checked: {int(np.sum(again.valid))} of {len(again.valid)} edges valid")
    args.output_dir.mkdir(parents=True, exist_ok=True)
    np.savetxt(
        args.output_dir / "roadmap_ur5_path.csv",
        waypoints,
        delimiter=",",
        header=",".join(robot.joint_names),
        comments="",
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
