"""Shared problems, independent NumPy checks and peer adapters for ``test_peers.py``.

Benchmarks only (never imported by the library). Every peer gets the same inputs; every answer
(jaxkin's included) is judged by the NumPy checks here, written from the geometry and not from
jaxkin or the peer: a case succeeds when its position error is below ``REL_TOL`` times the
mechanism's reach.

Tasks:

* **Four-bar / RRR dyad** (``fourbar_*``): ``n`` Grashof crank-rocker variants (ground pivots
  O1 = (0, 0) and O2 = (d, 0), crank a, coupler b, rocker c), each driven through
  ``FOURBAR_STEPS`` crank angles of 1 degree (pylinkage's default crank rate: step k records
  the crank at (k + 1) degrees). Unknown: the coupler-rocker joint C, an RRR dyad with
  A = crank pin, B = O2, l_ac = b, l_bc = c, assembled to the left of A->B (jaxkin mode +1),
  which a crank-rocker keeps for the whole turn. Error: ``max(||C - A| - b|, ||C - O2| - c|)``
  with A at the exact crank angle, over the reach ``a + b``.
* **Delta IK** (``delta_*``): the paper's Delta robot (7, 2.5, 15.5, 30 cm), platform points
  from actuator angles in [-0.3, 0.9] rad (closed-form FK of ``reference_delta``). Error: the
  largest ``||D_i - E_i| - l_rod|`` over the chains, over the reach ``l_arm + l_rod``.
  visual-kinematics' ``RobotDelta(r1, r2, l1, l2)`` has the same angle convention (positive
  down, zero horizontal outward) with chain i at 120 (i - 1) degrees where jaxkin has
  -90 + 120 (i - 1): its frame is jaxkin's turned by +90 degrees about z, so it gets
  ``(-y, x, z)`` and returns the angles chain by chain.
* **PUMA 560** (``puma_*``): standard DH of ``reference_serial.PUMA`` (Corke's table, d1 = 0);
  joint vectors uniform in (-pi, pi) kept away from the wrist (|sin q5| >= 0.1), elbow
  (|sin| of the elbow's planar angle >= 0.1) and shoulder (wrist centre >= 0.05 m beyond the
  shoulder offset) singularities; targets ``fk_dh_numpy(q)``; seeds for iterative solvers
  ``q + U(-0.3, 0.3)`` rad (the tracking case of ``test_serial.py``). Error: ``|p(q) - p*|``
  over the reach ``sum |a_i| + |d_i|`` (1.034 m); the rotation error
  ``|R(q)^T R* - I|_F`` is reported beside it.
"""

from __future__ import annotations

import math

import numpy as np

from tests.references.delta import PAPER, UX, UY, fk_closed_form_numpy
from tests.references.serial import PUMA, fk_dh_numpy

REL_TOL = 1e-6

# ------------------------------------------------------------------------------ four-bar

FOURBAR_STEPS = 360


