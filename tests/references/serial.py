"""NumPy references for serial-arm FK and Newton IK (benchmarks only, not the library).

Written independently of jaxkin.serial: DH FK by stacked 4x4 matrix products ([Lopez-Villagomez]
eqs. 2, 6); Newton IK as in [Pineiro] with ``numpy.linalg.pinv`` (the function the paper names),
the space-frame update ``q += J_s^+ Ad(T) log(T^-1 T_d)`` and the geometric Jacobian of the DH
frames, vectorised over the batch with early exit once every element has converged.
"""

from __future__ import annotations

import numpy as np

PUMA = dict(
    a=[0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0],
    alpha=[np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0],
    d=[0.0, 0.0, 0.15005, 0.4318, 0.0, 0.0],
    theta=[0.0] * 6,
    joint_types="RRRRRR",
)
ANTHROPOMORPHIC = dict(  # [Lopez-Villagomez, Table 1] with L1 = 0.5, L2 = 0.4, L3 = 0.3 m
    a=[0.0, 0.4, 0.3], alpha=[np.pi / 2, 0.0, 0.0], d=[0.5, 0.0, 0.0], theta=[0.0] * 3,
    joint_types="RRR",
)  # fmt: skip
PLANAR_2R = dict(a=[1.0, 1.0], alpha=[0.0, 0.0], d=[0.0, 0.0], theta=[0.0, 0.0], joint_types="RR")
ARMS = {"2R": PLANAR_2R, "anthropomorphic": ANTHROPOMORPHIC, "PUMA": PUMA}


def fk_dh_numpy(arm: dict, q: np.ndarray, all_frames: bool = False) -> np.ndarray:
    """(N, n) -> (N, 4, 4) (or (N, n, 4, 4)) by explicit DH matrices and matmul."""
    q = np.asarray(q)
    out = np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4))
    frames = []
    for i, kind in enumerate(arm["joint_types"]):
        theta = arm["theta"][i] + (q[..., i] if kind == "R" else 0.0)
        d = arm["d"][i] + (q[..., i] if kind == "P" else 0.0)
        theta, d = np.broadcast_arrays(theta, d)
        ct, st = np.cos(theta), np.sin(theta)
        ca, sa = np.cos(arm["alpha"][i]), np.sin(arm["alpha"][i])
        a = arm["a"][i]
        link = np.zeros((*theta.shape, 4, 4))
        link[..., 0, :] = np.stack([ct, -ca * st, sa * st, a * ct], -1)
        link[..., 1, :] = np.stack([st, ca * ct, -sa * ct, a * st], -1)
        link[..., 2, 1], link[..., 2, 2], link[..., 2, 3] = sa, ca, d
        link[..., 3, 3] = 1.0
        out = out @ link
        frames.append(out)
    return np.stack(frames, axis=-3) if all_frames else out


