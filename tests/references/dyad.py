"""Reference RRR dyad implementations for benchmarks (not part of the library).

The formulas follow the paper's trigonometric formulation literally ([Noriega, eqs. 1-10],
Figs. 2-3, errata corrected): theta by atan2, beta by arccos, then cos/sin of phi. They are
written once, elementwise (``dyad_formulas``, ``angle_formulas``), and run two ways: on whole
NumPy arrays (vectorised) and compiled by Numba into a fused parallel ``prange`` loop. No status
handling beyond a validity mask, which flatters the references.
"""

from __future__ import annotations

import numpy as np

try:  # the formulas below run as NumPy code and, compiled, inside Numba loops
    from numba.extending import register_jitable
except ImportError:  # numba is a benchmark extra

    def register_jitable(fn):
        return fn


@register_jitable
def angle_formulas(x, y, xd, yd, xdd, ydd):
    """Fig. 2 (corrected): theta, theta_dot, theta_ddot of the vector (x, y); elementwise."""
    r2 = x * x + y * y
    cross = x * yd - y * xd
    theta_dot = cross / r2
    theta_ddot = ((x * ydd - y * xdd) * r2 - cross * 2.0 * (x * xd + y * yd)) / (r2 * r2)
    return np.arctan2(y, x), theta_dot, theta_ddot


@register_jitable
def dyad_formulas(x, y, xd, yd, xdd, ydd, l_ac, l_bc, mode):
    """phi, phi_dot, phi_ddot of link AC for the vector A->B = (x, y) and its rates.

    Elementwise on scalars or arrays (eqs. 1-5, 9-10; eq. 4's A_ddot corrected).
    """
    theta, theta_dot, theta_ddot = angle_formulas(x, y, xd, yd, xdd, ydd)
    r2 = x * x + y * y
    l = np.sqrt(r2)
    dot = x * xd + y * yd
    l_dot = dot / l
    l_ddot = ((xd * xd + yd * yd + x * xdd + y * ydd) * l - dot * l_dot) / r2
    big_a = l_ac * l_ac + r2 - l_bc * l_bc
    a_dot = 2.0 * l * l_dot
    a_ddot = 2.0 * (l_dot * l_dot + l * l_ddot)
    big_b = 2.0 * l_ac * l
    b_dot = 2.0 * l_ac * l_dot
    b_ddot = 2.0 * l_ac * l_ddot
    u = np.minimum(np.maximum(big_a / big_b, -1.0), 1.0)
    s = np.sqrt(1.0 - u * u)
    q = a_dot * big_b - big_a * b_dot
    u_dot = q / (big_b * big_b)
    u_ddot = ((a_ddot * big_b - big_a * b_ddot) * big_b * big_b - 2.0 * q * big_b * b_dot) / (
        big_b**4
    )
    beta_dot = -u_dot / s
    beta_ddot = -(u * u_dot * u_dot / (s * s) + u_ddot) / s
    phi = theta + mode * np.arccos(u)
    return phi, theta_dot + mode * beta_dot, theta_ddot + mode * beta_ddot


@register_jitable
def link_end(px, py, vx, vy, ax, ay, length, phi, phi_dot, phi_ddot):
    """Eqs. 6-8: the far end of a link of ``length`` at angle phi from (px, py); elementwise."""
    c, s = np.cos(phi), np.sin(phi)
    return (
        px + length * c,
        py + length * s,
        vx - length * s * phi_dot,
        vy + length * c * phi_dot,
        ax - length * (c * phi_dot * phi_dot + s * phi_ddot),
        ay + length * (c * phi_ddot - s * phi_dot * phi_dot),
    )


@register_jitable
def _dyad_point(ax, ay, avx, avy, aax, aay, bx, by, bvx, bvy, bax, bay, l_ac, l_bc, mode):
    phi, phi_dot, phi_ddot = dyad_formulas(
        bx - ax, by - ay, bvx - avx, bvy - avy, bax - aax, bay - aay, l_ac, l_bc, mode
    )
    c = link_end(ax, ay, avx, avy, aax, aay, l_ac, phi, phi_dot, phi_ddot)
    return (*c, phi, phi_dot, phi_ddot)


def _columns(*arrays):
    return [arr[..., k] for arr in arrays for k in (0, 1)]


def dyad_numpy(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode=1):
    """Vectorised NumPy: returns (c_p, c_v, c_a, phi, phi_dot, phi_ddot)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out = _dyad_point(*_columns(a_p, a_v, a_a, b_p, b_v, b_a), l_ac, l_bc, mode)
    c_p, c_v, c_a = (np.stack(out[k : k + 2], axis=-1) for k in (0, 2, 4))
    return c_p, c_v, c_a, *out[6:]


def dyad_rows(a_p, a_v, a_a, b_p, b_v, b_a) -> list[np.ndarray]:
    """The twelve input components as contiguous rows (what a fused loop reads best)."""
    return [np.ascontiguousarray(col) for col in _columns(a_p, a_v, a_a, b_p, b_v, b_a)]


def make_numba_dyad(rows: bool = False):
    """The same formulas as one fused Numba ``prange`` loop, or None when numba is absent.

    ``rows=False``: ``run(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode=1)`` returns
    ``(c_p, c_v, c_a, phi, phi_dot, phi_ddot)`` like ``dyad_numpy``. ``rows=True``: ``run(rows,
    l_ac, l_bc, mode=1)`` takes the contiguous rows of ``dyad_rows`` (prepared outside a timer)
    and returns one ``(9, N)`` array (C's position, velocity, acceleration, phi and its rates):
    the fastest form of the loop, the reference the goal ratios are measured against.
    """
    try:
        import numba
    except ImportError:
        return None

    @numba.njit(parallel=True)
    def loop(ax, ay, avx, avy, aax, aay, bx, by, bvx, bvy, bax, bay, l_ac, l_bc, mode, out):
        for i in numba.prange(ax.shape[0]):
            res = _dyad_point(
                ax[i], ay[i], avx[i], avy[i], aax[i], aay[i],
                bx[i], by[i], bvx[i], bvy[i], bax[i], bay[i], l_ac, l_bc, mode,
            )  # fmt: skip
            for k in numba.literal_unroll(range(9)):
                out[k, i] = res[k]

    def run_rows(rows, l_ac, l_bc, mode=1):
        out = np.empty((9, rows[0].shape[0]), rows[0].dtype)
        loop(*rows, l_ac, l_bc, mode, out)
        return out

    def run(a_p, a_v, a_a, b_p, b_v, b_a, l_ac, l_bc, mode=1):
        out = np.empty((9, a_p.shape[0]), a_p.dtype)
        loop(*_columns(a_p, a_v, a_a, b_p, b_v, b_a), l_ac, l_bc, mode, out)
        c_p, c_v, c_a = (out[k : k + 2].T for k in (0, 2, 4))
        return c_p, c_v, c_a, out[6], out[7], out[8]

    return run_rows if rows else run


def random_dyads(n: int, seed: int = 0, dtype=np.float64):
    """A reproducible batch of mostly assemblable dyads: (arrays..., l_ac, l_bc)."""
    rng = np.random.default_rng(seed)
    a_p = rng.normal(size=(n, 2)) * 0.3
    b_p = rng.normal(size=(n, 2)) * 0.3 + np.array([1.6, 0.0])
    arrays = [a_p, rng.normal(size=(n, 2)), rng.normal(size=(n, 2))]
    arrays += [b_p, rng.normal(size=(n, 2)), rng.normal(size=(n, 2))]
    return [x.astype(dtype) for x in arrays], 1.2, 0.9
