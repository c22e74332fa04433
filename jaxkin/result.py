"""Result types shared by every solver: per-element statuses, ``.ok`` and ``raise_if_failed``.

``IKResult`` and ``FKResult`` are what the robot protocol returns (``jaxkin.ik``,
``jaxkin.fk``); a solver may return a subclass with more fields (the SCARA's elbow, the Newton
FK's iterations and residual).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._numerics import all_finite
from .jet import Jet, lift
from .status import STATUS_DTYPE, NamedStatusRepr, Status, describe

__all__ = ["FKResult", "IKResult", "SolverResult", "forward_result"]


class SolverResult(NamedStatusRepr):
    """Mixin for frozen result dataclasses that carry a per-element ``status`` array (their
    repr names the codes: ``status=Array([OK, UNREACHABLE], dtype=int8)``)."""

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


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class IKResult(SolverResult):
    """Inverse kinematics of a batch for one branch.

    Attributes:
        q: Jet of the joint coordinates, shape ``(..., n_joints)`` (rad for revolute joints,
            the length unit for prismatic ones).
        status: ``int8`` codes of ``jaxkin.Status``, shape ``(...)``.
        margin: distance to a singularity, shape ``(...)``: in (0, 1] where solved and
            regular, 0 at a singularity, negative where the target cannot be reached, -1 for
            invalid input (each robot documents its measure).
    """

    q: Jet
    status: Array
    margin: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class FKResult(SolverResult):
    """Forward kinematics of a batch.

    Attributes:
        x: Jet of the end-effector in the form of the robot's targets (``robot.target``),
            shape ``(..., *robot.target.shape)``.
        status: ``int8`` codes of ``jaxkin.Status``, shape ``(...)``.
    """

    x: Jet
    status: Array


def forward_result(pose: Callable[[Array], Array], q: Jet, rates: bool, target_ndim: int):
    """``FKResult`` of ``pose`` (joints ``(..., n)`` -> targets ``(..., *target)``) at ``q``.

    Rows with a NaN or inf joint value or rate are ``INVALID_INPUT``, their target the pose at
    ``q = 0`` with zero rates; the others ``OK``. With ``rates`` the target's rates come from
    ``jaxkin.lift`` (nested forward-mode derivatives), else they are zero.
    """
    valid = all_finite(jnp.concatenate([q.p, q.v, q.a], -1))
    safe = q.map(lambda x: jnp.where(valid[..., None], x, 0.0))
    x = lift(pose)(safe) if rates else Jet.constant(pose(safe.p))
    mask = valid.reshape(valid.shape + (1,) * target_ndim)
    x = Jet(x.p, jnp.where(mask, x.v, 0.0), jnp.where(mask, x.a, 0.0))
    status = jnp.where(valid, Status.OK, Status.INVALID_INPUT).astype(STATUS_DTYPE)
    return FKResult(x, status)
