"""The browser viewer (jaxkin.viewer, the viser extra): it serves its page over HTTP and its
scene over the websocket a browser opens, the robot's links placed where the written-out
kinematics puts them, the world and the motion's path."""

import builtins
import time
import urllib.request

import numpy as np
import pytest

viser = pytest.importorskip("viser")
msgpack = pytest.importorskip("msgspec.msgpack")
zstandard = pytest.importorskip("zstandard")

from scipy.spatial.transform import Rotation  # noqa: E402
from websockets.sync.client import connect  # noqa: E402  (viser's dependency)

from jaxkin import collision, serial, viewer  # noqa: E402
from tests.test_plot import anthropomorphic_points, distance_to_segment  # noqa: E402


def scene_names(url: str, wanted: set[str], timeout: float = 20.0) -> set[str]:
    """The node names a browser receives: viser's websocket frames (its 1.x wire format: the
    msgpack payload's sizes in 16 bytes, the zstd-compressed msgpack, then binary buffers),
    read until every ``wanted`` name came or ``timeout`` passed."""
    names: set[str] = set()
    protocol = "viser-v" + viser.__version__
    with connect(url.replace("http", "ws", 1), subprotocols=[protocol]) as ws:
        end = time.monotonic() + timeout
        while not wanted <= names and time.monotonic() < end:
            try:
                frame = ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            size = int.from_bytes(frame[:8], "little")
            packed = int.from_bytes(frame[8:16], "little")
            payload = zstandard.ZstdDecompressor().decompress(frame[16 : 16 + packed], size)
            for message in msgpack.decode(payload)["messages"]:
                if isinstance(message, dict) and isinstance(message.get("name"), str):
                    names.add(message["name"])
    return names


def test_viewer_serves_its_page_and_the_scene():
    l1, l2, l3 = 0.3, 0.25, 0.2
    arm = serial.Anthropomorphic(l1, l2, l3, link_radius=0.03)
    world = collision.World.create(
        boxes=collision.Boxes.create(center=[[0.3, 0.2, 0.2]], half_extents=[[0.05, 0.05, 0.2]]),
        halfspaces=collision.HalfSpaces.create([[0.0, 0.0, 1.0]], [0.0]),
    )
    motion = np.linspace([0.0, 0.3, 0.5], [1.2, 0.6, 0.9], 20)
    with viewer.view(arm, world=world, motion=motion, port=0, period=0.01) as shown:
        with urllib.request.urlopen(shown.url + "/", timeout=20) as response:
            page = response.read()
        assert response.status == 200 and page.lstrip().lower().startswith(b"<!doctype html")
        wanted = {
            "/robot/link1",
            "/robot/link3",
            "/robot/link3/capsule_0",
            "/world/box_0",
            "/world/halfspace_0",
            "/motion/tool_path",
        }
        names = scene_names(shown.url, wanted)
        assert wanted <= names, sorted(names)
        # the last sample shown: each link's frame at the written-out DH origin of its joint
        joints = anthropomorphic_points(l1, l2, l3, motion[-1])
        for k, link in ((1, "link1"), (2, "link2"), (3, "link3")):
            np.testing.assert_allclose(shown.frames[link].position, joints[k], atol=1e-6)
        shown.show_sample(0)
        first = anthropomorphic_points(l1, l2, l3, motion[0])
        np.testing.assert_allclose(shown.frames["link3"].position, first[3], atol=1e-6)
        q = np.array([0.4, 0.5, 0.7])
        shown.show(q)
        at = anthropomorphic_points(l1, l2, l3, q)
        np.testing.assert_allclose(shown.frames["link2"].position, at[2], atol=1e-6)
        # the forearm's mesh, in its link's frame, placed by the frame's pose (scipy's
        # quaternion, scalar last): at the capsule's radius from the elbow-wrist segment
        frame = shown.frames["link3"]
        w, x, y, z = frame.wxyz
        turn = Rotation.from_quat([x, y, z, w]).as_matrix()
        local = np.asarray(shown.nodes["/robot/link3/capsule_0"].vertices, float)
        placed = local @ turn.T + frame.position
        np.testing.assert_allclose(distance_to_segment(placed, at[2], at[3]), 0.03, atol=1e-6)
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
