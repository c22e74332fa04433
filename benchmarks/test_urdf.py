"""URDF chains (UR5, Franka Panda of example-robot-data) beside Pinocchio, float64.

FK (tool pose) and the space Jacobian of ``serial.from_urdf`` chains at 1e5 configurations
within the limits, against Pinocchio's per-configuration loop from Python
(``framesForwardKinematics`` / ``computeFrameJacobian``) on 1e4 of them (its rate per case does
not depend on the count). IK: ``jaxkin.ik`` with its defaults (no seed, restarts, joint
limits) on 1,000 pose targets made from joints within the limits; the success fraction
(``OK``: within 1e-10 rad and 1e-10 of the chain's size) goes to ``extra_info``.
"""

from __future__ import annotations

import importlib.metadata

import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest

import jaxkin
from jaxkin import Status, serial

ROBOTS = importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"
)
ARMS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand"),
}


def _setup(name: str, n: int):
    path = str(ROBOTS / ARMS[name][0])
    chain = serial.from_urdf(path, ARMS[name][1])
    q = np.random.default_rng(0).uniform(chain.lower, chain.upper, size=(n, chain.n_joints))
    return path, chain, q


@pytest.mark.parametrize("arm", list(ARMS))
def test_jaxkin_fk(measure, arm):
    _, chain, q = _setup(arm, 100_000)
    q = jnp.asarray(q)
    measure(lambda: jaxkin.fk(chain, q).x.p, len(q), kernel=f"fk[{arm}]", dtype="float64")


@pytest.mark.parametrize("arm", list(ARMS))
def test_jaxkin_space_jacobian(measure, arm):
    _, chain, q = _setup(arm, 100_000)
    q = jnp.asarray(q)
    measure(lambda: serial.space_jacobian(chain, q), len(q), kernel=f"jacobian[{arm}]")


def _pinocchio_loop(path: str, tip: str, chain, q: np.ndarray, jacobian: bool):
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    frame = model.getFrameId(tip)
    columns = [model.joints[model.getJointId(j)].idx_q for j in chain.joint_names]
    full = np.tile(pin.neutral(model), (len(q), 1))
    full[:, columns] = q

    def run():
        out = []
        for qi in full:
            if jacobian:
                out.append(pin.computeFrameJacobian(model, data, qi, frame, pin.WORLD))
            else:
                pin.framesForwardKinematics(model, data, qi)
                out.append(data.oMf[frame].homogeneous)
        return out

    return run


@pytest.mark.parametrize("what", ["fk", "jacobian"])
@pytest.mark.parametrize("arm", list(ARMS))
def test_pinocchio_loop(measure, arm, what):
    path, chain, q = _setup(arm, 10_000)
    run = _pinocchio_loop(path, ARMS[arm][1], chain, q, what == "jacobian")
    measure(run, len(q), rounds=3, kernel=f"pinocchio {what}[{arm}] (Python loop)")


@pytest.mark.parametrize("arm", list(ARMS))
def test_jaxkin_ik(measure, benchmark, arm):
    _, chain, q = _setup(arm, 1_000)
    targets = jnp.asarray(jaxkin.fk(chain, q).x.p)
    res = measure(lambda: jaxkin.ik(chain, targets), len(q), rounds=3, kernel=f"ik[{arm}]")
    benchmark.extra_info["success"] = float(np.mean(np.asarray(res.status) == Status.OK))
