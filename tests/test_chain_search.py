"""The chain IK search (``serial.search``): one compilation for every batch size, invariance to
the unit of a prismatic joint, honest ``OUT_OF_LIMITS``, and success on the real chains of
example-robot-data checked by Pinocchio's forward kinematics (slow tier).

Tolerances: the search's defaults (1e-10 rad, 1e-10 of the chain's size in float64); answers
are checked at 1e-9 rad and 1e-9 of the chain's size by an independent forward kinematics.
"""

from __future__ import annotations

import importlib.metadata

import numpy as np
import pytest
from jax import monitoring
from scipy.spatial.transform import Rotation

import jaxkin
from jaxkin import Status, serial
from jaxkin.serial import search

# A 6-joint chain with a prismatic joint (RRPRRR), in metres: screws at home, base frame.
_SCREWS = np.array(
    [
        [0, 0, 1, 0, 0, 0],  # about z through the origin
        [0, 1, 0, -0.4, 0, 0],  # about y through (0, 0, 0.4): v = -omega x r
        [0, 0, 0, 1, 0, 0],  # slides along x
        [1, 0, 0, 0, 0.4, 0],  # about x through (., 0, 0.4)
        [0, 1, 0, -0.4, 0, 0.6],  # about y through (0.6, 0, 0.4)
        [1, 0, 0, 0, 0.4, 0],  # about x through (., 0, 0.4)
    ],
    float,
)
_HOME = np.array([[1, 0, 0, 0.7], [0, 1, 0, 0], [0, 0, 1, 0.4], [0, 0, 0, 1]], float)
_LOWER = np.array([-2.9, -2.0, 0.05, -2.9, -2.0, -2.9])
_UPPER = np.array([2.9, 2.0, 0.45, 2.9, 2.0, 2.9])


def _chain(unit: float = 1.0, **names) -> serial.Chain:
    """The test chain with lengths in ``1 / unit`` metres (1000: millimetres)."""
    screws = _SCREWS.copy()
    screws[:, 3:] *= np.where(np.any(screws[:, :3] != 0, axis=1), unit, 1.0)[:, None]
    home = _HOME.copy()
    home[:3, 3] *= unit
    prismatic = np.array([False, False, True, False, False, False])
    scale = np.where(prismatic, unit, 1.0)
    return serial.Chain.create(screws, home, lower=_LOWER * scale, upper=_UPPER * scale, **names)


@pytest.fixture(scope="module")
def chain():
    return _chain()


def _targets(chain, n, seed):
    q = np.random.default_rng(seed).uniform(chain.lower, chain.upper, (n, chain.n_joints))
    return q, np.asarray(jaxkin.fk(chain, q).x.p)


def _pose_error(a, b):
    """(rotation angle, distance) between transforms ``(..., 4, 4)``."""
    relative = np.swapaxes(a[..., :3, :3], -1, -2) @ b[..., :3, :3]
    angle = Rotation.from_matrix(relative.reshape(-1, 3, 3)).magnitude().reshape(a.shape[:-2])
    return angle, np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1)


_COMPILED: list[str] = []
monitoring.register_event_duration_secs_listener(
    lambda event, _, **kw: (
        _COMPILED.append(kw.get("fun_name", ""))
        if event.endswith("backend_compile_duration")
        else None
    )
)


def test_every_batch_size_names_and_tip_share_one_compilation(chain):
    """After the first call, batch sizes 1 to two blocks and more, a grid, the chain with its
    joints and links renamed compile nothing: every concrete batch runs in blocks of
    ``search.BLOCK`` targets through one program; each answer is the whole batch's."""
    _, targets = _targets(chain, search.BLOCK + 40, seed=0)
    renamed = _chain(joint_names=[f"j{k}" for k in range(6)], base_link="b", tip_link="t")
    whole = jaxkin.ik(chain, targets)
    start = len(_COMPILED)
    one = jaxkin.ik(chain, targets[5])
    few = jaxkin.ik(renamed, targets[:3])
    grid = jaxkin.ik(chain, targets[:6].reshape(2, 3, 4, 4))
    again = jaxkin.ik(renamed, targets)
    assert _COMPILED[start:] == []
    np.testing.assert_array_equal(one.q.p, whole.q.p[5])
    np.testing.assert_array_equal(few.q.p, whole.q.p[:3])
    np.testing.assert_array_equal(grid.status, whole.status[:6].reshape(2, 3))
    np.testing.assert_array_equal(again.q.p, whole.q.p)
    assert one.q.p.shape == (6,) and one.status.shape == ()
    ok = np.asarray(whole.status) == Status.OK
    assert ok.mean() >= 0.99
    angle, distance = _pose_error(np.asarray(jaxkin.fk(chain, whole.q.p).x.p)[ok], targets[ok])
    assert angle.max() <= 1e-9 and distance.max() <= 1e-9 * float(chain.length_scale())


