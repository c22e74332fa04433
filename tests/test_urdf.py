"""URDF chains: parsed joints, forward kinematics and Jacobians against Pinocchio (its own URDF
parser, on the UR5 and Franka Panda files of example-robot-data), mimic, continuous and
prismatic joints against yourdfpy's own forward kinematics, errors that name the link or joint
(every defect Pinocchio's parser refuses is refused here too), IK with no seed checked with
Pinocchio's forward kinematics, pose paths through the planner checked by the forward
kinematics of the planned joints (rates included), and point targets (``target="point"``) on
a 3-joint DH arm (its closed form) and the 5-joint SO-101 (Pinocchio).

Tolerances: 1e-12 for forward kinematics and Jacobians (float64, chains of about 1 m); the IK
at its default tolerances (1e-10 rad and 1e-10 of the chain's size), checked at 1e-9 (or at
the position tolerance itself for point targets).
"""

from __future__ import annotations

import importlib.metadata
import io
import re

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from jax import monitoring
from scipy.spatial.transform import Rotation

import jaxkin
from jaxkin import Jet, Status, _batching, paths, plan, serial
from jaxkin.serial import search
from tests.helpers import marked_slow

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
ARMS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand"),
    "so101": ("so_arm_description/urdf/so101.urdf", "gripper_frame_link"),
}


def _path(arm: str) -> str:
    return str(ROBOTS / ARMS[arm][0])


@pytest.fixture(scope="module", params=list(ARMS))
def arm(request):
    """(name, chain, Pinocchio model, its data, the tip frame id, q -> chain order map)."""
    name = request.param
    chain = serial.from_urdf(_path(name), ARMS[name][1])
    model = pin.buildModelFromUrdf(_path(name))
    columns = [model.joints[model.getJointId(j)].idx_v for j in chain.joint_names]
    return name, chain, model, model.createData(), model.getFrameId(ARMS[name][1]), columns


def _random_q(chain, n, seed):
    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    return np.random.default_rng(seed).uniform(lower, upper, size=(n, chain.n_joints))


def _pinocchio(arm_fixture, q):
    """Tip poses, space Jacobians and body Jacobians (rows omega, v) by Pinocchio."""
    _, chain, model, data, frame, columns = arm_fixture
    poses, space, body = [], [], []
    swap = np.r_[3:6, 0:3]  # Pinocchio's rows are (v, omega)
    for qi in q:
        full = pin.neutral(model)
        full[columns] = qi  # one coordinate per joint in these arms
        pin.computeJointJacobians(model, data, full)
        pin.updateFramePlacements(model, data)
        poses.append(data.oMf[frame].homogeneous)
        local = pin.getFrameJacobian(model, data, frame, pin.ReferenceFrame.LOCAL)
        world = pin.getFrameJacobian(model, data, frame, pin.ReferenceFrame.WORLD)
        body.append(local[swap][:, columns])
        space.append(world[swap][:, columns])
    return np.array(poses), np.array(space), np.array(body)


def test_joints_and_limits_are_those_pinocchio_reads(arm):
    _, chain, model, _, _, columns = arm
    assert chain.joint_names == tuple(model.names[model.getJointId(j)] for j in chain.joint_names)
    assert all(kind == "revolute" for kind in chain.joint_kinds)
    np.testing.assert_array_equal(chain.lower, model.lowerPositionLimit[columns])
    np.testing.assert_array_equal(chain.upper, model.upperPositionLimit[columns])
    np.testing.assert_array_equal(chain.velocity, model.velocityLimit[columns])


def test_fk_and_jacobians_match_pinocchio(arm):
    chain = arm[1]
    q = _random_q(chain, 200, seed=0)
    poses, space, body = _pinocchio(arm, q)
    np.testing.assert_allclose(jaxkin.fk(chain, q).x.p, poses, atol=1e-12)
    np.testing.assert_allclose(serial.space_jacobian(chain, q), space, atol=1e-12)
    np.testing.assert_allclose(serial.body_jacobian(chain, q), body, atol=1e-12)


def _pose_error(a, b):
    """(rotation angle, distance) between transforms ``(..., 4, 4)``."""
    relative = np.swapaxes(a[..., :3, :3], -1, -2) @ b[..., :3, :3]
    angle = Rotation.from_matrix(relative.reshape(-1, 3, 3)).magnitude().reshape(a.shape[:-2])
    return angle, np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1)


