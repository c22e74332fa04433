"""Plain NumPy (and optional Numba) reference of SCARA inverse kinematics, [Noriega, eqs. 1-15].

Written from the paper's formulas (with the corrections of docs/errata.md), independently of
``jaxkin.dyad``, by reusing the elementwise reference formulas of ``reference_dyad``: the
shoulder A at the origin and the wrist C = (x_D, y_D) form the dyad whose middle joint is the
elbow B, so ``theta1`` is the dyad's ``phi`` (``theta + mode * beta``, ``beta`` by arccos);
theta_BC by ``arctan2`` and the corrected Fig. 2 rates; ``theta2 = theta1 - theta_BC``
(eq. 15); ``l3 = l_oa - z_D`` (eq. 14). No status handling: unreachable or singular targets
give NaN. Used by benchmarks/test_scara.py as the baseline and by tests/test_scara.py as a
cross-check.
"""

from __future__ import annotations

import numpy as np

from tests.references.dyad import angle_formulas, dyad_formulas, link_end, register_jitable


@register_jitable
def scara_formulas(x, y, z, xd, yd, zd, xdd, ydd, zdd, l_oa, l_ab, l_bc, mode):
    """(theta1, theta2, l3) and their two rates, elementwise on scalars or arrays."""
    t1, t1_d, t1_dd = dyad_formulas(x, y, xd, yd, xdd, ydd, l_ab, l_bc, mode)  # eqs. 1-10
    bx, by, bxd, byd, bxdd, bydd = link_end(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, l_ab, t1, t1_d, t1_dd)
    tbc, tbc_d, tbc_dd = angle_formulas(x - bx, y - by, xd - bxd, yd - byd, xdd - bxdd, ydd - bydd)
    return (t1, t1 - tbc, l_oa - z, t1_d, t1_d - tbc_d, -zd, t1_dd, t1_dd - tbc_dd, -zdd)


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
    columns = [arr[..., k] for arr in (p, v, a) for k in range(3)]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = scara_formulas(*columns, l_oa, l_ab, l_bc, mode)
    return tuple(np.stack(out[k : k + 3], axis=-1) for k in (0, 3, 6))


def make_numba_ik():
    """A fused-loop Numba version of ``ik_numpy`` over flat (n, 3) arrays (parallel ``prange``).

    Returns ``fn(p, v, a, l_oa, l_ab, l_bc, mode, out)`` writing ``out`` of shape (n, 9):
    q, q_dot, q_ddot. Raises ImportError when numba is missing.
    """
    import numba

    @numba.njit(parallel=True)
    def ik_loop(p, v, a, l_oa, l_ab, l_bc, mode, out):  # pragma: no cover - compiled
        for i in numba.prange(p.shape[0]):
            res = scara_formulas(
                p[i, 0], p[i, 1], p[i, 2], v[i, 0], v[i, 1], v[i, 2], a[i, 0], a[i, 1], a[i, 2],
                l_oa, l_ab, l_bc, mode,
            )  # fmt: skip
            for k in numba.literal_unroll(range(9)):
                out[i, k] = res[k]

    return ik_loop
