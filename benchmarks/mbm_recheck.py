"""An independent re-check of planned motions: Pinocchio places the spheres, NumPy measures.

Written apart from jaxkin's collision layer: Pinocchio reads the spherised URDF's kinematics
and its ``<collision>`` spheres (``buildModelFromUrdf``, ``buildGeomFromUrdf``) and places
them (``updateGeometryPlacements``); the signed distances are written here in NumPy (the
obstacles' arrays only are read from the problem's ``collision.World``):

- sphere (centre ``p``, radius ``r``) to box: ``u = R^T (p - c)``, ``e = |u| - h``,
  ``|max(e, 0)| + min(max_i e_i, 0) - r``;
- to cylinder (centre ``c``, unit axis ``a``, half height ``h``, radius ``R``): ``z = (p - c)
  . a``, ``rho = |p - c - z a|``, outside ``|(max(rho - R, 0), max(|z| - h, 0))|``, inside
  ``-min(R - rho, h - |z|)``, minus ``r``;
- to sphere: ``|p - p'| - r - r'``; self pairs the same between the links jaxkin checks (its
  SRDF and adjacency pairs, by name).

A configuration is free when every distance is positive. ``dense_states`` samples a path at
``8 x`` the planner's resolution: straight edges at joint steps of at most ``1 / (8 x 32)``, a
spline (natural cubic through the knots in chord length, SciPy's ``CubicSpline``, not
jaxkin's) at parameter steps that bound the joint step the same way.
"""

from __future__ import annotations

import numpy as np
from mbm_problems import HERE, TIPS  # noqa: F401


