"""The robots the ``jaxkin`` command knows: one registry entry each.

An entry says how to build the robot from named geometry values (options ``--l-oa`` or keys
of a TOML/JSON file), which robot the papers give (``--robot paper``), its length unit, and
nothing else: branches, joint and target column names, the default workspace box and the
solvers all come from the robot protocol (``jaxkin.robot``). Adding a robot to the command
line is one ``RobotEntry`` in ``ROBOTS``.
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the registry is read by --help, which must not load JAX
    from ..robot import Robot

__all__ = [
    "ROBOTS",
    "CliError",
    "RobotEntry",
    "build_robot",
    "describe_geometry",
    "geometry_values",
    "option",
    "paper_values",
    "parse_branch",
]


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def _scara(**values: Any) -> Robot:
    from ..scara import Scara

    return Scara(values["l_oa"], values["l_ab"], values["l_bc"], values.get("limits"))


def _delta(**values: Any) -> Robot:
    from ..delta import Delta

    limits = {k: values[k] for k in ("theta_min", "theta_max") if k in values}
    return Delta(values["r_base"], values["r_platform"], values["l_arm"], values["l_rod"], **limits)


def _scara_paper() -> Robot:
    from ..scara import Scara

    return Scara.paper()


def _delta_paper() -> Robot:
    from ..delta import Delta

    return Delta.paper()


def _puma_paper() -> Robot:
    from ..serial import Puma560

    return Puma560()


def _urdf(source: str, tip_link: str, base_link: str | None = None) -> Robot:
    from ..serial import from_urdf

    return from_urdf(source, tip_link, base_link=base_link)


def _arm(name: str) -> Callable[..., Robot]:
    def build(**values: Any) -> Robot:
        from .. import serial

        return getattr(serial, name)(**values)

    return build


@dataclasses.dataclass(frozen=True)
class RobotEntry:
    """How the command builds one kind of robot.

    Attributes:
        name: the ``ROBOT`` argument.
        build: geometry values (keyword arguments) -> the robot.
        fields: geometry keys, each an option ``--a-b`` for key ``a_b``.
        optional: further keys a robot file may give (limits).
        paper: the papers' robot (a factory), or None when they print no dimensions.
        unit: the length unit of ``paper``.
        summary: one line for ``--help``.
        from_file: the robot is described by a file (``--robot FILE``) and links (``--tip``,
            ``--base``) rather than by lengths: ``build(source, tip_link, base_link)``.
        defaults: values of ``fields`` that need not be given (the Stanford arm's tool
            offset ``d6``: 0).
    """

    name: str
    build: Callable[..., Robot]
    fields: tuple[str, ...]
    optional: tuple[str, ...] = ()
    paper: Callable[[], Robot] | None = None
    unit: str = "m"
    summary: str = ""
    from_file: bool = False
    defaults: dict[str, float] = dataclasses.field(default_factory=dict)


ROBOTS: dict[str, RobotEntry] = {
    entry.name: entry
    for entry in (
        RobotEntry(
            "scara",
            _scara,
            ("l_oa", "l_ab", "l_bc"),
            ("limits",),
            _scara_paper,
            "mm",
            "SCARA on the RRR dyad [Noriega]",
        ),
        RobotEntry(
            "delta",
            _delta,
            ("r_base", "r_platform", "l_arm", "l_rod"),
            ("theta_min", "theta_max"),
            _delta_paper,
            "cm",
            "Delta parallel robot [Cardona]",
        ),
        RobotEntry(
            "anthropomorphic",
            _arm("Anthropomorphic"),
            ("l1", "l2", "l3"),
            summary="3-DOF anthropomorphic RRR arm [Lopez-Villagomez]",
        ),
        RobotEntry("cylindrical", _arm("Cylindrical"), ("h",), summary="cylindrical RPP arm"),
        RobotEntry("spherical", _arm("Spherical"), ("h",), summary="spherical RRP arm"),
        RobotEntry("planar-2r", _arm("Planar2R"), ("l1", "l2"), summary="planar 2R arm"),
        RobotEntry(
            "puma560",
            _arm("Puma560"),
            ("d1", "a2", "a3", "d3", "d4", "d6"),
            ("link_radius",),
            _puma_paper,
            "m",
            "PUMA 560 6R arm, eight IK branches [Pineiro]; --robot paper: the DH parameters of "
            "Corke's mdl_puma560 (m)",
        ),
        RobotEntry(
            "stanford",
            _arm("Stanford"),
            ("d1", "a2", "d6"),
            ("link_radius",),
            summary="Stanford 2RP3R arm, four IK branches [Pineiro]: --d1 --a2 [--d6]",
            defaults={"d6": 0.0},
        ),
        RobotEntry(
            "urdf",
            _urdf,
            (),
            summary="a serial arm from its URDF: --robot FILE.urdf --tip LINK [--base LINK]",
            from_file=True,
        ),
    )
}


def option(key: str) -> str:
    """The command-line option of a geometry key: ``l_oa`` -> ``--l-oa``."""
    return "--" + key.replace("_", "-")


def all_fields() -> dict[str, list[str]]:
    """Every geometry key of every robot, with the robots that use it."""
    fields: dict[str, list[str]] = {}
    for entry in ROBOTS.values():
        for key in entry.fields:
            fields.setdefault(key, []).append(entry.name)
    return fields


def _read_robot_file(path: Path) -> dict[str, Any]:
    if not path.exists():
        raise CliError(f"--robot {path}: no such file (or use --robot paper)")
    suffix = path.suffix.lower()
    try:
        if suffix == ".toml":
            values = tomllib.loads(path.read_text(encoding="utf-8-sig"))
        elif suffix == ".json":
            values = json.loads(path.read_text(encoding="utf-8-sig"))
        else:
            raise CliError(f"--robot {path}: expected a .toml or .json file, or 'paper'")
    except tomllib.TOMLDecodeError as exc:
        raise CliError(f"{path}: invalid TOML: {exc}") from None
    except json.JSONDecodeError as exc:
        raise CliError(f"{path}:{exc.lineno}: invalid JSON: {exc.msg}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CliError(f"{path}: cannot read: {exc}") from None
    if not isinstance(values, dict):
        raise CliError(f"{path}: expected a table/object of geometry values")
    return values


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CliError(f"{where} must be a number, got {value!r}")
    return float(value)


def paper_values(entry: RobotEntry) -> dict[str, float]:
    """The geometry values of the papers' robot (empty when there is none)."""
    if entry.paper is None:
        return {}
    robot = entry.paper()
    return {k: float(getattr(robot, k)) for k in entry.fields}


