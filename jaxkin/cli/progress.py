"""The command line's progress bar on stderr, for file solves and workspace sweeps.

``bar(total, desc)`` returns an object with ``update(n)`` and ``close()`` (also a context
manager), the subset of ``tqdm``'s interface that the command uses. It is *active* only when
the stream (default ``sys.stderr``) is a terminal and ``enabled`` is not False, so logs, pipes,
CI and ``--quiet`` stay clean; ``enabled=True`` forces it on any stream. When active it is a
``tqdm`` bar (the ``cli`` extra: ``pip install 'jaxkin[cli]'``); where tqdm is not installed
the command draws its own one-line bar::

    workspace [###########.........]  55%  510k/928k  2.1 s

redrawn in place with a carriage return at most every ``min_interval`` seconds, and ended with
a newline by ``close()``. ``reporting(desc)`` gives a library call (``workspace.sweep``,
``optimize.optimize``) its ``progress(done, total)`` callback, drawn as such a bar.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from typing import IO, Any

__all__ = ["NullBar", "TextBar", "bar", "is_active", "reporting"]


class NullBar:
    """An inactive bar: every method does nothing."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> NullBar:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _human(n: float) -> str:
    for unit, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g}{unit}"
    return f"{n:.0f}"


class TextBar(NullBar):
    """A dependency-free bar drawn with ``#`` and ``.`` on one line of ``stream``."""

    def __init__(
        self,
        total: int,
        desc: str = "",
        stream: IO[str] | None = None,
        width: int = 24,
        min_interval: float = 0.1,
    ) -> None:
        self.total = max(int(total), 0)
        self.desc = desc
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.min_interval = min_interval
        self.count = 0
        self.start = time.perf_counter()
        self._last_draw = -float("inf")
        self._closed = False
        self._draw(force=True)

    def _draw(self, force: bool = False) -> None:
        now = time.perf_counter()
        if not force and now - self._last_draw < self.min_interval:
            return
        self._last_draw = now
        fraction = min(self.count / self.total, 1.0) if self.total else 1.0
        filled = int(round(fraction * self.width))
        line = (
            f"\r{self.desc} [{'#' * filled}{'.' * (self.width - filled)}] "
            f"{fraction * 100:3.0f}%  {_human(self.count)}/{_human(self.total)}  "
            f"{now - self.start:.1f} s"
        )
        self.stream.write(line)
        self.stream.flush()

    def update(self, n: int = 1) -> None:
        self.count += int(n)
        self._draw(force=self.count >= self.total)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._draw(force=True)
        self.stream.write("\n")
        self.stream.flush()


def is_active(enabled: bool | None = None, stream: IO[str] | None = None) -> bool:
    """Whether a bar would be shown: ``enabled`` True, or None and ``stream`` is a terminal."""
    if enabled is not None:
        return bool(enabled)
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty and isatty())
    except (OSError, ValueError):
        return False


def bar(
    total: int, desc: str = "", enabled: bool | None = None, stream: IO[str] | None = None
) -> Any:
    """A progress bar for ``total`` units of work (``tqdm`` if installed, else ``TextBar``).

    Args:
        total: the number of units ``update`` will count up to.
        desc: a short label shown before the bar.
        enabled: ``None`` (default): active only if ``stream`` is a terminal; ``False``: never
            (``--quiet``); ``True``: always.
        stream: where to draw, default ``sys.stderr``.
    """
    if not is_active(enabled, stream):
        return NullBar()
    stream = sys.stderr if stream is None else stream
    try:
        from tqdm import tqdm  # the cli extra
    except ImportError:
        return TextBar(total, desc, stream)
    return tqdm(total=total, desc=desc, file=stream, unit_scale=True, leave=True)


@contextlib.contextmanager
def reporting(
    desc: str, enabled: bool | None = None, stream: IO[str] | None = None
) -> Iterator[Callable[[int, int], None]]:
    """A library call's progress callback ``progress(done, total)`` drawn as a ``bar`` of
    ``total`` units (made at the first call, advanced to ``done`` at each), closed on exit."""
    meter: Any = None
    shown = 0

    def progress(done: int, total: int) -> None:
        nonlocal meter, shown
        if meter is None:
            meter = bar(total, desc, enabled, stream)
        meter.update(done - shown)
        shown = done

    try:
        yield progress
    finally:
        if meter is not None:
            meter.close()
