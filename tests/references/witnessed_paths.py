"""Witnessed pose paths of real URDF arms and an independent check of a path IK's answers
(tests and benchmarks only, not the library).

A witness is a smooth joint motion inside the limits: a Bezier curve (Bernstein polynomials,
[Farin 2002, eq. 4.7]) whose control points lie in the limits shrunk by ``MARGIN`` of each
joint's range, so the whole curve does (a Bezier curve lies in the convex hull of its control
points), played over a duration that keeps every joint below ``SPEED_FRACTION`` of its speed
limit. Its tool poses (Pinocchio's forward kinematics) and their rates make the pose path: a
continuous answer within every limit exists, the witness.

The check (``check_answers``) reads nothing the path IK computed but the answer's joints and
rates: Pinocchio's poses of the answer against the targets, the joints against the URDF's
limits, each step's joint change against the trapezoid rule of the answer's own rates (a jump
is a change no rate explains), each speed against the speed limits, and the rates themselves
against the targets' velocity through Pinocchio's Jacobian (``J q_dot = V``).
"""

from __future__ import annotations

import numpy as np

from tests.test_chain_search import _ROBOTS as ROBOTS
from tests.test_chain_search import REAL_CHAINS

# (URDF, tip link): the arms of the tests and the benchmark (the base is each file's root).
ARMS = {name: REAL_CHAINS[name][::2] for name in ("kinova", "xarm7", "panda", "z1", "ur5")}
# The witness's control points stay this fraction of each joint's range inside its limits.
MARGIN = 0.1
# Its control points move at most this far (rad, or the chain's length) from the first.
SPREAD = 0.8
# Its peak speed is this fraction of each joint's speed limit.
SPEED_FRACTION = 0.5
# Bezier control points of a witness.
CONTROLS = 5


class Arm:
    """A URDF arm read by Pinocchio: poses and body Jacobians of its tip for chain joints."""

    def __init__(self, name: str, joint_names: list[str]):
        import pinocchio as pin

        urdf, tip = ARMS[name]
        self.path = str(ROBOTS / urdf)
        self.tip = tip
        self.model = pin.buildModelFromUrdf(self.path)
        self.data = self.model.createData()
        self.frame = self.model.getFrameId(tip, pin.FrameType.BODY)
        self.joints = [self.model.joints[self.model.getJointId(j)] for j in joint_names]

    def _full(self, q: np.ndarray) -> np.ndarray:
        import pinocchio as pin

        full = pin.neutral(self.model)
        for joint, value in zip(self.joints, q, strict=True):
            if joint.nq == 2:  # continuous: (cos, sin)
                full[joint.idx_q : joint.idx_q + 2] = np.cos(value), np.sin(value)
            else:
                full[joint.idx_q] = value
        return full

    def pose(self, q: np.ndarray) -> np.ndarray:
        """The tip pose ``(4, 4)`` at chain joints ``q`` ``(n,)``."""
        import pinocchio as pin

        pin.framesForwardKinematics(self.model, self.data, self._full(q))
        return self.data.oMf[self.frame].homogeneous.copy()

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """The tip's body Jacobian ``(6, n)`` (rows v, omega: Pinocchio's LOCAL frame)."""
        import pinocchio as pin

        full = self._full(q)
        pin.computeJointJacobians(self.model, self.data, full)
        pin.framesForwardKinematics(self.model, self.data, full)
        jac = pin.getFrameJacobian(self.model, self.data, self.frame, pin.ReferenceFrame.LOCAL)
        return np.stack([jac[:, j.idx_v] for j in self.joints], axis=-1)


def witnesses(chain, count: int, samples: int, rng: np.random.Generator, spread: float = SPREAD):
    """``count`` witnesses of ``samples`` samples: ``(q, q_dot, q_ddot)`` each ``(count,
    samples, n)`` and the sampling period ``dt`` (one for all: the slowest one's); ``spread``:
    how far the control points move from the first (``SPREAD``)."""
    from jaxkin import paths

    lower, upper = np.asarray(chain.lower, float), np.asarray(chain.upper, float)
    lower = np.where(np.isfinite(lower), lower, -np.pi)
    upper = np.where(np.isfinite(upper), upper, np.pi)
    inset = MARGIN * (upper - lower)
    low, high = lower + inset, upper - inset
    n = chain.n_joints
    first = rng.uniform(low, high, (count, 1, n))
    moves = rng.uniform(-spread, spread, (count, CONTROLS - 1, n))
    controls = np.clip(np.concatenate([first, first + moves], axis=1), low, high)
    basis = paths.bezier_basis(CONTROLS, samples)
    q = np.einsum("tk,bkn->btn", basis[0], controls)
    rate = np.einsum("tk,bkn->btn", basis[1], controls)  # per unit of the path parameter
    accel = np.einsum("tk,bkn->btn", basis[2], controls)
    speed = np.asarray(chain.velocity, float)
    speed = np.where(np.isfinite(speed) & (speed > 0), speed, np.inf)
    duration = np.max(np.abs(rate) / (SPEED_FRACTION * speed))
    duration = max(float(duration), 1.0)
    return (q, rate / duration, accel / duration**2), duration / (samples - 1)


