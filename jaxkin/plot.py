"""Plots of jaxkin results (needs the optional ``plot`` extra: ``pip install 'jaxkin[plot]'``).

Every function builds a ``matplotlib.figure.Figure`` directly (no ``pyplot`` global state, no
GUI: rendering uses the Agg canvas, so it works headless, in threads and in notebooks), returns
it, and with ``path=`` also saves it (atomically: ``jaxkin._output.atomic_write``). The saved
image is ``figsize * dpi`` pixels (no tight bounding box).

* ``joint_trajectories``: joint positions, velocities and accelerations against time, one
  column per joint, with the samples whose status is not OK shaded (a colour per status).
* ``scara_pose`` / ``delta_pose``: the robot drawn at one instant (SCARA plan and side views;
  Delta in 3-D), optionally with the end point's path.
* ``workspace_slices``, ``workspace_cloud``, ``workspace_overview``: the reachable voxels of a
  ``jaxkin.workspace.WorkspaceResult`` as z slices, as a 3-D point cloud, or both.
* ``cost_curves``: optimisation cost against iteration (log scale by default).
* ``robot_scene``: any robot with a collision body (a URDF arm, the analytic arms, the SCARA,
  the Delta) in 3-D: its body's spheres and capsules at joints ``q`` (a colour per link), the
  obstacles of a ``collision.World`` and a planned motion (the body at a few of its samples,
  fainter towards the start, and the tool's path by forward kinematics); ``scene_meshes``:
  the triangles it draws, by artist.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from . import _validate, collision
from ._output import atomic_write
from .collision import surfaces
from .robot import fk
from .status import Status

__all__ = [
    "INSTALL_HINT",
    "cost_curves",
    "delta_points",
    "delta_pose",
    "joint_trajectories",
    "require_matplotlib",
    "robot_scene",
    "save",
    "scene_meshes",
    "scara_pose",
    "workspace_cloud",
    "workspace_overview",
    "workspace_slices",
]

INSTALL_HINT = "jaxkin.plot needs matplotlib: pip install 'jaxkin[plot]'"
_STATUS_COLOURS = {
    "UNREACHABLE": "tab:red",
    "SINGULAR_EXTENDED": "tab:orange",
    "SINGULAR_FOLDED": "gold",
    "SINGULAR_COINCIDENT": "tab:purple",
    "SINGULAR": "tab:orange",
    "NOT_CONVERGED": "tab:brown",
    "OUT_OF_LIMITS": "tab:pink",
    "INVALID_INPUT": "tab:gray",
}


def require_matplotlib() -> Any:
    """Import matplotlib, or raise ``ImportError`` saying how to install it."""
    try:
        import matplotlib
        import matplotlib.figure  # noqa: F401
    except ImportError:
        raise ImportError(INSTALL_HINT) from None
    return matplotlib


def _figure(figsize: tuple[float, float], dpi: float) -> Any:
    require_matplotlib()
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, dpi=dpi, layout="constrained")


def save(fig: Any, path: str | os.PathLike, dpi: float | None = None) -> None:
    """Save ``fig`` to ``path`` atomically (format from the suffix, PNG by default)."""
    fmt = os.path.splitext(os.fspath(path))[1].lstrip(".").lower() or "png"
    with atomic_write(path, "wb") as f:
        fig.savefig(f, format=fmt, dpi=dpi if dpi is not None else fig.dpi)


def _finish(fig: Any, path: str | os.PathLike | None) -> Any:
    if path is not None:
        save(fig, path)
    return fig


def _arrays(x: Any) -> Any:
    return np.asarray(x.p if hasattr(x, "p") and hasattr(x, "v") else x)


def _status_runs(status: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs ``(start, stop, code)`` of equal non-OK codes."""
    runs, start = [], 0
    for i in range(1, len(status) + 1):
        if i == len(status) or status[i] != status[start]:
            if status[start] != 0:
                runs.append((start, i, int(status[start])))
            start = i
    return runs


