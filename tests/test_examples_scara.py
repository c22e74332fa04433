"""Run the SCARA examples as scripts and check what they print and write."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def run(script: str) -> str:
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / script)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_scara_spiral_example():
    out = run("scara_spiral.py")
    assert "mode +1: status OK x1001" in out and "mode -1: status OK x1001" in out
    path = EXAMPLES / "output" / "scara_spiral.csv"
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == [
        "t", "theta1", "theta1_dot", "theta1_ddot", "theta2", "theta2_dot", "theta2_ddot",
        "l3", "l3_dot", "l3_ddot", "status", "mode",
    ]  # fmt: skip
    assert len(rows) == 2 * 1001
    assert {r["status"] for r in rows} == {"OK"} and {r["mode"] for r in rows} == {"1", "-1"}
    t = np.array([float(r["t"]) for r in rows])
    l3 = np.array([float(r["l3"]) for r in rows])
    np.testing.assert_allclose(l3, 150.0 - (50.0 + 10.0 * t), atol=1e-12)  # eq. 14 of eq. 16
    first = next(r for r in rows if r["mode"] == "1")
    assert abs(float(first["theta1_ddot"]) - 0.309) < 5e-4  # ERRATA seed 000 item 4


def test_scara_practical_case_example():
    out = run("scara_practical_case.py")
    assert out.count("corner 3") == 2 and out.count("centre") == 2
    # Corner 3 (3, 3): r = sqrt(18); |q2| = 180 - acos((9 + 4 - 18) / 12) in degrees.
    q2 = 180.0 - np.degrees(np.arccos((9.0 + 4.0 - 18.0) / 12.0))
    assert f"{q2:.4f}" in out and f"{-q2:.4f}" in out
    worst = float(out.split("fk(ik(P)) - P (m):")[1].split()[0])
    assert worst < 1e-10
