"""A tiny progress bar on stderr for long sweeps and optimisations (no dependencies).

``bar(total, desc)`` returns an object with ``update(n)`` and ``close()`` (also a context
manager), the subset of ``tqdm``'s interface that jaxkin uses. It is *active* only when the
stream (default ``sys.stderr``) is a terminal and ``enabled`` is not False, so logs, pipes,
CI and ``--quiet`` stay clean; ``enabled=True`` forces it on any stream. When active it uses
``tqdm`` if that is importable (never a dependency) and otherwise draws its own one-line bar::

    workspace [###########.........]  55%  510k/928k  2.1 s

redrawn in place with a carriage return at most every ``min_interval`` seconds, and ended with
a newline by ``close()``.
"""

from __future__ import annotations

import sys
import time
from typing import IO, Any


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
    """A progress bar for ``total`` units of work (``tqdm`` if importable, else ``TextBar``).

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
        from tqdm import tqdm  # optional, never a dependency
    except ImportError:
        return TextBar(total, desc, stream)
    return tqdm(total=total, desc=desc, file=stream, unit_scale=True, leave=True)