@pytest.mark.parametrize("arm", marked_slow(ARMS, ["ur5", "so101"]), indirect=True)
def test_ik_without_a_seed_solves_within_limits(arm):
    """200 targets made by Pinocchio from joints within the limits, no seed: at least 99.5 %
    are solved (all but one), every OK answer reaches its target within 1e-9 rad and 1e-9 m by
    Pinocchio's forward kinematics and lies within the limits, and every other one is honestly
    flagged: ``OUT_OF_LIMITS`` answers reach the target outside the limits."""
    chain = arm[1]
    targets, _, _ = _pinocchio(arm, _random_q(chain, 200, seed=1))
    res = jaxkin.ik(chain, targets)
    status = np.asarray(res.status)
    ok = status == Status.OK
    assert ok.mean() >= 0.995
    assert set(status[~ok]) <= {Status.OUT_OF_LIMITS, Status.NOT_CONVERGED}
    q = np.asarray(res.q.p)
    reached, _, _ = _pinocchio(arm, q[ok])
    angle, distance = _pose_error(reached, targets[ok])
    assert angle.max() <= 1e-9 and distance.max() <= 1e-9
    assert np.all((q[ok] >= chain.lower) & (q[ok] <= chain.upper))
    out = status == Status.OUT_OF_LIMITS
    if out.any():
        reached, _, _ = _pinocchio(arm, q[out])
        angle, distance = _pose_error(reached, targets[out])
        assert angle.max() <= 1e-9 and distance.max() <= 1e-9
        assert np.all(np.any((q[out] < chain.lower) | (q[out] > chain.upper), axis=-1))


def _five_point(x, dt):
    """Derivative along axis -2 of samples ``dt`` apart by the five-point stencil (truncation
    dt^4/30 of the fifth derivative), at the samples 2 .. T-3."""
    x = np.asarray(x)
    return (x[..., :-4, :] - 8 * x[..., 1:-3, :] + 8 * x[..., 3:-1, :] - x[..., 4:, :]) / (12 * dt)


@pytest.mark.slow
def test_pose_paths_through_the_planner(arm):
    """Smooth joint motions within the limits, sampled as poses (Pinocchio), splined by
    ``path_from_poses``. Along every candidate whose Jacobian (Pinocchio's) stays well
    conditioned (smallest singular value > 0.05, the arms are about 1 m) every sample is
    solved, warm-started from the previous one, and the forward kinematics of the planned
    joints (with their rates) gives back the path's poses, velocities and accelerations (the
    rates for arms of six joints or more: a five-joint arm's are the least-squares fit of the
    spline's twist); the joint rates agree with five-point differences of the planned joints
    (for the 5- and 7-joint arms, through the tool velocity they give: the 7-joint arm's
    minimum-norm rates need not follow its joint path's drift in the null space)."""
    chain = arm[1]
    n, t, dt = 6, 41, 0.01
    rng = np.random.default_rng(2)
    lower, upper = np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi)
    centre = rng.uniform(lower + 0.4, upper - 0.4, (n, 1, chain.n_joints))
    phase = rng.uniform(0, 2 * np.pi, (n, 1, chain.n_joints))
    time = np.arange(t)[None, :, None] * dt
    q = centre + 0.3 * np.sin(5.0 * time + phase)
    poses, space, _ = _pinocchio(arm, q.reshape(-1, chain.n_joints))
    poses = poses.reshape(n, t, 4, 4)
    sigma = np.linalg.svd(space, compute_uv=False)[:, -1].reshape(n, t).min(axis=1)
    regular = sigma > 0.05
    assert regular.sum() >= 3
    quat = Rotation.from_matrix(poses[..., :3, :3].reshape(-1, 3, 3)).as_quat()
    quat = quat.reshape(n, t, 4)[..., [3, 0, 1, 2]]
    path = paths.path_from_poses(poses[..., :3, 3], quat, dt)
    ev = plan.evaluate(chain, path, dt=dt)
    # solved everywhere; the URDF's speed limits apply by default: exactly the faster samples fail
    fast = np.any(np.abs(np.asarray(ev.q.v)) > np.asarray(chain.velocity), -1)[regular]
    expected = np.where(fast, Status.OUT_OF_LIMITS, Status.OK)
    np.testing.assert_array_equal(np.asarray(ev.status)[regular], expected)
    np.testing.assert_array_equal(np.asarray(ev.feasible)[regular], ~fast.any(-1))
    assert np.all(np.asarray(ev.min_margin)[regular] > 0)
    x = jaxkin.fk(chain, ev.q).x
    np.testing.assert_allclose(np.asarray(x.p)[regular], path.p[regular], atol=1e-9)
    if chain.n_joints >= 6:  # every twist is reachable; with 5 joints the rates are least squares
        np.testing.assert_allclose(np.asarray(x.v)[regular], path.v[regular], atol=1e-8)
        np.testing.assert_allclose(np.asarray(x.a)[regular], path.a[regular], atol=1e-6)
    qp, qv = np.asarray(ev.q.p)[regular], np.asarray(ev.q.v)[regular]
    differences = _five_point(qp, dt)
    if chain.n_joints == 6:  # a square Jacobian: the joint rates are the joint path's own
        np.testing.assert_allclose(qv[:, 2:-2], differences, atol=1e-4)
    else:  # minimum-norm (7 joints) or least-squares (5) rates: compare the tool's velocities
        inner, zero = qp[:, 2:-2], np.zeros_like(qp[:, 2:-2])
        by_rates = np.asarray(jaxkin.fk(chain, Jet(inner, qv[:, 2:-2], zero)).x.v)
        by_differences = np.asarray(jaxkin.fk(chain, Jet(inner, differences, zero)).x.v)
        np.testing.assert_allclose(by_rates, by_differences, atol=1e-4)


