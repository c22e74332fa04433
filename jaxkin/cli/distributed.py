"""``--distributed``: one ``jaxkin ik`` or ``jaxkin workspace`` run over several processes.

Every process runs the same command line (the multi-controller model of ``jax.distributed``).
``--distributed`` joins JAX's processes before anything else (``join``): the coordinator, the
process count and this process's id come from ``JAX_COORDINATOR_ADDRESS``,
``JAX_NUM_PROCESSES`` and ``JAX_PROCESS_ID`` when set, else from JAX's detection of the
cluster (SLURM, Open MPI, Kubernetes...). Every process reads the input, solves its own part
(rows of a file: ``solve_rows``; voxels: ``jaxkin.workspace.sweep``), the parts are gathered,
and only process 0 writes files and prints (``is_writer``).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Sequence
from typing import Any

import jax
import numpy as np

from .. import _processes
from .robots import CliError

__all__ = ["add_option", "is_writer", "join", "solve_rows"]

ENVIRONMENT = ("JAX_COORDINATOR_ADDRESS", "JAX_NUM_PROCESSES", "JAX_PROCESS_ID")


def add_option(parser: argparse.ArgumentParser) -> None:
    """The ``--distributed`` flag."""
    parser.add_argument(
        "--distributed",
        action="store_true",
        help="run as one of several processes (jax.distributed: JAX_COORDINATOR_ADDRESS, "
        "JAX_NUM_PROCESSES, JAX_PROCESS_ID, or the cluster's own variables, e.g. SLURM's); "
        "every process runs the same command and process 0 writes the output",
    )


def _environment_int(name: str) -> int | None:
    text = os.environ.get(name, "").strip()
    if not text:
        return None
    try:
        return int(text)
    except ValueError:
        raise CliError(f"--distributed: {name} must be an integer, got {text!r}") from None


def join(args: argparse.Namespace) -> None:
    """Join JAX's processes when ``--distributed`` was given (once; before any computation)."""
    if not getattr(args, "distributed", False) or jax.distributed.is_initialized():
        return
    try:
        jax.distributed.initialize(
            num_processes=_environment_int("JAX_NUM_PROCESSES"),
            process_id=_environment_int("JAX_PROCESS_ID"),
        )
    except (ValueError, RuntimeError) as exc:
        given = ", ".join(f"{k}={os.environ[k]}" for k in ENVIRONMENT if k in os.environ)
        raise CliError(
            f"--distributed: cannot join the processes ({' '.join(str(exc).split())}); set "
            f"{', '.join(ENVIRONMENT)} or run under a cluster JAX detects (got: "
            f"{given or 'none set'})"
        ) from None


def is_writer() -> bool:
    """True on the process that writes files and prints (process 0)."""
    return jax.process_index() == 0


def solve_rows(
    solve_in_chunks: Callable[..., list[np.ndarray]],
    fn: Callable[..., Any],
    arrays: Sequence[np.ndarray],
    *args: Any,
) -> list[np.ndarray]:
    """``solve_in_chunks(fn, arrays, *args)`` with the rows split over the processes: each
    solves its own run of rows (``_processes.process_range``), and every process gets every
    row's outputs."""
    if _processes.process_count() == 1:
        return solve_in_chunks(fn, arrays, *args)
    n = len(arrays[0])
    start, stop = _processes.process_range(n)
    if start == stop:  # more processes than rows: solve one row for the shapes, keep none
        outputs = [column[:0] for column in solve_in_chunks(fn, [x[:1] for x in arrays], *args)]
    else:
        outputs = solve_in_chunks(fn, [x[start:stop] for x in arrays], *args)
    return [_processes.allgather_rows(column) for column in outputs]
