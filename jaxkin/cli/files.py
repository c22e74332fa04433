"""The command line's trajectory files: CSV and NPZ, rates, safe writing.

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

Writing (``write_table``, or ``table_writer`` part by part) is atomic (``atomic_write`` of
``jaxkin._output``): the file is written to a temporary file in the target's directory and
renamed over the target (``os.replace``) only when complete, so an existing file is never
truncated or half-written by a failed or interrupted run. Output paths are checked first
(``output_target``, ``check_outputs``): a symlink writes its target, a named pipe or
character device is written into, and a read-only file, a directory, a socket, a block
device or an unwritable directory is refused.
Floats are written in the shortest form that reads back to the same value (``repr``). CSV is
read in blocks of ``READ_BLOCK`` rows and written part by part, so the text of a file is
never held whole.

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
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import jax
import numpy as np

from .. import _batching, _splines, _validate, lie
from .._output import InputError, atomic_write, given, one_line, output_target
from .progress import bar

__all__ = [
    "CARTESIAN",
    "InputError",
    "Table",
    "Trajectory",
    "atomic_write",
    "check_output_path",
    "check_times",
    "check_outputs",
    "complete_rates",
    "continuous_quaternions",
    "QuaternionSigns",
    "quaternion_signs",
    "file_format",
    "output_target",
    "rate_names",
    "read_table",
    "read_trajectory",
    "same_file",
    "solve_in_chunks",
    "solved_chunks",
    "table_writer",
    "trajectory_columns",
    "trajectory_parts",
    "completed_parts",
    "NotContiguous",
    "write_csv",
    "write_table",
]

CARTESIAN = ("x", "y", "z")
READ_BLOCK = 1 << 16  # CSV rows parsed as text before they become floats


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
        raise InputError(f"{path}: not a readable .npz archive ({one_line(exc)})") from None
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
            first = ""
            for line in f:  # the header: the first line that is neither blank nor a comment
                if line.strip() and not line.lstrip().startswith("#"):
                    first = line
                    break
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
        raise InputError(f"{path}: cannot read ({one_line(exc)})") from None


def _read_csv(path: Path, wanted: Sequence[str]) -> Table:
    parts = list(_csv_parts(path, wanted))
    data = {n: np.concatenate([part.data[n] for part in parts]) for n in parts[0].data}
    lines = np.concatenate([part.lines for part in parts])
    return Table(parts[0].source, parts[0].columns, data, lines)


def _csv_parts(path: Path, wanted: Sequence[str], block: int | None = None) -> Iterator[Table]:
    """The columns ``wanted`` of a CSV file, ``block`` rows (default ``READ_BLOCK``) at a
    time, each part a ``Table`` with its own line numbers; at least one part."""
    block = READ_BLOCK if block is None else block
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
    produced = False

    def convert() -> Table:  # the block's text cells to floats: memory by the block, not file
        numbers = np.asarray(lines, dtype=np.int64)
        data = {n: _to_float(path, n, cells[n], numbers) for n in used}
        for n in used:
            cells[n].clear()
        lines.clear()
        return Table(str(path), tuple(names), data, numbers)

    for line, row in rows:
        if len(row) != len(names):
            raise InputError(
                f"{path}:{line}: expected {len(names)} fields ({','.join(names)}), got {len(row)}"
            )
        lines.append(line)
        for n in used:
            cells[n].append(row[index[n]].strip() or "nan")
        if len(lines) == block:
            produced = True
            yield convert()
    if lines:
        produced = True
        yield convert()
    if not produced:
        raise InputError(f"{path}: no data rows after the header")


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


# ------------------------------------------------------------------------------- trajectories


@dataclasses.dataclass
class Trajectory:
    """Samples of one or more trajectories read from a file.

    Attributes:
        table: the underlying ``Table`` for messages (source name, line numbers; its
            columns, now in the fields below, are not kept).
        names: the position column names, e.g. ``("x", "y", "z")``.
        t: times, ``(N,)``, or ``None`` when the file has no ``t`` column (rows that are
            not samples of a trajectory: independent, at rest unless the file gives rates).
        candidate: integer labels ``(N,)``, or ``None`` when the file has no such column.
        p: positions, ``(N, k)``.
        v: velocities ``(N, k)``, or ``None`` when the file gives none.
        a: accelerations ``(N, k)``, or ``None`` when the file gives none.
    """

    table: Table
    names: tuple[str, ...]
    t: np.ndarray | None
    candidate: np.ndarray | None
    p: np.ndarray
    v: np.ndarray | None
    a: np.ndarray | None

    @property
    def valid(self) -> np.ndarray:
        """``(N,)`` True where every value of the row that is used is finite."""
        ok = np.all(np.isfinite(self.p), axis=-1)
        if self.t is not None:
            ok &= np.isfinite(self.t)
        for rates in (self.v, self.a):
            if rates is not None:
                ok &= np.all(np.isfinite(rates), axis=-1)
        return ok


def read_trajectory(
    path: str | os.PathLike, names: Sequence[str] = CARTESIAN, timed: bool = True
) -> Trajectory:
    """Read ``t``, positions ``names``, optional ``candidate`` and optional rate columns.

    ``t`` is required when ``timed`` (the default); otherwise a file without it gives
    ``Trajectory.t = None`` (independent rows).

    Raises:
        InputError: file problems (``read_table``), missing ``t`` or position columns, a rate
            set given only in part, or a ``candidate`` that is not an integer.
    """
    names = tuple(names)
    velocity, acceleration = rate_names(names)
    table = read_table(path, ("t", "candidate", *names, *velocity, *acceleration))
    return _trajectory_of(table, names, timed)


def trajectory_parts(
    path: str | os.PathLike,
    names: Sequence[str] = CARTESIAN,
    timed: bool = True,
    block: int | None = None,
) -> Iterator[Trajectory]:
    """``read_trajectory`` a block of rows at a time (``block``, default ``READ_BLOCK``): a
    CSV file is parsed as it is read; an NPZ archive is one part. The same errors, raised
    when the part that has them is read."""
    names = tuple(names)
    velocity, acceleration = rate_names(names)
    wanted = ("t", "candidate", *names, *velocity, *acceleration)
    path = given(path)
    if file_format(path) == "npz" or not path.exists() or path.is_dir():
        yield read_trajectory(path, names, timed)
        return
    for table in _csv_parts(path, wanted, block):
        yield _trajectory_of(table, names, timed)


def _trajectory_of(table: Table, names: tuple[str, ...], timed: bool) -> Trajectory:
    velocity, acceleration = rate_names(names)
    require(table, ("t", *names) if timed or "t" in table.data else names)
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
    t = table.data.get("t")
    table = dataclasses.replace(table, data={})  # the columns live on in t, p and the rates
    return Trajectory(table, names, t, candidate, p, rates[0], rates[1])


def trajectory_columns(
    t: np.ndarray | None,
    candidate: np.ndarray | None,
    names: Sequence[str],
    p: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    status_names: np.ndarray | None = None,
    extra: Mapping[str, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """Ordered output columns: ``t``, ``candidate``, positions, velocities, accelerations,
    ``status`` (names, e.g. ``"OK"``) and any ``extra`` columns (e.g. ``margin``); no ``t``
    column when ``t`` is None."""
    velocity, acceleration = rate_names(names)
    columns: dict[str, np.ndarray] = {} if t is None else {"t": np.asarray(t)}
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


def check_output_path(path: str | os.PathLike) -> Path:
    """The directory an output file ``path`` would be written in (``output_target``)."""
    return output_target(path).parent


def same_file(first: str | os.PathLike, second: str | os.PathLike) -> bool:
    """True when two spellings name one file (symlinks, ``./``, ``..``, hard links)."""
    try:
        if os.path.exists(first) and os.path.exists(second):
            return os.path.samefile(first, second)
        return os.path.realpath(first) == os.path.realpath(second)
    except OSError:
        return False


def check_outputs(outputs: Mapping[str, Any], inputs: Mapping[str, Any]) -> dict[str, Path]:
    """Check every output path against every input and every other output, before any work.

    Args:
        outputs: option -> output path (``None`` and ``"-"``, standard output, skipped).
        inputs: option -> input path (``None`` skipped; names that are not files are fine).

    Returns:
        option -> the file each output writes (``output_target``).

    Raises:
        InputError: an output names an input file or another output (through any spelling,
            symlink or hard link), or cannot be written (``output_target``); the message names
            both options.
    """
    targets: dict[str, Path] = {}
    for option, path in outputs.items():
        if path is None or os.fspath(path) == "-":
            continue
        for other, source in inputs.items():
            if source is not None and same_file(source, path):
                raise InputError(
                    f"{option} {path} is the input file {source} ({other}): it would be "
                    "overwritten; choose another name"
                )
        for other, done in targets.items():
            if same_file(done, path) or done == Path(os.path.realpath(path)):
                raise InputError(f"{option} {path} is also {other}: choose two names")
        try:
            targets[option] = output_target(path)
        except InputError as exc:
            raise InputError(f"{option} {exc}") from None
    return targets


def _format_column(values: np.ndarray) -> list[str]:
    values = np.asarray(values)
    if values.dtype.kind == "f":
        # An empty cell where there is no value (a row whose status explains it), never "nan".
        return [repr(x) if not math.isnan(x) else "" for x in values.astype(np.float64).tolist()]
    if values.dtype.kind == "b":
        return ["1" if x else "0" for x in values.tolist()]
    return [str(x) for x in values.tolist()]


def write_csv(f: IO[str], columns: Mapping[str, np.ndarray], header: bool = True) -> None:
    """Write ``columns`` (name -> 1-D array, all one length) as CSV rows, after a header row
    naming them unless ``header`` is False (a later part of one table)."""
    writer = csv.writer(f, lineterminator="\n")
    if header:
        writer.writerow(list(columns))
    formatted = [_format_column(values) for values in columns.values()]
    writer.writerows(zip(*formatted, strict=True))


def _checked_lengths(columns: Mapping[str, np.ndarray]) -> None:
    lengths = {len(np.asarray(v)) for v in columns.values()}
    if len(lengths) > 1:
        raise ValueError(f"columns of different lengths: {sorted(lengths)}")


@contextlib.contextmanager
def table_writer(
    path: str | os.PathLike | None,
) -> Iterator[Callable[[Mapping[str, np.ndarray]], None]]:
    """Write one table in parts: yields ``write(columns)``, which appends rows (the same
    column names every call).

    CSV goes out part by part (to a temporary file renamed at the end, ``atomic_write``, or to
    standard output for ``path == "-"``), so memory is bounded by a part, not the table; NPZ
    holds the parts until the end (an archive is written whole). ``path=None`` writes nothing
    (a process that does not write). On an exception nothing replaces an existing file.
    """
    if path is None:
        yield lambda columns: None
        return
    first = [True]

    def csv_part(f: IO[str]) -> Callable[[Mapping[str, np.ndarray]], None]:
        def write(columns: Mapping[str, np.ndarray]) -> None:
            _checked_lengths(columns)
            write_csv(f, columns, header=first[0])
            first[0] = False

        return write

    if str(path) == "-":
        yield csv_part(sys.stdout)
        return
    if file_format(path) == "npz":
        parts: dict[str, list[np.ndarray]] = {}

        def keep(columns: Mapping[str, np.ndarray]) -> None:
            _checked_lengths(columns)
            for key, value in columns.items():
                parts.setdefault(key, []).append(np.asarray(value))

        output_target(path)  # fail before the work, as the CSV writer does
        yield keep
        with atomic_write(path, "wb") as f:
            columns: dict[str, Any] = {k: np.concatenate(v) for k, v in parts.items()}
            np.savez(f, **columns)
        return
    with atomic_write(path, "w") as f:
        yield csv_part(f)


def write_table(path: str | os.PathLike, columns: Mapping[str, np.ndarray]) -> None:
    """Write columns to ``path`` (CSV, or NPZ for a ``.npz`` suffix) atomically.

    ``path == "-"`` writes CSV to standard output.
    """
    _checked_lengths(columns)
    with table_writer(path) as write:
        write(columns)


# ------------------------------------------------------------------------------------ solving


def complete_rates(traj: Trajectory, end: str) -> tuple[np.ndarray, ...]:
    """Positions, velocities, accelerations (``(N, k)``) and the valid-row mask ``(N,)``.

    Rates missing from the file come from a cubic spline in ``t`` over the valid rows of each
    candidate (``end``: ``"not-a-knot"`` or ``"natural"``; zero for a file without ``t``);
    invalid rows (NaN/inf) get NaN rates, hence status ``INVALID_INPUT``.

    Raises:
        InputError: ``t`` not strictly increasing within a candidate when rates are needed.
    """
    valid = traj.valid
    if traj.v is not None and traj.a is not None:
        return traj.p, traj.v, traj.a, valid
    if traj.t is None:  # rows, not samples: at rest unless the file gives their rates
        zero = np.zeros_like(traj.p)
        return traj.p, zero if traj.v is None else traj.v, zero if traj.a is None else traj.a, valid
    check_times(traj, valid, "to compute rates", "; or give the rate columns")
    group = traj.candidate if traj.candidate is not None else np.zeros(len(traj.t), np.int64)
    v, a = _splines.by_group(traj.t, traj.p, group, end=end, valid=valid)
    return traj.p, traj.v if traj.v is not None else v, traj.a if traj.a is not None else a, valid


def check_times(traj: Trajectory, valid: np.ndarray, why: str, hint: str = "") -> None:
    """Raise ``InputError`` at the first valid row of a candidate whose ``t`` does not
    increase strictly over the previous valid row of that candidate (``why``: what needs it)."""
    t = traj.t
    if t is None:  # rows at rest, no times
        return
    group = traj.candidate if traj.candidate is not None else np.zeros(len(t), np.int64)
    for label in np.unique(group[valid]):
        rows = np.flatnonzero(valid & (group == label))
        bad = np.flatnonzero(np.diff(t[rows]) <= 0)
        if bad.size:
            row = rows[bad[0] + 1]
            name = f"candidate {label}: " if traj.candidate is not None else ""
            raise InputError(
                f"{traj.table.where(row)}: {name}t must increase strictly {why} "
                f"(t = {t[row]:g} after {t[rows[bad[0]]]:g}){hint}"
            )


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
    """A pose trajectory (columns ``x, y, z, qw, qx, qy, qz``) with unit quaternions whose
    signs are continuous along each candidate.

    Each row's quaternion is scaled to unit length (``jaxkin._validate.unit_quaternions``:
    any length, ``q`` and ``c q`` being one rotation) and its given rates with it (at one
    instant, the rates of ``q / c`` are those of ``q`` divided by ``c``), so rows whose
    quaternions differ only in length give one rotation and splined rates are those of the
    unit quaternions, as in ``jaxkin.paths``. A zero quaternion becomes NaN: that row gets
    status ``INVALID_INPUT`` and is left out of the splines of the others. Signs then follow
    ``quaternion_signs`` (splining needs one hemisphere), rates flipped with them.
    """
    unit, length, _ = _validate.unit_quaternions(traj.p[:, 3:7])
    p = np.concatenate([traj.p[:, :3], unit], -1)
    scale = np.concatenate([np.ones((len(length), 3)), np.repeat(length[:, None], 4, 1)], 1)
    with np.errstate(invalid="ignore"):
        v, a = (None if r is None else r / scale for r in (traj.v, traj.a))
    traj = dataclasses.replace(traj, p=p, v=v, a=a)
    t = np.arange(len(unit), dtype=float) if traj.t is None else traj.t  # else: file order
    sign = quaternion_signs(t, traj.candidate, traj.valid, unit)
    flip = np.concatenate([np.ones((len(sign), 3)), np.repeat(sign[:, None], 4, axis=1)], 1)
    return dataclasses.replace(
        traj,
        p=traj.p * flip,
        v=None if traj.v is None else traj.v * flip,
        a=None if traj.a is None else traj.a * flip,
    )


def solved_chunks(
    fn: Callable[..., Any],
    arrays: Sequence[np.ndarray],
    chunk: int,
    desc: str,
    quiet: bool,
) -> Iterator[tuple[int, int, list[np.ndarray]]]:
    """``(start, stop, outputs)``: ``fn`` applied to row chunks of ``arrays``, its outputs (a
    pytree of arrays) flattened to host arrays of rows ``start:stop``, one chunk at a time.
    Every call has one shape (``jaxkin._batching.host_chunks``), so ``fn`` compiles once per
    file."""
    n = len(arrays[0])
    with bar(n, desc, enabled=False if quiet else None) as meter:
        for start, stop, index in _batching.host_chunks(n, chunk):
            out = fn(*(x[index] for x in arrays))
            yield start, stop, [np.array(x[: stop - start]) for x in jax.tree.leaves(out)]
            meter.update(stop - start)


def solve_in_chunks(
    fn: Callable[..., Any],
    arrays: Sequence[np.ndarray],
    chunk: int,
    desc: str,
    quiet: bool,
) -> list[np.ndarray]:
    """Every chunk of ``solved_chunks`` joined: ``fn``'s outputs for all rows."""
    parts = [outputs for _, _, outputs in solved_chunks(fn, arrays, chunk, desc, quiet)]
    return [np.concatenate(column) for column in zip(*parts, strict=True)]


