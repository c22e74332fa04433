"""The ``jaxkin`` command: solve trajectory files, sweep workspaces, run the demo.

Subcommands (``jaxkin SUBCOMMAND --help`` for every option; ``docs/cli.md`` for a tour)::

    jaxkin demo [NAME] [--list]             the main demo (a planner) or an example by name
    jaxkin ik ROBOT -i IN -o OUT [...]      joint trajectories from end-point trajectories
    jaxkin fk ROBOT -i IN -o OUT [...]      end-point trajectories from joint trajectories
    jaxkin plan ROBOT -i IN -o OUT [...]    rank candidate paths, write the best retimed
    jaxkin workspace ROBOT [...]            chunked voxel sweep, prints the reachable volume

``ROBOT`` is one of ``jaxkin.cli.robots.ROBOTS``; everything else about a robot (its branches,
joint and target columns, default workspace box) comes from the robot protocol.

Errors: bad input prints one line ``jaxkin: error: ...`` on stderr and exits with status 2,
never a traceback (``--traceback`` shows it). Rows with NaN/inf get status
``INVALID_INPUT`` and the rest is solved. Every output path is checked before any work
(``jaxkin.cli.files.check_outputs``): one naming an input file (``-i``, ``--robot``) or another
output is refused, as are read-only files and unwritable directories; a symlink writes its
target, a named pipe or ``/dev/null`` is written into. Regular files are written atomically:
a failed or interrupted run leaves an existing output file untouched. Ctrl-C exits with
status 130, SIGTERM with 143 and SIGHUP with 129, their temporary files removed; a closed
output pipe (``-o - | head``) ends quietly with status 141. ``--dtype float64`` (default)
turns on JAX's 64-bit mode in this process (an application's choice; the library itself
never changes JAX's configuration).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator, Sequence

__all__ = ["EXIT_BROKEN_PIPE", "EXIT_ERROR", "EXIT_INTERRUPTED", "Terminated", "main"]

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxkin`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--traceback" in argv
    try:
        with _terminated_as_exception():
            return _run(argv, debug)
    except Terminated as exc:
        print(
            f"jaxkin: terminated by signal {exc.signum} (existing output files are unchanged)",
            file=sys.stderr,
        )
        return 128 + exc.signum


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived: unwinds like Ctrl-C, so temporary files are removed."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _terminated_as_exception() -> Iterator[None]:
    """SIGTERM and SIGHUP raise ``Terminated`` in the main thread while the command runs (by
    default they end the process at once, leaving a half-written temporary file behind)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise Terminated(signum)

    names = ("SIGTERM", "SIGHUP")
    wanted = [getattr(signal, n) for n in names if hasattr(signal, n)]
    previous = {sig: signal.signal(sig, handler) for sig in wanted}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _run(argv: list[str], debug: bool) -> int:
    from .parser import build_parser
    from .robots import CliError

    try:
        args = build_parser().parse_args(argv)
        from .._execute.cache import enable_for_command  # after --help: JAX loads in ~1 s

        enable_for_command()  # the persistent compilation cache (docs/cli.md)
        from .._execute.latency import enable_for_command as low_latency

        low_latency()  # single queries run inline, small loops as one function (docs/cli.md)
        args.notes = []
        code = int(args.func(args) or 0)
        if not getattr(args, "quiet", False):
            for note in args.notes:
                print(note, file=sys.stderr)
        return code
    except BrokenPipeError:
        # The reader closed the pipe (``jaxkin ... -o - | head``): end quietly, with the usual
        # status of a process killed by SIGPIPE, and keep the interpreter's final flush quiet.
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        print("jaxkin: interrupted (existing output files are unchanged)", file=sys.stderr)
        return EXIT_INTERRUPTED
    except MemoryError:
        if debug:
            raise
        print(
            "jaxkin: error: out of memory: reduce the problem (a coarser --resolution, a "
            "smaller --chunk-size or a smaller file)",
            file=sys.stderr,
        )
        return EXIT_ERROR
    except Exception as exc:  # one line, never a traceback (unless --traceback)
        if debug:
            raise
        known = isinstance(exc, CliError | ValueError | OSError)
        text = " ".join(str(exc).split()) or type(exc).__name__
        prefix = "" if known else f"internal error ({type(exc).__name__}): "
        print(f"jaxkin: error: {prefix}{text}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
