"""Peers side by side: jaxkin and the libraries a user would pick instead, on the same tasks.

Run by ``make bench-peers`` (``benchmarks/install_peers.sh`` installs the peers into the venv;
each peer's benchmark is skipped, with the reason, when it is missing). Problems, the NumPy
success checks and the peer adapters are in ``peers_tasks.py`` (see its docstring for the
geometry and frame mappings). Everything is float64 on the CPU.

Rules: the same inputs for every solver; warm-up / JIT compilation outside the timer (one full
untimed call); the best of ``rounds`` timed calls; success = position error below 1e-6 of the
reach by an independent NumPy FK / constraint check (never the solver's own flag). Recorded in
``extra_info``: kernel, dtype, n_cases, cases_per_second, success_rate, max_error (relative to
the reach) and ``jaxkin_speedup`` (jaxkin's throughput over the peer's on the same task; jaxkin
runs first in each task). ``benchmarks/peers_results.md`` collects the table of one run.

Noise: pytorch_kinematics runs many small torch ops, each an OpenMP parallel region on the two
cores; when another process holds a core (other jobs on a shared machine) each region waits for
it, and its IK was measured 30-90x slower (1e3 targets: 0.13 s quiet, 4-12 s under load) while
jaxkin and the other peers moved by < 2x. Compare its rows only from a quiet machine.

Tasks and solvers:

* four-bar (1,000 crank-rockers x 360 crank steps = 360,000 RRR dyads): pylinkage ``Ensemble``
  of ``Crank`` + ``RRRDyad`` (``simulate``: numba stepping, a Python loop over members) vs a
  jitted crank + ``jaxkin.dyad.position`` (positions only, as pylinkage; the speedups refer
  to it) and ``jaxkin.dyad.solve`` (which also computes zero velocity/acceleration jets);
* Delta IK (10,000 poses): visual-kinematics ``RobotDelta.inverse``, one call per pose (each
  call also re-runs its FK), vs ``jaxkin.delta.ik`` (elbow-out, the same branch);
* PUMA 560 IK (1e3 and 1e4 targets; every iterative solver starts from the same seeds
  ``q + U(-0.3, 0.3)`` rad and is asked for 1e-8..1e-10 tolerances so that converged means the
  1e-6 criterion):
  roboticstoolbox ``ETS.ik_LM`` (C++, per pose; random restarts when a seed fails, its default),
  pytorch_kinematics ``PseudoInverseIK`` (one retry = the seed), PyRoki (jaxls
  Levenberg-Marquardt, ``jit(vmap)``), jaxkin ``serial.ik_all_branches`` (all 8 branches;
  success = at least one valid branch and every valid branch within tolerance; max error over
  valid branches) and
  ``serial.ik_newton`` (pseudo-inverse Newton with its default 1 rad step limit, tolerances
  1e-10, ``max_iter`` 20, its default, and 8: the batch steps until its last element
  converges, so the slowest element sets the cost);
* PUMA 560 FK (1e4 configurations): pytorch_kinematics, roboticstoolbox (``ETS.fkine`` of the
  batch), jaxkin's DH kernel (``serial.dh.transforms``, what the arm runs) and ``serial.fk``;
* URDF arms (UR5 and Franka Panda of example-robot-data, 500 poses from joints within the
  limits, no seed, joint limits on): roboticstoolbox ``ETS.ik_LM`` on the chain its own URDF
  parser builds (random restarts), pytorch_kinematics ``PseudoInverseIK`` (64 random retries
  within the limits, the first that passes the check counted), PyRoki (from the middle of the
  limits with its joint-limit cost; it has no restarts), vs ``jaxkin.ik`` on
  ``serial.from_urdf``; success also needs the joints within the limits and the orientation
  within 1e-6 rad (Pinocchio's FK).
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import peers_tasks as tasks
import pytest

from jaxkin import delta, dyad, serial
from jaxkin import ik as jaxkin_ik

IK_SIZES = [1_000, 10_000]
FK_SIZE = 10_000
DELTA_SIZE = 10_000
FOURBAR_VARIANTS = 1_000

_RATES: dict[tuple[str, int], float] = {}  # jaxkin's throughput per (task, batch)
_ROWS: list[tuple] = []


def _peer(module: str, package: str):
    return pytest.importorskip(
        module, reason=f"{package} is not installed (benchmarks/install_peers.sh installs it)"
    )


def _run(benchmark, fn, n, task, solver, rounds=3):
    """Untimed warm-up call, then the best of ``rounds``; returns the warm-up's output."""
    out = jax.block_until_ready(fn())
    benchmark.pedantic(
        lambda: jax.block_until_ready(fn()), rounds=rounds, iterations=1, warmup_rounds=0
    )
    rate = n / benchmark.stats.stats.min
    benchmark.extra_info.update(kernel=f"{task}: {solver}", dtype="float64", n_cases=n)
    benchmark.extra_info["cases_per_second"] = rate
    return out, rate