class QuaternionSigns:
    """Signs (+-1) that keep quaternions continuous along each candidate across the chunks
    of a file, in file order (time order when the rates were splined: ``t`` then increases):
    the last signed quaternion of each candidate is carried to the next chunk."""

    def __init__(self) -> None:
        self.last: dict[int, np.ndarray] = {}

    def __call__(
        self, candidate: np.ndarray | None, valid: np.ndarray, quat: np.ndarray
    ) -> np.ndarray:
        """``(n,)`` signs for one chunk's quaternions ``(n, 4)``."""
        group = candidate if candidate is not None else np.zeros(len(quat), np.int64)
        sign = np.ones(len(quat))
        for label in np.unique(group[valid]).tolist():
            rows = np.flatnonzero(valid & (group == label))
            previous = self.last.get(label)
            q = quat[rows] if previous is None else np.concatenate([previous[None], quat[rows]])
            signs = lie.hemisphere_signs(q, xp=np)[0 if previous is None else 1 :]
            sign[rows] = signs
            self.last[label] = quat[rows[-1]] * signs[-1]
        return sign


# ------------------------------------------------------------------------------- streaming
SPLINE_CONTEXT = 64  # rows on each side of a streamed part that its splines see


class NotContiguous(Exception):
    """A candidate's rows are not one block of the file: it cannot be streamed."""