class Reference:
    """The independent checker of one robot (``"panda"`` or ``"ur5"``)."""

    def __init__(self, name: str, link_pairs: list[tuple[str, str]], joint_names) -> None:
        import pinocchio as pin

        urdf = str(HERE / f"{name}_spherized.urdf")
        self.pin = pin
        self.model = pin.buildModelFromUrdf(urdf)
        self.geom = pin.buildGeomFromUrdf(self.model, urdf, pin.GeometryType.COLLISION)
        self.data = self.model.createData()
        self.gdata = pin.GeometryData(self.geom)
        self.radius = np.array([g.geometry.radius for g in self.geom.geometryObjects])
        frames = self.model.frames
        self.link = [frames[g.parentFrame].name for g in self.geom.geometryObjects]
        self.index = [self.model.getJointId(j) for j in joint_names]
        self.q_index = [self.model.joints[i].idx_q for i in self.index]
        pairs = []
        names = np.array(self.link)
        for a, b in link_pairs:
            ia, ib = np.flatnonzero(names == a), np.flatnonzero(names == b)
            pairs += [(i, j) for i in ia for j in ib]
        self.pairs = np.array(pairs, int).reshape(-1, 2)
        # each sphere's centre in its parent joint's frame (a sphere needs no rotation)
        objects = self.geom.geometryObjects
        self.parent = np.array([g.parentJoint for g in objects], int)
        self.local = np.array([g.placement.translation for g in objects]).reshape(-1, 3)

    def centres(self, q: np.ndarray) -> np.ndarray:
        """Sphere centres ``(S, 3)`` at joints ``q``."""
        pin = self.pin
        full = pin.neutral(self.model)
        full[self.q_index] = q
        pin.forwardKinematics(self.model, self.data, full)
        pin.updateGeometryPlacements(self.model, self.data, self.geom, self.gdata)
        return np.array([m.translation for m in self.gdata.oMg])

    def clearance(self, q: np.ndarray, world) -> float:
        """The smallest signed distance at ``q`` (world and self)."""
        return float(self.clearances(np.asarray(q)[None], world)[0])

    def joint_centres(self, q: np.ndarray) -> np.ndarray:
        """``centres`` from Pinocchio's joint placements alone: ``R_j c + t_j`` per sphere."""
        pin = self.pin
        full = pin.neutral(self.model)
        full[self.q_index] = q
        pin.forwardKinematics(self.model, self.data, full)
        rotation = np.array([m.rotation for m in self.data.oMi])[self.parent]
        translation = np.array([m.translation for m in self.data.oMi])[self.parent]
        return np.einsum("sij,sj->si", rotation, self.local) + translation

    def clearances(self, states: np.ndarray, world, block: int = 256) -> np.ndarray:
        """The smallest signed distance (world and self) per state ``(K, n) -> (K,)``:
        Pinocchio places the joints state by state, NumPy the spheres and the distances of
        a block of states at once."""
        out = []
        for start in range(0, len(states), block):
            p = np.stack([self.joint_centres(q) for q in states[start : start + block]])
            out.append(self._measure(p, world))
        return np.concatenate(out) if out else np.zeros(0)

    def _measure(self, p: np.ndarray, world) -> np.ndarray:
        """Per state the smallest signed distance of sphere centres ``p (K, S, 3)``."""
        r = self.radius
        out = [np.full(p.shape[0], np.inf)]
        boxes, cylinders, spheres = world.boxes, world.cylinders, world.spheres
        if len(boxes):
            rotation, centre = np.asarray(boxes.rotation), np.asarray(boxes.center)
            u = np.einsum("bji,ksbj->ksbi", rotation, p[:, :, None] - centre)
            e = np.abs(u) - np.asarray(boxes.half_extents)
            outside = np.linalg.norm(np.maximum(e, 0.0), axis=-1)
            inside = np.minimum(np.max(e, axis=-1), 0.0)
            out.append(np.min(outside + inside - r[:, None], axis=(1, 2)))
        if len(cylinders):
            axis = np.asarray(cylinders.axis)
            rel = p[:, :, None] - np.asarray(cylinders.center)
            z = np.einsum("ksci,ci->ksc", rel, axis)
            rho = np.linalg.norm(rel - z[..., None] * axis, axis=-1)
            dr = rho - np.asarray(cylinders.radius)
            dz = np.abs(z) - np.asarray(cylinders.half_length)
            outside = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0))
            inside = np.minimum(np.maximum(dr, dz), 0.0)
            out.append(np.min(outside + inside - r[:, None], axis=(1, 2)))
        if len(spheres):
            d = np.linalg.norm(p[:, :, None] - np.asarray(spheres.center), axis=-1)
            out.append(np.min(d - r[:, None] - np.asarray(spheres.radius), axis=(1, 2)))
        if len(self.pairs):
            i, j = self.pairs.T
            d = np.linalg.norm(p[:, i] - p[:, j], axis=-1) - r[i] - r[j]
            out.append(np.min(d, axis=1))
        return np.min(np.stack(out), axis=0)


def dense_states(knots: np.ndarray, smooth: bool, resolution: float = 8 * 32.0) -> np.ndarray:
    """States along a path's knots ``(K, n)``: straight edges, or the natural cubic spline in
    chord length when ``smooth``, at most ``1 / resolution`` apart (module docstring)."""
    steps = np.linalg.norm(np.diff(knots, axis=0), axis=-1)
    if len(knots) < 2:
        return knots
    if not smooth:
        out = [knots[:1]]
        for a, b, length in zip(knots[:-1], knots[1:], steps, strict=True):
            k = max(1, int(np.ceil(length * resolution)))
            t = np.arange(1, k + 1)[:, None] / k
            out.append(a + t * (b - a))
        return np.concatenate(out)
    from scipy.interpolate import CubicSpline

    s = np.concatenate([[0.0], np.cumsum(np.maximum(steps, 1e-9))])
    spline = CubicSpline(s, knots, bc_type="natural")
    fine = np.linspace(0.0, s[-1], 4097)
    speed = np.max(np.linalg.norm(spline(fine, 1), axis=-1))
    count = max(2, int(np.ceil(s[-1] * speed * resolution)) + 1)
    return spline(np.linspace(0.0, s[-1], count))
