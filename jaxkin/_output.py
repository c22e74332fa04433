"""Files the library writes: an output path checked before any work, then written atomically.

``output_target(path)`` says which file an output ``path`` writes, or raises ``InputError``
(a ``ValueError`` whose message is one line naming the file) when it cannot be written: a
symlink writes its target, a named pipe or character device is written into, and a read-only
file, a directory, a socket, a block device or an unwritable directory is refused.
``atomic_write(path)`` writes a temporary file in the target's directory and renames it over
the target (``os.replace``) only when complete, so an existing file is never truncated or
half-written by a failed or interrupted run. ``jaxkin.plot`` saves its figures through it;
the command line (``jaxkin.cli.files``) writes its tables and archives through it and
raises ``InputError`` for every problem with a file it reads.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

__all__ = ["InputError", "atomic_write", "given", "one_line", "output_target"]


class InputError(ValueError):
    """A file that cannot be used; the message is one line, naming the file (and line)."""


class _Given(type(Path())):  # type: ignore[misc]
    """A path that prints as the user spelled it (``./a.csv``, not ``a.csv``)."""

    _given: str | None = None

    def __str__(self) -> str:
        return self._given if self._given is not None else super().__str__()


def given(path: str | os.PathLike) -> Path:
    """``Path(path)`` that keeps the user's spelling for messages."""
    result = _Given(path)
    result._given = os.fspath(path)
    return result


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type's name when it has none)."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def _kind(mode: int) -> str:
    """What a ``stat`` mode names, for messages."""
    for test, name in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a named pipe"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def _streams_in_place(mode: int) -> bool:
    """Named pipes and character devices (``/dev/null``, a terminal) are written into."""
    return stat.S_ISFIFO(mode) or stat.S_ISCHR(mode)


def output_target(path: str | os.PathLike) -> Path:
    """The file an output ``path`` writes, after checking it can be written; before any work.

    A symlink is followed to its target (the link stays, its target gets the data). The
    target is a regular file, written atomically (``atomic_write``), or a named pipe or
    character device (``/dev/null``, a terminal), written into directly; anything else is
    refused, as is a read-only file (never replaced) and a directory where a temporary file
    cannot be created (checked by creating and removing one).

    Raises:
        InputError: naming ``path``: empty, a directory, a socket or block device, read-only,
            or its directory missing or not writable.
    """
    if not os.fspath(path):
        raise InputError("'': an empty name, expected an output file name")
    path = given(path)
    try:
        mode = os.stat(path).st_mode  # follows links, /dev/stdout's included
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({one_line(exc)})") from None
    if mode is not None and not stat.S_ISREG(mode):
        if _streams_in_place(mode):
            return path
        raise InputError(f"{path}: is {_kind(mode)}, expected an output file name")
    target = Path(os.path.realpath(path))
    if mode is not None and (not os.access(target, os.W_OK) or not mode & 0o222):
        raise InputError(f"{path}: is read-only; make it writable or choose another name")
    directory = target.parent
    if not directory.is_dir():
        raise InputError(f"{path}: cannot write: directory {directory} does not exist")
    try:  # the one reliable test of a writable directory (permissions, ACLs, read-only mounts)
        fd, probe = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(f"{path}: cannot write in {directory} ({one_line(exc)})") from None
    return target


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``'s target; on success rename it over the target.

    ``path`` is checked first (``output_target``: a symlink writes its target; a read-only
    file, a directory, a socket or a block device are refused). On any exception (including
    ``KeyboardInterrupt``, and SIGTERM under the command line) the temporary file is removed
    and the target is left exactly as it was. The new file gets the permissions of the file it
    replaces, or the usual ``0o666 & ~umask`` for a new file. A named pipe or a character
    device (``/dev/null``) is written into directly: there is nothing to replace.

    Raises:
        InputError: ``path`` cannot be written (``output_target``).
    """
    path = given(path)
    target = output_target(path)
    kwargs: dict[str, Any] = {"newline": "", "encoding": "utf-8"} if "b" not in mode else {}
    if target.exists() and _streams_in_place(os.stat(target).st_mode):
        with open(target, mode, **kwargs) as f:
            yield f
        return
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({one_line(exc)})") from None
    try:
        try:
            mode_bits = target.stat().st_mode & 0o777
        except OSError:
            umask = os.umask(0)
            os.umask(umask)
            mode_bits = 0o666 & ~umask
        os.chmod(tmp, mode_bits)
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