MIMIC_URDF = """<?xml version="1.0"?>
<robot name="gripper_arm">
  <link name="world"/> <link name="base"/> <link name="upper"/> <link name="slider"/>
  <link name="wrist"/> <link name="finger_a"/> <link name="finger_b"/> <link name="camera"/>
  <joint name="mount" type="fixed">
    <parent link="world"/><child link="base"/><origin xyz="0 0 0.1" rpy="0 0 0.3"/>
  </joint>
  <joint name="turn" type="continuous">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.2"/><axis xyz="0 0 2"/>
  </joint>
  <joint name="reach" type="prismatic">
    <parent link="upper"/><child link="slider"/><origin xyz="0.3 0 0" rpy="0.2 0 0"/>
    <axis xyz="1 0 0"/><limit lower="-0.1" upper="0.25" effort="1" velocity="0.5"/>
  </joint>
  <joint name="tilt" type="revolute">
    <parent link="slider"/><child link="wrist"/><origin xyz="0.1 0.02 0" rpy="0 0.4 0"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1.2" effort="1" velocity="2"/>
  </joint>
  <joint name="tilt_mimic" type="revolute">
    <parent link="wrist"/><child link="finger_a"/><origin xyz="0.05 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="3"/>
    <mimic joint="tilt" multiplier="-0.5" offset="0.1"/>
  </joint>
  <joint name="side" type="revolute">
    <parent link="wrist"/><child link="finger_b"/><origin xyz="0 0.05 0"/>
    <axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="cam" type="fixed">
    <parent link="finger_a"/><child link="camera"/><origin xyz="0.02 0 0.01" rpy="0.1 0 0"/>
  </joint>
</robot>
"""


def test_mimic_continuous_prismatic_and_fixed_joints_match_yourdfpy():
    """A chain with every supported joint kind (and a side branch, ``side``, ignored):
    tip poses equal yourdfpy's own forward kinematics, which applies the mimic coupling."""
    chain = serial.from_urdf(MIMIC_URDF, "camera")
    assert chain.joint_names == ("turn", "reach", "tilt")
    assert chain.joint_kinds == ("continuous", "prismatic", "revolute")
    assert chain.joint_types == "RPR"
    np.testing.assert_array_equal(chain.lower, [-np.inf, -0.1, -1.0])
    # the mimic joint's limits allow -3 <= -0.5 tilt + 0.1 <= 3: tilt keeps its own [-1, 1.2]
    np.testing.assert_array_equal(chain.upper, [np.inf, 0.25, 1.2])
    model = yourdfpy.URDF.load(io.StringIO(MIMIC_URDF), build_scene_graph=True, load_meshes=False)
    q = np.random.default_rng(3).uniform([-4, -0.1, -1.0], [4, 0.25, 1.2], (50, 3))
    expected = []
    for qi in q:
        model.update_cfg({"turn": qi[0], "reach": qi[1], "tilt": qi[2], "side": 0.0})
        expected.append(model.get_transform("camera", "world"))
    np.testing.assert_allclose(jaxkin.fk(chain, q).x.p, np.array(expected), atol=1e-12)


def test_mimic_limits_carry_over_and_continuous_joints_wrap():
    text = MIMIC_URDF.replace('lower="-3" upper="3"', 'lower="-0.2" upper="0.3"')
    chain = serial.from_urdf(text, "camera")
    # -0.2 <= -0.5 tilt + 0.1 <= 0.3  <=>  -0.4 <= tilt <= 0.6, within tilt's own [-1, 1.2]
    np.testing.assert_allclose(chain.lower[2], -0.4)
    np.testing.assert_allclose(chain.upper[2], 0.6)
    # One target, repeated to the work-queue test's batch of 100 (one compilation for both).
    q = np.repeat([[3.0 + 2 * np.pi, 0.1, 0.2]], 100, axis=0)
    res = jaxkin.ik(chain, jaxkin.fk(chain, q).x.p)
    assert np.all(np.asarray(res.status) == Status.OK)
    np.testing.assert_allclose(res.q.p[:, 0], 3.0, atol=1e-9)  # wrapped to [-pi, pi)


@pytest.mark.parametrize(
    ("change", "tip", "base", "message"),
    [
        (None, "nowhere", None, "no link 'nowhere'"),
        (None, "camera", "nowhere", "no link 'nowhere'"),
        (None, "base", "camera", "no path from base link 'camera' to tip link 'base'"),
        (None, "finger_b", "finger_a", "no path from base link 'finger_a'"),
        (('type="continuous"', 'type="floating"'), "camera", None, "joint 'turn' (floating)"),
        (('type="continuous"', 'type="planar"'), "camera", None, "joint 'turn' (planar)"),
        (('joint="tilt"', 'joint="side"'), "camera", None, "joint 'tilt_mimic' mimics 'side'"),
        (('<axis xyz="0 0 2"/>', '<axis xyz="0 0 0"/>'), "camera", None, "joint 'turn'"),
        (("</robot>", ""), "camera", None, "not well-formed XML"),
    ],
)
def test_errors_name_the_link_or_joint(change, tip, base, message):
    text = MIMIC_URDF if change is None else MIMIC_URDF.replace(*change)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        serial.from_urdf(text, tip, base_link=base)