def _joined(parts: Sequence[Trajectory | None]) -> Trajectory:
    """Consecutive parts of one file as one ``Trajectory`` (None parts left out)."""
    given = [part for part in parts if part is not None]
    if len(given) == 1:
        return given[0]
    first = given[0]

    def cat(name: str) -> np.ndarray | None:
        values = [getattr(part, name) for part in given]
        return None if values[0] is None else np.concatenate(values)

    lines = None if first.table.lines is None else np.concatenate([x.table.lines for x in given])
    table = dataclasses.replace(first.table, lines=lines)
    p = np.concatenate([part.p for part in given])
    return Trajectory(table, first.names, cat("t"), cat("candidate"), p, cat("v"), cat("a"))


def _rows_of(traj: Trajectory, rows: slice) -> Trajectory:
    def cut(x: np.ndarray | None) -> np.ndarray | None:
        return None if x is None else x[rows]

    lines = cut(traj.table.lines)
    return Trajectory(
        dataclasses.replace(traj.table, lines=lines),
        traj.names,
        cut(traj.t),
        cut(traj.candidate),
        traj.p[rows],
        cut(traj.v),
        cut(traj.a),
    )


def _length(traj: Trajectory | None) -> int:
    return 0 if traj is None else len(traj.p)


class _Carried:
    """What one part passes to the next: each candidate's last valid time and signed
    quaternion, the candidates already finished (a label coming back is not contiguous)."""

    def __init__(self, why: str, hint: str, quaternions: bool, times: bool) -> None:
        self.why, self.hint, self.quaternions, self.times = why, hint, quaternions, times
        self.last_t: dict[int, tuple[float, str]] = {}
        self.signs = QuaternionSigns()
        self.finished: set[int] = set()
        self.current: int | None = None

    def __call__(self, part: Trajectory) -> Trajectory:
        group = part.candidate if part.candidate is not None else np.zeros(len(part.p), np.int64)
        runs = np.r_[0, np.flatnonzero(np.diff(group)) + 1]
        for label in group[runs].tolist():
            if label != self.current:
                if label in self.finished:
                    raise NotContiguous(label)
                if self.current is not None:
                    self.finished.add(self.current)
                self.current = label
        if self.quaternions:
            part = continuous_quaternions(part)
            valid = part.valid
            sign = self.signs(part.candidate, valid, part.p[:, 3:7])  # carried across parts
            flip = np.concatenate([np.ones((len(sign), 3)), np.repeat(sign[:, None], 4, 1)], 1)
            part = dataclasses.replace(
                part,
                p=part.p * flip,
                v=None if part.v is None else part.v * flip,
                a=None if part.a is None else part.a * flip,
            )
        if self.times and part.t is not None:
            valid = part.valid
            for label in np.unique(group[valid]).tolist():
                rows = np.flatnonzero(valid & (group == label))
                t = part.t[rows]
                previous = self.last_t.get(label)
                if previous is not None and t[0] <= previous[0]:
                    self._refuse(part, rows[0], label, t[0], previous[0])
                bad = np.flatnonzero(np.diff(t) <= 0)
                if bad.size:
                    self._refuse(part, rows[bad[0] + 1], label, t[bad[0] + 1], t[bad[0]])
                self.last_t[label] = (float(t[-1]), "")
        return part

    def _refuse(self, part: Trajectory, row: int, label: int, t: float, before: float) -> None:
        name = f"candidate {label}: " if part.candidate is not None else ""
        raise InputError(
            f"{part.table.where(row)}: {name}t must increase strictly {self.why} "
            f"(t = {t:g} after {before:g}){self.hint}"
        )


