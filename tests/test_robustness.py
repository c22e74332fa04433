"""Regression cases for failures found outside float64 at unit scale, each as it was reported.

Expected values come from geometry (a target twice the reach cannot be reached; a point 1e200
robot sizes away neither), from the unit-scale solution of the same problem, or from the
command line's documented contract (exit status 2 before anything is written, 141 on a closed
pipe, empty cells rather than ``nan``).
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxkin
from jaxkin import Jet, Status, delta, dyad, optimize, paths, plan, scara, serial
from jaxkin.cli import main


def _finite(tree) -> bool:
    return all(np.all(np.isfinite(np.asarray(x))) for x in jax.tree.leaves(tree))


def test_float32_dyad_at_large_scale_has_finite_analytic_accelerations():
    """Reported: OK dyads with infinite accelerations from the analytic path in float32."""
    s = np.float32(1e9)
    a = Jet.of(np.zeros((1, 2), np.float32))
    b = Jet.of(np.array([[1.2, 0.3]], np.float32) * s, np.ones((1, 2), np.float32) * s)
    res = dyad.solve(a, b, np.float32(1.0) * s, np.float32(0.8) * s)
    unit = dyad.solve(a, Jet.of(b.p / s, b.v / s), np.float32(1.0), np.float32(0.8))
    assert int(res.status[0]) == Status.OK and _finite(res)
    np.testing.assert_allclose(res.phi.a, unit.phi.a, rtol=1e-5)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_delta_target_twice_the_reach_is_unreachable_at_every_scale(dtype):
    """Reported: a float32 Delta target twice the reach came back OK with margin 1."""
    for s in (1e-9, 1.0, 1e9) if dtype == np.float32 else (1e-150, 1.0, 1e150):
        robot = delta.Delta(7.0 * s, 2.5 * s, 15.5 * s, 30.0 * s)
        res = delta.ik(robot, np.array([[0.0, 0.0, -2 * 55.0 * s]], dtype))
        assert int(res.status[0]) == Status.UNREACHABLE and float(res.margin[0]) < 0


def test_delta_closed_form_and_newton_fk_at_extreme_scales():
    """Reported: the float32 closed-form FK returned inf, and the Newton FK did not converge
    at small scales (its tolerance was not relative to the robot's size)."""
    theta = np.array([[0.3, 0.5, 0.7]])
    unit = delta.fk_closed_form(delta.Delta.paper(), theta)
    for dtype, s in ((np.float32, 1e9), (np.float32, 1e-9), (np.float64, 1e-150)):
        robot = delta.Delta(7.0 * s, 2.5 * s, 15.5 * s, 30.0 * s)
        closed = delta.fk_closed_form(robot, theta.astype(dtype))
        newton = delta.fk(robot, theta.astype(dtype))
        assert _finite(closed) and _finite(newton)
        assert int(newton.status[0]) == Status.OK and int(closed.status[0]) == Status.OK
        tol = 1e-5 if dtype == np.float32 else 1e-12
        np.testing.assert_allclose(np.asarray(closed.x) / s, unit.x, rtol=tol)
        np.testing.assert_allclose(np.asarray(newton.x.p) / s, unit.x, rtol=tol)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_targets_whose_squared_distance_overflows_are_unreachable(dtype):
    """Reported: such targets came back OK (dyad, SCARA) or as NaN joints (an arm)."""
    huge = np.finfo(dtype).max / 4
    far = np.array([[huge, 0.0], [huge, -huge], [-huge, 1.0]], dtype)
    res = dyad.solve(np.zeros((3, 2), dtype), far, dtype(1.0), dtype(1.0))
    assert np.all(np.asarray(res.status) == Status.UNREACHABLE) and _finite(res)
    d = np.c_[far, np.zeros(3, dtype)]
    res = scara.ik(scara.Scara.paper(), d.astype(dtype))
    assert np.all(np.asarray(res.status) == Status.UNREACHABLE) and _finite(res)
    arm = serial.Anthropomorphic(0.3, 0.25, 0.2)
    res = jaxkin.ik(arm, d.astype(dtype))
    assert np.all(np.asarray(res.status) == Status.UNREACHABLE) and _finite(res)
    assert np.all(np.asarray(res.margin) < 0)
    res = delta.ik(delta.Delta.paper(), d.astype(dtype))
    assert np.all(np.asarray(res.status) == Status.UNREACHABLE) and _finite(res)


def test_empty_and_partly_invalid_batches():
    robot = scara.Scara.paper()
    ev = plan.evaluate(robot, paths.path_from_samples(np.zeros((0, 5, 3)), 0.1))
    assert ev.feasible.shape == (0,) and ev.q.p.shape == (0, 5, 3)
    assert plan.best(ev, 3)[0].size == 0
    positions = np.linspace([100.0, 0.0, 50.0], [80.0, 40.0, 60.0], 10)[None].repeat(3, 0)
    positions[1, 4, 0] = np.nan
    ev = plan.evaluate(robot, paths.path_from_samples(positions, 0.1))
    assert list(np.asarray(ev.feasible)) == [True, False, True]
    assert np.all(np.asarray(ev.status)[1] == Status.INVALID_INPUT)
    guesses = np.array([[[90.0, 20.0, 55.0]], [[np.nan, 20.0, 55.0]]])
    with pytest.raises(ValueError, match=r"interior.*\[1\]"):
        optimize.optimize(robot, [100.0, 0.0, 50.0], [80.0, 40.0, 60.0], guesses, steps=1)


def _spiral_csv(path: Path) -> Path:
    t = np.linspace(0.0, 8.0, 21)
    rows = np.c_[t, 100 + 20 * np.sin(t), -20 * np.cos(t), 50 + t]
    rows[3, 1] = np.nan  # one invalid row
    np.savetxt(path, rows, delimiter=",", header="t,x,y,z", comments="")
    return path


def test_cli_refuses_to_overwrite_its_input(tmp_path, monkeypatch, capsys):
    source = _spiral_csv(tmp_path / "in.csv")
    before = source.read_bytes()
    (tmp_path / "link.csv").symlink_to(source)
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    for output in ("in.csv", "./in.csv", "sub/../in.csv", "link.csv", str(source)):
        code = main(["ik", "scara", "--robot", "paper", "-i", "in.csv", "-o", output, "-q"])
        assert code == 2
        err = capsys.readouterr().err
        assert f"--output {output} is the input file in.csv" in err
        assert source.read_bytes() == before
    assert main(["ik", "scara", "--robot", "paper", "-i", "./nope.csv", "-o", "x.csv"]) == 2
    assert "./nope.csv: no such file" in capsys.readouterr().err


def test_cli_closed_pipe_ends_quietly(tmp_path, monkeypatch, capsys):
    source = _spiral_csv(tmp_path / "in.csv")

    class ClosedPipe(io.StringIO):
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def fileno(self):
            return os.open(os.devnull, os.O_WRONLY)

    monkeypatch.setattr("sys.stdout", ClosedPipe())
    code = main(["ik", "scara", "--robot", "paper", "-i", str(source), "-o", "-", "-q"])
    assert code == 141
    err = capsys.readouterr().err  # the NaN-row warning only: no error line, no traceback
    assert "error" not in err and "Traceback" not in err


def test_cli_writes_empty_cells_not_nan(tmp_path):
    source = _spiral_csv(tmp_path / "in.csv")
    out = tmp_path / "out.csv"
    assert main(["ik", "scara", "--robot", "paper", "-i", str(source), "-o", str(out), "-q"]) == 0
    text = out.read_text()
    assert "nan" not in text.lower()
    row = text.splitlines()[1 + 3].split(",")
    assert row[-2] == "INVALID_INPUT" and row[1:10] == [""] * 9
