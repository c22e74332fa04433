"""Trajectory files of the ``jaxkin`` command: CSV and NPZ reading, rates, atomic writing.

Formats (one row per sample; the two formats hold the same columns):

* **CSV**: UTF-8 text, a header row naming the columns, then one row of numbers per sample,
  comma-separated (a header without commas but with ``;`` or tabs selects that delimiter).
  Blank lines and lines starting with ``#`` are skipped. ``nan``/``inf`` and empty cells are
  read as non-finite values (the row then gets status ``INVALID_INPUT``); any other
  non-numeric cell in a column that is used is an error naming its line and column. Columns
  that are not used (e.g. a ``status`` column of names) are not parsed.
* **NPZ**: a NumPy ``.npz`` archive with one 1-D array per column, all of one length
  (``numpy.savez(path, t=t, x=x, ...)``), read without pickle.

Trajectory columns (``read_trajectory``): ``t`` and the position columns are required (the
robot's target coordinates, e.g. ``x, y, z``, or its joint names such as
``theta1, theta2, l3``); ``candidate`` (integer label of independent trajectories, default one
trajectory) and the rate columns are optional. Rates come as whole sets: ``vx, vy, vz`` and
``ax, ay, az`` for Cartesian coordinates, ``<name>_dot`` and ``<name>_ddot`` otherwise. Rates a
file does not give are computed by a cubic spline in ``t`` per candidate (``complete_rates``).

Writing (``write_table``) is atomic: the file is written to a temporary file in the target's
directory and renamed over the target (``os.replace``) only when complete, so an existing
file is never truncated or half-written by a failed or interrupted run. Floats are written
in the shortest form that reads back to the same value (``repr``).

Every problem with a file raises ``InputError`` (a ``ValueError``) with a one-line message that
starts with the file name and, for CSV, the line number.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import math
import os
import sys
import tempfile
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import jax
import numpy as np

from .. import _batching, _splines, lie
from .._progress import bar

__all__ = [
    "CARTESIAN",
    "InputError",
    "Table",
    "Trajectory",
    "atomic_write",
    "check_output_path",
    "complete_rates",
    "continuous_quaternions",
    "quaternion_signs",
    "file_format",
    "rate_names",
    "read_table",
    "read_trajectory",
    "solve_in_chunks",
    "trajectory_columns",
    "write_csv",
    "write_table",
]

CARTESIAN = ("x", "y", "z")


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


def rate_names(names: Sequence[str]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Velocity and acceleration column names for position columns ``names``.

    Cartesian coordinates get a prefix (``("x", "y", "z")`` -> ``("vx", "vy", "vz"),
    ("ax", "ay", "az")``); any other names ``n`` get ``n_dot`` and ``n_ddot``.
    """
    names = tuple(names)
    if all(n in CARTESIAN for n in names):
        return tuple(f"v{n}" for n in names), tuple(f"a{n}" for n in names)
    return tuple(f"{n}_dot" for n in names), tuple(f"{n}_ddot" for n in names)


def file_format(path: str | os.PathLike) -> str:
    """``"npz"`` for a ``.npz`` suffix (any case), else ``"csv"``."""
    return "npz" if Path(path).suffix.lower() == ".npz" else "csv"


# ------------------------------------------------------------------------------------ reading


@dataclasses.dataclass
class Table:
    """Columns read from a file.

    Attributes:
        source: the file name, for messages.
        columns: every column name in the file, in file order.
        data: the requested columns as float64 arrays, shape ``(n_rows,)``.
        lines: the source line of each row (CSV, 1-based) or ``None`` (NPZ).
    """

    source: str
    columns: tuple[str, ...]
    data: dict[str, np.ndarray]
    lines: np.ndarray | None

    @property
    def n_rows(self) -> int:
        return len(next(iter(self.data.values()))) if self.data else 0

    def where(self, row: int) -> str:
        """``"FILE:LINE"`` (CSV) or ``"FILE, row ROW"`` (NPZ, 0-based) for messages."""
        if self.lines is not None:
            return f"{self.source}:{int(self.lines[row])}"
        return f"{self.source}, row {row}"


def read_table(path: str | os.PathLike, wanted: Sequence[str]) -> Table:
    """Read the columns ``wanted`` that are present in a CSV or NPZ file.

    Missing columns are simply absent from ``Table.data`` (the caller decides which are
    required, see ``require``).

    Raises:
        InputError: the file is missing or unreadable, or a used cell is not a number.
    """
    path = given(path)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, expected a CSV or .npz file")
    if file_format(path) == "npz":
        return _read_npz(path, wanted)
    return _read_csv(path, wanted)


