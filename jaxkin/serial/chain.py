"""Joint chains: serial chains with named, typed, limited joints and mimic couplings.

A ``JointChain`` is what ``serial.from_urdf`` returns (and what ``JointChain.from_poe`` makes
of a PoE chain or a DH table). It holds the ``m`` moving joints on the path from a base link to
a tip link, each a unit screw ``S_i`` in the base frame (rows ``(omega, v)``, ``poe`` module),
and the home pose ``M`` of the tip at ``theta = 0``::

    T(q) = exp([S_1] theta_1) ... exp([S_m] theta_m) M,    theta_i = c_i q_{k(i)} + b_i

``q`` holds the ``n`` independent coordinates (one per joint that mimics no other); ``k(i)`` is
the coordinate path joint ``i`` follows: itself (``c_i = 1``, ``b_i = 0``) or, for a mimic
joint, its leader (URDF ``theta = multiplier * theta_leader + offset``). The Jacobians with
respect to ``q`` sum the PoE columns (``J_theta``) of the joints that follow one coordinate::

    J(q)[:, j] = sum_{i : k(i) = j} c_i J_theta(theta)[:, i]       (space or body frame)

Joint kinds: ``"revolute"`` (rad, position limits), ``"continuous"`` (rad, no position limits;
the IK returns it wrapped to [-pi, pi)), ``"prismatic"`` (length). Limits are arrays of the
``n`` coordinates: ``lower``/``upper`` (``-inf``/``+inf`` where none) and ``velocity``
(``|q_dot|`` bound, ``+inf`` where none). ``reach()`` bounds the tip's distance from a point
fixed in the base (on the first revolute axis): the sum of the distances between consecutive
joint axes (from a point on one to its projection on the next) plus the prismatic strokes,
each constant while the chain moves.

Every numeric field is a pytree leaf (a chain built afresh with the same joints compiles
nothing new); names, kinds, the coupling indices and the link names are static.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _validate, lie
from .._geometry import BOUND, REAL, geometry, number, static
from ..jet import Jet
from ..result import FKResult, forward_result
from ..robot import POSE, CompilePolicy, JointLimits, Robot, fk, promoted
from ..status import Status
from . import dh as _dh
from . import poe as _poe
from ._chain_options import CHAIN_MIN_PART, ChainIKOptions

__all__ = ["JOINT_KINDS", "JointChain"]

JOINT_KINDS = ("revolute", "continuous", "prismatic")


@geometry
class JointChain(Robot):
    """A serial chain with named joints, joint kinds, limits and mimic couplings (pose targets).

    The constructor validates every field (a ``ValueError`` naming it); ``create`` has keyword
    defaults, ``from_poe`` converts a ``PoEChain`` or ``DHTable`` and ``serial.from_urdf``
    reads a URDF.

    Attributes:
        screws: unit screws of the ``m`` moving joints on the path, base frame, ``(m, 6)``.
        home: tip pose at ``theta = 0`` (``M``), a rigid ``(4, 4)`` transform.
        multiplier: ``c_i``, ``(m,)`` (1 for an independent joint).
        offset: ``b_i``, ``(m,)`` (0 for an independent joint; rad or length as joint ``i``).
        lower, upper: position limits of the ``n`` coordinates, ``(n,)``, ``+-inf`` for none.
        velocity: speed limits ``|q_dot| <= velocity``, ``(n,)``, ``+inf`` for none.
        follows: static, ``k(i)`` per path joint (``m`` ints in ``[0, n)``).
        names: static, the ``n`` joint names (unique).
        kinds: static, ``"revolute"``, ``"continuous"`` or ``"prismatic"`` per coordinate.
        base_link, tip_link: static, the link names (for messages; may be empty).
    """

    screws: Array = number(REAL, (-1, 6))
    home: Array = number(REAL, (4, 4))
    multiplier: Array = number(REAL, (-1,))
    offset: Array = number(REAL, (-1,))
    lower: Array = number(BOUND, (-1,))
    upper: Array = number(BOUND, (-1,))
    velocity: Array = number(BOUND, (-1,))
    follows: tuple[int, ...] = static()
    names: tuple[str, ...] = static()
    kinds: tuple[str, ...] = static()
    base_link: str = static(default="")
    tip_link: str = static(default="")

    target: ClassVar = POSE
    branches: ClassVar = ("newton",)
    reachable: ClassVar = (Status.OK,)
    IKOptions: ClassVar = ChainIKOptions
    # The IK search is loop-bound: large batches run one work queue per host thread; batch
    # sizes are not padded (every element costs a search). FK is cheap per element: large
    # parts.
    ik_policy: ClassVar = CompilePolicy(pad=False, threads=True, min_part=CHAIN_MIN_PART)
    fk_policy: ClassVar = CompilePolicy(threads=True)

    def _validate(self) -> None:
        super()._validate()
        m = int(jnp.shape(self.screws)[0])
        names, kinds, follows = tuple(self.names), tuple(self.kinds), tuple(self.follows)
        n = len(names)
        if n < 1 or m < 1:
            raise ValueError(f"JointChain: needs at least one joint, got {m} screws, {n} names")
        if len(set(names)) != n or not all(isinstance(x, str) and x for x in names):
            raise ValueError(f"JointChain.names: expected unique non-empty strings, got {names}")
        if len(kinds) != n or any(k not in JOINT_KINDS for k in kinds):
            raise ValueError(
                f"JointChain.kinds: expected {n} entries, each one of {JOINT_KINDS}, got {kinds}"
            )
        if len(follows) != m or any(
            isinstance(k, bool) or not isinstance(k, int | np.integer) or not 0 <= k < n
            for k in follows
        ):
            raise ValueError(f"JointChain.follows: expected {m} indices in [0, {n}), got {follows}")
        if set(follows) != set(range(n)):
            raise ValueError(f"JointChain.follows: every coordinate must move a joint, {follows}")
        for field, size in (("multiplier", m), ("offset", m)) + tuple(
            (f, n) for f in ("lower", "upper", "velocity")
        ):
            if int(jnp.shape(getattr(self, field))[0]) != size:
                raise ValueError(
                    f"JointChain.{field}: expected {size} entries, got "
                    f"{jnp.shape(getattr(self, field))[0]}"
                )
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "kinds", kinds)
        object.__setattr__(self, "follows", tuple(int(k) for k in follows))
        leaves = (self.screws, self.home, self.lower, self.upper, self.velocity)
        if not all(_validate.is_concrete(x) for x in leaves):
            return
        _poe.check_screws_and_home(self.screws, self.home, "JointChain")
        lower, upper = np.asarray(self.lower, float), np.asarray(self.upper, float)
        bad = np.flatnonzero(lower > upper)
        if bad.size:
            raise ValueError(
                f"JointChain: joint {names[bad[0]]!r} has lower limit {lower[bad[0]]} > upper "
                f"{upper[bad[0]]}"
            )
        bad = np.flatnonzero(~(np.asarray(self.velocity, float) > 0))
        if bad.size:
            raise ValueError(
                f"JointChain.velocity: joint {names[bad[0]]!r} needs a positive speed limit "
                f"(inf for none), got {np.asarray(self.velocity)[bad[0]]}"
            )
        prismatic_rows = np.linalg.norm(np.asarray(self.screws, float)[:, :3], axis=1) < 0.5
        own = (np.asarray(self.multiplier) == 1.0) & (np.asarray(self.offset) == 0.0)
        for j, kind in enumerate(kinds):
            rows = [i for i, k in enumerate(self.follows) if k == j and own[i]]
            if not any(prismatic_rows[i] == (kind == "prismatic") for i in rows):
                raise ValueError(
                    f"JointChain: joint {names[j]!r} is {kind} but no screw following it with "
                    "multiplier 1 and offset 0 is of that kind (a rotation for revolute and "
                    "continuous joints, a translation for prismatic ones)"
                )
        dtype = jnp.result_type(*(getattr(self, f) for f in _NUMERIC), float)
        for f in _NUMERIC:
            object.__setattr__(self, f, jnp.asarray(getattr(self, f), dtype))

    @classmethod
    def create(
        cls,
        screws: ArrayLike,
        home: ArrayLike,
        names: Sequence[str] | None = None,
        kinds: Sequence[str] | None = None,
        lower: ArrayLike | None = None,
        upper: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        mimic: dict[int, tuple[int, float, float]] | None = None,
    ) -> JointChain:
        """A chain from space-frame screws ``(m, 6)`` and ``home``, keyword defaults.

        Args:
            screws, home: as the attributes (base frame).
            names: one per independent joint; default ``q1 ... qn``.
            kinds: one per independent joint; default from the screws (revolute or prismatic).
            lower, upper, velocity: ``(n,)`` limits; default none (``+-inf``).
            mimic: ``{row: (leader row, multiplier, offset)}``: path joint ``row`` follows the
                joint in row ``leader`` (which mimics no other).

        Raises:
            ValueError: malformed fields (see the class) or a mimic entry that does not name a
                row of ``screws`` whose joint is independent.
        """
        screws = np.asarray(screws, dtype=float)
        m = screws.shape[0] if screws.ndim == 2 else 0
        mimic = dict(mimic or {})
        for row, spec in mimic.items():
            if not (0 <= row < m) or len(spec) != 3 or not (0 <= spec[0] < m):
                raise ValueError(f"mimic: {row}: {spec} must be row: (leader row, c, b)")
            if spec[0] in mimic or spec[0] == row:
                raise ValueError(f"mimic: row {row} follows row {spec[0]}, itself a mimic joint")
        own = [i for i in range(m) if i not in mimic]
        index = {row: j for j, row in enumerate(own)}
        follows = tuple(index[mimic[i][0]] if i in mimic else index[i] for i in range(m))
        multiplier = np.array([float(mimic[i][1]) if i in mimic else 1.0 for i in range(m)])
        offset = np.array([float(mimic[i][2]) if i in mimic else 0.0 for i in range(m)])
        n = len(own)
        if kinds is None and m:
            rotating = np.linalg.norm(screws[own, :3], axis=1) > 0.5
            kinds = tuple("revolute" if r else "prismatic" for r in rotating)
        names = tuple(f"q{j + 1}" for j in range(n)) if names is None else tuple(names)
        bounds = [
            np.full(n, fill) if x is None else np.asarray(x, dtype=float)
            for x, fill in ((lower, -np.inf), (upper, np.inf), (velocity, np.inf))
        ]
        return cls(screws, home, multiplier, offset, *bounds, follows, names, tuple(kinds or ()))

    @classmethod
    def from_poe(cls, chain: _poe.PoEChain | _dh.DHTable) -> JointChain:
        """The same chain (same ``q``, same ``T(q)``) with default names and no limits."""
        poe_chain = _poe.change_frame(_poe.as_poe(chain), "space")
        return cls.create(np.asarray(poe_chain.screws), np.asarray(poe_chain.home))

    # -------------------------------------------------------------------- the robot protocol
    @property
    def n_joints(self) -> int:
        return len(self.names)

    @property
    def n_path_joints(self) -> int:
        """``m``: the moving joints on the path (mimic joints included)."""
        return len(self.follows)

    @property
    def dtype(self):
        screws = self.screws
        return screws.dtype if hasattr(screws, "dtype") else jnp.asarray(screws).dtype

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.names

    @property
    def joint_types(self) -> str:
        return "".join("P" if k == "prismatic" else "R" for k in self.kinds)

    def joint_limits(self) -> JointLimits:
        return JointLimits(self.lower, self.upper)

    def length_scale(self) -> Any:
        """``|p_home|`` plus the distances of the revolute axes from the base origin (``|v_i|``
        of their screws); 1 when all are zero (the ``PoEChain`` measure)."""
        rotating = jnp.any(self.screws[:, :3] != 0, axis=-1)
        offsets = jnp.where(rotating, jnp.linalg.norm(self.screws[:, 3:], axis=-1), 0.0)
        total = jnp.linalg.norm(self.home[:3, 3]) + jnp.sum(offsets)
        return jnp.where(total > 0, total, 1.0)

    def reach(self) -> tuple[Array, Array]:
        """``(centre (3,), radius)``: ``|p_tip(q) - centre| <= radius`` for every ``q`` within
        the limits (``radius`` inf with an unbounded prismatic joint); module docstring."""
        screws = self.screws
        omega, v = screws[:, :3], screws[:, 3:]
        rotating = jnp.any(omega != 0, axis=-1)
        foot = jnp.cross(omega, v)  # the point of a revolute axis nearest the base origin
        stroke_q = jnp.maximum(jnp.abs(self.lower), jnp.abs(self.upper))
        follows = np.asarray(self.follows)
        stroke = jnp.abs(self.multiplier) * stroke_q[follows] + jnp.abs(self.offset)
        # ``current``: a point fixed in the link before joint i (home coordinates) whose
        # distance from ``centre`` is at most ``radius`` in every configuration; a revolute
        # joint moves it to its projection on the joint's axis (fixed in both links).
        centre = jnp.where(rotating[0], foot[0], jnp.zeros(3, screws.dtype))
        current, radius = centre, jnp.zeros((), screws.dtype)
        for i in range(self.n_path_joints):
            on_axis = foot[i] + omega[i] * jnp.dot(omega[i], current - foot[i])
            step = jnp.linalg.norm(on_axis - current)
            radius = radius + jnp.where(rotating[i], step, stroke[i])
            current = jnp.where(rotating[i], on_axis, current)
        radius = radius + jnp.linalg.norm(self.home[:3, 3] - current)
        return centre, radius

    def ik_kernel(self, target: Jet, branch: Any, options: Any, rates: bool) -> Any:
        from .newton_ik import chain_ik_kernel

        return chain_ik_kernel(self, target, options, rates)

    def ik_path_kernel(self, path: Jet, index: Any, options: Any) -> Any:
        from .newton_ik import chain_ik_path_kernel

        return chain_ik_path_kernel(self, path, options)

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> FKResult:
        return _fk_core(_validate.cast_leaves(self, q.dtype), q, rates)

    def work_dtype(self, dtype: Any) -> Any:
        return promoted(dtype, self.screws.dtype)


_NUMERIC = ("screws", "home", "multiplier", "offset", "lower", "upper", "velocity")


# ------------------------------------------------------------------------------ kernels
def angles(chain: JointChain, q: Array) -> Array:
    """``theta_i = c_i q_{k(i)} + b_i``: ``(..., n) -> (..., m)``."""
    if chain.follows != tuple(range(chain.n_joints)):
        q = q[..., np.asarray(chain.follows)]
    return q * chain.multiplier + chain.offset


def couple(chain: JointChain, jac: Array) -> Array:
    """Jacobian columns of the path joints ``(..., 6, m)`` -> of the coordinates ``(..., 6, n)``
    (module docstring)."""
    if chain.follows == tuple(range(chain.n_joints)):
        return jac * chain.multiplier
    onto = jnp.asarray(follow_matrix(chain), jac.dtype)
    return jnp.einsum("...im,mn->...in", jac * chain.multiplier, onto)


def follow_matrix(chain: JointChain) -> np.ndarray:
    """``(m, n)``: 1 where path joint ``i`` follows coordinate ``k(i)``, else 0."""
    onto = np.zeros((chain.n_path_joints, chain.n_joints))
    onto[np.arange(chain.n_path_joints), np.asarray(chain.follows)] = 1.0
    return onto


def poe_chain(chain: JointChain) -> _poe.PoEChain:
    """The PoE chain of the path joints (no validation: works on traced chains)."""
    out = object.__new__(_poe.PoEChain)
    for name, value in (("screws", chain.screws), ("home", chain.home), ("frame", "space")):
        object.__setattr__(out, name, value)
    return out


def fk_rp(chain: JointChain, q: Array) -> tuple[Array, Array]:
    """Tip ``(R (..., 3, 3), p (..., 3))`` at ``q`` ``(..., n)``."""
    return _poe._fk_rp(poe_chain(chain), angles(chain, q))


def fk_and_jacobian(chain: JointChain, q: Array, which: str) -> tuple[Array, Array, Array]:
    """``(R, p, J)`` with ``J`` the ``which`` (``"space"``/``"body"``) Jacobian with respect
    to ``q``, ``(..., 6, n)``."""
    rot, p, jac = _poe._fk_and_jacobian(poe_chain(chain), angles(chain, q), which)
    return rot, p, couple(chain, jac)


def _fk_core(chain: JointChain, q: Jet, rates: bool) -> FKResult:
    """``FKResult`` at ``q`` (at rest its rates are zero, and the pipeline writes them)."""

    def pose(joints):
        return lie.from_rotation_translation(*fk_rp(chain, joints))

    return forward_result(pose, q, rates, 2)


def fk_joint_chain(chain: JointChain, q: Jet | ArrayLike) -> FKResult:
    """Forward kinematics as the robot protocol has it: ``jaxkin.fk(chain, q)``.

    Args:
        chain: a ``JointChain``.
        q: joint coordinates ``(..., n)``: a Jet (the pose's rates by ``jaxkin.lift``) or an
            array (at rest).

    Returns:
        ``FKResult``: ``x`` (Jet of 4x4 tip poses in the base frame) and ``status``
        (``INVALID_INPUT`` for NaN/inf in ``q``, where ``x`` is the pose at ``q = 0``).
    """
    return fk(chain, q)
