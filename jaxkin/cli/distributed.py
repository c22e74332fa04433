"""``--distributed``: one ``jaxkin ik`` or ``jaxkin workspace`` run over several processes.

Every process runs the same command line (the multi-controller model of ``jax.distributed``).
``--distributed`` joins JAX's processes before anything else (``join``): the coordinator, the
process count and this process's id come from ``JAX_COORDINATOR_ADDRESS``,
``JAX_NUM_PROCESSES`` and ``JAX_PROCESS_ID`` when set, else from JAX's detection of the
cluster (SLURM, Open MPI, Kubernetes...). Every process reads the input, solves its own part
(rows of a file: ``solve_rows``; voxels: ``jaxkin.workspace.sweep``), the parts are gathered,
and only process 0 writes files and prints (``is_writer``).

Joining waits at most ``--distributed-timeout`` seconds (default ``DISTRIBUTED_TIMEOUT`` of
``jaxkin.cli.parser``). With the three
variables set, the processes first meet on the coordinator's port (``rendezvous``: process 0
listens, the others connect and say who they are), so a missing process or a wrong address is
one line naming the missing processes (on process 0) or the coordinator that did not answer
(on the others), exit status 2, before JAX's runtime starts (JAX itself, once started, aborts
the interpreter when a peer is missing). Without them (a cluster JAX detects), a watchdog ends
the process with the same kind of line and status 2 when joining outlasts the timeout.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import jax
import numpy as np

from .. import _processes
from . import files
from .parser import DISTRIBUTED_TIMEOUT
from .robots import CliError

__all__ = [
    "is_writer",
    "join",
    "rendezvous",
    "solve_rows",
    "solved_chunks",
]

ENVIRONMENT = ("JAX_COORDINATOR_ADDRESS", "JAX_NUM_PROCESSES", "JAX_PROCESS_ID")
_GRACE = 15.0  # JAX's own timeout is this much later, so the watchdog's line comes first


def _environment_int(name: str) -> int | None:
    text = os.environ.get(name, "").strip()
    if not text:
        return None
    try:
        return int(text)
    except ValueError:
        raise CliError(f"--distributed: {name} must be an integer, got {text!r}") from None


def _host_port(address: str) -> tuple[str, int]:
    """``host:port`` or ``[v6]:port`` -> ``(host, port)``."""
    host, sep, port = address.strip().rpartition(":")
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not sep or not host or not 0 < number < 65536:
        raise CliError(f"--distributed: JAX_COORDINATOR_ADDRESS must be HOST:PORT, got {address!r}")
    return host.strip("[]"), number


def _listed(ids: Sequence[int]) -> str:
    return ("process " if len(ids) == 1 else "processes ") + ", ".join(map(str, ids))


def rendezvous(address: str, count: int, index: int, timeout: float) -> None:
    """Meet every process on the coordinator's port before JAX's runtime starts.

    Process 0 listens on the port of ``address`` and waits for the ids of processes ``1 ..
    count - 1``; each of them connects (retrying until the deadline) and sends its id. When all
    have come, process 0 answers ``go`` to each and closes the port for JAX's coordinator;
    otherwise it answers with the missing ids, so every process fails with the same names.

    Raises:
        CliError: one line: the processes that did not join within ``timeout`` seconds, the
            coordinator that did not answer, or an id outside ``[0, count)``.
    """
    if not 0 <= index < count:
        raise CliError(
            f"--distributed: JAX_PROCESS_ID={index} is not in 0..{count - 1} "
            f"(JAX_NUM_PROCESSES={count})"
        )
    if count == 1:
        return
    host, port = _host_port(address)
    deadline = time.monotonic() + timeout
    if index == 0:
        _coordinate(address, port, count, deadline, timeout)
    else:
        _report(address, host, port, index, deadline, timeout)


def _coordinate(address: str, port: int, count: int, deadline: float, timeout: float) -> None:
    try:
        server = socket.create_server(("", port), family=socket.AF_INET6, dualstack_ipv6=True)
    except (OSError, ValueError):
        try:
            server = socket.create_server(("", port))
        except OSError as exc:
            raise CliError(
                f"--distributed: process 0 cannot listen on port {port} of the coordinator "
                f"address {address} ({exc.strerror or exc})"
            ) from None
    peers: dict[int, socket.socket] = {}
    try:
        with server:
            while len(peers) < count - 1 and (left := deadline - time.monotonic()) > 0:
                server.settimeout(left)
                try:
                    conn, _ = server.accept()
                except TimeoutError:
                    break
                conn.settimeout(max(0.1, deadline - time.monotonic()))
                with contextlib.suppress(OSError, ValueError):
                    peer = int(_read_line(conn))
                    if 0 < peer < count and peer not in peers:
                        peers[peer] = conn
                        continue
                conn.close()
            missing = [i for i in range(1, count) if i not in peers]
            answer = "go" if not missing else "missing " + ",".join(map(str, missing))
            for conn in peers.values():
                with contextlib.suppress(OSError):
                    conn.sendall(answer.encode() + b"\n")
            for conn in peers.values():  # the peers close first: the port is free for JAX
                with contextlib.suppress(OSError):
                    conn.settimeout(5.0)
                    conn.recv(1)
    finally:
        for conn in peers.values():
            conn.close()
    if missing:
        raise CliError(
            f"--distributed: {_listed(missing)} did not join the coordinator at {address} "
            f"within {timeout:g} s ({count - len(missing)} of {count} processes joined)"
        )


def _report(address: str, host: str, port: int, index: int, deadline: float, timeout: float):
    conn = None
    while conn is None and deadline - time.monotonic() > 0:
        try:
            conn = socket.create_connection((host, port), timeout=1.0)
        except OSError:
            time.sleep(0.2)
    if conn is None:
        raise CliError(
            f"--distributed: process 0 (the coordinator at {address}) did not answer process "
            f"{index} within {timeout:g} s"
        )
    with conn:
        try:
            conn.sendall(f"{index}\n".encode())
            conn.settimeout(max(0.1, deadline - time.monotonic()) + 5.0)
            answer = _read_line(conn)
        except OSError:
            answer = ""
    if answer == "go":
        return
    if answer.startswith("missing "):
        missing = [int(i) for i in answer.split()[1].split(",")]
        raise CliError(
            f"--distributed: {_listed(missing)} did not join the coordinator at {address} "
            f"within {timeout:g} s"
        )
    raise CliError(
        f"--distributed: process 0 (the coordinator at {address}) did not let process {index} "
        f"join within {timeout:g} s (another process {index}?)"
    )


def _read_line(conn: socket.socket) -> str:
    data = b""
    while not data.endswith(b"\n") and len(data) < 64:
        chunk = conn.recv(64)
        if not chunk:
            break
        data += chunk
    return data.decode("ascii", "replace").strip()


@contextlib.contextmanager
def _watchdog(timeout: float, what: str) -> Iterator[None]:
    """End the process with one line and status 2 if the block outlasts ``timeout`` seconds
    (JAX's runtime cannot be interrupted from Python while it waits for its peers)."""

    def expire() -> None:
        print(f"jaxkin: error: --distributed: {what} within {timeout:g} s", file=sys.stderr)
        sys.stderr.flush()
        os._exit(2)

    timer = threading.Timer(timeout, expire)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


@contextlib.contextmanager
def _stdout_silenced() -> Iterator[None]:
    """File descriptor 1 to /dev/null: the CPU collectives print a line per process on
    connecting, which would land in ``-o -`` output."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def join(args: argparse.Namespace) -> None:
    """Join JAX's processes when ``--distributed`` was given (once; before any computation)."""
    if not getattr(args, "distributed", False) or jax.distributed.is_initialized():
        return
    timeout = float(getattr(args, "distributed_timeout", DISTRIBUTED_TIMEOUT))
    count = _environment_int("JAX_NUM_PROCESSES")
    index = _environment_int("JAX_PROCESS_ID")
    address = os.environ.get("JAX_COORDINATOR_ADDRESS", "").strip()
    if address and count is not None and index is not None:
        rendezvous(address, count, index, timeout)
    where = f"the coordinator at {address}" if address else "the cluster's coordinator"
    try:
        with _watchdog(timeout + _GRACE, f"the processes did not join {where}"):
            jax.distributed.initialize(
                num_processes=count,
                process_id=index,
                initialization_timeout=int(timeout + 2 * _GRACE),
            )
            with _stdout_silenced():  # the collectives connect on their first use
                _processes.allgather(np.zeros(1, np.uint8))
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


def solved_chunks(
    fn: Callable[..., Any], arrays: Sequence[np.ndarray], chunk: int, desc: str, quiet: bool
) -> Iterator[tuple[int, int, list[np.ndarray]]]:
    """``jaxkin.cli.files.solved_chunks`` (one process: a chunk at a time), or with several
    processes every row solved by ``solve_rows`` and then handed out in the same chunks."""
    if _processes.process_count() == 1:
        yield from files.solved_chunks(fn, arrays, chunk, desc, quiet)
        return
    outputs = solve_rows(files.solve_in_chunks, fn, arrays, chunk, desc, quiet)
    for start in range(0, len(arrays[0]), chunk):
        stop = min(start + chunk, len(arrays[0]))
        yield start, stop, [column[start:stop] for column in outputs]