def test_float32_poses_of_a_float64_chain_are_poses_to_float32_precision(chain):
    """Poses rounded to float32 (``jaxkin.ik`` and a compiled handle of float32 targets) are
    solved by the float64 chain in float64: ``OK`` to the float64 defaults (1e-10 rad, 1e-10
    of the size) against the pose whose rotation is the polar factor of the float32 block
    (scipy's, an independent computation), checked by the forward kinematics at 1e-9; that
    rotation is no farther from the float32 block than the float64 rotation rounded to it.
    Blocks that are not rotations in float32 (skewed by 1e-3, beyond its ``sqrt(eps)`` of
    3.5e-4; scaled by 1.01; mirrored; NaN) stay ``INVALID_INPUT``."""
    from scipy.linalg import polar

    _, poses = _targets(chain, 6, seed=7)
    given = poses.astype(np.float32)
    bad = np.stack([given[0]] * 4)
    bad[0, 0, 1] += 1e-3
    bad[1, :3, :3] *= 1.01
    bad[2, :3, 2] *= -1.0
    bad[3, 1, 1] = np.nan
    result = jaxkin.ik(chain, np.concatenate([given, bad]))
    handle = jaxkin.compiled(jaxkin.ik, chain, batch=(6,), dtype=np.float32)(given)
    names = [Status(int(s)).name for s in result.status]
    assert names == ["OK"] * 6 + ["INVALID_INPUT"] * 4
    assert result.q.p.dtype == np.float64 and np.all(np.isfinite(np.asarray(result.q.p)))
    np.testing.assert_array_equal(handle.status, result.status[:6])
    block = given[:, :3, :3].astype(np.float64)
    meant = given.astype(np.float64)
    meant[:, :3, :3] = [polar(b)[0] for b in block]
    for q in (result.q.p[:6], handle.q.p):
        angle, distance = _pose_error(np.asarray(jaxkin.fk(chain, q).x.p), meant)
        assert angle.max() <= 1e-9 and distance.max() <= 1e-9 * float(chain.length_scale())
    moved = np.linalg.norm(meant[:, :3, :3] - block, axis=(-2, -1))
    rounded = np.linalg.norm(poses[:, :3, :3] - block, axis=(-2, -1))
    assert np.all(moved <= rounded)


def test_a_prismatic_joint_in_millimetres_solves_as_in_metres(chain):
    """The same chain in millimetres (its lengths and its prismatic stroke times 1000): the same
    poses (translations times 1000) get the same statuses and the same joints (the prismatic
    one times 1000), to 1e-6 of each joint's range."""
    mm = _chain(1000.0)
    _, targets = _targets(chain, 64, seed=1)
    scaled = targets.copy()
    scaled[:, :3, 3] *= 1000.0
    metres, millimetres = jaxkin.ik(chain, targets), jaxkin.ik(mm, scaled)
    np.testing.assert_array_equal(metres.status, millimetres.status)
    assert np.mean(np.asarray(metres.status) == Status.OK) >= 0.99
    q = np.asarray(millimetres.q.p) / np.array([1, 1, 1000.0, 1, 1, 1])
    np.testing.assert_allclose(q, metres.q.p, atol=1e-6 * np.max(_UPPER - _LOWER))


def test_out_of_limits_only_where_every_unbounded_run_lands_outside(chain):
    """The base joint limited to [0, 0.5]: targets made with it at 2.0 (the other joints within
    their limits) are solved only outside the limits; every one comes back ``OUT_OF_LIMITS``
    with joints that reach it (the chain's own FK, 1e-9) and leave the limits. Targets made
    within the limits come back ``OK`` within them."""
    lower, upper = _LOWER.copy(), _UPPER.copy()
    lower[0], upper[0] = 0.0, 0.5
    narrow = serial.Chain.create(_SCREWS, _HOME, lower=lower, upper=upper)
    q, _ = _targets(narrow, 8, seed=2)
    outside = q.copy()
    outside[:4, 0] = 2.0
    targets = np.asarray(jaxkin.fk(narrow, outside).x.p)
    res = jaxkin.ik(narrow, targets)
    status = np.asarray(res.status)
    assert status[:4].tolist() == [Status.OUT_OF_LIMITS] * 4
    assert np.all(status[4:] == Status.OK)
    angle, distance = _pose_error(np.asarray(jaxkin.fk(narrow, res.q.p).x.p), targets)
    assert angle.max() <= 1e-9 and distance.max() <= 1e-9
    joints = np.asarray(res.q.p)
    assert np.all(np.any((joints[:4] < lower) | (joints[:4] > upper), axis=-1))
    assert np.all((joints[4:] >= lower) & (joints[4:] <= upper))


# ---------------------------------------------------------------- real chains (slow tier)

_ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
# Every arm of example-robot-data with six or more joints from its base to its tool (torsos
# with a prismatic lift included): (URDF, base link or None for the root, tip link).
REAL_CHAINS = {
    "ur3": ("ur_description/urdf/ur3_robot.urdf", None, "tool0"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", None, "tool0"),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", None, "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", None, "panda_hand"),
    "kinova": ("kinova_description/robots/kinova.urdf", None, "j2s6s200_end_effector"),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", None, "link_eef"),
    "z1": ("z1_description/urdf/z1.urdf", None, "gripperStator"),
    "tiago": ("tiago_description/robots/tiago.urdf", "base_link", "arm_tool_link"),
    "tiago_pro": ("tiago_pro_description/robots/tiago_pro.urdf", "base_link", "arm_left_tool_link"),
    "baxter": ("baxter_description/urdf/baxter.urdf", "torso", "left_gripper"),
    "pr2": ("pr2_description/urdf/pr2.urdf", "base_link", "r_gripper_tool_frame"),
}


def real_chain_success(name: str, n: int = 300, seed: int = 0) -> dict:
    """IK of ``n`` poses made by Pinocchio from joints uniform within the URDF's limits
    (continuous joints over [-pi, pi)), each answer checked by Pinocchio: the pose error of
    ``OK`` answers, their joints within the limits, ``OUT_OF_LIMITS`` answers reaching the
    target outside the limits. Returns the rate of ``OK`` and the checks' results."""
    import pinocchio as pin

    urdf, base, tip = REAL_CHAINS[name]
    path = str(_ROBOTS / urdf)
    chain = serial.from_urdf(path, tip, base_link=base)
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    frame = model.getFrameId(tip, pin.FrameType.BODY)  # the link (a joint may share its name)
    base_frame = None if base is None else model.getFrameId(base, pin.FrameType.BODY)
    joints = [model.joints[model.getJointId(j)] for j in chain.joint_names]

    def poses(q):
        out = []
        for qi in q:
            full = pin.neutral(model)
            for joint, value in zip(joints, qi, strict=True):
                if joint.nq == 2:  # continuous: (cos, sin)
                    full[joint.idx_q : joint.idx_q + 2] = np.cos(value), np.sin(value)
                else:
                    full[joint.idx_q] = value
            pin.framesForwardKinematics(model, data, full)
            pose = data.oMf[frame]
            if base_frame is not None:
                pose = data.oMf[base_frame].actInv(pose)
            out.append(pose.homogeneous)
        return np.array(out)

    lower = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    q = np.random.default_rng(seed).uniform(lower, upper, (n, chain.n_joints))
    targets = poses(q)
    res = jaxkin.ik(chain, targets)
    status, answer = np.asarray(res.status), np.asarray(res.q.p)
    ok = status == Status.OK
    size = float(chain.length_scale())
    angle, distance = _pose_error(poses(answer), targets)
    within = np.all((answer >= chain.lower) & (answer <= chain.upper), axis=-1)
    out = status == Status.OUT_OF_LIMITS
    return {
        "chain": chain,
        "rate": ok.mean(),
        "ok_errors": (angle[ok].max(initial=0.0), distance[ok].max(initial=0.0) / size),
        "ok_within": bool(within[ok].all()),
        "out_honest": bool(
            np.all(angle[out] <= 1e-9)
            and np.all(distance[out] <= 1e-9 * size)
            and not within[out].any()
        ),
        "statuses": {Status(int(s)).name: int(np.sum(status == s)) for s in np.unique(status)},
    }


@pytest.mark.slow
@pytest.mark.parametrize("name", list(REAL_CHAINS))
def test_real_chains_solve_in_limit_poses(name):
    """At least 99.5 % of 300 poses made from joints within the limits are ``OK`` on every
    real chain, each ``OK`` answer within 1e-9 rad and 1e-9 of the chain's size of its target
    by Pinocchio and within the URDF's limits; ``OUT_OF_LIMITS`` answers reach their targets
    outside the limits; the rest is ``NOT_CONVERGED``."""
    found = real_chain_success(name)
    assert found["chain"].n_joints >= 6
    assert found["rate"] >= 0.995, found["statuses"]
    assert found["ok_errors"][0] <= 1e-9 and found["ok_errors"][1] <= 1e-9
    assert found["ok_within"] and found["out_honest"]
    assert set(found["statuses"]) <= {"OK", "OUT_OF_LIMITS", "NOT_CONVERGED"}