def joint_trajectories(
    t: Any,
    q: Any,
    qd: Any = None,
    qdd: Any = None,
    status: Any = None,
    names: Sequence[str] | None = None,
    candidate: Any = None,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (10.0, 7.0),
    dpi: float = 100.0,
    max_candidates: int = 10,
) -> Any:
    """Joint positions (and velocities, accelerations) against time with status shading.

    Args:
        t: times ``(N,)``.
        q: joint positions ``(N, n)`` (or a ``Jet``: its ``v``/``a`` fill ``qd``/``qdd``).
        qd, qdd: velocities and accelerations ``(N, n)``, optional.
        status: ``(N,)`` status codes; samples that are not OK are shaded by status (for the
            first candidate when there are several; the others' failures are marked ``x``).
        names: joint names for the titles.
        candidate: ``(N,)`` labels of independent trajectories (drawn as separate lines, at
            most ``max_candidates``).
        path: where to save the figure (PNG), optional.

    Returns:
        The ``Figure`` (rows: position, velocity, acceleration; one column per joint).
    """
    if hasattr(q, "p") and hasattr(q, "v"):
        q, qd, qdd = (np.asarray(x) for x in (q.p, q.v, q.a))
    t = np.asarray(t, float)
    blocks = [
        (np.asarray(b, float), label)
        for b, label in ((q, ""), (qd, "rate"), (qdd, "acceleration"))
        if b is not None
    ]
    n_joints = blocks[0][0].shape[-1]
    names = list(names) if names is not None else [f"q{j + 1}" for j in range(n_joints)]
    status = None if status is None else np.asarray(status).astype(int)
    candidate = np.zeros(len(t), int) if candidate is None else np.asarray(candidate)
    labels = list(dict.fromkeys(candidate.tolist()))[:max_candidates]
    fig = _figure(figsize, dpi)
    axes = fig.subplots(len(blocks), n_joints, squeeze=False, sharex=True)
    shaded: dict[str, Any] = {}
    for row, (block, kind) in enumerate(blocks):
        for j in range(n_joints):
            ax = axes[row, j]
            for k, label in enumerate(labels):
                rows = np.flatnonzero(candidate == label)
                rows = rows[np.argsort(t[rows], kind="stable")]
                ax.plot(
                    t[rows],
                    block[rows, j],
                    lw=1.0,
                    label=f"candidate {label}" if len(labels) > 1 else None,
                )
                if status is None:
                    continue
                if k == 0:
                    for start, stop, code in _status_runs(status[rows]):
                        name = Status(code).name
                        lo = t[rows][start]
                        hi = t[rows][min(stop, len(rows) - 1)]
                        span = ax.axvspan(
                            lo, hi, color=_STATUS_COLOURS.get(name, "tab:red"), alpha=0.25, lw=0
                        )
                        shaded.setdefault(name, span)
                else:
                    failed = rows[status[rows] != Status.OK]
                    ax.plot(t[failed], block[failed, j], "x", ms=4, color="k")
            _readable_limits(ax, block[:, j])
            title = names[j] if not kind else f"{names[j]} {kind}"
            ax.set_title(title, fontsize=9)
            ax.grid(alpha=0.3)
            if row == len(blocks) - 1:
                ax.set_xlabel("t")
    if shaded:
        fig.legend(
            list(shaded.values()),
            list(shaded),
            loc="outside lower center",
            ncol=min(len(shaded), 4),
            fontsize=8,
        )
    if len(labels) > 1:
        axes[0, 0].legend(fontsize=7)
    return _finish(fig, path)


def _readable_limits(ax: Any, values: np.ndarray) -> None:
    # A constant signal plus rounding noise (e.g. 1e-11) would be zoomed into noise: show a
    # band of +-10 % (at least +-1e-3) around it instead.
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return
    centre, span = float(np.mean(finite)), float(np.ptp(finite))
    scale = max(abs(centre), 1e-2)
    if span < 1e-8 * scale:
        ax.set_ylim(centre - 0.1 * scale, centre + 0.1 * scale)


