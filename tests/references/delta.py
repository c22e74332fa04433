"""Reference implementations of the Delta robot's kinematics for benchmarks (not the library).

Written from the geometry directly (the convention of ``jaxkin.delta``: z up, chain 1 on the
-y side, chains at +120/+240 degrees, theta positive downward from the horizontal), in plain
NumPy (vectorised) and in Numba (a fused ``prange`` loop). ``tests/test_delta.py``
(``test_references_agree_with_jaxkin``) checks they agree with jaxkin.

* ``ik_numpy(p, robot)``: elbow-out angles from ``A cos th + B sin th = C`` by atan2/arccos (an
  independent form of eq. 5, not the half-angle substitution), ``(N, 3)``; NaN where
  unreachable.
* ``fk_closed_form_numpy(theta, robot)``: lower three-sphere intersection, ``(N, 3)``.
* ``fk_newton_numpy(theta, robot, iterations=8)``: fixed-iteration Newton with Cramer solves.
* ``make_numba_fk_newton()``: compiles the fused loop (imports numba lazily,
  so this module imports without numba).
"""

from __future__ import annotations

import math

import numpy as np

SQ3 = math.sqrt(3.0) / 2.0
UX = np.array([0.0, SQ3, -SQ3])
UY = np.array([-1.0, 0.5, 0.5])
PAPER = (7.0, 2.5, 15.5, 30.0)  # r_base, r_platform, l_arm, l_rod (cm)


def ik_numpy(p: np.ndarray, robot=PAPER) -> np.ndarray:
    """Elbow-out IK, ``p`` shape ``(N, 3)`` -> ``theta`` shape ``(N, 3)``."""
    rb, rp, la, lr = robot
    x, y, z = p[:, 0:1], p[:, 1:2], p[:, 2:3]
    radial = x * UX + y * UY - (rb - rp)  # Q_i . u_i
    tangential = -x * UY + y * UX
    # (radial - la cos th)^2 + tangential^2 + (z + la sin th)^2 = lr^2
    # <=> A cos th + B sin th = C with A = -2 la radial, B = 2 la z.
    a = -2.0 * la * radial
    b = 2.0 * la * z
    c = lr**2 - radial**2 - tangential**2 - z**2 - la**2
    # theta = atan2(B, A) -/+ acos(C / sqrt(A^2 + B^2)); elbow-out has the larger cos(theta).
    base = np.arctan2(b, a)
    with np.errstate(invalid="ignore"):
        gamma = np.arccos(c / np.hypot(a, b))
    t1, t2 = base + gamma, base - gamma
    theta = np.where(np.cos(t1) >= np.cos(t2), t1, t2)
    return (theta + np.pi) % (2.0 * np.pi) - np.pi


def _centres(theta: np.ndarray, robot) -> np.ndarray:
    rb, rp, la, _ = robot
    u = np.stack([UX, UY, np.zeros(3)], axis=-1)  # (3 chains, 3 coords)
    ez = np.array([0.0, 0.0, 1.0])
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    elbow = rb * u + la * (c * u - s * ez)
    return elbow - rp * u  # (N, 3, 3)


def fk_closed_form_numpy(theta: np.ndarray, robot=PAPER) -> np.ndarray:
    """Lower intersection of the three spheres of radius l_rod, ``(N, 3)``."""
    lr = robot[3]
    cen = _centres(theta, robot)
    p1, p2, p3 = cen[:, 0], cen[:, 1], cen[:, 2]
    # Classic trilateration in the frame (ex, ey, ez) of the three centres.
    d = np.linalg.norm(p2 - p1, axis=-1)
    ex = (p2 - p1) / d[:, None]
    i = np.sum(ex * (p3 - p1), -1)
    ey_raw = p3 - p1 - i[:, None] * ex
    ey = ey_raw / np.linalg.norm(ey_raw, axis=-1)[:, None]
    ez = np.cross(ex, ey)
    j = np.sum(ey * (p3 - p1), -1)
    xx = d / 2.0
    yy = (i * i + j * j) / (2.0 * j) - i * xx / j
    zz = np.sqrt(np.maximum(lr * lr - xx * xx - yy * yy, 0.0))
    base = p1 + xx[:, None] * ex + yy[:, None] * ey
    cand1 = base + zz[:, None] * ez
    cand2 = base - zz[:, None] * ez
    return np.where((cand1[:, 2] < cand2[:, 2])[:, None], cand1, cand2)