def _record(benchmark, task, solver, n, rate, err, jaxkin=False, **extra):
    """Success rate and max error from the independent check; ratio to jaxkin."""
    err = np.asarray(err, dtype=float).reshape(n, -1).max(-1)
    err = np.where(np.isfinite(err), err, np.inf)
    success = float(np.mean(err < tasks.REL_TOL))
    info = dict(success_rate=success, max_error=float(err.max()), **extra)
    if jaxkin:
        _RATES.setdefault((task, n), rate)
        ratio = 1.0
    else:
        base = _RATES.get((task, n))
        ratio = None if base is None else base / rate
        if ratio is not None:
            info["jaxkin_speedup"] = ratio
    benchmark.extra_info.update(info)
    _ROWS.append((solver, task, n, rate, success, float(err.max()), ratio))


@pytest.fixture(scope="module", autouse=True)
def _write_table():
    yield
    if not _ROWS:
        return
    lines = [
        "# Peers side by side (one `make bench-peers` run)",
        "",
        "Float64, CPU; throughput = best of the timed rounds after an untimed warm-up. Success: "
        "position error < 1e-6 of the reach (NumPy check). Speedup: jaxkin's throughput on the "
        "task (the first jaxkin row) over the row's.",
        "",
        "| solver | task | batch | cases/s | success | max error (rel.) | jaxkin speedup |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for solver, task, n, rate, success, err, ratio in _ROWS:
        r = "" if ratio is None else f"{ratio:,.1f}x"
        lines.append(
            f"| {solver} | {task} | {n:,} | {rate:,.0f} | {success:.1%} | {err:.1e} | {r} |"
        )
    Path(__file__).with_name("peers_results.md").write_text("\n".join(lines) + "\n")


# ------------------------------------------------------------------------ four-bar / dyad


@pytest.fixture(scope="module")
def fourbar():
    return tasks.fourbar_variants(FOURBAR_VARIANTS)


def _fourbar_jaxkin(benchmark, fourbar, kernel, name, reference):
    steps = tasks.FOURBAR_STEPS
    n = FOURBAR_VARIANTS * steps
    th = jnp.asarray(tasks.fourbar_angles(steps))
    a, b, c, d = (jnp.asarray(fourbar[k])[:, None] for k in "abcd")
    # The crank's (cos, sin) in their own jit, on the (steps,) angles: inside the dyad's jit XLA
    # fuses them into the (variants, steps) loop and evaluates them per element (measured
    # 8.8 M/s instead of ~16 M/s at 1,000 x 360 float64, with XLA's cos/sin).
    unit = jax.jit(lambda th: (jnp.cos(th), jnp.sin(th)))

    @jax.jit
    def solve(cos_sin, a, b, c, d):
        pin = jnp.stack([a * cos_sin[0], a * cos_sin[1]], -1)  # (variants, steps, 2)
        o2 = jnp.stack([d, jnp.zeros_like(d)], -1)  # (variants, 1, 2)
        res = kernel(pin, o2, b, c, mode=1)
        return (res.c if isinstance(res, dyad.DyadPosition) else res.c.p), res.status

    (c_xy, status), rate = _run(
        benchmark, lambda: solve(unit(th), a, b, c, d), n, "four-bar", name, rounds=5
    )
    assert (np.asarray(status) == 0).all()
    error = tasks.fourbar_error(fourbar, np.asarray(c_xy))
    _record(benchmark, "four-bar", f"jaxkin.{name}", n, rate, error, jaxkin=reference)


def test_fourbar_jaxkin_position(benchmark, fourbar):
    """The task's reference row: positions only, what pylinkage computes."""
    _fourbar_jaxkin(benchmark, fourbar, dyad.position, "dyad.position", reference=True)


def test_fourbar_jaxkin_solve(benchmark, fourbar):
    """``dyad.solve`` on the same sweep: also computes (zero) velocities and accelerations."""
    _fourbar_jaxkin(benchmark, fourbar, dyad.solve, "dyad.solve", reference=False)


def test_fourbar_pylinkage(benchmark, fourbar):
    _peer("pylinkage", "pylinkage")
    steps = tasks.FOURBAR_STEPS
    n = FOURBAR_VARIANTS * steps
    ensemble = tasks.pylinkage_ensemble(fourbar)
    traj, rate = _run(
        benchmark,
        lambda: ensemble.simulate(iterations=steps, store=False),
        n,
        "four-bar",
        "pylinkage",
        rounds=5,
    )
    c_xy = traj[:, :, 3, :]
    # pylinkage keeps the branch nearest to the previous step: check it stayed in mode +1
    side = tasks.fourbar_side(fourbar, c_xy)
    err = np.where(side > 0, tasks.fourbar_error(fourbar, c_xy), np.inf)
    _record(benchmark, "four-bar", "pylinkage Ensemble (numba)", n, rate, err)


# ------------------------------------------------------------------------ Delta IK


@pytest.fixture(scope="module")
def delta_poses():
    return tasks.delta_poses(DELTA_SIZE)


def test_delta_ik_jaxkin(benchmark, delta_poses):
    robot, p = delta.Delta.paper(), jnp.asarray(delta_poses)
    res, rate = _run(benchmark, lambda: delta.ik(robot, p), DELTA_SIZE, "Delta IK", "jaxkin")
    theta = np.asarray(res.q.p)
    err = np.where(np.asarray(res.status) == 0, tasks.delta_error(theta, delta_poses), np.inf)
    _record(benchmark, "Delta IK", "jaxkin.delta.ik", DELTA_SIZE, rate, err, jaxkin=True)


def test_delta_ik_visual_kinematics(benchmark, delta_poses):
    _peer("visual_kinematics", "visual-kinematics")
    robot = tasks.visual_kinematics_delta()
    # agreement on a few poses first (frames mapped as in peers_tasks), outside the timer
    theta_vk, _ = tasks.visual_kinematics_ik(robot, delta_poses[:8])
    theta_jk = np.asarray(delta.ik(delta.Delta.paper(), delta_poses[:8]).q.p)
    np.testing.assert_allclose(theta_vk, theta_jk, rtol=0, atol=1e-9)
    (theta, reached), rate = _run(
        benchmark,
        lambda: tasks.visual_kinematics_ik(robot, delta_poses),
        DELTA_SIZE,
        "Delta IK",
        "visual-kinematics",
    )
    err = np.where(reached, tasks.delta_error(theta, delta_poses), np.inf)
    _record(benchmark, "Delta IK", "visual-kinematics RobotDelta", DELTA_SIZE, rate, err)


# ------------------------------------------------------------------------ PUMA 560 IK


@pytest.fixture(scope="module")
def puma():
    return {n: tasks.puma_problems(n, seed=n) for n in IK_SIZES}


def _ik_record(benchmark, solver, n, rate, q, targets, jaxkin=False, **extra):
    pos, rot = tasks.puma_errors(q, targets)
    extra["max_rot_error"] = float(np.max(np.where(pos < tasks.REL_TOL, rot, 0.0)))
    _record(benchmark, "PUMA IK", solver, n, rate, pos, jaxkin=jaxkin, **extra)


@pytest.mark.parametrize("n", IK_SIZES)
def test_ik_jaxkin_analytic(benchmark, puma, n):
    _, targets, _ = puma[n]
    arm, t = serial.Puma560(), jnp.asarray(targets)
    res, rate = _run(
        benchmark, lambda: serial.ik_all_branches(arm, t), n, f"PUMA IK {n}", "jaxkin ik"
    )
    q, valid = np.asarray(res.q), np.asarray(res.valid)  # (n, 8, 6), (n, 8)
    pos, rot = tasks.puma_errors(q, targets[:, None])
    err = np.where(valid, pos, 0.0).max(-1)
    err = np.where(valid.any(-1), err, np.inf)
    benchmark.extra_info["mean_valid_branches"] = float(valid.sum(-1).mean())
    benchmark.extra_info["max_rot_error"] = float(np.where(valid, rot, 0.0).max())
    name = "jaxkin.serial.ik_all_branches (8 branches)"
    _record(benchmark, "PUMA IK", name, n, rate, err, jaxkin=True)


@pytest.mark.parametrize("max_iter", [20, 8])
@pytest.mark.parametrize("n", IK_SIZES)
def test_ik_jaxkin_newton(benchmark, puma, n, max_iter):
    """Pseudo-inverse Newton; steps stop once every element converged, else at max_iter."""
    _, targets, seeds = puma[n]
    table = serial.from_dh(serial.Puma560().dh_table())
    t, q0 = jnp.asarray(targets), jnp.asarray(seeds)
    res, rate = _run(
        benchmark,
        lambda: serial.ik_newton(table, t, q0, eps_omega=1e-10, eps_v=1e-10, max_iter=max_iter),
        n,
        f"PUMA IK {n}",
        f"jaxkin ik_newton max_iter={max_iter}",
    )
    converged = np.asarray(res.converged)
    _ik_record(
        benchmark,
        f"jaxkin.serial.ik_newton (max_iter {max_iter})",
        n,
        rate,
        np.asarray(res.q),
        targets,
        converged_flag=float(converged.mean()),
        mean_iterations=float(np.asarray(res.iterations)[converged].mean()),
    )


@pytest.mark.parametrize("n", IK_SIZES)
def test_ik_roboticstoolbox(benchmark, puma, n):
    _peer("roboticstoolbox", "roboticstoolbox-python")
    _, targets, seeds = puma[n]
    ets = tasks.rtb_puma_ets()

    def run():
        # tol bounds E = e^T W e / 2 (default 1e-6 leaves ~1e-3 m); 1e-16 gives ~1e-8
        return [ets.ik_LM(targets[i], q0=seeds[i], tol=1e-16, joint_limits=False) for i in range(n)]

    sols, rate = _run(benchmark, run, n, f"PUMA IK {n}", "roboticstoolbox", rounds=3)
    q = np.stack([s.q for s in sols])
    _ik_record(
        benchmark,
        "roboticstoolbox ETS.ik_LM (C++)",
        n,
        rate,
        q,
        targets,
        converged_flag=float(np.mean([s.success for s in sols])),
    )


@pytest.mark.parametrize("n", IK_SIZES)
def test_ik_pytorch_kinematics(benchmark, puma, n):
    _peer("pytorch_kinematics", "pytorch-kinematics")
    import pytorch_kinematics as pk
    import torch

    _, targets, seeds = puma[n]
    chain = tasks.pytorch_kinematics_chain()
    ik = pk.PseudoInverseIK(
        chain,
        retry_configs=torch.zeros(1, 6, dtype=torch.float64),
        pos_tolerance=1e-9,
        rot_tolerance=1e-9,
        max_iterations=30,
    )
    ik.initial_config = torch.as_tensor(seeds).reshape(n, 1, 6)  # one retry: the shared seed
    goal = pk.Transform3d(matrix=torch.as_tensor(targets), dtype=torch.float64)
    sol, rate = _run(
        benchmark,
        lambda: ik.solve(goal),
        n,
        f"PUMA IK {n}",
        "pytorch_kinematics",
        rounds=3,
    )
    _ik_record(
        benchmark,
        "pytorch_kinematics PseudoInverseIK",
        n,
        rate,
        sol.solutions[:, 0].numpy(),
        targets,
        converged_flag=float(sol.converged_any.double().mean()),
    )


@pytest.mark.parametrize("n", IK_SIZES)
def test_ik_pyroki(benchmark, puma, n):
    _peer("pyroki", "almond-pyroki")
    _, targets, seeds = puma[n]
    solve = tasks.pyroki_ik_solver()
    t, q0 = jnp.asarray(targets), jnp.asarray(seeds)
    q, rate = _run(
        benchmark, lambda: solve(t, q0), n, f"PUMA IK {n}", "pyroki", rounds=1 if n > 1_000 else 3
    )
    _ik_record(benchmark, "PyRoki (jaxls LM)", n, rate, np.asarray(q), targets)


# ------------------------------------------------------------------------ PUMA 560 FK


@pytest.fixture(scope="module")
def fk_configs():
    q, targets, _ = tasks.puma_problems(FK_SIZE, seed=7)
    return q, targets


def _fk_record(benchmark, solver, rate, t, targets, jaxkin=False):
    t = np.asarray(t)
    pos = np.linalg.norm(t[:, :3, 3] - targets[:, :3, 3], axis=-1) / tasks.PUMA_REACH
    benchmark.extra_info["max_rot_error"] = float(np.abs(t[:, :3, :3] - targets[:, :3, :3]).max())
    _record(benchmark, "PUMA FK", solver, FK_SIZE, rate, pos, jaxkin=jaxkin)


def test_fk_jaxkin_fk_dh(benchmark, fk_configs):
    q, targets = fk_configs
    table, qj = serial.Puma560().dh_table(), jnp.asarray(q)
    kernel = jax.jit(serial.dh.transforms)
    t, rate = _run(benchmark, lambda: kernel(table, qj), FK_SIZE, "PUMA FK", "fk_dh", rounds=10)
    _fk_record(benchmark, "jaxkin.serial.fk_dh", rate, t, targets, jaxkin=True)


def test_fk_jaxkin_arm_fk(benchmark, fk_configs):
    q, targets = fk_configs
    arm, qj = serial.Puma560(), jnp.asarray(q)
    t, rate = _run(benchmark, lambda: serial.fk(arm, qj).x.p, FK_SIZE, "PUMA FK", "fk", rounds=10)
    _fk_record(benchmark, "jaxkin.serial.fk", rate, t, targets)


def test_fk_pytorch_kinematics(benchmark, fk_configs):
    _peer("pytorch_kinematics", "pytorch-kinematics")
    import torch

    q, targets = fk_configs
    chain, qt = tasks.pytorch_kinematics_chain(), torch.as_tensor(q)
    with torch.no_grad():
        t, rate = _run(
            benchmark,
            lambda: chain.forward_kinematics(qt).get_matrix(),
            FK_SIZE,
            "PUMA FK",
            "pytorch_kinematics",
            rounds=10,
        )
    _fk_record(benchmark, "pytorch_kinematics forward_kinematics", rate, t.numpy(), targets)


def test_fk_roboticstoolbox(benchmark, fk_configs):
    _peer("roboticstoolbox", "roboticstoolbox-python")
    q, targets = fk_configs
    ets = tasks.rtb_puma_ets()
    t, rate = _run(benchmark, lambda: ets.fkine(q), FK_SIZE, "PUMA FK", "roboticstoolbox")
    _fk_record(benchmark, "roboticstoolbox ETS.fkine (batch)", rate, np.asarray(t.A), targets)


# ------------------------------------------------------------------- URDF arms: IK with limits
URDF_ARMS = {
    "UR5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "Panda": ("panda_description/urdf/panda.urdf", "panda_hand"),
}
URDF_SIZE = 500


@pytest.fixture(scope="module", params=list(URDF_ARMS))
def urdf_arm(request):
    """(name, path, tip, chain, targets from joints within the limits, Pinocchio's FK)."""
    pin = _peer("pinocchio", "pin")
    import importlib.metadata

    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    rel, tip = URDF_ARMS[request.param]
    path = str(robots / rel)
    chain = serial.from_urdf(path, tip)
    model = pin.buildModelFromUrdf(path)
    data, frame = model.createData(), model.getFrameId(tip)
    columns = [model.joints[model.getJointId(j)].idx_q for j in chain.joint_names]

    def fk(q):
        out = []
        for qi in q:
            full = pin.neutral(model)
            full[columns] = qi
            pin.framesForwardKinematics(model, data, full)
            out.append(data.oMf[frame].homogeneous)
        return np.array(out)

    rng = np.random.default_rng(0)
    q = rng.uniform(chain.lower, chain.upper, size=(URDF_SIZE, chain.n_joints))
    return request.param, path, tip, chain, fk(q), fk


def _urdf_errors(urdf_arm, q, per_target: int = 1):
    """Position error relative to the reach (Pinocchio's FK), inf outside the joint limits or
    beyond 1e-6 rad of orientation error; ``per_target`` consecutive rows of ``q`` per target."""
    _, _, _, chain, targets, fk = urdf_arm
    targets = np.repeat(targets, per_target, axis=0)
    reached = fk(q)
    pos = np.linalg.norm(reached[:, :3, 3] - targets[:, :3, 3], axis=-1) / float(chain.reach()[1])
    relative = np.swapaxes(reached[:, :3, :3], -1, -2) @ targets[:, :3, :3]
    cos = np.clip((np.trace(relative, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    within = np.all((q >= chain.lower - 1e-12) & (q <= chain.upper + 1e-12), axis=-1)
    return np.where(within & (np.arccos(cos) <= 1e-6), pos, np.inf)


def test_urdf_ik_jaxkin(benchmark, urdf_arm):
    name, _, _, chain, targets, _ = urdf_arm
    goal = jnp.asarray(targets)
    res, rate = _run(benchmark, lambda: jaxkin_ik(chain, goal), URDF_SIZE, f"{name} IK", "jaxkin")
    err = _urdf_errors(urdf_arm, np.asarray(res.q.p))
    _record(benchmark, f"{name} IK", "jaxkin.ik (no seed, limits)", URDF_SIZE, rate, err, True)


def test_urdf_ik_roboticstoolbox(benchmark, urdf_arm):
    _peer("roboticstoolbox", "roboticstoolbox-python")
    name, path, tip, _, targets, _ = urdf_arm
    ets = tasks.rtb_urdf_ets(path, tip)

    def run():
        # no seed (its random restarts), joint limits on; tol 1e-16 on E = e^T W e / 2
        return [ets.ik_LM(t, tol=1e-16, joint_limits=True, slimit=100) for t in targets]

    sols, rate = _run(benchmark, run, URDF_SIZE, f"{name} IK", "roboticstoolbox", rounds=1)
    err = _urdf_errors(urdf_arm, np.stack([np.asarray(s.q) for s in sols]))
    _record(benchmark, f"{name} IK", "roboticstoolbox ETS.ik_LM (C++)", URDF_SIZE, rate, err)


def _first_within(urdf_arm, solutions: np.ndarray) -> np.ndarray:
    """Per target, the first of a peer's ``(B, R, n)`` solutions that passes
    ``_urdf_errors`` (else the first): its best honest answer."""
    b, r, n = solutions.shape
    err = _urdf_errors(urdf_arm, solutions.reshape(b * r, n), r).reshape(b, r)
    good = err < tasks.REL_TOL
    pick = np.where(np.any(good, -1), np.argmax(good, -1), 0)
    return solutions[np.arange(b), pick]


def test_urdf_ik_pytorch_kinematics(benchmark, urdf_arm):
    _peer("pytorch_kinematics", "pytorch-kinematics")
    import pytorch_kinematics as pk
    import torch

    name, path, tip, chain, targets, _ = urdf_arm
    text = tasks.urdf_without_geometry(path)
    pchain = pk.build_serial_chain_from_urdf(text.encode(), tip).to(dtype=torch.float64)
    assert tuple(pchain.get_joint_parameter_names()) == chain.joint_names
    limits = torch.as_tensor(np.stack([chain.lower, chain.upper], -1), dtype=torch.float64)
    # no seed: 64 random retries within the limits (as jaxkin's 64 restarts), limits on
    ik = pk.PseudoInverseIK(
        pchain,
        num_retries=64,
        joint_limits=limits,
        pos_tolerance=1e-9,
        rot_tolerance=1e-9,
        max_iterations=30,
        early_stopping_any_converged=True,
    )
    goal = pk.Transform3d(matrix=torch.as_tensor(targets), dtype=torch.float64)
    sol, rate = _run(
        benchmark, lambda: ik.solve(goal), URDF_SIZE, f"{name} IK", "pytorch_kinematics", rounds=1
    )
    q = _first_within(urdf_arm, sol.solutions.numpy())
    _record(
        benchmark,
        f"{name} IK",
        "pytorch_kinematics PseudoInverseIK",
        URDF_SIZE,
        rate,
        _urdf_errors(urdf_arm, q),
    )


def test_urdf_ik_pyroki(benchmark, urdf_arm):
    _peer("pyroki", "almond-pyroki")
    name, path, tip, chain, targets, _ = urdf_arm
    solve = tasks.pyroki_ik_solver(
        urdf_text=tasks.urdf_without_geometry(path), tip=tip, limits=True
    )
    # no seed: the middle of the limits (PyRoki has no restarts; its actuated joints may
    # include side branches such as the Panda's finger); its limit cost on
    joints = solve.joints
    middle = (np.asarray(joints.lower_limits) + np.asarray(joints.upper_limits)) / 2
    q0 = jnp.broadcast_to(jnp.asarray(middle), (URDF_SIZE, len(middle)))
    ours = [joints.actuated_names.index(j) for j in chain.joint_names]
    t = jnp.asarray(targets)
    q, rate = _run(benchmark, lambda: solve(t, q0), URDF_SIZE, f"{name} IK", "pyroki", rounds=3)
    q = np.asarray(q)[:, ours]
    _record(
        benchmark,
        f"{name} IK",
        "PyRoki (jaxls LM, limit cost)",
        URDF_SIZE,
        rate,
        _urdf_errors(urdf_arm, q),
    )
