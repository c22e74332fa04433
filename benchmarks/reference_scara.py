"""Plain NumPy (and optional Numba) reference of SCARA inverse kinematics, seed 000 eqs. 1-15.

Written directly from the paper's formulas (with the ERRATA corrections), independently of
``jaxkin.dyad``: ``beta`` by ``arccos``, ``theta1 = theta + mode * beta`` summed as printed
(which is the dyad's unwrapped ``phi``), theta_BC by ``arctan2`` and the corrected Fig. 2 rates,
``theta2 = theta1 - theta_BC`` (eq. 15), ``l3 = l_oa - z_D`` (eq. 14). No status handling:
unreachable or singular targets give NaN. Used by benchmarks/test_scara.py as the baseline and
by tests/test_scara.py as a cross-check.
"""

from __future__ import annotations

import numpy as np


def ik_numpy(
    p: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    l_oa: float,
    l_ab: float,
    l_bc: float,
    mode: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SCARA IK of end-point position ``p``, velocity ``v``, acceleration ``a`` (each (..., 3)).

    Returns ``(q, q_dot, q_ddot)``, each ``(..., 3)`` with columns ``(theta1, theta2, l3)``.
    """
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    xd, yd, zd = v[..., 0], v[..., 1], v[..., 2]
    xdd, ydd, zdd = a[..., 0], a[..., 1], a[..., 2]

    # Fig. 2 (corrected): angle theta of A->C with A at the origin.
    r2 = x * x + y * y
    cross = x * yd - y * xd
    theta = np.arctan2(y, x)
    theta_d = cross / r2
    theta_dd = ((x * ydd - y * xdd) * r2 - cross * 2.0 * (x * xd + y * yd)) / (r2 * r2)
    # Fig. 3: distance l = |AC| and its rates.
    l = np.sqrt(r2)
    dot = x * xd + y * yd
    l_d = dot / l
    l_dd = ((xd * xd + x * xdd + yd * yd + y * ydd) * l - dot * l_d) / (l * l)
    # Eqs. 4-5 (A_ddot corrected) and eqs. 1-3.
    big_a = l_ab * l_ab + l * l - l_bc * l_bc
    big_a_d = 2.0 * l * l_d
    big_a_dd = 2.0 * (l_d * l_d + l * l_dd)
    big_b = 2.0 * l_ab * l
    big_b_d = 2.0 * l_ab * l_d
    big_b_dd = 2.0 * l_ab * l_dd
    u = big_a / big_b
    u_d = (big_a_d * big_b - big_a * big_b_d) / big_b**2
    u_dd = (
        (big_a_dd * big_b - big_a * big_b_dd) * big_b**2
        - (big_a_d * big_b - big_a * big_b_d) * 2.0 * big_b * big_b_d
    ) / big_b**4
    with np.errstate(invalid="ignore"):
        beta = np.arccos(u)
        s = np.sqrt(1.0 - u * u)
    beta_d = -u_d / s
    beta_dd = -(u * u_d * u_d / (s * s) + u_dd) / s
    # Eqs. 9-10: theta1 = phi.
    t1 = theta + mode * beta
    t1_d = theta_d + mode * beta_d
    t1_dd = theta_dd + mode * beta_dd
    # Elbow B (eqs. 6-8) and the forearm vector B->C.
    c1, s1 = np.cos(t1), np.sin(t1)
    bx, by = l_ab * c1, l_ab * s1
    bxd, byd = -l_ab * s1 * t1_d, l_ab * c1 * t1_d
    bxdd = -l_ab * (c1 * t1_d**2 + s1 * t1_dd)
    bydd = l_ab * (-s1 * t1_d**2 + c1 * t1_dd)
    fx, fy = x - bx, y - by
    fxd, fyd = xd - bxd, yd - byd
    fxdd, fydd = xdd - bxdd, ydd - bydd
    f2 = fx * fx + fy * fy
    fcross = fx * fyd - fy * fxd
    tbc = np.arctan2(fy, fx)
    tbc_d = fcross / f2
    tbc_dd = ((fx * fydd - fy * fxdd) * f2 - fcross * 2.0 * (fx * fxd + fy * fyd)) / (f2 * f2)
    # Eqs. 15 and 14.
    q = np.stack([t1, t1 - tbc, l_oa - z], axis=-1)
    q_d = np.stack([t1_d, t1_d - tbc_d, -zd], axis=-1)
    q_dd = np.stack([t1_dd, t1_dd - tbc_dd, -zdd], axis=-1)
    return q, q_d, q_dd


def make_numba_ik():
    """A fused-loop Numba version of ``ik_numpy`` over flat (n, 3) arrays (parallel ``prange``).

    Returns ``fn(p, v, a, l_oa, l_ab, l_bc, mode, out)`` writing ``out`` of shape (n, 9):
    q, q_dot, q_ddot. Raises ImportError when numba is missing.
    """
    import numba

    @numba.njit(parallel=True, fastmath=False, cache=False)
    def ik_loop(p, v, a, l_oa, l_ab, l_bc, mode, out):  # pragma: no cover - compiled
        n = p.shape[0]
        for i in numba.prange(n):
            x, y, z = p[i, 0], p[i, 1], p[i, 2]
            xd, yd, zd = v[i, 0], v[i, 1], v[i, 2]
            xdd, ydd, zdd = a[i, 0], a[i, 1], a[i, 2]
            r2 = x * x + y * y
            cross = x * yd - y * xd
            theta = np.arctan2(y, x)
            theta_d = cross / r2
            theta_dd = ((x * ydd - y * xdd) * r2 - cross * 2.0 * (x * xd + y * yd)) / (r2 * r2)
            l = np.sqrt(r2)
            dot = x * xd + y * yd
            l_d = dot / l
            l_dd = ((xd * xd + x * xdd + yd * yd + y * ydd) * l - dot * l_d) / (l * l)
            big_a = l_ab * l_ab + l * l - l_bc * l_bc
            big_a_d = 2.0 * l * l_d
            big_a_dd = 2.0 * (l_d * l_d + l * l_dd)
            big_b = 2.0 * l_ab * l
            big_b_d = 2.0 * l_ab * l_d
            big_b_dd = 2.0 * l_ab * l_dd
            u = big_a / big_b
            num = big_a_d * big_b - big_a * big_b_d
            u_d = num / (big_b * big_b)
            u_dd = (
                (big_a_dd * big_b - big_a * big_b_dd) * big_b * big_b - num * 2.0 * big_b * big_b_d
            ) / big_b**4
            s = np.sqrt(1.0 - u * u)
            beta = np.arccos(u)
            beta_d = -u_d / s
            beta_dd = -(u * u_d * u_d / (s * s) + u_dd) / s
            t1 = theta + mode * beta
            t1_d = theta_d + mode * beta_d
            t1_dd = theta_dd + mode * beta_dd
            c1, s1 = np.cos(t1), np.sin(t1)
            fx, fy = x - l_ab * c1, y - l_ab * s1
            fxd, fyd = xd + l_ab * s1 * t1_d, yd - l_ab * c1 * t1_d
            fxdd = xdd + l_ab * (c1 * t1_d * t1_d + s1 * t1_dd)
            fydd = ydd - l_ab * (-s1 * t1_d * t1_d + c1 * t1_dd)
            f2 = fx * fx + fy * fy
            fcross = fx * fyd - fy * fxd
            tbc = np.arctan2(fy, fx)
            tbc_d = fcross / f2
            tbc_dd = ((fx * fydd - fy * fxdd) * f2 - fcross * 2.0 * (fx * fxd + fy * fyd)) / (
                f2 * f2
            )
            out[i, 0] = t1
            out[i, 1] = t1 - tbc
            out[i, 2] = l_oa - z
            out[i, 3] = t1_d
            out[i, 4] = t1_d - tbc_d
            out[i, 5] = -zd
            out[i, 6] = t1_dd
            out[i, 7] = t1_dd - tbc_dd
            out[i, 8] = -zdd

    return ik_loop
