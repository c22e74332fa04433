"""The chain IK along pose paths (``serial.track``, the default of ``plan.evaluate``) on real
arms: pose paths made by Pinocchio from smooth joint motions inside the limits (each a witness
that a continuous answer within every limit exists, ``tests/references/witnessed_paths``) are
found feasible, and every feasible answer passes an independent check: Pinocchio's poses
within 1e-8 (rad plus lengths of the chain's size; the IK's tolerance is 1e-10), the URDF's
position and speed limits, every step explained by the answer's own rates (no jump), and those
rates mapped by Pinocchio's Jacobian onto the target's twist within 1e-6 of it.

The default tier solves a few paths on the two arms the path IK used to lose (the Kinova Jaco's
branches, the xArm7's self-motion); the slow tier sweeps every arm, held-out ones too (Panda,
Z1, UR5), and narrowed limits that the witnesses leave.
"""

from __future__ import annotations

import numpy as np
import pytest

from jaxkin import paths, plan, serial
from jaxkin.status import Status

from .helpers import compilations
from .references import witnessed_paths as wp


def _solve(name: str, count: int, samples: int, draw: int, narrow: float = 0.0):
    """``plan.evaluate`` of ``count`` witnessed pose paths of arm ``name``; ``narrow``: each
    finite limit moved this fraction of its range inwards (after the witnesses are made, so
    that they may leave them). Returns the evaluation and the independent check."""
    urdf, tip = wp.ARMS[name]
    chain = serial.from_urdf(str(wp.ROBOTS / urdf), tip)
    arm = wp.Arm(name, list(chain.joint_names))
    (q, q_dot, q_ddot), dt = wp.witnesses(chain, count, samples, np.random.default_rng(draw))
    p, v, a = wp.pose_path(arm, q, q_dot, q_ddot)
    if narrow:
        lower, upper = np.asarray(chain.lower), np.asarray(chain.upper)
        inset = np.where(np.isfinite(upper - lower), narrow * (upper - lower), 0.0)
        chain = serial.Chain.create(
            chain.screws, chain.home, lower=lower + inset, upper=upper - inset,
            velocity=chain.velocity,
        )  # fmt: skip
    path = paths.Path(p, v, a, dt=dt)
    ev = plan.evaluate(chain, path)
    answer = tuple(np.asarray(x, float) for x in (ev.q.p, ev.q.v, ev.q.a))
    return ev, chain, wp.check_answers(arm, chain, answer, p, v, dt)


def _assert_honest(ev, check, pose_tol: float = 1e-8, rate_tol: float = 1e-6) -> None:
    """Every feasible answer passes the independent check."""
    feasible = np.asarray(ev.feasible)
    assert np.all(check["pose"][feasible] <= pose_tol), check["pose"][feasible].max()
    assert np.all(check["within"][feasible])
    assert np.all(check["slow"][feasible])
    assert np.all(check["explained"][feasible])
    assert np.all(check["rates"][feasible] <= rate_tol), check["rates"][feasible].max()


@pytest.mark.parametrize("name", ["kinova", "xarm7"])
def test_witnessed_paths_are_feasible(name):
    """Four witnessed paths of 32 samples on each of the two arms: every one feasible, every
    answer honest; four other paths of the same shapes compile nothing new."""
    ev, _, check = _solve(name, 4, 32, draw=11)
    assert np.all(ev.feasible), np.asarray(ev.status)
    _assert_honest(ev, check)
    with compilations() as count:
        again, _, check = _solve(name, 4, 32, draw=12)
    assert count.n == 0, count.events
    assert np.all(again.feasible), np.asarray(again.status)
    _assert_honest(again, check)


def test_float32_pose_paths_of_a_float64_chain():
    """The default tier's Kinova paths rounded to float32, given to the float64 chain: poses
    to float32's precision (``Chain.work_target``), solved in float64, every path feasible and
    every answer honest against the float64 witnesses to float32's rounding of them (poses
    1e-6, rates 1e-5 of the twist)."""
    urdf, tip = wp.ARMS["kinova"]
    chain = serial.from_urdf(str(wp.ROBOTS / urdf), tip)
    arm = wp.Arm("kinova", list(chain.joint_names))
    (q, q_dot, q_ddot), dt = wp.witnesses(chain, 4, 32, np.random.default_rng(11))
    p, v, a = wp.pose_path(arm, q, q_dot, q_ddot)
    ev = plan.evaluate(chain, paths.Path(p, v, a, dt=dt).astype(np.float32))
    assert ev.q.p.dtype == np.float64
    assert np.all(ev.feasible), np.asarray(ev.status)
    answer = tuple(np.asarray(x, float) for x in (ev.q.p, ev.q.v, ev.q.a))
    _assert_honest(ev, wp.check_answers(arm, chain, answer, p, v, dt), 1e-6, 1e-5)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(wp.ARMS))
def test_witnessed_paths_sweep(name):
    """40 witnessed paths of 64 samples per arm, the held-out arms too, their control points
    up to 1.6 rad apart: at least 95 % feasible, every feasible answer honest."""
    ev, _, check = _solve(name, 40, 64, draw=sum(map(ord, name)))
    assert np.mean(ev.feasible) >= 0.95, np.asarray(ev.first_failure)
    _assert_honest(ev, check)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["kinova", "xarm7"])
def test_narrowed_limits_give_no_feasible_answer_outside_them(name):
    """Limits narrowed by 30 % of each range on each side, after the witnesses were made
    within 10 % of them: a feasible answer stays within the narrowed limits (the others are
    ``OUT_OF_LIMITS``, ``DISCONTINUOUS`` or ``NOT_CONVERGED``, none ``OK`` throughout)."""
    ev, chain, check = _solve(name, 16, 32, draw=5, narrow=0.3)
    _assert_honest(ev, check)
    status = np.asarray(ev.status)
    assert not np.all(ev.feasible)
    bad = {Status.OUT_OF_LIMITS, Status.DISCONTINUOUS, Status.NOT_CONVERGED, Status.SINGULAR}
    for row in status[~np.asarray(ev.feasible)]:
        assert Status(int(row[row != Status.OK][0])) in bad


@pytest.mark.slow
@pytest.mark.parametrize("name", ["kinova", "xarm7"])
def test_witnessed_paths_in_float32(name):
    """float32: the chain's path IK kernel (``ik_path_kernel``, computing in float32) solves
    every sample of the default tier's witnessed paths, each answer within the check's float32
    tolerances (poses 3e-4, rates 1e-3 of the twist) and continuous within the limits."""
    urdf, tip = wp.ARMS[name]
    chain = serial.from_urdf(str(wp.ROBOTS / urdf), tip)
    arm = wp.Arm(name, list(chain.joint_names))
    (q, q_dot, q_ddot), dt = wp.witnesses(chain, 4, 32, np.random.default_rng(11))
    p, v, a = wp.pose_path(arm, q, q_dot, q_ddot)
    path = paths.Path(p, v, a, dt=dt).astype(np.float32)
    res = chain.ik_path_kernel(path.jet, 0, chain.IKOptions())
    assert res.q.p.dtype == np.float32
    assert np.all(np.asarray(res.status) == Status.OK), np.asarray(res.status)
    answer = tuple(np.asarray(x, float) for x in (res.q.p, res.q.v, res.q.a))
    check = wp.check_answers(arm, chain, answer, p, v, dt)
    # The float32 tolerances: 1000 eps in rotation and in position (of the chain's size).
    assert np.all(check["pose"] <= 3e-4), check["pose"]
    assert np.all(check["rates"] <= 1e-3), check["rates"]
    assert np.all(check["within"] & check["slow"] & check["explained"])