def scara_pose(
    robot: Any,
    q: Any,
    trace: Any = None,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (9.0, 4.5),
    dpi: float = 100.0,
) -> Any:
    """A SCARA (``jaxkin.scara.Scara``) at joint values ``q = (theta1, theta2, l3)``.

    Left: plan view (x-y) of the column, arm O-B and forearm B-C; right: side view (x-z) with
    the column, the arm plane at ``l_oa`` and the prismatic joint down to D. ``trace``
    ``(N, 3)`` optionally draws the end point's path. Elbow ``B = l_ab (cos theta1,
    sin theta1)``; ``D`` comes from ``jaxkin.fk``.
    """
    q = np.asarray(_arrays(q), float).reshape(3)
    d = np.asarray(fk(robot, q).x.p, float)
    l_oa, l_ab = float(robot.l_oa), float(robot.l_ab)
    b = l_ab * np.array([np.cos(q[0]), np.sin(q[0])])
    fig = _figure(figsize, dpi)
    plan, side = fig.subplots(1, 2)
    if trace is not None:
        trace = np.asarray(_arrays(trace), float)
        plan.plot(trace[:, 0], trace[:, 1], "k-", lw=0.7, label="path of D")
        side.plot(trace[:, 0], trace[:, 2], "k-", lw=0.7)
    plan.plot([0, b[0], d[0]], [0, b[1], d[1]], "o-", color="tab:blue", lw=2)
    plan.annotate("A", (0, 0)), plan.annotate("B", b), plan.annotate("C, D", d[:2])
    reach = l_ab + float(robot.l_bc)
    plan.add_patch(_circle((0, 0), reach))
    plan.set_aspect("equal")
    plan.set_xlabel("x")
    plan.set_ylabel("y")
    plan.set_title(f"plan view, theta1 = {q[0]:.3f}, theta2 = {q[1]:.3f}", fontsize=9)
    side.plot([0, 0, b[0], d[0], d[0]], [0, l_oa, l_oa, l_oa, d[2]], "o-", color="tab:blue", lw=2)
    side.axhline(0.0, color="k", lw=0.8)
    side.set_aspect("equal")
    side.set_xlabel("x")
    side.set_ylabel("z")
    side.set_title(f"side view, l3 = {q[2]:.3f}", fontsize=9)
    if trace is not None:
        plan.legend(fontsize=7)
    return _finish(fig, path)


def _circle(centre: tuple[float, float], radius: float) -> Any:
    from matplotlib.patches import Circle

    return Circle(centre, radius, fill=False, ls="--", lw=0.6, color="gray")


def delta_points(robot: Any, theta: Any, p: Any) -> dict[str, np.ndarray]:
    """Joint positions for drawing a Delta (``jaxkin.delta`` convention), each ``(3, 3)``:
    base joints ``A_i = r_base u_i``, elbows ``E_i = A_i + l_arm (cos theta_i u_i -
    sin theta_i e_z)`` and platform joints ``D_i = p + r_platform u_i``, with
    ``u_i = (cos phi_i, sin phi_i, 0)``, ``phi_i = -90 + 120 (i - 1)`` degrees."""
    theta = np.asarray(theta, float).reshape(3)
    p = np.asarray(p, float).reshape(3)
    phi = np.deg2rad(-90.0 + 120.0 * np.arange(3))
    u = np.stack([np.cos(phi), np.sin(phi), np.zeros(3)], axis=-1)
    e_z = np.array([0.0, 0.0, 1.0])
    base = float(robot.r_base) * u
    elbow = base + float(robot.l_arm) * (np.cos(theta)[:, None] * u - np.sin(theta)[:, None] * e_z)
    return {"base": base, "elbow": elbow, "platform": p + float(robot.r_platform) * u}


