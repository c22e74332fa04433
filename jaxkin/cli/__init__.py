"""The ``jaxkin`` command: solve trajectory files, sweep workspaces, run the demo.

Subcommands (``jaxkin SUBCOMMAND --help`` for every option; ``docs/cli.md`` for a tour)::

    jaxkin demo [NAME] [--list]             the main demo (a planner) or an example by name
    jaxkin ik ROBOT -i IN -o OUT [...]      joint trajectories from end-point trajectories
    jaxkin fk ROBOT -i IN -o OUT [...]      end-point trajectories from joint trajectories
    jaxkin workspace ROBOT [...]            chunked voxel sweep, prints the reachable volume

``ROBOT`` is one of ``jaxkin.cli.robots.ROBOTS``; everything else about a robot (its branches,
joint and target columns, default workspace box) comes from the robot protocol.

Errors: bad input prints one line ``jaxkin: error: ...`` on stderr and exits with status 2,
never a traceback (``--traceback`` shows it). Rows with NaN/inf get status
``INVALID_INPUT`` and the rest is solved. Outputs are written atomically: a failed or
interrupted run leaves an existing output file untouched, and an output that names the input
file (through any spelling or symlink) is refused before anything is written. Ctrl-C exits
with status 130; a closed output pipe (``-o - | head``) ends quietly with status 141.
``--dtype float64`` (default) turns on JAX's 64-bit mode in this process (an application's
choice; the library itself never changes JAX's configuration).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Sequence

from .._compile_cache import enable_for_command

__all__ = ["EXIT_BROKEN_PIPE", "EXIT_ERROR", "EXIT_INTERRUPTED", "main"]

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxkin`` console script; returns the exit status."""
    from .parser import build_parser
    from .robots import CliError

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--traceback" in argv
    enable_for_command()  # the persistent compilation cache (docs/cli.md)
    try:
        args = build_parser().parse_args(argv)
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
