"""The browser viewer (jaxkin.viewer, the viser extra): it serves its page over HTTP, and what
it adds through viser's public scene and GUI API (recorded by a wrapper of the real server,
each call passed on to it) places the robot's links where the written-out kinematics puts
them, the world's obstacles and the motion's tool path."""

import builtins
import urllib.request

import numpy as np
import pytest

viser = pytest.importorskip("viser")

from scipy.spatial.transform import Rotation  # noqa: E402

from jaxkin import serial, viewer  # noqa: E402
from tests.test_plot import (  # noqa: E402
    anthropomorphic_points,
    arm_scene,
    distance_to_segment,
)


class _Recorded:
    """``target`` (a viser API object) whose method calls are passed on and recorded in
    ``calls`` as ``(prefix + method, first argument, returned handle)``."""

    def __init__(self, target, prefix: str, calls: list) -> None:
        self._target, self._prefix, self._calls = target, prefix, calls

    def __getattr__(self, attr):
        value = getattr(self._target, attr)
        if not callable(value):
            return value

        def call(*args, **kwargs):
            result = value(*args, **kwargs)
            self._calls.append((self._prefix + attr, args[0] if args else None, result))
            return result

        return call


class RecordingServer:
    """A real ``viser.ViserServer`` whose ``scene`` and ``gui`` calls are recorded."""

    started: list["RecordingServer"] = []

    def __init__(self, *args, **kwargs) -> None:
        self._server = _REAL_SERVER(*args, **kwargs)
        self.calls: list = []
        self.scene = _Recorded(self._server.scene, "scene.", self.calls)
        self.gui = _Recorded(self._server.gui, "gui.", self.calls)
        RecordingServer.started.append(self)

    def __getattr__(self, attr):
        return getattr(self._server, attr)

    def added(self, method: str) -> dict:
        """Name (or label) -> the handle viser returned, for every call of ``method``."""
        return {name: handle for kind, name, handle in self.calls if kind == method}


_REAL_SERVER = viser.ViserServer


def test_viewer_serves_its_page_and_adds_the_scene_through_viser(monkeypatch):
    monkeypatch.setattr(viser, "ViserServer", RecordingServer)
    RecordingServer.started.clear()
    l1, l2, l3, r, arm, centre, half, world, motion = arm_scene(0.05, 20)
    with viewer.view(arm, world=world, motion=motion, port=0, period=0.01) as shown:
        with urllib.request.urlopen(shown.url + "/", timeout=20) as response:
            page = response.read()
        assert response.status == 200 and page.lstrip().lower().startswith(b"<!doctype html")
        (server,) = RecordingServer.started
        frames = server.added("scene.add_frame")
        meshes = server.added("scene.add_mesh_simple")
        assert set(frames) == {f"/robot/{link}" for link in shown.links}
        assert {"link1", "link2", "link3"} <= set(shown.links)
        assert {"/robot/link3/capsule_0", "/world/box_0", "/world/halfspace_0"} <= set(meshes)
        assert {name.rsplit("/", 1)[0] for name in meshes if name.startswith("/robot")} <= set(
            frames
        )
        assert set(server.added("gui.add_slider")) == {"sample"}
        assert set(server.added("gui.add_checkbox")) == {"play"}
        # the tool path: the written-out wrist at every sample
        (spline,) = server.added("scene.add_spline_catmull_rom").items()
        assert spline[0] == "/motion/tool_path"
        wrists = np.stack([anthropomorphic_points(l1, l2, l3, m)[3] for m in motion])
        np.testing.assert_allclose(spline[1].points, wrists, rtol=0, atol=1e-6)
        # the world: the box's 8 corners, the floor at z = 0
        corners = centre + half * np.array(
            [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
        )
        box = np.unique(np.asarray(meshes["/world/box_0"].vertices, float).round(6), axis=0)
        np.testing.assert_allclose(box, np.unique(corners.round(6), axis=0), atol=1e-6)
        np.testing.assert_allclose(meshes["/world/halfspace_0"].vertices[:, 2], 0.0, atol=1e-7)
        # the last sample shown: each link's frame at the written-out DH origin of its joint
        joints = anthropomorphic_points(l1, l2, l3, motion[-1])
        for k in (1, 2, 3):
            np.testing.assert_allclose(frames[f"/robot/link{k}"].position, joints[k], atol=1e-6)
        shown.show_sample(0)
        first = anthropomorphic_points(l1, l2, l3, motion[0])
        np.testing.assert_allclose(frames["/robot/link3"].position, first[3], atol=1e-6)
        q = np.array([0.4, 0.5, 0.7])
        shown.show(q)
        at = anthropomorphic_points(l1, l2, l3, q)
        np.testing.assert_allclose(frames["/robot/link2"].position, at[2], atol=1e-6)
        # the forearm's mesh, in its link's frame, placed by the frame's pose (scipy's
        # quaternion, scalar last): at the capsule's radius from the elbow-wrist segment
        frame = frames["/robot/link3"]
        w, x, y, z = frame.wxyz
        turn = Rotation.from_quat([x, y, z, w]).as_matrix()
        local = np.asarray(meshes["/robot/link3/capsule_0"].vertices, float)
        placed = local @ turn.T + frame.position
        np.testing.assert_allclose(distance_to_segment(placed, at[2], at[3]), r, atol=1e-6)
        with pytest.raises(ValueError, match=r"q: expected joints of shape \(3,\)"):
            shown.show(np.zeros(2))


def test_viewer_refuses_bad_arguments_and_names_the_extra(monkeypatch):
    arm = serial.Anthropomorphic(0.3, 0.25, 0.2, link_radius=0.03)
    with pytest.raises(ValueError, match="motion: expected joints of shape"):
        viewer.view(arm, motion=np.zeros((4, 2)), port=0)
    with pytest.raises(ValueError, match="period must be a positive number"):
        viewer.view(arm, motion=np.zeros((4, 3)), period=0.0, port=0)
    with pytest.raises(ValueError, match="world: expected a collision.World"):
        viewer.view(arm, world=np.zeros(3), port=0)
    real_import = builtins.__import__

    def no_viser(name, *args, **kwargs):
        if name == "viser":
            raise ImportError("No module named 'viser'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_viser)
    with pytest.raises(ImportError, match=r"jaxkin\[viewer\]"):
        viewer.view(arm, port=0)