def test_a_path_and_its_text_give_the_same_chain(tmp_path):
    path = tmp_path / "robot.urdf"
    path.write_text(MIMIC_URDF)
    a = serial.from_urdf(path, "camera")
    b = serial.from_urdf(str(path), "camera", base_link="world")
    for leaf_a, leaf_b in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(leaf_a, leaf_b)
    with pytest.raises(ValueError, match="no such URDF file"):
        serial.from_urdf(tmp_path / "missing.urdf", "camera")


@pytest.mark.slow
def test_command_line_pose_files_of_a_urdf_arm(tmp_path, capsys):
    """``jaxkin fk urdf --robot FILE --tip LINK`` writes pose columns (x, y, z, qw, qx, qy, qz
    and their rates) that Pinocchio's forward kinematics and five-point differences confirm;
    ``jaxkin ik urdf`` on that file gives joints whose poses (Pinocchio) are the file's."""
    from jaxkin import cli

    model = pin.buildModelFromUrdf(_path("ur5"))
    fixture = ("ur5", serial.from_urdf(_path("ur5"), "tool0"), model, model.createData())
    fixture += (model.getFrameId("tool0"), list(range(6)))
    t = np.linspace(0.0, 1.0, 41)
    q = np.stack([0.3 + 0.5 * t, -1.0 + 0.3 * t, 1.2 - 0.2 * t, -0.5 + t, 1.0 + 0.4 * t, t], -1)
    names = fixture[1].joint_names
    np.savetxt(tmp_path / "joints.csv", np.c_[t, q], delimiter=",", comments="",
               header="t," + ",".join(names))  # fmt: skip
    robot = ["--robot", _path("ur5"), "--tip", "tool0", "-q"]
    assert cli.main(["fk", "urdf", *robot, "-i", str(tmp_path / "joints.csv"),
                     "-o", str(tmp_path / "poses.csv")]) == 0  # fmt: skip
    table = np.genfromtxt(tmp_path / "poses.csv", delimiter=",", names=True, dtype=None)
    pose = np.stack([table[c] for c in ("x", "y", "z", "qw", "qx", "qy", "qz")], -1)
    rates = np.stack([table[f"{c}_dot"] for c in ("x", "y", "z", "qw", "qx", "qy", "qz")], -1)
    expected, _, _ = _pinocchio(fixture, q)
    np.testing.assert_allclose(pose[:, :3], expected[:, :3, 3], atol=1e-12)
    rotation = Rotation.from_quat(pose[:, [4, 5, 6, 3]]).as_matrix()
    np.testing.assert_allclose(rotation, expected[:, :3, :3], atol=1e-12)
    np.testing.assert_allclose(rates[2:-2], _five_point(pose, t[1] - t[0]), atol=1e-6)
    assert cli.main(["ik", "urdf", *robot, "-i", str(tmp_path / "poses.csv"),
                     "-o", str(tmp_path / "back.csv")]) == 0  # fmt: skip
    back = np.genfromtxt(tmp_path / "back.csv", delimiter=",", names=True, dtype=None)
    assert set(back["status"].astype(str)) == {"OK"}
    reached, _, _ = _pinocchio(fixture, np.stack([back[n] for n in names], -1))
    angle, distance = _pose_error(reached, expected)
    assert angle.max() <= 1e-9 and distance.max() <= 1e-9
    code = cli.main(["ik", "urdf", "--robot", _path("ur5"), "-i", "x.csv", "-o", "y.csv"])
    assert code == 2 and "--tip LINK is required" in capsys.readouterr().err


def test_work_queue_gives_the_results_of_the_batch_in_step():
    """A batch larger than ``QUEUE_SLOTS`` runs as a work queue; run in step instead (the
    search kernel compiled with a queue larger than the batch), every target gets the same
    joints and status, bit for bit: invalid and unreachable rows included."""
    chain = serial.from_urdf(MIMIC_URDF, "camera")
    q = np.random.default_rng(4).uniform([-4, -0.1, -1.0], [4, 0.25, 1.2], (100, 3))
    targets = np.array(jaxkin.fk(chain, q).x.p)
    targets[3, 0, 0] = np.nan
    targets[7, :3, 3] = 50.0
    queued = jaxkin.ik(chain, targets)
    assert targets.shape[0] > search.QUEUE_SLOTS
    tols = (jnp.asarray(1e-10), jnp.asarray(1e-10 * chain.length_scale()))
    budget = search.Budget(12, 64, 12, slots=1000)
    solve = jax.jit(  # compiled as the library compiles it (the same code generation)
        search.solve,
        static_argnames=("budget", "use_limits", "rates"),
        compiler_options=dict(search.COMPILER_OPTIONS),
    )
    in_step = solve(chain, Jet.constant(targets), tols, budget, True, False)
    np.testing.assert_array_equal(queued.status, in_step.status)
    np.testing.assert_array_equal(queued.q.p, in_step.q.p)
    assert int(queued.status[3]) == Status.INVALID_INPUT
    assert int(queued.status[7]) == Status.UNREACHABLE
    assert np.mean(np.asarray(queued.status) == Status.OK) >= 0.95


