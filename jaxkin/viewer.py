"""A browser viewer of a robot, its collision body, a world and an animated motion (the
optional ``viewer`` extra: ``pip install 'jaxkin[viewer]'``, the viser package, as PyRoki and
VAMP use).

``view(robot, q, world, motion)`` starts a viser server (``http://127.0.0.1:8080`` by
default; ``port=0`` picks a free one) and returns a ``Viewer``; open ``viewer.url`` in a
browser. The scene tree:

* ``/robot/<link>``: one frame per link of the robot's collision body, placed by
  ``robot.link_poses(q)``; under it the link's spheres and capsules as meshes in the link's
  own frame (``collision.surfaces.link_surfaces``), so moving the robot moves frames only;
* ``/world/<kind>_<i>``: the obstacles of a ``collision.World`` (half-spaces as squares
  about the robot);
* ``/motion/tool_path``: with a motion, the tool's path by forward kinematics
  (``robot.target.position``); the GUI then has a ``sample`` slider and a ``play`` checkbox,
  and playing steps through the motion every ``period`` seconds (in a daemon thread).

The link poses of the whole motion are computed in one batched call when it is given;
``Viewer.show(q)`` places the robot at other joints. ``Viewer.close()`` (or a ``with``
block) stops the thread and the server.
"""

from __future__ import annotations

import socket
import threading
from typing import Any

import numpy as np

from . import collision, lie
from .collision import surfaces
from .robot import fk

__all__ = ["INSTALL_HINT", "Viewer", "view"]

INSTALL_HINT = "jaxkin.viewer needs viser: pip install 'jaxkin[viewer]'"
_COLOURS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189)]


def _viser() -> Any:
    try:
        import viser
    except ImportError:
        raise ImportError(INSTALL_HINT) from None
    return viser


def _free_port(host: str) -> int:
    with socket.socket() as probe:
        probe.bind((host, 0))
        return int(probe.getsockname()[1])


