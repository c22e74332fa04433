"""Reference RRR dyad implementations for benchmarks (not part of the library).

Both follow the paper's trigonometric formulation literally (seed 000 eqs. 1-10, Fig. 2-3,
errata corrected): theta by atan2, beta by arccos, then cos/sin of phi. Only OK elements are
meaningful (no status handling beyond a validity mask), which flatters the references.
"""

from __future__ import annotations

import numpy as np


def dyad_numpy(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode=1):
    """Vectorised NumPy: returns (c_p, c_v, c_a, phi, phi_dot, phi_ddot, ok)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return _dyad_numpy(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode)


def _dyad_numpy(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode):
    d, dv, da = b_p - a_p, b_v - a_v, b_a - a_a
    x, y = d[..., 0], d[..., 1]
    xd, yd = dv[..., 0], dv[..., 1]
    xdd, ydd = da[..., 0], da[..., 1]
    r2 = x * x + y * y
    l = np.sqrt(r2)
    theta = np.arctan2(y, x)
    cross = x * yd - y * xd
    theta_dot = cross / r2
    theta_ddot = ((x * ydd - y * xdd) * r2 - cross * 2.0 * (x * xd + y * yd)) / (r2 * r2)
    dot = x * xd + y * yd
    l_dot = dot / l
    l_ddot = ((xd * xd + yd * yd + x * xdd + y * ydd) * l - dot * l_dot) / r2
    big_a = l_ac * l_ac + r2 - l_bc * l_bc
    a_dot = 2.0 * l * l_dot
    a_ddot = 2.0 * (l_dot * l_dot + l * l_ddot)
    big_b = 2.0 * l_ac * l
    b_dot = 2.0 * l_ac * l_dot
    b_ddot = 2.0 * l_ac * l_ddot
    u = big_a / big_b
    ok = np.abs(u) < 1.0
    u = np.clip(u, -1.0, 1.0)
    beta = np.arccos(u)
    s = np.sqrt(1.0 - u * u)
    q = a_dot * big_b - big_a * b_dot
    u_dot = q / (big_b * big_b)
    u_ddot = ((a_ddot * big_b - big_a * b_ddot) * big_b * big_b - 2.0 * q * big_b * b_dot) / (
        big_b**4
    )
    beta_dot = -u_dot / s
    beta_ddot = -(u * u_dot * u_dot / (s * s) + u_ddot) / s
    phi = theta + mode * beta
    phi_dot = theta_dot + mode * beta_dot
    phi_ddot = theta_ddot + mode * beta_ddot
    cphi, sphi = np.cos(phi), np.sin(phi)
    c_p = a_p + l_ac * np.stack([cphi, sphi], axis=-1)
    c_v = a_v + l_ac * np.stack([-sphi * phi_dot, cphi * phi_dot], axis=-1)
    c_a = a_a + l_ac * np.stack(
        [-(cphi * phi_dot**2 + sphi * phi_ddot), -sphi * phi_dot**2 + cphi * phi_ddot], axis=-1
    )
    return c_p, c_v, c_a, phi, phi_dot, phi_ddot, ok


def make_numba_dyad():
    """A fused Numba ``prange`` loop of the same formulas, or None when numba is absent."""
    try:
        import numba
    except ImportError:
        return None

    @numba.njit(parallel=True, fastmath=False, cache=False)
    def dyad_numba(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode, c_p, c_v, c_a, phi_out):
        n = a_p.shape[0]
        for i in numba.prange(n):
            x = b_p[i, 0] - a_p[i, 0]
            y = b_p[i, 1] - a_p[i, 1]
            xd = b_v[i, 0] - a_v[i, 0]
            yd = b_v[i, 1] - a_v[i, 1]
            xdd = b_a[i, 0] - a_a[i, 0]
            ydd = b_a[i, 1] - a_a[i, 1]
            r2 = x * x + y * y
            l = np.sqrt(r2)
            theta = np.arctan2(y, x)
            cross = x * yd - y * xd
            theta_dot = cross / r2
            theta_ddot = ((x * ydd - y * xdd) * r2 - cross * 2.0 * (x * xd + y * yd)) / (r2 * r2)
            dot = x * xd + y * yd
            l_dot = dot / l
            l_ddot = ((xd * xd + yd * yd + x * xdd + y * ydd) * l - dot * l_dot) / r2
            big_a = l_ac * l_ac + r2 - l_bc * l_bc
            a_dot = 2.0 * l * l_dot
            a_ddot = 2.0 * (l_dot * l_dot + l * l_ddot)
            big_b = 2.0 * l_ac * l
            b_dot = 2.0 * l_ac * l_dot
            b_ddot = 2.0 * l_ac * l_ddot
            u = min(max(big_a / big_b, -1.0), 1.0)
            beta = np.arccos(u)
            s = np.sqrt(1.0 - u * u)
            q = a_dot * big_b - big_a * b_dot
            u_dot = q / (big_b * big_b)
            u_ddot = (
                (a_ddot * big_b - big_a * b_ddot) * big_b * big_b - 2.0 * q * big_b * b_dot
            ) / big_b**4
            beta_dot = -u_dot / s
            beta_ddot = -(u * u_dot * u_dot / (s * s) + u_ddot) / s
            phi = theta + mode * beta
            phi_dot = theta_dot + mode * beta_dot
            phi_ddot = theta_ddot + mode * beta_ddot
            cphi = np.cos(phi)
            sphi = np.sin(phi)
            c_p[i, 0] = a_p[i, 0] + l_ac * cphi
            c_p[i, 1] = a_p[i, 1] + l_ac * sphi
            c_v[i, 0] = a_v[i, 0] - l_ac * sphi * phi_dot
            c_v[i, 1] = a_v[i, 1] + l_ac * cphi * phi_dot
            c_a[i, 0] = a_a[i, 0] - l_ac * (cphi * phi_dot * phi_dot + sphi * phi_ddot)
            c_a[i, 1] = a_a[i, 1] + l_ac * (-sphi * phi_dot * phi_dot + cphi * phi_ddot)
            phi_out[i, 0] = phi
            phi_out[i, 1] = phi_dot
            phi_out[i, 2] = phi_ddot

    def run(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode=1):
        n = a_p.shape[0]
        c_p, c_v, c_a = (np.empty((n, 2), a_p.dtype) for _ in range(3))
        phi = np.empty((n, 3), a_p.dtype)
        dyad_numba(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode, c_p, c_v, c_a, phi)
        return c_p, c_v, c_a, phi[:, 0], phi[:, 1], phi[:, 2]

    return run


def random_dyads(n: int, seed: int = 0, dtype=np.float64):
    """A reproducible batch of mostly assemblable dyads: (arrays..., l_ac, l_bc)."""
    rng = np.random.default_rng(seed)
    a_p = rng.normal(size=(n, 2)) * 0.3
    b_p = rng.normal(size=(n, 2)) * 0.3 + np.array([1.6, 0.0])
    arrays = [a_p, rng.normal(size=(n, 2)), rng.normal(size=(n, 2))]
    arrays += [b_p, rng.normal(size=(n, 2)), rng.normal(size=(n, 2))]
    return [x.astype(dtype) for x in arrays], 1.2, 0.9