@pytest.mark.slow
def test_host_thread_parts_give_the_results_of_one_thread():
    """A batch of more than two blocks (``search.BLOCK``) runs its blocks on the host threads,
    each its own work queue: the same joints and statuses, bit for bit, as one thread."""
    chain = serial.from_urdf(MIMIC_URDF, "camera")
    n = 2 * search.BLOCK + 7
    q = np.random.default_rng(5).uniform([-4, -0.1, -1.0], [4, 0.25, 1.2], (n, 3))
    targets = jaxkin.fk(chain, q).x.p
    split = jaxkin.ik(chain, targets)
    _batching.set_num_threads(1)
    try:
        whole = jaxkin.ik(chain, targets)
    finally:
        _batching.set_num_threads(None)
    np.testing.assert_array_equal(split.status, whole.status)
    np.testing.assert_array_equal(split.q.p, whole.q.p)
    assert np.mean(np.asarray(split.status) == Status.OK) >= 0.95


_TRACED: list[str] = []
monitoring.register_event_duration_secs_listener(
    lambda event, _, **kw: (
        _TRACED.append(kw.get("fun_name", "")) if event.endswith("jaxpr_trace_duration") else None
    )
)


def test_names_tip_and_batch_sizes_share_compilations():
    """Joint and link names are labels: the same arm renamed, with another tip name, runs the
    programs already compiled; batches of 2 to 32 targets share the IK's 32-row program (and
    one target, of shape () or (1,), its 1-row program), with the results of the whole."""
    chain = serial.from_urdf(MIMIC_URDF, "camera")
    text = MIMIC_URDF.replace('"turn"', '"spin"').replace('"camera"', '"eye"')
    renamed = serial.from_urdf(text, "eye", base_link="world")
    assert renamed.joint_names[0] == "spin" and renamed.tip_link == "eye"
    q = np.random.default_rng(6).uniform([-3, -0.1, -1.0], [3, 0.25, 1.2], (7, 3))
    targets = np.asarray(jaxkin.fk(chain, q).x.p)
    whole = jaxkin.ik(chain, targets)
    single = jaxkin.ik(chain, targets[:1])
    start = len(_TRACED)
    few = jaxkin.ik(renamed, targets[:3])
    grid = jaxkin.ik(renamed, targets[:6].reshape(2, 3, 4, 4))
    one = jaxkin.ik(renamed, targets[0])
    jaxkin.fk(renamed, q)
    traced = _TRACED[start:]
    assert not {"solve", "_fk_core"} & set(traced), traced
    np.testing.assert_array_equal(few.q.p, whole.q.p[:3])
    np.testing.assert_array_equal(grid.q.p, whole.q.p[:6].reshape(2, 3, 3))
    np.testing.assert_array_equal(grid.status, whole.status[:6].reshape(2, 3))
    np.testing.assert_array_equal(one.q.p, single.q.p[0])
    assert one.q.p.shape == (3,) and one.status.shape == ()


def test_a_target_that_is_not_a_rigid_transform_is_invalid_input():
    """Rotation blocks that are not rotations (scaled, mirrored, skewed by 1e-6, NaN) are
    ``INVALID_INPUT``, never ``OK``; the rigid target beside them is solved."""
    chain = serial.from_urdf(MIMIC_URDF, "camera")
    good = np.asarray(jaxkin.fk(chain, np.array([0.4, 0.1, 0.3])).x.p)
    bad = np.stack([good] * 4)
    bad[0, :3, :3] *= 2.0
    bad[1, :3, 2] *= -1.0
    bad[2, 0, 1] += 1e-6
    bad[3, 1, 1] = np.nan
    result = jaxkin.ik(chain, np.concatenate([good[None], bad]))
    names = [Status(int(s)).name for s in result.status]
    assert names == ["OK"] + ["INVALID_INPUT"] * 4
    assert np.all(np.isfinite(np.asarray(result.q.p)))


# ----------------------------------------------------------------- what the reader refuses
_TILT_ORIGIN = '<origin xyz="0.1 0.02 0" rpy="0 0.4 0"/>'
DEFECTS = {
    "duplicate joint": (
        ('<joint name="side"', '<joint name="tilt"'),
        "two joints are named 'tilt'",
    ),
    "duplicate link": (
        ('<link name="camera"/>', '<link name="camera"/><link name="camera"/>'),
        "two links are named 'camera'",
    ),
    "two parent joints": (
        ('<child link="finger_b"/>', '<child link="finger_a"/>'),
        "link 'finger_a' is the child of two joints, 'tilt_mimic' and 'side'",
    ),
    "NaN in an origin's xyz": (
        (_TILT_ORIGIN, '<origin xyz="nan 0.02 0" rpy="0 0.4 0"/>'),
        "joint 'tilt': <origin> has a NaN or inf",
    ),
    "inf in an origin's rpy": (
        (_TILT_ORIGIN, '<origin xyz="0.1 0.02 0" rpy="0 inf 0"/>'),
        "joint 'tilt': <origin> has a NaN or inf",
    ),
    "NaN off the path": (
        ('<origin xyz="0 0.05 0"/>', '<origin xyz="0 NaN 0"/>'),
        "joint 'side': <origin> has a NaN or inf",
    ),
    "NaN in an axis": (
        ('<axis xyz="0 1 0"/>', '<axis xyz="0 nan 0"/>'),
        "joint 'tilt': <axis> has a NaN or inf",
    ),
    "inf in a limit": (
        ('lower="-1" upper="1.2"', 'lower="-1" upper="inf"'),
        "joint 'tilt': <limit upper> has a NaN or inf",
    ),
    "NaN speed limit": (
        ('effort="1" velocity="2"', 'effort="1" velocity="nan"'),
        "joint 'tilt': <limit velocity> has a NaN or inf",
    ),
    "NaN mimic multiplier": (
        ('multiplier="-0.5"', 'multiplier="nan"'),
        "joint 'tilt_mimic': <mimic multiplier> has a NaN or inf",
    ),
}