def require(table: Table, names: Sequence[str], what: str = "column") -> None:
    """Raise ``InputError`` listing every name of ``names`` missing from ``table``."""
    missing = [n for n in names if n not in table.data]
    if missing:
        found = ", ".join(table.columns) if table.columns else "none"
        raise InputError(f"{table.source}: missing {what}(s) {', '.join(missing)} (found: {found})")


def _read_npz(path: Path, wanted: Sequence[str]) -> Table:
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise InputError(f"{path}: a single .npy array, expected a .npz archive of columns")
        with loaded as archive:
            columns = tuple(archive.files)
            arrays = {name: archive[name] for name in wanted if name in archive.files}
    except InputError:
        raise
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"{path}: not a readable .npz archive ({_one_line(exc)})") from None
    data: dict[str, np.ndarray] = {}
    length = None
    for name, arr in arrays.items():
        if arr.ndim != 1:
            raise InputError(f"{path}: array {name!r} has shape {arr.shape}, expected 1-D")
        if not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
            raise InputError(f"{path}: array {name!r} is not numeric (dtype {arr.dtype})")
        if length is not None and len(arr) != length:
            raise InputError(f"{path}: array {name!r} has {len(arr)} rows, others have {length}")
        length = len(arr)
        data[name] = arr.astype(np.float64)
    if length == 0:
        raise InputError(f"{path}: no data rows")
    return Table(str(path), columns, data, None)


def _rows(path: Path) -> Iterator[tuple[int, list[str]]]:
    """Non-blank, non-comment CSV rows with their line numbers."""
    try:
        with path.open("r", newline="", encoding="utf-8-sig") as f:
            first = f.readline()
            delimiter = ","
            if "," not in first:
                delimiter = ";" if ";" in first else "\t" if "\t" in first else ","
            f.seek(0)
            reader = csv.reader(f, delimiter=delimiter, strict=True)
            try:
                for row in reader:
                    if not row or all(not c.strip() for c in row):
                        continue
                    if row[0].lstrip().startswith("#"):
                        continue
                    yield reader.line_num, row
            except csv.Error as exc:
                raise InputError(f"{path}:{reader.line_num}: malformed CSV ({exc})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text CSV file (binary data?)") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({_one_line(exc)})") from None


def _read_csv(path: Path, wanted: Sequence[str]) -> Table:
    rows = _rows(path)
    header = next(rows, None)
    if header is None:
        raise InputError(f"{path}: empty file, expected a header row such as 't,x,y,z'")
    header_line, names = header
    names = [n.strip().lower() for n in names]
    if any(not n for n in names):
        raise InputError(f"{path}:{header_line}: empty column name in the header")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise InputError(f"{path}:{header_line}: duplicate column(s) {', '.join(duplicates)}")
    try:
        float(names[0])
    except ValueError:
        pass
    else:
        raise InputError(
            f"{path}:{header_line}: the first row must be a header naming the columns "
            f"(e.g. 't,x,y,z'), got numbers"
        )
    index = {n: i for i, n in enumerate(names)}
    used = [n for n in wanted if n in index]
    cells: dict[str, list[str]] = {n: [] for n in used}
    lines: list[int] = []
    for line, row in rows:
        if len(row) != len(names):
            raise InputError(
                f"{path}:{line}: expected {len(names)} fields ({','.join(names)}), got {len(row)}"
            )
        lines.append(line)
        for n in used:
            cells[n].append(row[index[n]].strip() or "nan")
    if not lines:
        raise InputError(f"{path}: no data rows after the header")
    line_numbers = np.asarray(lines)
    data = {n: _to_float(path, n, cells[n], line_numbers) for n in used}
    return Table(str(path), tuple(names), data, line_numbers)


def _to_float(path: Path, name: str, cells: list[str], lines: np.ndarray) -> np.ndarray:
    try:
        return np.array(cells, dtype=np.float64)
    except ValueError:
        pass
    out = np.empty(len(cells))
    for i, cell in enumerate(cells):
        try:
            out[i] = float(cell)
        except ValueError:
            raise InputError(
                f"{path}:{lines[i]}: column {name!r}: not a number: {cell[:40]!r}"
            ) from None
    return out


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


# ------------------------------------------------------------------------------- trajectories


@dataclasses.dataclass
class Trajectory:
    """Samples of one or more trajectories read from a file.

    Attributes:
        table: the underlying ``Table`` (source name, line numbers).
        names: the position column names, e.g. ``("x", "y", "z")``.
        t: times, ``(N,)``.
        candidate: integer labels ``(N,)``, or ``None`` when the file has no such column.
        p: positions, ``(N, k)``.
        v: velocities ``(N, k)``, or ``None`` when the file gives none.
        a: accelerations ``(N, k)``, or ``None`` when the file gives none.
    """

    table: Table
    names: tuple[str, ...]
    t: np.ndarray
    candidate: np.ndarray | None
    p: np.ndarray
    v: np.ndarray | None
    a: np.ndarray | None

    @property
    def valid(self) -> np.ndarray:
        """``(N,)`` True where every value of the row that is used is finite."""
        ok = np.isfinite(self.t) & np.all(np.isfinite(self.p), axis=-1)
        for rates in (self.v, self.a):
            if rates is not None:
                ok &= np.all(np.isfinite(rates), axis=-1)
        return ok