@pytest.mark.parametrize("target", ["pose", "point"])
def test_task_jacobian_rate_matches_autodiff(target):
    """The closed-form rate of the task Jacobian (Lie brackets of the body Jacobian's columns)
    equals forward-mode autodiff of the Jacobian along ``q_dot`` to 1e-12, for pose and point
    targets, on the test chain with a mimic joint (row 5 follows row 3, c = -1.5, b = 0.2)."""
    import jax

    from jaxkin.serial import _kinematics

    base = _chain()
    mimic = serial.Chain.create(base.screws, base.home, mimic={5: (3, -1.5, 0.2)}, target=target)
    rng = np.random.default_rng(5)
    q = rng.uniform(-2.0, 2.0, (16, mimic.n_joints))
    q_dot = rng.normal(size=q.shape)
    expected = jax.jvp(lambda x: search._task_jacobian(mimic, x), (q,), (q_dot,))[1]
    theta = _kinematics.angles(mimic, q)
    rot, _, jac_theta = _kinematics.screws_fk_and_jacobian(mimic.screws, mimic.home, theta, "body")
    rate = search._task_jacobian_rate(mimic, rot, jac_theta, q_dot)
    assert rate.shape == expected.shape
    np.testing.assert_allclose(rate, expected, rtol=0, atol=1e-12)


def _with_leaf(chain: serial.Chain, name: str, value):
    """``chain`` with its numeric field ``name`` replaced (no validation: ``value`` may be
    traced)."""
    import jax

    def pick(path, leaf):
        return value if path[-1] == jax.tree_util.GetAttrKey(name) else leaf

    return jax.tree_util.tree_map_with_path(pick, chain)


@pytest.mark.slow
def test_implicit_derivatives_keep_the_tool_on_the_target(chain):
    """Derivatives of ``jaxkin.ik``'s joints, checked through the forward kinematics (autodiff
    of ``jaxkin.fk``, independent of the search), on 4 poses of the test chain (all ``OK``):

    * along a body twist ``xi`` of the target, ``T(e) = T exp(e [xi])``: the joints' derivative
      moves the tool by ``T^-1 dT = [xi]`` (to 1e-9: measured 6e-11; the solution meets 1e-10);
    * along a change of the chain (its home pose's translation; its screws, kept unit), with
      the target fixed: the tool stays on the target, ``d fk(chain(e), q(e)) = 0`` (to 1e-9;
      measured 2e-10);
    * reverse mode equals forward mode (to 1e-12), and every derivative is finite.

    Slow tier: each derivative compiles the search once more (about 40 s in all)."""
    import jax
    import jax.numpy as jnp

    from jaxkin import lie

    q0, poses = _targets(chain, 4, 11)
    result = jaxkin.ik(chain, poses)
    assert (np.asarray(result.status) == Status.OK).all()
    q = np.asarray(result.q.p)
    xi = np.random.default_rng(12).normal(size=(4, 6))

    def solved(e):
        return jaxkin.ik(chain, poses @ lie.se3_exp(e[:, None] * xi)).q.p

    zero = jnp.zeros(4)
    q_ref, dq = jax.jvp(solved, (zero,), (jnp.ones(4),))
    np.testing.assert_allclose(q_ref, q, rtol=0, atol=1e-12)  # a traced program of its own

    def tool(c, joints):
        return jaxkin.fk(c, joints).x.p

    moved = jax.jvp(lambda x: tool(chain, x), (q,), (dq,))[1]
    np.testing.assert_allclose(np.linalg.inv(poses) @ moved, lie.se3_hat(xi), rtol=0, atol=1e-9)

    rng = np.random.default_rng(13)
    screws = np.asarray(chain.screws)
    rotating = np.linalg.norm(screws[:, :3], axis=1) > 0.5
    unit = np.where(rotating[:, None], screws[:, :3], screws[:, 3:])  # each screw's unit vector
    # Tangents that keep unit screws (a revolute axis turned and moved, a sliding direction
    # turned): the kernels assume unit screws, so only these are changes of a chain.
    turned = np.cross(unit, rng.normal(size=unit.shape))
    moved = np.cross(unit, rng.normal(size=unit.shape))
    for name, tangent in (
        ("home", np.pad(rng.normal(size=(3, 1)), ((0, 1), (3, 0)))),
        ("screws", np.concatenate([turned * rotating[:, None], moved], axis=1)),
    ):
        base = jnp.asarray(getattr(chain, name))

        def on_target(x, name=name):
            changed = _with_leaf(chain, name, x)
            return tool(changed, jaxkin.ik(changed, poses).q.p)

        drift = jax.jvp(on_target, (base,), (jnp.asarray(tangent),))[1]
        assert np.isfinite(drift).all()
        np.testing.assert_allclose(drift, 0.0, rtol=0, atol=1e-9, err_msg=name)

    weights = rng.normal(size=q.shape)
    forward = jax.jacfwd(solved)(zero)
    reverse = jax.grad(lambda e: jnp.sum(weights * solved(e)))(zero)
    assert np.isfinite(forward).all()
    np.testing.assert_allclose(reverse, np.einsum("ij,ijk->k", weights, forward), atol=1e-12)