def describe_geometry(entry: RobotEntry, values: dict[str, Any]) -> str:
    """``l_oa 150, l_ab 80, l_bc 50 mm``."""
    return ", ".join(f"{k} {values[k]:g}" for k in entry.fields) + f" {entry.unit}"


def geometry_values(entry: RobotEntry, spec: str | None, options: dict[str, Any], notes: list):
    """Geometry values from ``--robot`` (paper or a file) and the options (options win)."""
    values: dict[str, Any] = {}
    paper = paper_values(entry)
    if spec is not None and spec.strip().lower() == "paper":
        if not paper:
            raise CliError(f"--robot paper: the papers give no {entry.name} dimensions")
        values.update(paper)
    elif spec is not None:
        path = Path(spec)
        raw = _read_robot_file(path)
        declared = raw.pop("robot", raw.pop("type", entry.name))
        if declared != entry.name:
            raise CliError(f"{path}: describes a {declared!r} robot, not {entry.name!r}")
        unknown = sorted(set(raw) - set(entry.fields) - set(entry.optional))
        if unknown:
            expected = ", ".join(entry.fields + entry.optional)
            raise CliError(f"{path}: unknown key(s) {', '.join(unknown)} (expected {expected})")
        for key, value in raw.items():
            values[key] = value if key == "limits" else _number(value, f"{path}: {key}")
    values.update(options)
    for key, value in entry.defaults.items():
        values.setdefault(key, value)
    if spec is None and not options and paper:
        # Printed after a successful run only: a failing run prints exactly one line.
        notes.append(
            f"jaxkin: note: no geometry given, used the paper's {entry.name} "
            f"({describe_geometry(entry, paper)}); see --robot"
        )
        values.update(paper)
    missing = [option(k) for k in entry.fields if k not in values]
    if missing:
        instead = "--robot paper / --robot FILE.toml" if paper else "--robot FILE.toml"
        raise CliError(
            f"missing geometry {', '.join(missing)} for {entry.name} (or give {instead})"
        )
    return values


def build_robot(entry: RobotEntry, values: dict[str, Any]) -> Robot:
    """The robot, or a ``CliError`` naming the bad value."""
    try:
        return entry.build(**values)
    except (ValueError, TypeError) as exc:
        raise CliError(f"invalid {entry.name} geometry: {exc}") from None


def parse_branch(robot: Robot, text: str | None) -> Any:
    """``--branch`` text to one of ``robot.branches`` (``+1``, ``1``, ``-1``, ``out`` ...)."""
    if text is None:
        return robot.default_branch
    spelled = text.strip().lower()
    for branch in robot.branches:
        spellings = {str(branch).lower()}
        if isinstance(branch, int):
            spellings.add(f"{branch:+d}")
        if spelled in spellings:
            return branch
    choices = ", ".join(f"{b:+d}" if isinstance(b, int) else str(b) for b in robot.branches)
    raise CliError(f"--branch for {type(robot).__name__} must be one of {choices}, got {text!r}")