@pytest.mark.parametrize("defect", list(DEFECTS))
def test_the_reader_refuses_what_pinocchio_refuses_naming_the_joint_or_link(defect):
    """Each defect is refused by Pinocchio's own URDF parser (urdfdom) and by ours, whose
    message names the joint or link."""
    change, message = DEFECTS[defect]
    text = MIMIC_URDF.replace(*change)
    assert text != MIMIC_URDF
    pin.buildModelFromXML(MIMIC_URDF)  # the unchanged file loads
    with pytest.raises(ValueError):
        pin.buildModelFromXML(text)
    with pytest.raises(ValueError, match=re.escape(message)):
        serial.from_urdf(text, "camera")


@pytest.mark.parametrize(
    ("mimic", "message"),
    [
        ('multiplier="0" offset="5"', "multiplier 0, so it stays at its offset 5.0, outside"),
        ('multiplier="1" offset="10"', "its limits leave no position for its leader 'tilt'"),
    ],
)
def test_a_mimic_joint_that_can_never_be_within_its_limits_is_refused(mimic, message):
    """``tilt_mimic`` (limits [-3, 3]) at ``c tilt + b``, tilt in [-1, 1.2]: a constant 5, or
    [9, 11.2]. Pinocchio loads both files (it does not check mimic limits); the chain would
    answer poses no limit-respecting robot reaches."""
    text = MIMIC_URDF.replace('multiplier="-0.5" offset="0.1"', mimic)
    pin.buildModelFromXML(text)
    with pytest.raises(ValueError, match=re.escape(message)) as refused:
        serial.from_urdf(text, "camera")
    assert str(refused.value).startswith("joint 'tilt_mimic': ")


def test_a_constant_mimic_joint_within_its_limits_is_kept():
    chain = serial.from_urdf(
        MIMIC_URDF.replace('multiplier="-0.5" offset="0.1"', 'multiplier="0" offset="0.5"'),
        "camera",
    )
    assert chain.joint_names == ("turn", "reach", "tilt")
    np.testing.assert_array_equal(chain.multiplier, [1.0, 1.0, 1.0, 0.0])
    np.testing.assert_array_equal(chain.offset, [0.0, 0.0, 0.0, 0.5])
    np.testing.assert_array_equal(chain.lower, [-np.inf, -0.1, -1.0])  # tilt's own limits


def test_an_unknown_target_kind_is_refused():
    with pytest.raises(ValueError, match="target: expected one of"):
        serial.from_urdf(MIMIC_URDF, "camera", target="position")
    with pytest.raises(ValueError, match="Chain.target_kind"):
        serial.Chain.create(np.array([[0.0, 0, 1, 0, 0, 0]]), np.eye(4), target="frame")


# ------------------------------------------------------------------------ point targets
def _dh_point(a, alpha, d, q):
    """The tip origin of a standard DH chain, ``prod Rz(q) Tz(d) Tx(a) Rx(alpha)``, in numpy."""
    pose = np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4)).copy()
    for i in range(q.shape[-1]):
        c, s = np.cos(q[..., i]), np.sin(q[..., i])
        ca, sa = np.cos(alpha[i]), np.sin(alpha[i])
        link = np.zeros((*q.shape[:-1], 4, 4))
        link[..., 0, :] = np.stack([c, -s * ca, s * sa, a[i] * c], -1)
        link[..., 1, :] = np.stack([s, c * ca, -c * sa, a[i] * s], -1)
        link[..., 2, :] = [0.0, sa, ca, d[i]]
        link[..., 3, 3] = 1.0
        pose = pose @ link
    return pose[..., :3, 3]


ELBOW = {"a": [0.0, 0.4, 0.3], "alpha": [np.pi / 2, 0.0, 0.0], "d": [0.2, 0.0, 0.0]}