def read_trajectory(path: str | os.PathLike, names: Sequence[str] = CARTESIAN) -> Trajectory:
    """Read ``t``, positions ``names``, optional ``candidate`` and optional rate columns.

    Raises:
        InputError: file problems (``read_table``), missing ``t`` or position columns, a rate
            set given only in part, or a ``candidate`` that is not an integer.
    """
    names = tuple(names)
    velocity, acceleration = rate_names(names)
    table = read_table(path, ("t", "candidate", *names, *velocity, *acceleration))
    require(table, ("t", *names))
    rates = []
    for group, label in ((velocity, "velocity"), (acceleration, "acceleration")):
        present = [n for n in group if n in table.data]
        if present and len(present) != len(group):
            missing = [n for n in group if n not in table.data]
            raise InputError(
                f"{table.source}: {label} columns come as a set: {', '.join(present)} given "
                f"but {', '.join(missing)} missing"
            )
        rates.append(np.stack([table.data[n] for n in group], -1) if present else None)
    candidate = None
    if "candidate" in table.data:
        raw = table.data["candidate"]
        bad = np.flatnonzero(~np.isfinite(raw) | (raw != np.round(raw)) | (np.abs(raw) > 2**53))
        if bad.size:
            raise InputError(
                f"{table.where(bad[0])}: column 'candidate' must hold integers, got {raw[bad[0]]!r}"
            )
        candidate = raw.astype(np.int64)
    p = np.stack([table.data[n] for n in names], axis=-1)
    return Trajectory(table, names, table.data["t"], candidate, p, rates[0], rates[1])