def completed_parts(
    parts: Iterator[Trajectory],
    end: str,
    size: int,
    quaternions: bool = False,
    whole: bool = False,
    why: str = "to compute rates",
    hint: str = "; or give the rate columns",
    ordered: bool = False,
) -> Iterator[tuple[Trajectory, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """``complete_rates`` of a file read in parts (``trajectory_parts``), a part of about
    ``size`` rows at a time, in file order: ``(part, p, v, a, valid)``.

    Memory is bounded by a part, not by the file: a part's splines see ``SPLINE_CONTEXT``
    rows on each side of it, which gives the rates of the spline through the whole candidate
    to rounding (a cubic spline's dependence on a sample decays by at least 2 per knot,
    ``2 - sqrt(3)`` for even spacing, so 64 knots away it is below ``2**-64``). With
    ``whole`` a part ends at a candidate's end (a candidate longer than ``size`` is one
    part). ``quaternions``: pose rows (``continuous_quaternions``, signs carried from part to
    part). Times must increase strictly along each candidate (``why``, ``hint`` for the
    message) when rates are splined, ``whole`` or ``ordered`` (parts of paths that may end
    within a candidate: ``cli.planning.PathSolver`` carries a path from part to part).

    Raises:
        NotContiguous: a candidate's rows are split by another's (read the file whole).
        InputError: as ``read_trajectory`` and ``complete_rates``.
    """
    carried: _Carried | None = None
    history: Trajectory | None = None  # rows already given out, the splines' left context
    pending: Trajectory | None = None
    spline = None

    def finish(core: Trajectory, ahead: Trajectory | None) -> tuple:
        nonlocal history
        before = _length(history)
        if spline:
            window = _joined([history, core, ahead])
            group = window.candidate
            if group is None:
                group = np.zeros(len(window.p), np.int64)
            valid = window.valid
            v, a = _splines.by_group(window.t, window.p, group, end=end, valid=valid)
            rows = slice(before, before + len(core.p))
            v = core.v if core.v is not None else v[rows]
            a = core.a if core.a is not None else a[rows]
        else:
            zero = np.zeros_like(core.p)
            v = zero if core.v is None else core.v
            a = zero if core.a is None else core.a
        joined = _joined([history, core])
        history = _rows_of(joined, slice(max(0, len(joined.p) - SPLINE_CONTEXT), None))
        return core, core.p, v, a, core.valid

    def cut(traj: Trajectory, final: bool) -> int | None:
        """Rows of ``traj`` to give out now (None: wait for more)."""
        n = len(traj.p)
        context = SPLINE_CONTEXT if spline else 0
        if not final and n < size + context:
            return None
        if not whole:
            return n if final else size
        if traj.candidate is None:
            return n if final else None
        starts = np.flatnonzero(np.diff(traj.candidate)) + 1  # a new candidate's first row
        usable = starts[starts <= n - context] if not final else starts
        if final:
            return n
        within = usable[usable <= size]
        if within.size:
            return int(within[-1])
        return int(usable[0]) if usable.size else None

    for part in parts:
        if carried is None:
            spline = part.t is not None and (part.v is None or part.a is None)
            carried = _Carried(why, hint, quaternions, spline or whole or ordered)
        pending = _joined([pending, carried(part)])
        while pending is not None and len(pending.p):
            rows = cut(pending, final=False)
            if rows is None:
                break
            ahead = _rows_of(pending, slice(rows, rows + SPLINE_CONTEXT))
            yield finish(_rows_of(pending, slice(0, rows)), ahead)
            pending = _rows_of(pending, slice(rows, None))
    while pending is not None and len(pending.p):
        rows = cut(pending, final=True)
        yield finish(_rows_of(pending, slice(0, rows)), None)
        pending = _rows_of(pending, slice(rows, None))