def delta_pose(
    robot: Any,
    theta: Any,
    p: Any = None,
    trace: Any = None,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (6.0, 6.0),
    dpi: float = 100.0,
) -> Any:
    """A Delta (``jaxkin.delta.Delta``) at actuator angles ``theta`` ``(3,)`` in 3-D.

    ``p`` (the platform centre) defaults to ``jaxkin.fk(robot, theta)``. Draws the base
    triangle, the three arms, the parallelogram rods (as single lines) and the platform;
    ``trace`` ``(N, 3)`` optionally draws the platform's path.
    """
    theta = np.asarray(_arrays(theta), float).reshape(3)
    if p is None:
        p = np.asarray(fk(robot, theta).x.p, float)
    pts = delta_points(robot, theta, p)
    fig = _figure(figsize, dpi)
    ax = fig.add_subplot(projection="3d")
    for key, colour in (("base", "k"), ("platform", "tab:green")):
        tri = np.vstack([pts[key], pts[key][:1]])
        ax.plot(tri[:, 0], tri[:, 1], tri[:, 2], "-", color=colour, lw=2)
    for i in range(3):
        arm = np.stack([pts["base"][i], pts["elbow"][i]])
        rod = np.stack([pts["elbow"][i], pts["platform"][i]])
        ax.plot(*arm.T, "o-", color="tab:blue", lw=2.5)
        ax.plot(*rod.T, "-", color="tab:orange", lw=1.5)
    if trace is not None:
        trace = np.asarray(_arrays(trace), float)
        ax.plot(trace[:, 0], trace[:, 1], trace[:, 2], "k-", lw=0.7)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title("theta = (" + ", ".join(f"{x:.3f}" for x in theta) + ")", fontsize=9)
    _equal_3d(ax, np.vstack([*pts.values()] + ([trace] if trace is not None else [])))
    return _finish(fig, path)


def _equal_3d(ax: Any, points: np.ndarray) -> None:
    centre = (points.max(0) + points.min(0)) / 2.0
    half = max(float((points.max(0) - points.min(0)).max()) / 2.0, 1e-12)
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        setter(c - half, c + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))


def _slice_indices(result: Any, n: int) -> list[int]:
    areas = np.asarray(result.slice_areas)
    nonzero = np.flatnonzero(areas > 0)
    if nonzero.size == 0:
        return list(np.linspace(0, len(areas) - 1, n).round().astype(int))
    return list(np.linspace(nonzero[0], nonzero[-1], n + 2)[1:-1].round().astype(int))


def _draw_slice(ax: Any, result: Any, k: int) -> None:
    x, y, z = result.axes
    h = result.resolution
    ax.imshow(
        result.mask[:, :, k].T,
        origin="lower",
        cmap="Blues",
        vmin=0,
        vmax=1,
        extent=(x[0] - h / 2, x[-1] + h / 2, y[0] - h / 2, y[-1] + h / 2),
        interpolation="nearest",
    )
    ax.set_title(f"z = {z[k]:.3g}: area {result.slice_areas[k]:.4g}", fontsize=8)
    ax.set_aspect("equal")


def workspace_slices(
    result: Any,
    n_slices: int = 6,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (10.0, 6.5),
    dpi: float = 100.0,
) -> Any:
    """``n_slices`` horizontal slices of a workspace mask (evenly spaced over the z range
    that has reachable voxels), reachable voxels filled."""
    n_slices = _validate.count(n_slices, "n_slices")
    fig = _figure(figsize, dpi)
    cols = int(np.ceil(n_slices / 2)) if n_slices > 3 else n_slices
    rows = int(np.ceil(n_slices / cols))
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, k in zip(axes, _slice_indices(result, n_slices), strict=False):
        _draw_slice(ax, result, k)
    for ax in axes[n_slices:]:
        ax.set_visible(False)
    return _finish(fig, path)


def _draw_cloud(ax: Any, result: Any, max_points: int, seed: int) -> None:
    x, y, z = result.axes
    idx = np.argwhere(result.mask)
    if len(idx) > max_points:
        idx = idx[np.random.default_rng(seed).choice(len(idx), max_points, replace=False)]
    pts = np.stack([x[idx[:, 0]], y[idx[:, 1]], z[idx[:, 2]]], -1) if len(idx) else np.zeros((0, 3))
    ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=1, c=pts[:, 2], cmap="viridis", alpha=0.5)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title(f"{result.n_reachable} of {result.n_evaluated} voxels reachable", fontsize=9)


