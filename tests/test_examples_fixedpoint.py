"""examples/fixed_point_accuracy.py runs and states its conclusion."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_fixed_point_accuracy_example_runs():
    proc = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "fixed_point_accuracy.py")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout
    assert "smallest width with RMS Cartesian error <= 1 mm: 12 bits (truncation)" in out
    assert "paper's 10-bit claim" in out
    assert (ROOT / "examples" / "output" / "fixed_point_accuracy.csv").exists()
    lines = [line for line in out.splitlines() if line.strip().startswith("40 ")]
    assert lines and float(lines[0].split()[4]) < 1e-10  # RMS xyz at 40 bits
