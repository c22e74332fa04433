"""Base class for solver results: ``.ok`` and a host-side ``raise_if_failed``."""

from __future__ import annotations

import numpy as np
from jax import Array

from .status import Status, describe


class SolverResult:
    """Mixin for frozen result dataclasses that carry a per-element ``status`` array."""

    status: Array

    @property
    def ok(self) -> Array:
        """Boolean mask, batch shape: True where ``status == Status.OK``."""
        return self.status == Status.OK

    def raise_if_failed(self, max_listed: int = 10) -> None:
        """Host-side check: raise ``RuntimeError`` naming failing batch indices and statuses.

        Never call this inside ``jit``: it reads the status array back to the host.
        """
        status = np.asarray(self.status)
        failing = np.argwhere(status != Status.OK)
        if failing.size == 0:
            return
        lines = [
            f"  index {tuple(int(i) for i in idx)}: {describe(status[tuple(idx)])}"
            for idx in failing[:max_listed]
        ]
        more = len(failing) - len(lines)
        if more > 0:
            lines.append(f"  ... and {more} more")
        raise RuntimeError(f"{len(failing)} of {status.size} elements failed:\n" + "\n".join(lines))