def fk_newton_numpy(
    theta: np.ndarray, robot=PAPER, iterations: int = 8, guess: np.ndarray | None = None
) -> np.ndarray:
    """Fixed-iteration Newton on |p - C_i|^2 = l_rod^2 with Cramer 3x3 solves, ``(N, 3)``."""
    lr = robot[3]
    cen = _centres(theta, robot)
    if guess is None:
        centroid = cen.mean(axis=1)
        spread = np.mean(np.sum((cen - centroid[:, None])[..., :2] ** 2, -1), -1)
        guess = centroid - np.stack(
            [0 * spread, 0 * spread, np.sqrt(np.maximum(lr * lr - spread, lr * lr / 4))], -1
        )
    p = np.array(guess, dtype=float)
    for _ in range(iterations):
        d = p[:, None, :] - cen  # rows of the Jacobian (up to 2 and 1 / (2 lr))
        r = (np.sum(d * d, -1) - lr * lr) / 2.0
        c0, c1, c2 = (
            np.cross(d[:, 1], d[:, 2]),
            np.cross(d[:, 2], d[:, 0]),
            np.cross(d[:, 0], d[:, 1]),
        )
        det = np.sum(d[:, 0] * c0, -1)
        step = (c0 * r[:, 0:1] + c1 * r[:, 1:2] + c2 * r[:, 2:3]) / det[:, None]
        p = p - step
    return p


def make_numba_fk_newton():
    """Compile a fused Numba Newton (8 iterations); needs numba (benchmark extra)."""
    import numba

    sq3 = SQ3

    @numba.njit(parallel=True, fastmath=False, cache=False)
    def fk(theta, rb, rp, la, lr, iterations):
        n = theta.shape[0]
        out = np.empty((n, 3))
        ux = (0.0, sq3, -sq3)
        uy = (-1.0, 0.5, 0.5)
        for k in numba.prange(n):
            cx = np.empty(3)
            cy = np.empty(3)
            cz = np.empty(3)
            for i in range(3):
                c = math.cos(theta[k, i])
                s = math.sin(theta[k, i])
                rad = rb + la * c - rp
                cx[i] = rad * ux[i]
                cy[i] = rad * uy[i]
                cz[i] = -la * s
            mx = (cx[0] + cx[1] + cx[2]) / 3.0
            my = (cy[0] + cy[1] + cy[2]) / 3.0
            mz = (cz[0] + cz[1] + cz[2]) / 3.0
            spread = 0.0
            for i in range(3):
                spread += (cx[i] - mx) ** 2 + (cy[i] - my) ** 2
            spread /= 3.0
            px, py, pz = mx, my, mz - math.sqrt(max(lr * lr - spread, lr * lr / 4.0))
            for _ in range(iterations):
                d0x, d0y, d0z = px - cx[0], py - cy[0], pz - cz[0]
                d1x, d1y, d1z = px - cx[1], py - cy[1], pz - cz[1]
                d2x, d2y, d2z = px - cx[2], py - cy[2], pz - cz[2]
                r0 = 0.5 * (d0x * d0x + d0y * d0y + d0z * d0z - lr * lr)
                r1 = 0.5 * (d1x * d1x + d1y * d1y + d1z * d1z - lr * lr)
                r2 = 0.5 * (d2x * d2x + d2y * d2y + d2z * d2z - lr * lr)
                a0x, a0y, a0z = d1y * d2z - d1z * d2y, d1z * d2x - d1x * d2z, d1x * d2y - d1y * d2x
                a1x, a1y, a1z = d2y * d0z - d2z * d0y, d2z * d0x - d2x * d0z, d2x * d0y - d2y * d0x
                a2x, a2y, a2z = d0y * d1z - d0z * d1y, d0z * d1x - d0x * d1z, d0x * d1y - d0y * d1x
                det = d0x * a0x + d0y * a0y + d0z * a0z
                px -= (a0x * r0 + a1x * r1 + a2x * r2) / det
                py -= (a0y * r0 + a1y * r1 + a2y * r2) / det
                pz -= (a0z * r0 + a1z * r1 + a2z * r2) / det
            out[k, 0] = px
            out[k, 1] = py
            out[k, 2] = pz
        return out

    def run(theta: np.ndarray, robot=PAPER, iterations: int = 8) -> np.ndarray:
        return fk(np.ascontiguousarray(theta, dtype=np.float64), *robot, iterations)

    return run