def trajectory_columns(
    t: np.ndarray,
    candidate: np.ndarray | None,
    names: Sequence[str],
    p: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    status_names: np.ndarray | None = None,
    extra: Mapping[str, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """Ordered output columns: ``t``, ``candidate``, positions, velocities, accelerations,
    ``status`` (names, e.g. ``"OK"``) and any ``extra`` columns (e.g. ``margin``)."""
    velocity, acceleration = rate_names(names)
    columns: dict[str, np.ndarray] = {"t": np.asarray(t)}
    if candidate is not None:
        columns["candidate"] = np.asarray(candidate)
    for block, labels in ((p, names), (v, velocity), (a, acceleration)):
        block = np.asarray(block)
        for j, label in enumerate(labels):
            columns[label] = block[:, j]
    if status_names is not None:
        columns["status"] = np.asarray(status_names).astype(str)
    for key, value in (extra or {}).items():
        columns[key] = np.asarray(value)
    return columns


# ------------------------------------------------------------------------------------ writing


def check_output_path(path: str | Path) -> Path:
    """The directory an output file ``path`` would be written in, after checking it exists.

    Raises:
        InputError: ``path`` is a directory, or its directory does not exist.
    """
    path = given(path)
    directory = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, expected an output file name")
    if not directory.is_dir():
        raise InputError(f"{path}: cannot write: directory {directory} does not exist")
    return directory


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success rename it over ``path``.

    On any exception (including ``KeyboardInterrupt``) the temporary file is removed and
    ``path`` is left exactly as it was. The new file gets the permissions of the file it
    replaces, or the usual ``0o666 & ~umask`` for a new file.

    Raises:
        InputError: the directory does not exist or ``path`` is a directory.
    """
    path = given(path)
    directory = check_output_path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({_one_line(exc)})") from None
    try:
        try:
            mode_bits = path.stat().st_mode & 0o777
        except OSError:
            umask = os.umask(0)
            os.umask(umask)
            mode_bits = 0o666 & ~umask
        os.chmod(tmp, mode_bits)
        kwargs = {"newline": "", "encoding": "utf-8"} if "b" not in mode else {}
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _format_column(values: np.ndarray) -> list[str]:
    values = np.asarray(values)
    if values.dtype.kind == "f":
        # An empty cell where there is no value (a row whose status explains it), never "nan".
        return [repr(x) if not math.isnan(x) else "" for x in values.astype(np.float64).tolist()]
    if values.dtype.kind == "b":
        return ["1" if x else "0" for x in values.tolist()]
    return [str(x) for x in values.tolist()]


def write_csv(f: IO[str], columns: Mapping[str, np.ndarray]) -> None:
    """Write ``columns`` (name -> 1-D array, all one length) as CSV with a header row."""
    writer = csv.writer(f, lineterminator="\n")
    writer.writerow(list(columns))
    formatted = [_format_column(values) for values in columns.values()]
    writer.writerows(zip(*formatted, strict=True))


def write_table(path: str | os.PathLike, columns: Mapping[str, np.ndarray]) -> None:
    """Write columns to ``path`` (CSV, or NPZ for a ``.npz`` suffix) atomically.

    ``path == "-"`` writes CSV to standard output.
    """
    lengths = {len(np.asarray(v)) for v in columns.values()}
    if len(lengths) > 1:
        raise ValueError(f"columns of different lengths: {sorted(lengths)}")
    if str(path) == "-":
        write_csv(sys.stdout, columns)
        return
    if file_format(path) == "npz":
        with atomic_write(path, "wb") as f:
            np.savez(f, **{k: np.asarray(v) for k, v in columns.items()})
    else:
        with atomic_write(path, "w") as f:
            write_csv(f, columns)


# ------------------------------------------------------------------------------------ solving


def complete_rates(traj: Trajectory, end: str) -> tuple[np.ndarray, ...]:
    """Positions, velocities, accelerations (``(N, k)``) and the valid-row mask ``(N,)``.

    Rates missing from the file come from a cubic spline in ``t`` over the valid rows of each
    candidate (``end``: ``"not-a-knot"`` or ``"natural"``); invalid rows (NaN/inf) get NaN
    rates, hence status ``INVALID_INPUT``.

    Raises:
        InputError: ``t`` not strictly increasing within a candidate when rates are needed.
    """
    valid = traj.valid
    if traj.v is not None and traj.a is not None:
        return traj.p, traj.v, traj.a, valid
    group = traj.candidate if traj.candidate is not None else np.zeros(len(traj.t), np.int64)
    for label in np.unique(group[valid]):
        rows = np.flatnonzero(valid & (group == label))
        bad = np.flatnonzero(np.diff(traj.t[rows]) <= 0)
        if bad.size:
            row = rows[bad[0] + 1]
            name = f"candidate {label}: " if traj.candidate is not None else ""
            raise InputError(
                f"{traj.table.where(row)}: {name}t must increase strictly to compute rates "
                f"(t = {traj.t[row]:g} after {traj.t[rows[bad[0]]]:g}); or give the rate columns"
            )
    v, a = _splines.by_group(traj.t, traj.p, group, end=end, valid=valid)
    return traj.p, traj.v if traj.v is not None else v, traj.a if traj.a is not None else a, valid


def quaternion_signs(
    t: np.ndarray, candidate: np.ndarray | None, valid: np.ndarray, quat: np.ndarray
) -> np.ndarray:
    """``(N,)`` signs (+-1) that make quaternions ``(N, 4)`` continuous along each candidate
    in time (``q`` and ``-q`` are one rotation); the first valid row of each keeps its own."""
    group = candidate if candidate is not None else np.zeros(len(t), np.int64)
    sign = np.ones(len(t))
    for label in np.unique(group[valid]):
        rows = np.flatnonzero(valid & (group == label))
        rows = rows[np.argsort(t[rows], kind="stable")]
        sign[rows] = lie.hemisphere_signs(quat[rows], xp=np)
    return sign


def continuous_quaternions(traj: Trajectory) -> Trajectory:
    """A pose trajectory (columns ``x, y, z, qw, qx, qy, qz``) with the quaternions' signs made
    continuous along each candidate (``quaternion_signs``: splining needs one sign), rates
    flipped with them."""
    sign = quaternion_signs(traj.t, traj.candidate, traj.valid, traj.p[:, 3:7])
    flip = np.concatenate([np.ones((len(sign), 3)), np.repeat(sign[:, None], 4, axis=1)], 1)
    return dataclasses.replace(
        traj,
        p=traj.p * flip,
        v=None if traj.v is None else traj.v * flip,
        a=None if traj.a is None else traj.a * flip,
    )


def solve_in_chunks(
    fn: Callable[..., Any],
    arrays: Sequence[np.ndarray],
    chunk: int,
    desc: str,
    quiet: bool,
) -> list[np.ndarray]:
    """Apply ``fn`` to row chunks of ``arrays`` and concatenate its outputs (a pytree of
    arrays, flattened to host arrays). Every chunk has one shape
    (``jaxkin._batching.host_chunks``), so ``fn`` compiles once per file."""
    n = len(arrays[0])
    parts: list[list[np.ndarray]] = []
    with bar(n, desc, enabled=False if quiet else None) as meter:
        for start, stop, index in _batching.host_chunks(n, chunk):
            out = fn(*(x[index] for x in arrays))
            parts.append([np.asarray(x)[: stop - start] for x in jax.tree.leaves(out)])
            meter.update(stop - start)
    return [np.concatenate(column) for column in zip(*parts, strict=True)]