def fourbar_variants(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """``n`` Grashof crank-rockers ``a + max <= rest - 0.3`` (crank fully rotates, margin)."""
    rng = np.random.default_rng(seed)
    out = {k: [] for k in "abcd"}
    while len(out["a"]) < n:
        a, b, c, d = (
            rng.uniform(lo, hi, 4 * n)
            for lo, hi in ((0.3, 0.7), (1.6, 2.4), (1.2, 1.8), (1.6, 2.2))
        )
        longest = np.maximum(np.maximum(b, c), d)
        ok = a + longest <= (b + c + d - longest) - 0.3
        for k, v in zip("abcd", (a, b, c, d), strict=True):
            out[k].extend(v[ok].tolist())
    return {k: np.asarray(v[:n]) for k, v in out.items()}


def fourbar_angles(steps: int = FOURBAR_STEPS) -> np.ndarray:
    """Crank angle of each recorded step: (k + 1) degrees, shape ``(steps,)``."""
    return np.deg2rad(np.arange(1, steps + 1, dtype=float))


def fourbar_start(var: dict[str, np.ndarray]) -> np.ndarray:
    """C at crank angle 0 to the left of A->B (mode +1), shape ``(n, 2)`` (circle-circle)."""
    a, b, c, d = var["a"], var["b"], var["c"], var["d"]
    base = d - a  # A = (a, 0), B = (d, 0): A->B along +x
    along = (b**2 - c**2 + base**2) / (2 * base)
    return np.stack([a + along, np.sqrt(b**2 - along**2)], -1)


def fourbar_error(var: dict[str, np.ndarray], c_xy: np.ndarray) -> np.ndarray:
    """Relative constraint error of C, ``(n, steps, 2)`` -> ``(n, steps)``; NaN stays NaN."""
    th = fourbar_angles(c_xy.shape[1])
    a, b, c, d = (var[k][:, None] for k in "abcd")
    ax, ay = a * np.cos(th), a * np.sin(th)
    cx, cy = c_xy[..., 0], c_xy[..., 1]
    e1 = np.abs(np.hypot(cx - ax, cy - ay) - b)
    e2 = np.abs(np.hypot(cx - d, cy) - c)
    return np.maximum(e1, e2) / (a + b)


def fourbar_side(var: dict[str, np.ndarray], c_xy: np.ndarray) -> np.ndarray:
    """Sign of (A->B) x (A->C): +1 where C is left of A->B (jaxkin mode +1)."""
    th = fourbar_angles(c_xy.shape[1])
    a, d = var["a"][:, None], var["d"][:, None]
    ax, ay = a * np.cos(th), a * np.sin(th)
    cross = (d - ax) * (c_xy[..., 1] - ay) - (0.0 - ay) * (c_xy[..., 0] - ax)
    return np.sign(cross)


def pylinkage_ensemble(var: dict[str, np.ndarray]):
    """pylinkage ``Ensemble`` of the variants: Ground O1, O2, Crank, RRRDyad (numba solver)."""
    import pylinkage as pl
    from pylinkage.population import Ensemble

    o1, o2 = pl.Ground(0.0, 0.0, name="O1"), pl.Ground(2.0, 0.0, name="O2")
    crank = pl.Crank(anchor=o1, radius=0.5, name="crank")
    rocker = pl.RRRDyad(anchor1=crank.output, anchor2=o2, distance1=2.0, distance2=1.5, name="C")
    linkage = pl.Linkage([o1, o2, crank, rocker])
    assert len(linkage.get_constraints()) == 3  # crank radius, distance1, distance2
    n = len(var["a"])
    dims = np.stack([var["a"], var["b"], var["c"]], -1)
    pos = np.zeros((n, 4, 2))
    pos[:, 1, 0] = var["d"]
    pos[:, 2, 0] = var["a"]
    pos[:, 3] = fourbar_start(var)
    return Ensemble(linkage, dims, pos)


# ------------------------------------------------------------------------------ Delta

DELTA_REACH = PAPER[2] + PAPER[3]


def delta_poses(n: int, seed: int = 0) -> np.ndarray:
    """Reachable platform points ``(n, 3)`` (cm) from angles in [-0.3, 0.9] rad."""
    rng = np.random.default_rng(seed)
    p = fk_closed_form_numpy(rng.uniform(-0.3, 0.9, (n, 3)))
    assert np.isfinite(p).all()
    return p


def delta_error(theta: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Largest rod-length error over the chains, over the reach: ``(n, 3), (n, 3) -> (n,)``."""
    r_base, r_plat, l_arm, l_rod = PAPER
    ux, uy = UX, UY  # radial unit vectors of the chains
    ex = (r_base + l_arm * np.cos(theta)) * ux
    ey = (r_base + l_arm * np.cos(theta)) * uy
    ez = -l_arm * np.sin(theta)
    dx = p[:, :1] + r_plat * ux - ex
    dy = p[:, 1:2] + r_plat * uy - ey
    dz = p[:, 2:3] - ez
    return np.abs(np.sqrt(dx**2 + dy**2 + dz**2) - l_rod).max(-1) / DELTA_REACH


def visual_kinematics_delta():
    """visual-kinematics' RobotDelta of the paper's geometry (matplotlib on Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    from visual_kinematics.RobotDelta import RobotDelta

    return RobotDelta(np.array(PAPER, dtype=float))


def visual_kinematics_ik(robot, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One ``robot.inverse(Frame)`` per pose, as the library offers; jaxkin frame in and out."""
    from visual_kinematics.Frame import Frame

    eye = np.eye(3)
    p_vk = np.stack([-p[:, 1], p[:, 0], p[:, 2]], -1)[:, :, None]  # +90 degrees about z
    theta = np.empty((len(p), 3))
    reached = np.empty(len(p), dtype=bool)
    for i in range(len(p)):
        theta[i] = robot.inverse(Frame.from_r_3_3(eye, p_vk[i]))
        reached[i] = robot.is_reachable_inverse
    return theta, reached


# ------------------------------------------------------------------------------ PUMA 560

PUMA_REACH = float(sum(abs(x) for x in PUMA["a"]) + sum(abs(x) for x in PUMA["d"]))


def puma_problems(n: int, seed: int = 0, noise: float = 0.3):
    """``(q_true (n, 6), targets (n, 4, 4), seeds (n, 6))``, away from singularities."""
    rng = np.random.default_rng(seed)
    a3, d3, d4 = PUMA["a"][2], PUMA["d"][2], PUMA["d"][3]
    psi = math.atan2(d4, a3)
    keep = []
    while sum(len(k) for k in keep) < n:
        q = rng.uniform(-np.pi, np.pi, (4 * n, 6))
        t = fk_dh_numpy(PUMA, q)
        r = np.hypot(t[:, 0, 3], t[:, 1, 3])  # wrist centre = tool point (d6 = 0)
        ok = (np.abs(np.sin(q[:, 4])) >= 0.1) & (r >= abs(d3) + 0.05)
        # elbow: a3 c23 - d4 s23 = L3 cos(q2 + q3 + psi), so the forearm makes the angle
        # q3 + psi with the upper arm: stretched or folded where its sine vanishes
        ok &= np.abs(np.sin(q[:, 2] + psi)) >= 0.1
        keep.append(q[ok])
    q_true = np.concatenate(keep)[:n]
    return q_true, fk_dh_numpy(PUMA, q_true), q_true + rng.uniform(-noise, noise, q_true.shape)


def puma_errors(q: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(position error / reach, rotation error |R^T R* - I|_F)``, each ``q.shape[:-1]``."""
    t = fk_dh_numpy(PUMA, q)
    targets = np.broadcast_to(targets, t.shape)
    pos = np.linalg.norm(t[..., :3, 3] - targets[..., :3, 3], axis=-1) / PUMA_REACH
    rel = np.swapaxes(t[..., :3, :3], -1, -2) @ targets[..., :3, :3]
    rot = np.linalg.norm(rel - np.eye(3), axis=(-2, -1))
    return np.where(np.isfinite(pos), pos, np.inf), np.where(np.isfinite(rot), rot, np.inf)


def puma_urdf() -> str:
    """The PUMA's DH table as URDF: joint i at ``Tz(d) Tx(a) Rx(alpha)`` of link i - 1."""
    a, alpha, d = PUMA["a"], PUMA["alpha"], PUMA["d"]
    lines = ['<?xml version="1.0"?>', '<robot name="puma560">', '<link name="base"/>']
    parent, origin = "base", (0.0, 0.0, 0.0)
    for i in range(6):
        lines += [
            f'<link name="link{i + 1}"/>',
            f'<joint name="q{i + 1}" type="revolute"><parent link="{parent}"/>'
            f'<child link="link{i + 1}"/><origin xyz="{origin[0]!r} 0 {origin[1]!r}" '
            f'rpy="{origin[2]!r} 0 0"/><axis xyz="0 0 1"/>'
            '<limit lower="-6.3" upper="6.3" effort="1" velocity="1"/></joint>',
        ]
        parent, origin = f"link{i + 1}", (float(a[i]), float(d[i]), float(alpha[i]))
    lines += [
        '<link name="tool"/>',
        f'<joint name="tool_fixed" type="fixed"><parent link="{parent}"/><child link="tool"/>'
        f'<origin xyz="{origin[0]!r} 0 {origin[1]!r}" rpy="{origin[2]!r} 0 0"/></joint>',
        "</robot>",
    ]
    return "\n".join(lines)


def rtb_puma_ets():
    """roboticstoolbox: the PUMA as a DHRobot, converted once to its ETS (C++ ik_LM, fkine)."""
    import roboticstoolbox as rtb

    links = [
        rtb.RevoluteDH(a=PUMA["a"][i], alpha=PUMA["alpha"][i], d=PUMA["d"][i]) for i in range(6)
    ]
    return rtb.DHRobot(links, name="puma").ets()


def pytorch_kinematics_chain():
    """pytorch_kinematics serial chain of the PUMA URDF, float64 on the CPU."""
    import pytorch_kinematics as pk
    import torch

    return pk.build_serial_chain_from_urdf(puma_urdf().encode(), "tool").to(dtype=torch.float64)


def pyroki_ik_solver(
    max_iterations: int = 30, urdf_text: str | None = None, tip: str = "tool", limits=False
):
    """``jit(vmap(solve))`` of PyRoki's IK pattern: pose cost, jaxls Levenberg-Marquardt.

    ``linear_solver="conjugate_gradient"`` (jaxls' default): ``"dense_cholesky"``, used in
    PyRoki's examples, fails under ``jax_enable_x64`` (int64/int32 index mix in jaxls'
    ``to_dense``). Tolerances are tightened so that converged means the 1e-6 criterion.
    ``urdf_text``/``tip``: another arm than the PUMA; ``limits``: add PyRoki's joint-limit
    cost (its way of keeping joints within the limits).
    """
    import io

    import jax
    import jax.numpy as jnp
    import jaxlie
    import jaxls
    import pyroki
    import yourdfpy

    text = puma_urdf() if urdf_text is None else urdf_text
    urdf = yourdfpy.URDF.load(io.BytesIO(text.encode()), load_meshes=False)
    robot = pyroki.Robot.from_urdf(urdf)
    link = jnp.asarray(robot.links.names.index(tip), dtype=jnp.int32)
    termination = jaxls.TerminationConfig(
        max_iterations=max_iterations,
        cost_tolerance=1e-14,
        gradient_tolerance=1e-14,
        parameter_tolerance=1e-14,
    )

    def solve(target, q0):
        var = robot.joint_var_cls(0)
        cost = pyroki.costs.pose_cost_analytic_jac(
            robot, var, jaxlie.SE3.from_matrix(target), link, pos_weight=50.0, ori_weight=10.0
        )
        costs = [cost, pyroki.costs.limit_cost(robot, var, weight=100.0)] if limits else [cost]
        sol = (
            jaxls.LeastSquaresProblem(costs, [var])
            .analyze()
            .solve(
                initial_vals=jaxls.VarValues.make([var.with_value(q0)]),
                verbose=False,
                linear_solver="conjugate_gradient",
                trust_region=jaxls.TrustRegionConfig(lambda_initial=1.0),
                termination=termination,
            )
        )
        return sol[var]

    solver = jax.jit(jax.vmap(solve))
    solver.joints = robot.joints  # actuated names and limits, for arms with more joints
    return solver


def urdf_without_geometry(path: str) -> str:
    """A URDF file's text with its visual and collision elements removed (their mesh paths are
    not resolvable here)."""
    import re

    with open(path, encoding="utf-8") as f:
        return re.sub(r"<(visual|collision)\b.*?</\1>", "", f.read(), flags=re.S)


def rtb_urdf_ets(path: str, tip: str):
    """roboticstoolbox: the chain from the root to ``tip`` of a URDF file, by its own parser
    (``urdf_without_geometry``)."""
    import io

    import roboticstoolbox as rtb
    from roboticstoolbox.models.URDF.URDFRobot import URDF_file

    links, name, *_ = URDF_file(io.StringIO(urdf_without_geometry(path)))
    return rtb.Robot(links, name=name).ets(end=tip)
