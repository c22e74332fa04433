"""The robot protocol: every robot through ``jaxkin.ik`` / ``jaxkin.fk``, with one test body.

Independent checks: the round trip ``fk(ik(t)) == t`` on targets made by the forward
kinematics of random joints (closed-form FK against the IK under test), on every branch, for
positions and for rates (the IK's joint rates pushed through the FK's own rates, computed by a
different formula or by autodiff, must give back the target's rates); jit and vmap equal eager;
no compilation on a repeated call with new values and a freshly built robot; and a robot written
in this file, knowing nothing of the library's robots, runs through the planner, the workspace
sweep and the optimiser (the protocol is all they need).
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import Jet, Status, delta, optimize, paths, plan, scara, serial, workspace
from jaxkin._geometry import LENGTH, geometry, number
from jaxkin.result import FKResult, IKResult
from jaxkin.robot import PLANAR_POINT, POINT, POSE, Robot
from tests.helpers import compilations, marked_slow

ROOT = Path(__file__).resolve().parents[1]


def _delta_joints(rng, n):
    return rng.uniform(0.2, 0.9, size=(n, 3))  # arms below horizontal: a hanging platform


# name -> (factory, joint sampler); targets are fk of the sampled joints.
ROBOTS = {
    "scara": (
        scara.Scara.paper,
        lambda rng, n: np.c_[
            rng.uniform(-1, 1, n), rng.uniform(0.4, 2.6, n), rng.uniform(0, 100, n)
        ],
    ),
    "delta": (delta.Delta.paper, _delta_joints),
    "planar2r": (lambda: serial.Planar2R(1.0, 0.7), lambda r, n: r.uniform(0.3, 2.5, (n, 2))),
    "planar3r": (lambda: serial.Planar3R(1.0, 0.7, 0.3), lambda r, n: r.uniform(0.3, 2.5, (n, 3))),
    "anthropomorphic": (
        lambda: serial.Anthropomorphic(0.3, 0.25, 0.2),
        lambda r, n: r.uniform(0.3, 2.5, (n, 3)),
    ),
    "cylindrical": (
        lambda: serial.Cylindrical(0.5),
        lambda r, n: np.c_[r.uniform(-3, 3, n), r.uniform(0.2, 1.0, n), r.uniform(-0.4, 0.4, n)],
    ),
    "spherical": (
        lambda: serial.Spherical(0.5),
        lambda r, n: np.c_[r.uniform(-3, 3, n), r.uniform(-1.2, 1.2, n), r.uniform(0.2, 1.0, n)],
    ),
    "puma560": (serial.Puma560, lambda r, n: r.uniform(0.3, 1.2, (n, 6))),
    "stanford": (lambda: serial.Stanford(0.4, 0.3), lambda r, n: r.uniform(0.3, 1.2, (n, 6))),
    "dh-chain": (
        lambda: serial.from_dh(
            serial.DHTable.create(a=[0.0, 0.4, 0.3], alpha=[np.pi / 2, 0.0, 0.0], d=[0.5, 0, 0])
        ),
        lambda r, n: r.uniform(0.3, 1.2, (n, 3)),
    ),
    "screw-chain": (
        lambda: serial.from_dh(serial.Puma560().dh_table()),
        lambda r, n: r.uniform(0.3, 1.2, (n, 6)),
    ),
}
N = 7


def _targets(name: str, n: int = N, seed: int = 0):
    factory, sample = ROBOTS[name]
    robot = factory()
    q = sample(np.random.default_rng(seed), n)
    return robot, q, np.asarray(jaxkin.fk(robot, q).x.p)


def _close(a, b, atol):
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=atol)


# Their round trips repeat, for another chain of the same kind, what the others check.
SLOW_CHAINS = ("screw-chain", "dh-chain", "stanford")


@pytest.mark.parametrize("name", list(ROBOTS))
def test_protocol_attributes(name):
    robot = ROBOTS[name][0]()
    assert isinstance(robot, Robot)
    assert isinstance(robot.branches, tuple) and robot.default_branch in robot.branches
    assert robot.target in (PLANAR_POINT, POINT, jaxkin.robot.PLANAR_POSE, POSE)
    assert len(robot.joint_names) == robot.n_joints == len(robot.joint_types)
    assert set(robot.joint_types) <= {"R", "P"}
    limits = robot.joint_limits()
    assert np.shape(limits.lower) == np.shape(limits.upper) == (robot.n_joints,)
    assert float(robot.length_scale()) > 0
    assert all(isinstance(s, Status) for s in robot.reachable)


@pytest.mark.parametrize("name", marked_slow(ROBOTS, SLOW_CHAINS))
def test_round_trip_every_branch(name):
    """fk(ik(t)).x == t (1e-9 of the robot's size) on every branch that solves the target; the
    default branch reproduces the targets made from the sampled joints."""
    robot, _, t = _targets(name)
    scale = float(robot.length_scale())
    solved_any = np.zeros(N, bool)
    for branch in robot.branches:
        res = jaxkin.ik(robot, t, branch)
        assert isinstance(res, IKResult)
        assert res.q.p.shape == (N, robot.n_joints) and res.status.shape == (N,)
        assert res.status.dtype == jnp.int8 and res.margin.shape == (N,)
        ok = np.asarray(res.status) == Status.OK
        solved_any |= ok
        back = jaxkin.fk(robot, res.q)
        assert isinstance(back, FKResult) and back.x.p.shape == t.shape
        _close(np.asarray(back.x.p)[ok], t[ok], 1e-9 * scale)
        margin = np.asarray(res.margin)[ok]
        assert np.all((margin > 0) & (margin <= 1))
    assert solved_any.all()
    assert np.all(np.asarray(jaxkin.ik(robot, t).status) == Status.OK) or name == "scara"


@pytest.mark.parametrize("name", marked_slow(ROBOTS, SLOW_CHAINS))
def test_rates_round_trip(name):
    """Joint rates from the IK of a target Jet, pushed through the FK's rates, give back the
    target's velocity and acceleration (both computed by the library, by different formulas:
    the check fails if either is wrong)."""
    robot, q, _ = _targets(name, seed=1)
    rng = np.random.default_rng(2)
    joints = Jet.of(q, rng.normal(size=q.shape), rng.normal(size=q.shape))
    target = jaxkin.fk(robot, joints).x
    res = jaxkin.ik(robot, target)
    ok = np.asarray(res.status) == Status.OK
    assert ok.sum() >= N - 1
    back = jaxkin.fk(robot, res.q).x
    scale = float(robot.length_scale())
    for got, want in ((back.v, target.v), (back.a, target.a)):
        _close(np.asarray(got)[ok], np.asarray(want)[ok], 1e-7 * scale * (1 + np.abs(want).max()))


@pytest.mark.parametrize("name", marked_slow(ROBOTS, SLOW_CHAINS))
def test_plain_arrays_are_at_rest_and_errors_name_the_argument(name):
    robot, q, t = _targets(name)
    res = jaxkin.ik(robot, t)
    assert not np.any(np.asarray(res.q.v)) and not np.any(np.asarray(res.q.a))
    x = jaxkin.fk(robot, q).x
    assert not np.any(np.asarray(x.v)) and not np.any(np.asarray(x.a))
    with pytest.raises(ValueError, match="branch"):
        jaxkin.ik(robot, t, branch="no-such-branch")
    wrong = np.zeros((2, 5))
    with pytest.raises(ValueError, match="target|path|p:|d:"):
        jaxkin.ik(robot, wrong)
    with pytest.raises(ValueError, match="q|theta"):
        jaxkin.fk(robot, np.zeros((2, robot.n_joints + 1)))
    with pytest.raises(ValueError, match="robot"):
        jaxkin.ik(object(), t)


@pytest.mark.parametrize(
    "name", marked_slow(["scara", "delta", "anthropomorphic", "puma560", "dh-chain"], ["dh-chain"])
)
def test_jit_vmap_and_no_recompilation(name):
    """Under a user's jit and vmap the protocol gives the eager values; a repeated call with new
    values and a freshly built robot compiles (and traces) nothing."""
    robot, _, t = _targets(name)
    eager = jaxkin.ik(robot, t)
    jitted = jax.jit(lambda x: jaxkin.ik(robot, x).q.p)(jnp.asarray(t))
    _close(jitted, eager.q.p, 1e-12)
    mapped = jax.vmap(lambda x: jaxkin.fk(robot, x).x.p)(eager.q.p)
    _close(mapped, jaxkin.fk(robot, eager.q).x.p, 1e-12)
    _, _, t2 = _targets(name, seed=5)
    fresh = ROBOTS[name][0]()
    t2 = jnp.asarray(t2)
    jax.block_until_ready(t2)
    with compilations() as count:
        jax.block_until_ready(jaxkin.fk(fresh, jaxkin.ik(fresh, t2).q).x.p)
    assert count.n == 0


# ------------------------------------------------------------------------- a robot of our own
@geometry
class Slider2D(Robot):
    """A Cartesian XY table written here: two prismatic joints, q = (x, y) - offset. Two
    branches that differ by nothing but their name (to exercise branch handling)."""

    offset: Any = number(LENGTH, default=1.0)

    target: ClassVar = PLANAR_POINT
    branches: ClassVar = ("left", "right")

    @property
    def joint_names(self):
        return ("x", "y")

    @property
    def joint_types(self):
        return "PP"

    def joint_limits(self):
        return jaxkin.JointLimits(np.array([-5.0, -5.0]), np.array([5.0, 5.0]))

    def length_scale(self):
        return 10.0

    def workspace_box(self):
        return ((-8.0, 8.0), (-8.0, 8.0)), 1.0

    def ik_kernel(self, target, branch, options, rates):
        q = Jet(target.p - self.offset, target.v, target.a)
        inside = jnp.all(jnp.abs(q.p) <= 5.0, axis=-1)
        status = jnp.where(inside, Status.OK, Status.UNREACHABLE).astype(jnp.int8)
        margin = 1.0 - jnp.max(jnp.abs(q.p), axis=-1) / 5.0
        return IKResult(q, status, margin)

    def fk_kernel(self, q, options, rates):
        x = Jet(q.p + self.offset, q.v, q.a)
        return FKResult(x, jnp.zeros(q.p.shape[:-1], jnp.int8))


def test_a_new_robot_needs_only_the_protocol():
    robot = Slider2D()
    with pytest.raises(ValueError, match="Slider2D.offset"):
        Slider2D(offset=-1.0)
    t = np.array([[1.0, 2.0], [9.0, 0.0]])
    res = jaxkin.ik(robot, t)
    _close(res.q.p, t - 1.0, 0.0)
    assert list(np.asarray(res.status)) == [Status.OK, Status.UNREACHABLE]
    s = np.linspace(0.0, 1.0, 11)[None, :, None]
    goals = np.array([[4.0, 3.0], [2.0, -1.0], [12.0, 0.0]])  # the last leaves x - 1 <= 5
    path = paths.path_from_samples(goals[:, None, :] * s, dt=0.1)
    ev = plan.evaluate(robot, path, dt=0.1, branch="best")
    assert list(np.asarray(ev.feasible)) == [True, True, False]
    ws = workspace.sweep(robot)
    assert ws.mask.shape == (17, 17) and ws.n_reachable == 11 * 11  # x - 1 in [-5, 5]
    result = optimize.optimize(robot, [0.0, 0.0], [3.0, 1.0], [[1.0, 2.0]], steps=5, n_samples=8)
    assert result.controls.shape == (1, 3, 2) and np.all(np.isfinite(result.history))


def test_consumers_never_ask_which_robot():
    """The planner, optimiser, workspace sweeps and the command's solvers import no robot
    module: they are written against the protocol alone."""
    robot_modules = {"scara", "delta", "serial", "dyad"}
    consumers = ("plan.py", "paths.py", "costs.py", "optimize.py", "workspace.py")
    for path in (*consumers, "cli/commands.py", "cli/files.py"):
        tree = ast.parse((ROOT / "jaxkin" / path).read_text())
        imported = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                imported |= {a.name for a in node.names} | set((node.module or "").split("."))
            elif isinstance(node, ast.Import):
                imported |= {part for a in node.names for part in a.name.split(".")}
        assert not imported & robot_modules, (path, imported & robot_modules)


def test_every_public_module_declares_all():
    """Every public module has ``__all__`` and every name in it exists."""
    for path in sorted((ROOT / "jaxkin").rglob("*.py")):
        rel = path.relative_to(ROOT / "jaxkin").with_suffix("")
        if any(part.startswith("_") and part != "__init__" for part in rel.parts):
            continue
        name = ".".join(("jaxkin", *rel.parts)).removesuffix(".__init__")
        module = __import__(name, fromlist=["__all__"])
        assert hasattr(module, "__all__"), name
        missing = [n for n in module.__all__ if not hasattr(module, n)]
        assert not missing, (name, missing)


def test_results_are_frozen_pytrees():
    robot, q, t = _targets("delta", n=2)
    res = jaxkin.ik(robot, t)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.q = None
    leaves = jax.tree.leaves(res)
    assert len(leaves) == 5  # q (p, v, a), status, margin


# ------------------------------------------------------------------------- the kernel contract
def test_a_robot_without_a_kernel_fails_when_its_class_is_defined():
    with pytest.raises(TypeError, match="fk_kernel"):

        @geometry
        class NoForward(Robot):
            target: ClassVar = POINT
            branches: ClassVar = ("only",)

            def ik_kernel(self, target, branch, options, rates):
                raise NotImplementedError

    class Partial(Robot, abstract=True):  # declared abstract: no kernels needed yet
        target: ClassVar = POINT

    with pytest.raises(TypeError, match="abstract"):
        Partial()


def test_options_are_frozen_dataclasses_and_unknown_keys_are_named():
    robot = delta.Delta.paper()
    theta = np.full((2, 3), 0.4)
    default = jaxkin.fk(robot, theta)
    given = jaxkin.fk(robot, theta, robot.FKOptions(max_iter=30))
    by_key = jaxkin.fk(robot, theta, max_iter=30)
    for res in (given, by_key):
        np.testing.assert_array_equal(res.x.p, default.x.p)
    assert hash(robot.FKOptions()) == hash(robot.FKOptions())
    with pytest.raises(dataclasses.FrozenInstanceError):
        robot.FKOptions().max_iter = 3
    with pytest.raises(ValueError, match=r"\['iters'\]"):
        jaxkin.fk(robot, theta, iters=3)
    with pytest.raises(ValueError, match="max_iter"):
        jaxkin.fk(robot, theta, max_iter=0)
    with pytest.raises(ValueError, match="options"):
        jaxkin.fk(robot, theta, scara.Scara.IKOptions())
    with pytest.raises(ValueError, match="method"):
        jaxkin.ik(scara.Scara.paper(), np.zeros(3), method="numeric")


def test_a_new_tolerance_compiles_nothing_new():
    """Tolerances of a chain's IK are data (``options(dynamic=...)``): a new value reuses the
    compiled search."""
    chain = serial.from_screws(*_planar_screws())
    target = np.asarray(jaxkin.fk(chain, np.array([[0.3, 0.4]])).x.p)
    jaxkin.ik(chain, target, position_tol=1e-8)
    with compilations() as count:
        res = jaxkin.ik(chain, target, position_tol=2e-8)
    assert count.n == 0
    assert int(res.status[0]) == Status.OK


def _planar_screws():
    """A planar 2R chain (links 1 and 0.7) as space screws and home pose."""
    screws = np.array([[0, 0, 1, 0, 0, 0], [0, 0, 1, 0, -1.0, 0]], float)
    home = np.eye(4)
    home[0, 3] = 1.7
    return screws, home


@pytest.mark.parametrize("name", ["scara", "delta", "screw-chain"])
def test_single_query_gives_the_batched_results(name):
    """One target (batch ``()``) runs straight in the program compiled for its shape, without
    padding: the same joints and statuses as that element of a batch (to 4 ulp of the robot's
    size), and a second single query compiles nothing."""
    robot, q, t = _targets(name)
    batched_ik, batched_fk = jaxkin.ik(robot, t), jaxkin.fk(robot, q)
    scale = float(robot.length_scale())
    tol = 4 * np.finfo(np.float64).eps * max(scale, 1.0)
    for i in (0, 1):
        one_ik, one_fk = jaxkin.ik(robot, t[i]), jaxkin.fk(robot, q[i])
        assert one_ik.q.p.shape == (robot.n_joints,) and one_ik.status.shape == ()
        assert int(one_ik.status) == int(batched_ik.status[i])
        assert int(one_fk.status) == int(batched_fk.status[i])
        _close(one_ik.q.p, batched_ik.q.p[i], tol * 1e3 if name == "screw-chain" else tol)
        _close(one_fk.x.p, batched_fk.x.p[i], tol)
    with compilations() as count:
        jax.block_until_ready(jaxkin.fk(robot, q[2]).x.p)
    assert count.n == 0
