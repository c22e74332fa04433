"""Reading and writing YAML for the collision files, with PyYAML imported when first needed
(the ``yaml`` extra: PyYAML is not a run-time dependency of jaxkin)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["dump", "load"]


def _module(path: Path, what: str) -> Any:
    try:
        import yaml
    except ImportError:
        raise ImportError(
            f"{path}: {what} a YAML file needs the 'yaml' extra (PyYAML): "
            "pip install 'jaxkin[yaml]'"
        ) from None
    return yaml


def load(path: Path) -> Any:
    """The document of a YAML file (safe loader: plain data only), or a ``ValueError`` naming
    the file and, for a syntax error, where it is."""
    yaml = _module(path, "reading")
    try:
        with open(path, encoding="utf-8") as f:
            # the C loader when PyYAML was built with it (the same safe subset, ~10x faster)
            return yaml.load(f, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not readable YAML ({' '.join(str(exc).split())})") from None


def dump(data: Any, path: Path) -> str:
    """``data`` (plain lists, dictionaries, numbers and strings) as YAML text."""
    yaml = _module(path, "writing")
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