def pose_path(arm: Arm, q: np.ndarray, q_dot: np.ndarray, q_ddot: np.ndarray):
    """The tip poses ``(..., T, 4, 4)`` of joints ``q`` with their first and second time
    derivatives (``dT/dt = T [V]``, ``V = J q_dot``; the second by central differences of
    the first along a step of ``1e-6`` in time)."""

    def hat(v):
        out = np.zeros((*v.shape[:-1], 4, 4))
        w, lin = v[..., 3:], v[..., :3]
        out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
        out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
        out[..., :3, 3] = lin
        return out

    def first(qi, qdi):
        pose = arm.pose(qi)
        return pose, pose @ hat(arm.jacobian(qi) @ qdi)

    shape = q.shape[:-1]
    flat = [x.reshape(-1, q.shape[-1]) for x in (q, q_dot, q_ddot)]
    p, v, a = (np.zeros((len(flat[0]), 4, 4)) for _ in range(3))
    h = 1e-6
    for i, (qi, qdi, qddi) in enumerate(zip(*flat, strict=True)):
        p[i], v[i] = first(qi, qdi)
        ahead = first(qi + h * qdi + 0.5 * h * h * qddi, qdi + h * qddi)[1]
        behind = first(qi - h * qdi + 0.5 * h * h * qddi, qdi - h * qddi)[1]
        a[i] = (ahead - behind) / (2 * h)
    return tuple(x.reshape(*shape, 4, 4) for x in (p, v, a))


def check_answers(arm: Arm, chain, answer, targets, target_rates, dt) -> dict:
    """Per path ``(N,)``, for answers ``(q, q_dot, q_ddot)`` each ``(N, T, n)`` of targets
    ``(N, T, 4, 4)`` with rates ``(N, T, 4, 4)``: ``pose`` the largest pose error (rad plus
    distance in the chain's lengths), ``within`` every joint within the chain's limits (by
    ``1e-9``), ``slow`` every speed within its limit, ``explained`` every step within half
    of the joints' reach of its prediction by the answer's rates (the trapezoid rule with its
    end correction, exact to ``O(dt^5)``; the planner's test of a jump), ``rates`` the
    largest ``|J q_dot - V|`` relative to ``|V|`` (Pinocchio's Jacobian)."""
    q, q_dot, q_ddot = answer
    size = float(chain.length_scale())
    lower, upper = np.asarray(chain.lower, float), np.asarray(chain.upper, float)
    speed = np.asarray(chain.velocity, float)
    revolute = np.array([k != "prismatic" for k in chain.joint_kinds])
    n_paths, samples = q.shape[:2]
    pose = np.zeros(n_paths)
    rates = np.zeros(n_paths)
    for i in range(n_paths):
        for t in range(samples):
            reached = arm.pose(q[i, t])
            err = np.linalg.inv(reached) @ targets[i, t]
            skew = err[:3, :3] - err[:3, :3].T
            sine = 0.5 * np.linalg.norm([skew[2, 1], skew[0, 2], skew[1, 0]])
            angle = np.arctan2(sine, 0.5 * (np.trace(err[:3, :3]) - 1))
            pose[i] = max(pose[i], angle + np.linalg.norm(err[:3, 3]) / size)
            twist = np.linalg.inv(targets[i, t]) @ target_rates[i, t]
            want = np.concatenate([twist[:3, 3], [twist[2, 1], twist[0, 2], twist[1, 0]]])
            got = arm.jacobian(q[i, t]) @ q_dot[i, t]
            unit = np.linalg.norm(want[:3]) / size + np.linalg.norm(want[3:]) + 1e-12
            miss = np.linalg.norm((got - want)[:3]) / size + np.linalg.norm((got - want)[3:])
            rates[i] = max(rates[i], miss / unit)
    within = np.all((q >= lower - 1e-9) & (q <= upper + 1e-9), axis=(1, 2))
    slow = np.all(np.abs(q_dot) <= speed * (1 + 1e-9), axis=(1, 2))
    step = np.diff(q, axis=1)
    step = np.where(revolute, step - 2 * np.pi * np.round(step / (2 * np.pi)), step)
    mean = 0.5 * dt * (q_dot[:, 1:] + q_dot[:, :-1])
    mean = mean + dt * dt * (q_ddot[:, :-1] - q_ddot[:, 1:]) / 12
    reach = 0.5 * dt * (np.abs(q_dot[:, 1:]) + np.abs(q_dot[:, :-1]))
    reach = reach + dt * dt * (np.abs(q_ddot[:, 1:]) + np.abs(q_ddot[:, :-1])) / 12
    explained = np.all(np.abs(step - mean) <= 0.5 * reach + 1e-9, axis=(1, 2))
    return {"pose": pose, "within": within, "slow": slow, "explained": explained, "rates": rates}
