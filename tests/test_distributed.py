"""Two processes joined by ``jax.distributed`` on this machine against one process.

One launch of two worker processes (``tests/distributed_worker.py``: loopback, a free port,
CPU collectives over gloo) runs the planner, ``plan.best``, the Delta's workspace, the
optimiser and the ``workspace`` and ``ik`` subcommands; this process computes the same in one
process meanwhile. Statuses, counts, indices and masks must be equal; the planner's and the
sweeps' floats bit for bit (each call gets the same batch per device in both runs, so the
arithmetic is the same), the optimiser's and the ``ik`` file's to 1e-12 (their batches per
call differ, which may change XLA's vectorisation of a reduction). The planner's outputs must
be global arrays spread over both processes, and no process may hold every candidate when
each was given only its own rows.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from jaxkin.cli import distributed
from tests import distributed_worker as worker

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT = 240  # seconds for both workers (each imports JAX and compiles ~10 kernels)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _launch(out_dir: Path) -> list[subprocess.Popen]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "XLA_"))}
    env.update(
        JAX_COORDINATOR_ADDRESS=f"127.0.0.1:{_free_port()}",
        JAX_NUM_PROCESSES="2",
        JAX_PLATFORMS="cpu",
        JAXKIN_TEST_CACHE=jax.config.jax_compilation_cache_dir or "",
    )
    return [
        subprocess.Popen(
            [sys.executable, "-m", "tests.distributed_worker", str(out_dir)],
            cwd=ROOT,
            env={**env, "JAX_PROCESS_ID": str(i)},
            stdout=subprocess.DEVNULL,
            stderr=(out_dir / f"stderr-{i}.txt").open("w"),
        )
        for i in range(2)
    ]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """(one process's results, [each worker's results], the two output directories)."""
    if jax.device_count() != 1:
        pytest.skip("this process must have one device to be the one-process reference")
    one, two = tmp_path_factory.mktemp("one"), tmp_path_factory.mktemp("two")
    workers = _launch(two)
    try:
        reference = worker.run(one, distributed=False)
        for proc in workers:
            proc.wait(timeout=TIMEOUT)
    finally:
        for proc in workers:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    for i, proc in enumerate(workers):
        log = (two / f"stderr-{i}.txt").read_text()
        assert proc.returncode == 0, f"worker {i} failed:\n{log[-4000:]}"
    results = []
    for i in range(2):
        with np.load(two / f"process-{i}.npz") as data:
            results.append(dict(data))
    return reference, results, one, two


def _values(results: dict) -> dict:
    """The computed values (not the facts about where they were held)."""
    layout = (".held_rows", ".devices")
    skip = ("processes", "holds_every_candidate", "writes")
    return {k: v for k, v in results.items() if not k.endswith(layout) and k not in skip}


def assert_same(got: np.ndarray, expected: np.ndarray, rtol: float, message: str) -> None:
    """Equal dtypes; floats to ``rtol`` of the array's largest value (0: bit for bit), NaN
    where NaN; the rest exactly."""
    assert got.dtype == expected.dtype, message
    if rtol and np.issubdtype(expected.dtype, np.floating):
        scale = np.nanmax(np.abs(expected), initial=0.0, where=np.isfinite(expected))
        np.testing.assert_allclose(got, expected, rtol=rtol, atol=rtol * scale, err_msg=message)
    else:
        np.testing.assert_array_equal(got, expected, err_msg=message)


@pytest.mark.slow
def test_every_result_equals_one_process(runs):
    reference, results, _, _ = runs
    expected = _values(reference)
    assert len(expected) > 80
    for process, result in enumerate(results):
        assert result["processes"] == 2
        got = _values(result)
        assert got.keys() == expected.keys()
        for key, value in expected.items():
            rtol = 1e-12 if key.startswith("optimize.") else 0.0
            assert_same(got[key], value, rtol, f"process {process}: {key}")


@pytest.mark.slow
def test_planner_outputs_are_global_arrays_over_both_processes(runs):
    _, results, _, _ = runs
    for result in results:
        assert not result["holds_every_candidate"]
        for name in ("local", f"host{worker.N}", "optimize"):
            counts = [k for k in result if k.startswith(f"{name}.") and k.endswith(".devices")]
            assert counts, name
            for key in counts:
                assert result[key] == 2, key
                held = result[key.replace(".devices", ".held_rows")]
                assert held == worker.N // 2 or key.startswith("optimize"), key
        # not a multiple of the device count: every process holds every row
        assert result[f"host{worker.N - 1}.0.held_rows"] == worker.N - 1
        # the mask is split along x when 2 divides nx, else replicated
        assert result["ws26.mask.0.held_rows"] == 13
        assert result["ws51.mask.0.held_rows"] == 51


@pytest.mark.slow
def test_command_line_writes_once_from_process_zero(runs):
    _, results, one, two = runs
    assert [int(r["writes"]) for r in results] == [2, 0]
    expected, got = (
        np.genfromtxt(d / "ik.csv", delimiter=",", names=True, dtype=None, encoding=None)
        for d in (one, two)
    )
    assert got.dtype.names == expected.dtype.names and len(got) == len(expected) == 2 * worker.T
    for name in expected.dtype.names:
        assert_same(got[name], expected[name], 1e-12, f"ik.csv column {name}")
    with np.load(one / "ws.npz") as expected, np.load(two / "ws.npz") as got:
        assert expected.files == got.files
        for key in expected.files:
            np.testing.assert_array_equal(got[key], expected[key], err_msg=key)


@pytest.mark.slow
def test_distributed_option_reads_the_environment(monkeypatch):
    """--distributed passes JAX_NUM_PROCESSES and JAX_PROCESS_ID to jax.distributed (JAX reads
    JAX_COORDINATOR_ADDRESS itself), and a failure to join is one line naming the variables."""
    calls = []

    def initialize(**kwargs):
        calls.append(kwargs)
        raise ValueError("coordinator_address should be defined.")

    monkeypatch.setattr(jax.distributed, "is_initialized", lambda: False)
    monkeypatch.setattr(jax.distributed, "initialize", initialize)
    monkeypatch.setenv("JAX_NUM_PROCESSES", "4")
    monkeypatch.setenv("JAX_PROCESS_ID", "3")
    args = type("Args", (), {"distributed": True})()
    with pytest.raises(distributed.CliError, match="JAX_COORDINATOR_ADDRESS.*JAX_NUM_PROCESSES=4"):
        distributed.join(args)
    assert calls == [{"num_processes": 4, "process_id": 3}]
    monkeypatch.setenv("JAX_PROCESS_ID", "three")
    with pytest.raises(distributed.CliError, match="JAX_PROCESS_ID must be an integer"):
        distributed.join(args)
