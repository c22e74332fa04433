"""examples/planar_2r_newton.py runs, and its iterates agree with seed 003's printed table."""

from __future__ import annotations

import re
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "planar_2r_newton.py"
SEED = ROOT.parent / "shared" / "seeds" / "003_a8692dd5cacfc958.txt"


@pytest.fixture(scope="module")
def example():
    return runpy.run_path(str(EXAMPLE), run_name="planar_2r_newton")


def _parse_seed_table(text: str) -> np.ndarray:
    """Rows like ``1\t(34.23, 79.18)\t(0.429, 1.480)\t(0.115, -0.074, 0.108)``."""
    rows = []
    pattern = re.compile(r"^(\d)\s+\(([^)]*)\)\s+\(([^)]*)\)\s+\(([^)]*)\)\s*$")
    for line in text.splitlines():
        match = pattern.match(line.strip())
        if match:
            numbers = [float(match.group(1))]
            for group in match.groups()[1:]:
                numbers += [float(x) for x in group.split(",")]
            rows.append(numbers)
    return np.array(rows)


def test_transcribed_table_matches_seed_text(example):
    if not SEED.exists():
        pytest.skip("seed text not available")
    parsed = _parse_seed_table(SEED.read_text(encoding="utf-8"))
    assert parsed.shape == (4, 8)
    np.testing.assert_array_equal(parsed, example["PAPER_TABLE"])


def test_iterates_match_paper_table(example):
    rows, result = example["run"]()
    paper, decimals = example["PAPER_TABLE"], example["PAPER_DECIMALS"]
    # ERRATA seed 003: 4 table rows = 3 body-frame updates, then converged.
    assert rows.shape == paper.shape
    assert int(result.iterations) == 3
    assert bool(result.converged) and int(result.status) == 0
    half_unit = 0.5 * 10.0 ** -decimals.astype(float)
    diff = np.abs(rows - paper)
    # One printed entry is inconsistent with the paper's own iterate: at i = 2,
    # theta = (29.98, 90.22) deg gives v_yb = -0.00347 (also from the rounded angles:
    # -0.00346), printed -0.004. Every other entry agrees to the printed precision.
    exceptions = {(2, 7)}
    for i in range(paper.shape[0]):
        for j in range(1, paper.shape[1]):
            limit = 1.5 * half_unit[j] if (i, j) in exceptions else half_unit[j] + 1e-12
            assert diff[i, j] <= limit, (i, j, rows[i, j], paper[i, j])
    # Converged solution: theta = (30, 90) deg to within the tolerances' reach.
    np.testing.assert_allclose(rows[-1, 1:3], [30.0, 90.0], atol=5e-3)


def test_example_script_runs():
    proc = subprocess.run(
        [sys.executable, str(EXAMPLE)], capture_output=True, text=True, timeout=300, cwd=ROOT
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "after 3 updates (4 table rows)" in proc.stdout
    assert (ROOT / "examples" / "output" / "planar_2r_newton.csv").exists()