class Viewer:
    """A running viser server showing one robot (``view`` makes one).

    Attributes:
        server: the ``viser.ViserServer``.
        url: ``http://host:port``.
        links: the body's link names, in the order of ``robot.link_poses``.
        frames: link name -> its frame handle (``position``, ``wxyz`` as shown).
        nodes: every scene node this viewer added, by name.
        motion: the motion's joints ``(T, n)``, or None.
    """

    def __init__(self, robot: Any, server: Any, url: str, segments: int) -> None:
        self.robot = robot
        self.server = server
        self.url = url
        self.motion: np.ndarray | None = None
        self._poses: np.ndarray | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        body = robot.collision_body()
        self.links = tuple(body.links)
        self.frames: dict[str, Any] = {}
        self.nodes: dict[str, Any] = {}
        shapes = surfaces.link_surfaces(body, segments)
        scene = server.scene
        for k, link in enumerate(self.links):
            name = f"/robot/{link}"
            self.frames[link] = self.nodes[name] = scene.add_frame(name, show_axes=False)
            for shape in shapes.get(link, []):
                mesh_name = f"{name}/{shape.name.replace(' ', '_')}"
                self.nodes[mesh_name] = scene.add_mesh_simple(
                    mesh_name,
                    shape.vertices.astype(np.float32),
                    shape.faces.astype(np.uint32),
                    color=_COLOURS[k % len(_COLOURS)],
                    opacity=0.8,
                )

    def show(self, q: Any) -> None:
        """Place the robot at joints ``q`` ``(n,)``."""
        q = np.asarray(q, float)
        if q.shape != (self.robot.n_joints,):
            raise ValueError(f"q: expected joints of shape ({self.robot.n_joints},), got {q.shape}")
        self._place(surfaces.link_poses(self.robot, q))

    def _place(self, poses: np.ndarray) -> None:
        wxyz = lie.matrix_to_quaternion(poses[:, :3, :3].astype(float), xp=np)
        with self.server.atomic():
            for k, link in enumerate(self.links):
                self.frames[link].position = poses[k, :3, 3].astype(float)
                self.frames[link].wxyz = wxyz[k]

    def show_sample(self, index: int) -> None:
        """Place the robot at sample ``index`` of the motion."""
        if self._poses is None:
            raise ValueError("show_sample: the viewer has no motion")
        self._place(self._poses[int(index)])

    def _add_world(self, world: Any, centre: np.ndarray, extent: float, segments: int) -> None:
        if not isinstance(world, collision.World):
            raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
        for shape in surfaces.world_surfaces(world, extent, centre, segments):
            name = "/world/" + shape.name.replace(" ", "_")
            self.nodes[name] = self.server.scene.add_mesh_simple(
                name,
                shape.vertices.astype(np.float32),
                shape.faces.astype(np.uint32),
                color=(150, 150, 150),
                opacity=0.5,
                side="double",
            )

    def _add_motion(self, motion: np.ndarray, period: float) -> None:
        self.motion = motion
        self._poses = surfaces.link_poses(self.robot, motion)
        tool = np.asarray(self.robot.target.position(fk(self.robot, motion).x.p), float)
        size = float(np.ptp(self._poses[..., :3, 3].reshape(-1, 3), axis=0).max()) or 1.0
        self.nodes["/motion/tool_path"] = self.server.scene.add_spline_catmull_rom(
            "/motion/tool_path", tool.astype(np.float32), thickness=0.005 * size
        )
        gui = self.server.gui
        slider = gui.add_slider("sample", 0, len(motion) - 1, 1, len(motion) - 1)
        playing = gui.add_checkbox("play", False)
        slider.on_update(lambda _: self.show_sample(slider.value))

        def run() -> None:
            while not self._stop.wait(period):
                if playing.value:
                    index = (int(slider.value) + 1) % len(motion)
                    slider.value = index
                    self.show_sample(index)

        self._thread = threading.Thread(target=run, name="jaxkin-viewer", daemon=True)
        self._thread.start()
        self.show_sample(len(motion) - 1)

    def close(self) -> None:
        """Stop the animation thread and the server."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def view(
    robot: Any,
    q: Any = None,
    world: Any = None,
    motion: Any = None,
    period: float = 0.05,
    host: str = "127.0.0.1",
    port: int = 8080,
    segments: int = 16,
) -> Viewer:
    """Serve a robot's collision body, a world and a motion to a browser (module docstring).

    Args:
        robot: any robot with a collision body (``collision.CollisionRobot``).
        q: joints ``(n,)`` to show (default: the motion's last sample, else zeros).
        world: a ``collision.World`` (unbatched), optional.
        motion: joints ``(T, n)`` (or a ``Jet``: its positions) to animate, optional.
        period: seconds between samples when playing.
        host, port: where to serve (``port=0``: a free port).
        segments: meridians of each sphere and capsule's mesh.

    Returns:
        The running ``Viewer`` (``viewer.url``); ``viewer.close()`` stops it.

    Raises:
        ImportError: viser is missing (the ``viewer`` extra).
        ValueError: ``q``, ``motion``, ``world`` or ``period`` not as described (named).
    """
    viser = _viser()
    start, moves = surfaces.scene_joints(robot.n_joints, q, motion, at_rest=True)
    if not (isinstance(period, int | float) and period > 0):
        raise ValueError(f"period must be a positive number of seconds, got {period!r}")
    port = _free_port(host) if port == 0 else port
    server = viser.ViserServer(host=host, port=port, verbose=False)
    try:
        viewer = Viewer(robot, server, f"http://{host}:{server.get_port()}", segments)
        if world is not None:
            placed = surfaces.link_poses(robot, start if moves is None else moves)
            centre, extent = surfaces.bounding_cube(placed[..., :3, 3])
            viewer._add_world(world, centre, 2.0 * extent, segments)
        if moves is not None:
            viewer._add_motion(moves, float(period))
        viewer.show(start)
    except BaseException:
        server.stop()
        raise
    return viewer
