"""The default collision covers against Pinocchio + coal on the original meshes (a script).

For the Panda and the UR5 of example-robot-data: random configurations within the joint
limits among random spheres and boxes (``--scenes`` scenes, each about half the configurations
colliding); coal decides every robot-obstacle pair and the SRDF's self pairs on the meshes
(``pinocchio.computeCollisions``); jaxkin's body (placed with Pinocchio's link poses) is
checked by the per-primitive queries (``collision.nearest_obstacles``,
``collision.self_distances``). Printed per robot and cover: primitives, the largest overshoot
bound, the cover's build time (CPU seconds), collisions missed (must be 0) and the false
positives, the share of the configurations free on the meshes that the cover flags (overall,
robot-world, self). With ``--breakdown``, also where the false positives come from: per link,
the share of the configurations free on the meshes whose link's primitives touch an obstacle,
and per checked link pair, the share of those free of self-collision on the meshes whose
covers touch. ``docs/performance.md`` records a run.

    .venv/bin/python benchmarks/cover_quality.py [--n 1000] [--scenes 3] [--robots panda ur5]
        [--spheres 6] [--boxes 4] [--bounds 0.005 ...] [--breakdown]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import numpy as np

from jaxkin import collision as col

ROBOTS = {
    "panda": ("panda_description/urdf/panda.urdf", "panda_description/srdf/panda.srdf"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "ur_description/srdf/ur5.srdf"),
}


def robots_folder() -> Path:
    for base in map(Path, sys.path):
        root = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if root.is_dir():
            return root
    raise SystemExit("example-robot-data's robots folder not found")


def scene(rng: np.random.Generator, spheres: int, boxes: int, fixed: list) -> dict:
    """Spheres (radius 3-12 cm) and boxes (half-edges 2-10 cm) about the robot, each at least
    5 cm from the links that never move (``fixed``: coal geometries and placements), which
    would otherwise decide every configuration of the scene alike."""
    import coal
    from scipy.spatial.transform import Rotation

    reach = 0.9
    lo, hi = [-reach, -reach, -0.2], [reach, reach, reach]

    def clear(shape, rotation, centre) -> bool:
        pose = coal.Transform3s(rotation, centre)
        request, result = coal.DistanceRequest(), coal.DistanceResult()
        return all(
            coal.distance(shape, pose, geometry, place, request, result) >= 0.05
            for geometry, place in fixed
        )

    out = {key: [] for key in ("s_center", "s_radius", "b_center", "b_half", "b_rot")}
    while len(out["s_radius"]) < spheres:
        centre, radius = rng.uniform(lo, hi), rng.uniform(0.03, 0.12)
        if clear(coal.Sphere(radius), np.eye(3), centre):
            out["s_center"].append(centre)
            out["s_radius"].append(radius)
    while len(out["b_half"]) < boxes:
        centre, half = rng.uniform(lo, hi), rng.uniform(0.02, 0.1, 3)
        rotation = Rotation.random(random_state=rng.integers(1 << 31)).as_matrix()
        if clear(coal.Box(*(2.0 * half)), rotation, centre):
            out["b_center"].append(centre)
            out["b_half"].append(half)
            out["b_rot"].append(rotation)
    return {key: np.array(value) for key, value in out.items()}


def fixed_links(path: Path, package: str) -> list:
    """The coal geometries of the links no joint moves, with their placements."""
    import coal
    import pinocchio as pin

    model, cmodel, _ = pin.buildModelsFromUrdf(str(path), package)
    data, cdata = model.createData(), pin.GeometryData(cmodel)
    pin.updateGeometryPlacements(model, data, cmodel, cdata, pin.neutral(model))
    return [
        (obj.geometry, coal.Transform3s(cdata.oMg[g].rotation, cdata.oMg[g].translation))
        for g, obj in enumerate(cmodel.geometryObjects)
        if obj.parentJoint == 0
    ]


def coal_reference(path: Path, package: str, names: tuple, checked: set, obstacles: dict, qs):
    """Per configuration: colliding on the meshes (robot-world or the checked self pairs),
    colliding by a self pair, and every body link's pose (Pinocchio's frames)."""
    import coal
    import pinocchio as pin

    model, cmodel, _ = pin.buildModelsFromUrdf(str(path), package)
    robot_geoms = list(range(len(cmodel.geometryObjects)))
    ids = []
    for k, (c, r) in enumerate(zip(obstacles["s_center"], obstacles["s_radius"], strict=True)):
        obj = pin.GeometryObject(f"s{k}", 0, 0, pin.SE3(np.eye(3), c), coal.Sphere(r))
        ids.append(cmodel.addGeometryObject(obj))
    for k in range(len(obstacles["b_half"])):
        place = pin.SE3(obstacles["b_rot"][k], obstacles["b_center"][k])
        box = coal.Box(*(2.0 * obstacles["b_half"][k]))
        ids.append(cmodel.addGeometryObject(pin.GeometryObject(f"b{k}", 0, 0, place, box)))
    for g in robot_geoms:
        for o in ids:
            cmodel.addCollisionPair(pin.CollisionPair(g, o))
    link_of = {g: model.frames[cmodel.geometryObjects[g].parentFrame].name for g in robot_geoms}
    for a in robot_geoms:
        for b in robot_geoms[a + 1 :]:
            if frozenset((link_of[a], link_of[b])) in checked:
                cmodel.addCollisionPair(pin.CollisionPair(a, b))
    data, cdata = model.createData(), pin.GeometryData(cmodel)
    frames = [model.getFrameId(name) for name in names]
    n_world = len(robot_geoms) * len(ids)
    hit, self_hit = np.zeros(len(qs), bool), np.zeros(len(qs), bool)
    clearance = np.zeros(len(qs))
    poses = np.zeros((len(qs), len(frames), 4, 4))
    for k, q in enumerate(qs):
        hit[k] = pin.computeCollisions(model, data, cmodel, cdata, q, False)
        self_hit[k] = any(r.isCollision() for r in cdata.collisionResults[n_world:])
        pin.computeDistances(model, data, cmodel, cdata, q)
        clearance[k] = min(r.min_distance for r in cdata.distanceResults)
        pin.framesForwardKinematics(model, data, q)
        poses[k] = [data.oMf[f].homogeneous for f in frames]
    return hit, self_hit, poses, clearance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="configurations per scene")
    parser.add_argument("--scenes", type=int, default=3)
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS))
    parser.add_argument("--spheres", type=int, default=6, help="obstacle spheres per scene")
    parser.add_argument("--boxes", type=int, default=4, help="obstacle boxes per scene")
    parser.add_argument(
        "--bounds", type=float, nargs="*", default=[], help="max_overshoot besides the default"
    )
    parser.add_argument(
        "--breakdown", action="store_true", help="false positives per link and link pair"
    )
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    import pinocchio as pin

    root = robots_folder()
    print(f"{args.n} configurations x {args.scenes} scenes per robot")
    for robot in args.robots:
        urdf, srdf = ROBOTS[robot]
        path = root / urdf
        disabled = col.read_srdf_disabled(root / srdf)
        model = pin.buildModelFromUrdf(str(path))
        fixed = fixed_links(path, str(root.parent.parent))
        rng = np.random.default_rng(28)
        scenes = []
        for _ in range(args.scenes):
            obstacles = scene(rng, args.spheres, args.boxes, fixed)
            qs = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit, (args.n, model.nq))
            scenes.append((obstacles, qs))
        reference = None
        covers = {"default": {}} | {f"{100 * b:g} cm": {"max_overshoot": b} for b in args.bounds}
        for label, options in covers.items():
            start = time.process_time()
            read = col.body_from_urdf(path, **options)
            built = time.process_time() - start
            body = read.body
            link_pairs = col.self_collision_link_pairs(body, read.joints, disabled)
            pairs = col.SelfPairs.create(body, link_pairs)
            if reference is None:
                checked = {frozenset((body.links[i], body.links[j])) for i, j in link_pairs}
                reference = [
                    coal_reference(path, str(root.parent.parent), body.links, checked, o, qs)
                    for o, qs in scenes
                ]
                free = np.concatenate([c[~h] for h, _, _, c in reference])
                print(
                    f"{robot}: share of the free configurations within 0.5, 1, 2 cm of contact "
                    f"on the meshes: "
                    + ", ".join(f"{100 * np.mean(free < x):.1f} %" for x in (0.005, 0.01, 0.02))
                )
            hits, self_hits, world_hits, coal_hits, coal_self = [], [], [], [], []
            by_link, by_pair = [], []
            owner = np.concatenate([np.asarray(body.sphere_link), np.asarray(body.capsule_link)])
            owner = owner.astype(np.int64)
            for (obstacles, _), (hit, self_hit, poses, _) in zip(scenes, reference, strict=True):
                world = col.World.create(
                    spheres=col.Spheres.create(obstacles["s_center"], obstacles["s_radius"]),
                    boxes=col.Boxes.create(
                        obstacles["b_center"], obstacles["b_half"], obstacles["b_rot"]
                    ),
                )

                def distances(x, body, world, pairs=pairs):
                    spheres, capsules = body.place(x)
                    near = col.nearest_obstacles(spheres, capsules, world)
                    d_world = jax.numpy.concatenate([n.distance for n in near], axis=-1)
                    return d_world, col.self_distances(spheres, capsules, pairs)

                # a few configurations at a time: the per-primitive queries hold every pair
                run = jax.jit(distances)
                chunks = [run(poses[k : k + 20], body, world) for k in range(0, len(poses), 20)]
                d_world, d_self = (
                    np.concatenate([np.asarray(c[i]) for c in chunks]) for i in (0, 1)
                )
                touching = d_world <= 0  # (configurations, primitives)
                links = np.stack(
                    [touching[:, owner == k].any(axis=1) for k in range(len(body.links))], 1
                )
                by_link.append(links[~hit])
                by_pair.append((d_self <= 0)[~self_hit])
                in_world, in_self = touching.any(axis=1), (d_self <= 0).any(axis=1)
                hits.append(in_world | in_self)
                self_hits.append(in_self)
                world_hits.append(in_world)
                coal_hits.append(hit)
                coal_self.append(self_hit)
            mine, ref = np.concatenate(hits), np.concatenate(coal_hits)
            ref_self = np.concatenate(coal_self)
            missed = int(np.sum(ref & ~mine))
            fp = np.mean(mine[~ref])
            fp_world = np.mean(np.concatenate(world_hits)[~ref])
            fp_self = np.mean(np.concatenate(self_hits)[~ref_self])
            bound = max(read.overshoot.values())
            print(
                f"{robot:5s} {label:8s} {body.num_spheres:4d} spheres + {body.num_capsules:3d} "
                f"capsules, bound {100 * bound:.1f} cm, built in {built:5.2f} s CPU; "
                f"{ref.mean():.2f} colliding, missed {missed}, false positives "
                f"{100 * fp:.1f} % ({100 * fp_world:.1f} % world, {100 * fp_self:.1f} % self)",
                flush=True,
            )
            if args.breakdown:
                shares = 100 * np.concatenate(by_link).mean(axis=0)
                print("  world, per link: " + ", ".join(
                    f"{body.links[k]} {shares[k]:.2f} %" for k in np.argsort(-shares) if shares[k]
                ))  # fmt: skip
                shares = 100 * np.concatenate(by_pair).mean(axis=0)
                names = [f"{body.links[i]}-{body.links[j]}" for i, j in pairs.link_pairs]
                print("  self, per link pair: " + ", ".join(
                    f"{names[k]} {shares[k]:.2f} %" for k in np.argsort(-shares)[:8] if shares[k]
                ))  # fmt: skip


if __name__ == "__main__":
    main()