def _log_se3(t: np.ndarray) -> np.ndarray:
    """Matrix log of (N, 4, 4) transforms -> (N, 6) twists (omega, v); Modern Robotics form."""
    rot, p = t[:, :3, :3], t[:, :3, 3]
    cos = np.clip((np.trace(rot, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    sin = np.sin(theta)
    anti = np.stack(
        [rot[:, 2, 1] - rot[:, 1, 2], rot[:, 0, 2] - rot[:, 2, 0], rot[:, 1, 0] - rot[:, 0, 1]], -1
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(theta < 1e-8, 0.5, theta / (2.0 * sin))
        omega = factor[:, None] * anti
        # Near pi: axis from the symmetric part (MR's special case), sign from anti.
        near_pi = theta > np.pi - 1e-6
        if np.any(near_pi):
            b = (rot[near_pi] + np.eye(3)) / 2.0
            k = np.argmax(np.diagonal(b, axis1=1, axis2=2), axis=1)
            col = b[np.arange(len(k)), :, k]
            axis = col / np.sqrt(col[np.arange(len(k)), k])[:, None]
            omega[near_pi] = axis * theta[near_pi, None]
        w = np.zeros((len(t), 3, 3))
        w[:, 0, 1], w[:, 0, 2] = -omega[:, 2], omega[:, 1]
        w[:, 1, 0], w[:, 1, 2] = omega[:, 2], -omega[:, 0]
        w[:, 2, 0], w[:, 2, 1] = -omega[:, 1], omega[:, 0]
        half = theta / 2.0
        coef = np.where(theta < 1e-8, 1.0 / 12.0, (1.0 - half / np.tan(half)) / theta**2)
    g_inv = np.eye(3) - 0.5 * w + coef[:, None, None] * (w @ w)
    return np.concatenate([omega, np.einsum("nij,nj->ni", g_inv, p)], axis=-1)


def _space_jacobian(arm: dict, frames: np.ndarray) -> np.ndarray:
    """Geometric space Jacobian (N, 6, n) from the DH frames: (z, o x z) or (0, z)."""
    n_batch = frames.shape[0]
    before = np.concatenate([np.broadcast_to(np.eye(4), (n_batch, 1, 4, 4)), frames[:, :-1]], 1)
    z, o = before[..., :3, 2], before[..., :3, 3]
    cols = []
    for i, kind in enumerate(arm["joint_types"]):
        if kind == "R":
            cols.append(np.concatenate([z[:, i], np.cross(o[:, i], z[:, i])], -1))
        else:
            cols.append(np.concatenate([np.zeros_like(z[:, i]), z[:, i]], -1))
    return np.stack(cols, axis=-1)


def ik_newton_numpy(arm, target, q0, eps_omega=1e-3, eps_v=1e-4, max_iter=20):
    """[Pineiro] Newton IK, space frame, np.linalg.pinv, stopping on the tool's rotation angle
    and distance to the target. Returns (q, converged, iterations)."""
    q = np.array(q0, dtype=np.float64)
    n_batch = q.shape[0]
    converged = np.zeros(n_batch, bool)
    iterations = np.zeros(n_batch, np.int64)
    active = np.arange(n_batch)
    for _ in range(max_iter + 1):
        frames = fk_dh_numpy(arm, q[active], all_frames=True)
        t = frames[:, -1]
        rot_t = np.swapaxes(t[:, :3, :3], 1, 2)
        t_bd = np.zeros_like(t)
        t_bd[:, :3, :3] = rot_t @ target[active, :3, :3]
        t_bd[:, :3, 3] = np.einsum("nij,nj->ni", rot_t, target[active, :3, 3] - t[:, :3, 3])
        t_bd[:, 3, 3] = 1.0
        v_b = _log_se3(t_bd)
        w_s = np.einsum("nij,nj->ni", t[:, :3, :3], v_b[:, :3])
        v_s = np.cross(t[:, :3, 3], w_s) + np.einsum("nij,nj->ni", t[:, :3, :3], v_b[:, 3:])
        # Stop on the tool's own errors: rotation angle and distance to the target.
        angle = np.linalg.norm(v_b[:, :3], axis=1)
        distance = np.linalg.norm(t_bd[:, :3, 3], axis=1)
        done = (angle <= eps_omega) & (distance <= eps_v)
        converged[active[done]] = True
        keep = ~done
        if _ == max_iter or not np.any(keep):
            break
        jac = _space_jacobian(arm, frames[keep])
        twist = np.concatenate([w_s[keep], v_s[keep]], axis=1)
        active = active[keep]
        q[active] += np.einsum("nij,nj->ni", np.linalg.pinv(jac), twist)
        iterations[active] += 1
    return q, converged, iterations


def random_problems(arm: dict, n: int, noise: float = 0.3, seed: int = 0):
    """Reachable targets fk(q_true) and seeds q_true + U(-noise, noise)."""
    rng = np.random.default_rng(seed)
    n_joints = len(arm["joint_types"])
    q_true = rng.uniform(-np.pi, np.pi, size=(n, n_joints))
    q0 = q_true + rng.uniform(-noise, noise, size=q_true.shape)
    return q_true, fk_dh_numpy(arm, q_true), q0