def workspace_cloud(
    result: Any,
    max_points: int = 20_000,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (7.0, 6.0),
    dpi: float = 100.0,
    seed: int = 0,
) -> Any:
    """The reachable voxel centres as a 3-D point cloud (a random subset of at most
    ``max_points``, coloured by z)."""
    fig = _figure(figsize, dpi)
    _draw_cloud(fig.add_subplot(projection="3d"), result, max_points, seed)
    return _finish(fig, path)


def workspace_overview(
    result: Any,
    title: str | None = None,
    max_points: int = 20_000,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (13.0, 6.0),
    dpi: float = 100.0,
) -> Any:
    """Point cloud (left) and four z slices (right) in one figure, titled with the volume."""
    fig = _figure(figsize, dpi)
    grid = fig.add_gridspec(2, 4)
    _draw_cloud(fig.add_subplot(grid[:, :2], projection="3d"), result, max_points, 0)
    for i, k in enumerate(_slice_indices(result, 4)):
        _draw_slice(fig.add_subplot(grid[i // 2, 2 + i % 2]), result, k)
    label = f"reachable volume {result.volume:.6g} (voxel edge {result.resolution:g})"
    fig.suptitle(f"{title}: {label}" if title else label)
    return _finish(fig, path)


def cost_curves(
    costs: Mapping[str, Any] | Any,
    log: bool = True,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (7.0, 4.5),
    dpi: float = 100.0,
    xlabel: str = "iteration",
    ylabel: str = "cost",
) -> Any:
    """Optimisation cost against iteration: one curve per entry of ``costs`` (a mapping of
    label to ``(n_iter,)`` arrays), or one curve per column of an ``(n_iter, k)`` array."""
    fig = _figure(figsize, dpi)
    ax = fig.subplots()
    if not isinstance(costs, Mapping):
        arr = np.asarray(costs, float)
        arr = arr[:, None] if arr.ndim == 1 else arr
        costs = (
            {f"run {j}": arr[:, j] for j in range(arr.shape[1])}
            if arr.shape[1] > 1
            else {"cost": arr[:, 0]}
        )
    for label, values in costs.items():
        values = np.asarray(values, float)
        ax.plot(np.arange(len(values)), values, label=str(label))
    if log:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3, which="both")
    if len(costs) > 1:
        ax.legend(fontsize=8)
    return _finish(fig, path)


def _mesh(ax: Any, triangles: np.ndarray, gid: str, style: dict[str, Any]) -> Any:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    polygons = Poly3DCollection(triangles, **style)
    polygons.set_gid(gid)
    ax.add_collection3d(polygons)
    return polygons


class _Scene:
    """What ``robot_scene`` draws: the joints ``q``, the link origins ``(L, 3)``, the tool's
    path ``(T, 3)`` or None, ``meshes`` (gid -> triangles ``(F, 3, 3)``), their ``styles``
    (gid -> keyword arguments of the artist) and the ``points`` the view is fitted to."""

    def __init__(self, robot: Any, q: Any, world: Any, motion: Any, frames: int, segments: int):
        body = robot.collision_body()
        self.q, moves = surfaces.scene_joints(robot.n_joints, q, motion)
        frames = _validate.count(frames, "frames", minimum=0) if moves is not None else 0
        if world is not None and not isinstance(world, collision.World):
            raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
        self.meshes: dict[str, np.ndarray] = {}
        self.styles: dict[str, dict[str, Any]] = {}
        colours = [f"C{k % 10}" for k in range(len(body.links))]
        poses = surfaces.link_poses(robot, self.q)
        self.origins = poses[:, :3, 3]
        points = [self.origins]

        def add(shape: Any, gid: str, **style: Any) -> None:
            triangles = shape.vertices[shape.faces]  # a link's primitives: one mesh
            if gid in self.meshes:
                triangles = np.concatenate([self.meshes[gid], triangles])
            self.meshes[gid] = triangles
            self.styles[gid] = style

        for shape in surfaces.body_surfaces(body, poses, segments):
            colour = colours[body.links.index(shape.name)]
            add(shape, f"body {shape.name}", color=colour, alpha=0.55, lw=0)
            points.append(shape.vertices)
        self.tool = None
        if moves is not None:
            self.tool = np.asarray(robot.target.position(fk(robot, moves).x.p), float)
            points.append(self.tool)
            picks = np.linspace(0, len(moves) - 1, frames).round().astype(int)
            every = surfaces.link_poses(robot, moves[picks])
            for k, placed in enumerate(every):
                alpha = 0.08 + 0.22 * (k + 1) / len(picks)
                for shape in surfaces.body_surfaces(body, placed, segments):
                    colour = colours[body.links.index(shape.name)]
                    add(shape, f"motion {k} {shape.name}", color=colour, alpha=alpha, lw=0)
                    points.append(shape.vertices)
        if world is not None:
            centre, extent = surfaces.bounding_cube(np.concatenate(points))
            for shape in surfaces.world_surfaces(world, extent, centre, segments):
                add(shape, f"world {shape.name}", color="0.5", alpha=0.3, lw=0.2)
                if not shape.name.startswith("halfspace"):
                    points.append(shape.vertices)
        self.points = np.concatenate(points)


def scene_meshes(
    robot, q=None, world=None, motion=None, frames: int = 4, segments: int = 12
) -> dict[str, np.ndarray]:
    """The triangles ``robot_scene`` draws with the same arguments, by the gid of their
    artist (``"body <link>"``, ``"motion <k> <link>"``, ``"world <kind> <i>"``): each
    ``(F, 3, 3)``, the corners of ``F`` triangles in the base frame (e.g. to hand the scene
    to another renderer). Raises as ``robot_scene``."""
    return _Scene(robot, q, world, motion, frames, segments).meshes


def robot_scene(
    robot: Any,
    q: Any = None,
    world: Any = None,
    motion: Any = None,
    frames: int = 4,
    path: str | os.PathLike | None = None,
    figsize: tuple[float, float] = (7.0, 6.5),
    dpi: float = 100.0,
    segments: int = 12,
) -> Any:
    """A robot's collision body, a world and a planned motion in 3-D.

    Args:
        robot: any robot with a collision body (``robot.collision_body()``,
            ``robot.link_poses(q)``: ``collision.CollisionRobot``).
        q: joints ``(n,)`` to draw the body at (solid); None with a ``motion``: its last
            sample.
        world: a ``collision.World`` (unbatched) whose obstacles are drawn in grey; its
            half-spaces as squares about the robot, as large as the drawing.
        motion: joints ``(T, n)`` (or a ``Jet``: its positions) of a planned motion: the
            tool's path (``robot.target.position`` of ``jaxkin.fk``) and the body at
            ``frames`` of its samples, evenly spaced, fainter towards the start.
        frames: how many samples of the motion to draw the body at (0: the path alone).
        path: where to save the figure, optional.
        segments: meridians of each sphere and capsule's mesh (``collision.surfaces``).

    Returns:
        The ``Figure``. Its artists carry ``gid``s: ``"body <link>"`` (one mesh per link,
        its spheres and capsules, at ``q``), ``"motion <k> <link>"`` (the body at the
        ``k``-th drawn sample), ``"world <kind> <i>"``, ``"tool path"`` and ``"link
        origins"``; the meshes' triangles are ``scene_meshes``'s.

    Raises:
        ValueError: a robot without a collision body (from the robot), ``q`` or ``motion``
            of the wrong shape, or neither given.
    """
    scene = _Scene(robot, q, world, motion, frames, segments)
    fig = _figure(figsize, dpi)
    ax = fig.add_subplot(projection="3d")
    for gid, triangles in scene.meshes.items():
        _mesh(ax, triangles, gid, scene.styles[gid])
    ax.plot(*scene.origins.T, "k.", ms=4, gid="link origins")
    if scene.tool is not None:
        ax.plot(*scene.tool.T, "-", color="k", lw=1.2, gid="tool path")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    q_text = ", ".join(f"{x:.3g}" for x in scene.q)
    ax.set_title(f"{type(robot).__name__} at q = ({q_text})")
    _equal_3d(ax, scene.points)
    return _finish(fig, path)
