"""URDF chains: parsed joints, forward kinematics and Jacobians against Pinocchio (its own URDF
parser, on the UR5 and Franka Panda files of example-robot-data), mimic, continuous and
prismatic joints against yourdfpy's own forward kinematics, errors that name the link or joint,
IK with no seed checked with Pinocchio's forward kinematics, and pose paths through the planner
checked by the forward kinematics of the planned joints (rates included).

Tolerances: 1e-12 for forward kinematics and Jacobians (float64, chains of about 1 m); the IK
at its default tolerances (1e-10 rad and 1e-10 of the chain's size), checked at 1e-9.
"""

from __future__ import annotations

import importlib.metadata
import io

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
    solve = jax.jit(search.solve, static_argnames=("budget", "use_limits", "rates"))
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
