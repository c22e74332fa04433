"""``jaxkin demo``: run the shipped examples, by default the main job (the planner).

The examples are the scripts of the repository's ``examples/`` folder, installed with the
package as ``jaxkin.examples``, so ``jaxkin demo`` works from a plain ``pip install``. Each runs
in this process with ``--output-dir`` (default: the current directory) for the files it writes.
"""

from __future__ import annotations

import argparse
import ast
import runpy
import sys
from importlib import resources
from pathlib import Path

from .robots import CliError

__all__ = ["DEFAULT", "cmd_demo", "examples"]

DEFAULT = "planner-scara"


def examples() -> dict[str, Path]:
    """The shipped example scripts by name: ``scara_spiral.py`` -> ``scara-spiral``
    (a ``_demo`` suffix is dropped: ``dyad_demo.py`` -> ``dyad``)."""
    try:
        root = resources.files("jaxkin.examples")
    except ModuleNotFoundError:
        return {}
    found = {}
    for entry in sorted(root.iterdir(), key=lambda e: e.name):
        if not entry.name.endswith(".py") or entry.name.startswith("_"):
            continue
        stem = entry.name.removesuffix(".py").removesuffix("_demo")
        found[stem.replace("_", "-")] = Path(str(entry))
    return found


def _first_doc_line(path: Path) -> str:
    try:
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    except (OSError, SyntaxError, UnicodeDecodeError):
        return ""
    return doc.strip().splitlines()[0] if doc else ""


def resolve_example(name: str, found: dict[str, Path]) -> str:
    """An example's name from an exact name or a unique prefix (``planner`` ->
    ``planner-scara``); ``CliError`` listing the available names otherwise."""
    name = name.strip().lower().replace("_", "-").removesuffix(".py")
    if name in found:
        return name
    matches = [n for n in found if n.startswith(name)]
    if len(matches) == 1:
        return matches[0]
    problem = "is ambiguous" if matches else "is not an example"
    raise CliError(f"example {name!r} {problem}; available: {', '.join(found)}")


def _own_options(rest: list[str], output_dir: str, quiet: bool) -> tuple[list[str], str, bool]:
    """``--output-dir DIR`` (or ``=DIR``) and ``-q`` given after the example's name are the
    command's own (argparse passes everything after the name on): take them out of ``rest``;
    the last ``--output-dir`` wins."""
    kept: list[str] = []
    items = iter(rest)
    for item in items:
        if item == "--output-dir":
            given = next(items, None)
            if given is None:
                raise CliError("--output-dir: expected one argument (a directory)")
            output_dir = given
        elif item.startswith("--output-dir="):
            output_dir = item.partition("=")[2]
        elif item in ("-q", "--quiet"):
            quiet = True
        else:
            kept.append(item)
    return kept, output_dir, quiet


def cmd_demo(args: argparse.Namespace) -> int:
    """Run (or list) the examples."""
    found = examples()
    if not found:
        raise CliError("no examples installed: reinstall jaxkin (they ship as jaxkin.examples)")
    if args.list:
        width = max(len(n) for n in found)
        for name, path in found.items():
            marker = "  (default)" if name == DEFAULT else ""
            print(f"{name:{width}s}  {_first_doc_line(path)}{marker}")
        return 0
    name = resolve_example(args.name or DEFAULT, found)
    rest, output_dir, quiet = _own_options(list(args.args), args.output_dir, args.quiet)
    output = Path(output_dir)
    if not output.is_dir():
        raise CliError(f"--output-dir {output}: no such directory")
    if not quiet:
        print(f"jaxkin: running the {name} example; files go to {output}", file=sys.stderr)
    argv = sys.argv
    sys.argv = [str(found[name]), "--output-dir", str(output), *rest]
    try:
        runpy.run_path(str(found[name]), run_name="__main__")
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        sys.argv = argv
    return 0