def test_point_chains_return_points_and_pose_chains_are_unchanged():
    """``target="point"``: ``fk`` gives the tip origin (the DH closed form, 1e-12) with its
    rates; the same table as a pose chain still gives 4x4 poses with the same translation."""
    table = serial.DHTable.create(**ELBOW)
    point = serial.from_dh(table, target="point")
    pose = serial.from_dh(table)
    assert point.target is jaxkin.robot.POINT and pose.target is jaxkin.robot.POSE
    q = np.random.default_rng(5).uniform(-3, 3, (7, 3))
    q_dot = np.random.default_rng(6).normal(size=(7, 3))
    x = jaxkin.fk(point, Jet(q, q_dot, np.zeros_like(q))).x
    assert x.p.shape == (7, 3)
    expected = _dh_point(ELBOW["a"], ELBOW["alpha"], ELBOW["d"], q)
    np.testing.assert_allclose(x.p, expected, rtol=0, atol=1e-12)
    h = 1e-6  # central differences of the closed form: O(h^2) ~ 1e-12
    by_differences = (
        _dh_point(ELBOW["a"], ELBOW["alpha"], ELBOW["d"], q + h * q_dot)
        - _dh_point(ELBOW["a"], ELBOW["alpha"], ELBOW["d"], q - h * q_dot)
    ) / (2 * h)
    np.testing.assert_allclose(x.v, by_differences, rtol=0, atol=1e-8)
    np.testing.assert_allclose(jaxkin.fk(pose, q).x.p[..., :3, 3], expected, atol=1e-12)


@pytest.mark.slow
def test_a_three_joint_point_chain_solves_positions_with_rates():
    """Points of an elbow arm (from joints within the limits): ``OK`` and the DH closed form at
    the returned joints is the point to the position tolerance; joint rates reproduce the
    point's velocity (a square Jacobian); NaN and out-of-reach points are flagged."""
    table = serial.DHTable.create(**ELBOW)
    limits = np.full(3, 2.5)
    chain = serial.from_dh(table, lower=-limits, upper=limits, target="point")
    rng = np.random.default_rng(7)
    q = rng.uniform(-2.4, 2.4, (30, 3))
    q_dot = rng.normal(size=(30, 3))
    target = jaxkin.fk(chain, Jet(q, q_dot, np.zeros_like(q))).x
    p = np.concatenate([np.asarray(target.p), [[np.nan, 0, 0], [2.0, 0, 0.2]]])
    v = np.concatenate([np.asarray(target.v), np.zeros((2, 3))])
    result = jaxkin.ik(chain, Jet(p, v, np.zeros_like(p)))
    status = np.asarray(result.status)
    assert status[:30].tolist() == [Status.OK] * 30
    assert status[30:].tolist() == [Status.INVALID_INPUT, Status.UNREACHABLE]
    solved = np.asarray(result.q.p)[:30]
    assert np.all(np.abs(solved) <= 2.5)
    reached = _dh_point(ELBOW["a"], ELBOW["alpha"], ELBOW["d"], solved)
    tolerance = 1e-10 * float(chain.length_scale())
    assert np.max(np.linalg.norm(reached - p[:30], axis=-1)) <= tolerance
    # the rates: J(q) q_dot = p_dot at the solution (whichever branch it is)
    by_rates = jaxkin.fk(chain, Jet(solved, np.asarray(result.q.v)[:30], np.zeros((30, 3)))).x.v
    np.testing.assert_allclose(by_rates, v[:30], rtol=0, atol=1e-8 * np.abs(v).max())


@pytest.mark.slow
def test_a_five_joint_arm_solves_positions_checked_by_pinocchio():
    """The SO-101 (5 joints to ``gripper_frame_link``) with point targets: every point of a
    configuration within the limits is ``OK``, within the limits, and Pinocchio's placement of
    the tip frame at the returned joints is the point to the position tolerance; the same
    points as a planned path (``plan.evaluate``) come back solved and continuous."""
    chain = serial.from_urdf(_path("so101"), ARMS["so101"][1], target="point")
    assert chain.n_joints == 5 and chain.target.shape == (3,)
    model = pin.buildModelFromUrdf(_path("so101"))
    data = model.createData()
    frame = model.getFrameId(ARMS["so101"][1])
    columns = [model.joints[model.getJointId(j)].idx_q for j in chain.joint_names]

    def tip(q):
        full = pin.neutral(model)
        full[columns] = q
        pin.framesForwardKinematics(model, data, full)
        return data.oMf[frame].translation.copy()

    q = _random_q(chain, 48, 11)
    points = np.array([tip(qi) for qi in q])
    np.testing.assert_allclose(jaxkin.fk(chain, q).x.p, points, rtol=0, atol=1e-12)
    result = jaxkin.ik(chain, points)
    assert np.all(np.asarray(result.status) == Status.OK)
    solved = np.asarray(result.q.p)
    assert np.all((solved >= chain.lower) & (solved <= chain.upper))
    reached = np.array([tip(qi) for qi in solved])
    tolerance = 1e-10 * float(chain.length_scale())
    assert np.max(np.linalg.norm(reached - points, axis=-1)) <= tolerance

    # a path of points made from a slow joint motion, evaluated as a plan
    dt, t = 0.02, np.arange(40) * 0.02
    motion = 0.3 * np.sin(np.outer(t, [1.0, 0.7, -0.5, 0.9, 1.3]))[None] + np.array(
        [0.2, -0.3, 0.4, 0.1, -0.2]
    )
    path = paths.path_from_samples(np.array([[tip(qi) for qi in motion[0]]]), dt)
    ev = plan.evaluate(chain, path, dt=dt)
    assert np.all(np.asarray(ev.status) == Status.OK) and bool(np.asarray(ev.feasible)[0])
    along = np.array([tip(qi) for qi in np.asarray(ev.q.p)[0]])
    assert np.max(np.linalg.norm(along - path.p[0], axis=-1)) <= 1e-9


def test_joints_off_the_path_held_and_mimicked_as_pinocchio_places_them():
    """``fixed={"panda_finger_joint1": 0.03}``: both fingers (the second mimics the first)
    and every other link are where Pinocchio's forward kinematics of the whole model puts
    them with both finger joints at 0.03, at random arm joints (1e-12)."""
    chain = serial.from_urdf(_path("panda"), "panda_hand", fixed={"panda_finger_joint1": 0.03})
    assert dict(chain.links.held) == {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.03}
    closed = serial.from_urdf(_path("panda"), "panda_hand")
    model = pin.buildModelFromUrdf(_path("panda"))
    data = model.createData()
    for q7 in _random_q(chain, 3, seed=4):
        q = pin.neutral(model)
        q[:7], q[7:9] = q7, 0.03
        pin.framesForwardKinematics(model, data, q)
        base = np.linalg.inv(data.oMf[model.getFrameId("panda_link0")].homogeneous)
        poses = np.asarray(chain.link_poses(q7))
        for i, name in enumerate(chain.links.names):
            reference = base @ data.oMf[model.getFrameId(name)].homogeneous
            np.testing.assert_allclose(poses[i], reference, atol=1e-12, err_msg=name)
        moved = np.linalg.norm(
            poses[:, :3, 3] - np.asarray(closed.link_poses(q7))[:, :3, 3], axis=-1
        )
        fingers = [chain.links.names.index(n) for n in ("panda_leftfinger", "panda_rightfinger")]
        np.testing.assert_allclose(moved[fingers], 0.03, atol=1e-15)
        assert np.delete(moved, fingers).max() == 0.0
    np.testing.assert_array_equal(chain.screws, closed.screws)  # the kinematics are the same


@pytest.mark.parametrize(
    "fixed, message",
    [
        ({"panda_finger_joint1": 0.05}, "'panda_finger_joint1' = 0.05 lies outside its limits"),
        ({"panda_finger_joint1": np.nan}, "'panda_finger_joint1' = nan lies outside"),
        ({"panda_finger_joint1": "open"}, "needs a number"),
        ({"panda_finger_joint2": 0.01}, "mimics 'panda_finger_joint1': give that joint's"),
        ({"panda_joint3": 0.1}, "'panda_joint3' is on the chain's path"),
        ({"panda_hand_joint": 0.0}, "'panda_hand_joint' is fixed, not a moving joint"),
        ({"gripper": 0.0}, r"no joint 'gripper'.*joints off the path: 'panda_finger_joint1'"),
        ([("panda_finger_joint1", 0.01)], "expected a mapping"),
    ],
)
def test_fixed_joints_are_checked_naming_the_joint(fixed, message):
    with pytest.raises(ValueError, match=message):
        serial.from_urdf(_path("panda"), "panda_hand", fixed=fixed)


# ---------------------------------------------------------------- example-robot-data by name


def test_example_robots_name_existing_files_and_links():
    """Every listed arm's URDF (and SRDF) exists under the installed data, its tool and base
    links are links of its URDF, and ``package_dir`` holds its description folder."""
    for name in serial.example_robots.EXAMPLE_ROBOTS:
        found = serial.example_robot(name)
        assert found.name == name and found.urdf.is_file(), name
        assert found.urdf.is_relative_to(ROBOTS) and found.package_dir == ROBOTS
        assert found.srdf is None or found.srdf.is_file()
        text = found.urdf.read_text()
        for link in (found.tip, found.base):
            assert link is None or re.search(rf'<link\s+name="{re.escape(link)}"', text), link
        assert (found.package_dir / found.urdf.relative_to(ROBOTS).parts[0]).is_dir()


def test_example_robot_chain_is_the_urdf_chain_with_the_srdf():
    panda = serial.example_robot("panda")
    chain = panda.chain()
    by_hand = serial.from_urdf(str(ROBOTS / "panda_description/urdf/panda.urdf"), "panda_hand")
    by_hand = by_hand.with_srdf(str(ROBOTS / "panda_description/srdf/panda.srdf"))
    assert chain.joint_names == by_hand.joint_names
    assert chain.links.disabled == by_hand.links.disabled and len(chain.links.disabled) == 35
    q = np.linspace(-0.5, 0.5, 7)
    np.testing.assert_array_equal(jaxkin.fk(chain, q).x.p, jaxkin.fk(by_hand, q).x.p)


def test_example_robot_errors_name_the_robots_and_the_extra(monkeypatch):
    with pytest.raises(ValueError, match=r"name: expected one of panda, ur3, .* got 'pumaa'"):
        serial.example_robot("pumaa")

    def absent(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "distribution", absent)
    with pytest.raises(ImportError, match=r"example-robot-data.*jaxkin\[robots\]"):
        serial.example_robot("panda")
