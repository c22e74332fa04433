"""The chain robot: a serial chain with named, typed, limited joints and mimic couplings.

``Chain`` is the one serial-chain robot of jaxkin. Its builders read the usual descriptions:
``serial.from_dh`` (a standard Denavit-Hartenberg table), ``serial.from_screws`` (screws and
a home pose, in the base or the tool frame) and ``serial.from_urdf`` (the chain from a base
link to a tip link of a URDF); ``Chain.create`` takes base-frame screws directly. It holds the
``m`` moving joints on the path from the base to the tip, each a unit screw ``S_i`` in the base
frame (rows ``(omega, v)``), and the home pose ``M`` of the tip at ``theta = 0``::

    T(q) = exp([S_1] theta_1) ... exp([S_m] theta_m) M,    theta_i = c_i q_{k(i)} + b_i

``q`` holds the ``n`` independent coordinates (one per joint that mimics no other); ``k(i)`` is
the coordinate path joint ``i`` follows: itself (``c_i = 1``, ``b_i = 0``) or, for a mimic
joint, its leader (URDF ``theta = multiplier * theta_leader + offset``). The kernels and the
Jacobians' coupling are written in ``serial._kinematics``.

Joint kinds: ``"revolute"`` (rad, position limits), ``"continuous"`` (rad, no position limits;
the IK returns it wrapped to [-pi, pi)), ``"prismatic"`` (length). Limits are arrays of the
``n`` coordinates: ``lower``/``upper`` (``-inf``/``+inf`` where none) and ``velocity``
(``|q_dot|`` bound, ``+inf`` where none). ``reach()`` bounds the tip's distance from a point
fixed in the base (on the first revolute axis): the sum of the distances between consecutive
joint axes (from a point on one to its projection on the next) plus the prismatic strokes,
each constant while the chain moves.

Forward kinematics is ``jaxkin.fk(chain, q)``: its ``x`` is the Jet of the tip's 4x4 poses in
the base frame, so ``jaxkin.fk(chain, q).x.p`` is THE way to the transform of the last frame.
A chain built with ``target_kind="point"`` (``from_urdf(..., target="point")`` and the other
builders' ``target`` argument) takes and returns the tip's origin ``p(q)`` ``(3,)`` instead:
its IK solves position only (the residual is ``p_d - p(q)``), for chains of fewer than six
joints (a leg's foot, a finger's tip, a 5-joint arm).
``space_jacobian`` and ``body_jacobian`` give the Jacobians; ``jaxkin.ik`` the IK search
(``serial.search``) and ``serial.ik_newton`` the textbook Newton iteration from given starts.

Every numeric field is a pytree leaf; the joint kinds and the coupling indices are static; the
joint names and the link names are labels (``_geometry.label``): a chain that differs only in
names (a renamed joint, the same arm loaded with another tip link name) compiles nothing new.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .. import _validate
from .._execute import Kernel, Policy
from .._geometry import BOUND, REAL, Geometry, Numeric, geometry, label, number, static
from .._numerics import eps, safe_norm
from ..collision.body import Body, link_spheres
from ..collision.check import chain_self_pairs
from ..collision.pairs import read_srdf_disabled, self_collision_link_pairs
from ..jet import Jet
from ..result import FKResult, IKResult, forward_result
from ..robot import POINT, POSE, CompilePolicy, JointLimits, Robot, Target, promoted
from ..status import Status
from . import _kinematics, _step, search, track
from .search import ChainIKOptions

__all__ = ["JOINT_KINDS", "TARGETS", "Chain", "ChainLinks", "body_jacobian", "space_jacobian"]

JOINT_KINDS = ("revolute", "continuous", "prismatic")
TARGETS = ("pose", "point")  # ``Chain.target_kind``: the tip's 4x4 pose, or its origin (3,)
_UNIT_TOL = 1e-6  # tolerance on |omega| = 1 (revolute) or |v| = 1 with omega = 0 (prismatic)


def check_screws_and_home(screws: ArrayLike, home: ArrayLike, prefix: str = "") -> None:
    """Host-side: unit screws ``(m, 6)``, m >= 1, and a rigid ``home``; a ``ValueError``
    naming ``{prefix}screws`` / ``{prefix}home`` otherwise."""
    values = np.asarray(screws, dtype=np.float64)
    if values.ndim != 2 or values.shape[0] < 1 or values.shape[1] != 6:
        raise ValueError(f"{prefix}screws: expected shape (m, 6) with m >= 1, got {values.shape}")
    w_norm = np.linalg.norm(values[:, :3], axis=1)
    v_norm = np.linalg.norm(values[:, 3:], axis=1)
    revolute = np.abs(w_norm - 1.0) <= _UNIT_TOL
    prismatic = (w_norm <= _UNIT_TOL) & (np.abs(v_norm - 1.0) <= _UNIT_TOL)
    bad = np.flatnonzero(~(revolute | prismatic))
    if bad.size:
        raise ValueError(
            f"{prefix}screws: rows {bad.tolist()} are not unit screws (need |omega| = 1 for "
            "a revolute joint, or omega = 0 and |v| = 1 for a prismatic joint); got "
            f"|omega| = {w_norm[bad]}, |v| = {v_norm[bad]}"
        )
    m = np.asarray(home, dtype=np.float64)
    if m.shape != (4, 4):
        raise ValueError(f"{prefix}home: expected shape (4, 4), got {m.shape}")
    rot = m[:3, :3]
    if (
        np.max(np.abs(m[3] - np.array([0.0, 0.0, 0.0, 1.0]))) > _UNIT_TOL
        or np.max(np.abs(rot.T @ rot - np.eye(3))) > _UNIT_TOL
        or np.linalg.det(rot) < 0.0
    ):
        raise ValueError(
            f"{prefix}home: expected a rigid transform [[R, p], [0, 0, 0, 1]] with R a "
            f"rotation (R^T R = I, det R = +1), got {m}"
        )


def positive(x: ArrayLike, name: str, allow_zero: bool = False) -> None:
    """Host side: a ``ValueError`` naming ``name`` unless ``x`` is finite and positive (or
    non-negative); tracers pass unchecked."""
    if _validate.is_concrete(x):
        values = np.asarray(x, dtype=np.float64)
        bad = ~np.isfinite(values) | (values < 0.0 if allow_zero else values <= 0.0)
        if np.any(bad):
            kind = "non-negative" if allow_zero else "positive"
            raise ValueError(f"{name} must be {kind} and finite, got {values}")


@geometry
class Chain(Robot):
    """A serial chain with named joints, joint kinds, limits and mimic couplings (pose targets).

    The constructor validates every field (a ``ValueError`` naming it); ``create`` has keyword
    defaults; ``serial.from_dh``, ``serial.from_screws`` and ``serial.from_urdf`` build one
    from a DH table, screws or a URDF.

    Attributes:
        screws: unit screws of the ``m`` moving joints on the path, base frame, ``(m, 6)``.
        home: tip pose at ``theta = 0`` (``M``), a rigid ``(4, 4)`` transform.
        multiplier: ``c_i``, ``(m,)`` (1 for an independent joint).
        offset: ``b_i``, ``(m,)`` (0 for an independent joint; rad or length as joint ``i``).
        lower, upper: position limits of the ``n`` coordinates, ``(n,)``, ``+-inf`` for none.
        velocity: speed limits ``|q_dot| <= velocity``, ``(n,)``, ``+inf`` for none.
        follows: static, ``k(i)`` per path joint (``m`` ints in ``[0, n)``).
        joint_kinds: static, ``"revolute"``, ``"continuous"`` or ``"prismatic"`` per coordinate
            (the protocol's ``joint_types`` is its ``"R"``/``"P"`` view).
        joint_names: label, the ``n`` coordinate names (unique); empty for ``q1 ... qn``.
        base_link, tip_link: labels, the link names (for messages; may be empty).
        target_kind: static, ``"pose"`` (targets are 4x4 poses, ``target`` is ``POSE``) or
            ``"point"`` (the tip's origin ``(3,)``, ``target`` is ``POINT``).
        links: ``ChainLinks`` (every link's pose at ``theta = 0`` and the path joints that
            move it: ``link_poses``, ``collision_body``), set by ``from_urdf``; None for the
            default links ``base, link1, ..., linkm`` (the base frame carried by the first
            ``k`` joints).
    """

    screws: Numeric = number(REAL, (-1, 6))
    home: Numeric = number(REAL, (4, 4))
    multiplier: Numeric = number(REAL, (-1,))
    offset: Numeric = number(REAL, (-1,))
    lower: Numeric = number(BOUND, (-1,))
    upper: Numeric = number(BOUND, (-1,))
    velocity: Numeric = number(BOUND, (-1,))
    follows: tuple[int, ...] = static()
    joint_kinds: tuple[str, ...] = static()
    joint_names: tuple[str, ...] = label(default=())
    base_link: str = label(default="")
    tip_link: str = label(default="")
    target_kind: str = static(default="pose")
    links: Any = None

    branches: ClassVar = ("newton",)
    reachable: ClassVar = (Status.OK,)
    IKOptions: ClassVar = ChainIKOptions
    # The IK search is loop-bound: every batch size shares one compilation, blocks of
    # ``search.BLOCK`` targets (a smaller batch padded with NaN targets, ended at once; a larger
    # one as blocks on the host threads). FK is cheap per element: padded, large parts.
    ik_policy: ClassVar = CompilePolicy(
        pad=False, bucket=search.BLOCK, compiler_options=search.COMPILER_OPTIONS
    )
    fk_policy: ClassVar = CompilePolicy(threads=True)

    @property
    def target(self) -> Target:  # type: ignore[override]  # a class attribute of other robots
        """``POSE`` (4x4 poses) or ``POINT`` (the tip's origin), after ``target_kind``."""
        return POINT if self.target_kind == "point" else POSE

    def _validate(self) -> None:
        super()._validate()
        if self.target_kind not in TARGETS:
            raise ValueError(
                f"Chain.target_kind: expected one of {TARGETS}, got {self.target_kind!r}"
            )
        m = int(jnp.shape(self.screws)[0])
        names, kinds, follows = (
            tuple(self.joint_names),
            tuple(self.joint_kinds),
            tuple(self.follows),
        )
        n = len(kinds)
        names = names or tuple(f"q{j + 1}" for j in range(n))
        if n < 1 or m < 1:
            raise ValueError(f"Chain: needs at least one joint, got {m} screws, {n} joint kinds")
        named = all(isinstance(x, str) and x for x in names)
        if len(names) != n or len(set(names)) != n or not named:
            raise ValueError(
                f"Chain.joint_names: expected {n} unique non-empty strings, got {names}"
            )
        if any(k not in JOINT_KINDS for k in kinds):
            raise ValueError(
                f"Chain.joint_kinds: expected {n} entries, each one of {JOINT_KINDS}, got {kinds}"
            )
        if len(follows) != m or any(
            isinstance(k, bool) or not isinstance(k, int | np.integer) or not 0 <= k < n
            for k in follows
        ):
            raise ValueError(f"Chain.follows: expected {m} indices in [0, {n}), got {follows}")
        if set(follows) != set(range(n)):
            raise ValueError(f"Chain.follows: every coordinate must move a joint, {follows}")
        for field, size in (("multiplier", m), ("offset", m)) + tuple(
            (f, n) for f in ("lower", "upper", "velocity")
        ):
            if int(jnp.shape(getattr(self, field))[0]) != size:
                raise ValueError(
                    f"Chain.{field}: expected {size} entries, got "
                    f"{jnp.shape(getattr(self, field))[0]}"
                )
        for name in ("base_link", "tip_link"):
            if not isinstance(getattr(self, name), str):
                raise ValueError(f"Chain.{name}: expected a string, got {getattr(self, name)!r}")
        object.__setattr__(self, "joint_names", names)
        object.__setattr__(self, "joint_kinds", kinds)
        object.__setattr__(self, "follows", tuple(int(k) for k in follows))
        leaves = (self.screws, self.home, self.lower, self.upper, self.velocity)
        if not all(_validate.is_concrete(x) for x in leaves):
            return
        check_screws_and_home(self.screws, self.home, "Chain.")
        lower, upper = np.asarray(self.lower, float), np.asarray(self.upper, float)
        bad = np.flatnonzero(lower > upper)
        if bad.size:
            raise ValueError(
                f"Chain: joint {names[bad[0]]!r} has lower limit {lower[bad[0]]} > upper "
                f"{upper[bad[0]]}"
            )
        bad = np.flatnonzero(~(np.asarray(self.velocity, float) > 0))
        if bad.size:
            raise ValueError(
                f"Chain.velocity: joint {names[bad[0]]!r} needs a positive speed limit "
                f"(inf for none), got {np.asarray(self.velocity)[bad[0]]}"
            )
        prismatic_rows = np.linalg.norm(np.asarray(self.screws, float)[:, :3], axis=1) < 0.5
        own = (np.asarray(self.multiplier) == 1.0) & (np.asarray(self.offset) == 0.0)
        for j, kind in enumerate(kinds):
            rows = [i for i, k in enumerate(self.follows) if k == j and own[i]]
            if not any(prismatic_rows[i] == (kind == "prismatic") for i in rows):
                raise ValueError(
                    f"Chain: joint {names[j]!r} is {kind} but no screw following it with "
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
        joint_names: Sequence[str] | None = None,
        joint_kinds: Sequence[str] | None = None,
        lower: ArrayLike | None = None,
        upper: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        mimic: dict[int, tuple[int, float, float]] | None = None,
        base_link: str = "",
        tip_link: str = "",
        target: str = "pose",
    ) -> Chain:
        """A chain from base-frame screws ``(m, 6)`` and ``home``, keyword defaults.

        Args:
            screws, home: as the attributes (base frame).
            joint_names: one per independent joint; default ``q1 ... qn``.
            joint_kinds: one per independent joint; default from the screws (revolute or
                prismatic).
            lower, upper, velocity: ``(n,)`` limits; default none (``+-inf``).
            mimic: ``{row: (leader row, multiplier, offset)}``: path joint ``row`` follows the
                joint in row ``leader`` (which mimics no other).
            base_link, tip_link: the link names (labels).
            target: ``"pose"`` or ``"point"`` (``target_kind``).

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
        if joint_kinds is None and m and screws.shape[1:] == (6,):
            rotating = np.linalg.norm(screws[own, :3], axis=1) > 0.5
            joint_kinds = tuple("revolute" if r else "prismatic" for r in rotating)
        low, high, speed = (
            np.full(n, fill) if x is None else np.asarray(x, dtype=float)
            for x, fill in ((lower, -np.inf), (upper, np.inf), (velocity, np.inf))
        )
        return cls(
            screws,
            home,
            multiplier,
            offset,
            low,
            high,
            speed,
            follows=follows,
            joint_kinds=tuple(joint_kinds or ()),
            joint_names=tuple(joint_names or ()),
            base_link=base_link,
            tip_link=tip_link,
            target_kind=target,
        )

    # -------------------------------------------------------------------- the robot protocol
    @property
    def n_joints(self) -> int:
        return len(self.joint_kinds)

    @property
    def n_path_joints(self) -> int:
        """``m``: the moving joints on the path (mimic joints included)."""
        return len(self.follows)

    @property
    def dtype(self):
        screws = self.screws
        return screws.dtype if hasattr(screws, "dtype") else jnp.asarray(screws).dtype

    @property
    def joint_types(self) -> str:
        """The protocol's view of ``joint_kinds``: ``"P"`` for prismatic, ``"R"`` else."""
        return "".join("P" if k == "prismatic" else "R" for k in self.joint_kinds)

    def joint_limits(self) -> JointLimits:
        return JointLimits(self.lower, self.upper, self.velocity)

    def length_scale(self) -> Any:
        """``|p_home|`` plus the distances of the revolute axes from the base origin (``|v_i|``
        of their screws); 1 when all are zero."""
        screws, home = self.screws, self.home
        xp: Any = jnp
        norm: Any = safe_norm
        if _validate.is_concrete(screws) and _validate.is_concrete(home):
            # on the host: eager JAX operations would compile a program each per process
            screws, home = np.asarray(screws), np.asarray(home)
            xp, norm = np, np.linalg.norm
        rotating = xp.any(screws[:, :3] != 0, axis=-1)
        offsets = xp.where(rotating, norm(screws[:, 3:], axis=-1), 0.0)
        total = norm(home[:3, 3]) + xp.sum(offsets)
        return xp.where(total > 0, total, 1.0)

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

        def joint(carry: tuple, axis: tuple) -> tuple:
            current, radius = carry
            foot_i, omega_i, rotating_i, stroke_i = axis
            on_axis = foot_i + omega_i * jnp.dot(omega_i, current - foot_i)
            step = safe_norm(on_axis - current)
            radius = radius + jnp.where(rotating_i, step, stroke_i)
            return (jnp.where(rotating_i, on_axis, current), radius), None

        # A loop, not unrolled: one copy in the chain IK's compiled program.
        start = (centre, jnp.zeros((), screws.dtype))
        (current, radius), _ = jax.lax.scan(joint, start, (foot, omega, rotating, stroke))
        radius = radius + safe_norm(self.home[:3, 3] - current)
        return centre, radius

    def ik_kernel(self, target: Jet, branch: Any, options: ChainIKOptions, rates: bool) -> IKResult:
        """The IK search of ``serial.search`` (its module docstring): ``OK`` means the tool's
        rotation angle to the target is at most ``orientation_tol`` and its distance at most
        ``position_tol`` at the returned joints; with ``use_limits`` the joints of every status
        but ``OUT_OF_LIMITS`` lie within the limits; continuous joints come back in
        [-pi, pi)."""
        chain = _validate.cast_leaves(self, target.dtype)
        budget = search.Budget(options.max_iter, options.restarts, options.max_iter)
        tols = _tolerances(chain, target.dtype, options)
        return search.solve(chain, self._as_pose(target), tols, budget, options.use_limits, rates)

    def ik_path_kernel(
        self, path: Jet, index: Any, options: ChainIKOptions, seed: Any = None
    ) -> IKResult:
        """The IK along sampled paths ``(..., T, 4, 4)`` of ``serial.track``: ``path_lanes``
        solutions of the first sample (or the joints ``seed`` of the last solved sample
        before it) followed along the path with predicted, continuity-checked warm starts of
        ``warm_iter`` updates, the lane that stays continuous and within the limits longest
        kept; a redundant chain's rates are its weighted least-norm ones."""
        chain = _validate.cast_leaves(self, path.dtype)
        budget = search.Budget(
            options.max_iter, options.restarts, options.warm_iter, lanes=options.path_lanes
        )
        tols = _tolerances(chain, path.dtype, options)
        pose = self._as_pose(path)
        return track.solve_paths(chain, pose, tols, budget, options.use_limits, seed)

    def _as_pose(self, target: Jet) -> Jet:
        """Point targets ``(..., 3)`` as the poses the search reads (identity rotation, the
        point as translation, its rates in the translation column); poses unchanged."""
        if self.target_kind != "point":
            return target

        def embed(x: Array, corner: float) -> Array:
            column = jnp.concatenate([x, jnp.full(x.shape[:-1] + (1,), corner, x.dtype)], -1)
            block = jnp.zeros(x.shape[:-1] + (4, 3), x.dtype)
            block = block.at[..., :3, :].set(corner * jnp.eye(3, dtype=x.dtype))
            return jnp.concatenate([block, column[..., None]], -1)

        return Jet(embed(target.p, 1.0), embed(target.v, 0.0), embed(target.a, 0.0))

    def fk_kernel(self, q: Jet, options: Any, rates: bool) -> FKResult:
        """The tip's pose ``T(q)`` (``x``: a Jet of 4x4 transforms in the base frame), or its
        origin ``p(q)`` ``(..., 3)`` for point targets; ``INVALID_INPUT`` for NaN/inf in
        ``q``, where ``x`` is the pose (point) at ``q = 0``."""
        chain = _validate.cast_leaves(self, q.dtype)
        # One configuration: the joints in a loop (_kinematics._over_joints), the same values.
        looped = math.prod(q.p.shape[:-1]) == 1

        def pose(joints: Array) -> Array:
            return _kinematics.pose(chain, joints, looped)

        if self.target_kind == "point":
            return forward_result(lambda joints: pose(joints)[..., :3, 3], q, rates, 1)
        return forward_result(pose, q, rates, 2)

    def work_dtype(self, dtype: Any) -> Any:
        return promoted(dtype, self.screws.dtype)

    def work_target(self, x: Any, dtype: Any) -> Any:
        """Targets in the work dtype; a pose given in a less precise dtype (a float32 target
        of a float64 chain) is that pose to its own precision: its rotation block, where it is
        a rotation in that dtype, becomes the nearest rotation in ``dtype``
        (``_step.promoted_pose``), so the default tolerances in ``dtype`` can be met."""
        if self.target_kind == "point":
            return x.astype(dtype)
        return _step.promoted_pose(x, dtype)

    # -------------------------------------------------------------------- collision
    def link_poses(self, q: Array) -> Array:
        """Every link's pose in the base frame at coordinates ``q`` ``(..., n)``:
        ``exp([S_1] theta_1) ... exp([S_k] theta_k) M_l`` for a link at home pose ``M_l``
        carried by the first ``k`` path joints, ``(..., L, 4, 4)`` (``links``)."""
        chain = _validate.cast_leaves(self, q.dtype)
        prefix = _kinematics.joint_prefix_poses(chain, q)
        if chain.links is None:
            return prefix
        carried = prefix[..., np.asarray(chain.links.moved_by, dtype=np.int32), :, :]
        return jnp.einsum("...lij,ljk->...lik", carried, chain.links.homes)

    def link_frame_rows(self, q: Array) -> tuple[tuple[Array, Array], tuple[int, ...], Any]:
        """``Robot.link_frame_rows``: the joint-prefix poses ``exp([S_1] theta_1) ...
        exp([S_k] theta_k)``, ``k = 0 ... n`` (``_kinematics.joint_prefix_frames``), each link
        carried by its prefix at its home pose ``M_l`` (``links``)."""
        chain = _validate.cast_leaves(self, q.dtype)
        frames = _kinematics.joint_prefix_frames(chain, q)
        if chain.links is None:
            return frames, tuple(range(frames[0].shape[0])), None
        return frames, tuple(chain.links.moved_by), chain.links.homes

    def collision_body(self) -> Body:
        """The body: from the URDF's ``<collision>`` elements for a chain read from a URDF
        (``collision.read_collision``: read with the chain, covered on the first call and kept,
        ``collision.body_from_urdf``'s defaults), else a skeleton of capsules of radius 0: link
        ``k`` from a point on joint ``k``'s axis to one on joint ``k + 1``'s (each the
        projection of the previous point on the next axis, as ``reach()``), the last link to
        the tip; a prismatic joint's travel is not covered. A body given by ``with_body``
        (e.g. ``collision.Body.load`` of one saved once) replaces either; links given spheres
        by ``with_link_spheres`` have those instead, the other links keep their own (the
        URDF's, or the skeleton's when the URDF has no ``<collision>`` elements)."""
        links = self.links
        spheres = dict(links.spheres) if links is not None else {}
        if links is not None and links.body:  # with_body: the user's, in place of any other
            given_spheres, given_capsules = (dict(part) for part in links.body)
            body = Body.create(tuple(links.names), given_spheres, given_capsules)
            return body.with_link_spheres(spheres) if spheres else body
        if links is not None and links.collision is not None:
            return _urdf_body(links, spheres)[0]
        screws = np.asarray(self.screws, float)
        current, points = np.zeros(3), [np.zeros(3)]
        for omega, v in zip(screws[:, :3], screws[:, 3:], strict=True):
            if np.linalg.norm(omega) > 0.5:
                foot = np.cross(omega, v)
                current = foot + omega * np.dot(omega, current - foot)
            points.append(current)
        points.append(np.asarray(self.home, float)[:3, 3])
        names = _default_link_names(len(screws))
        capsules = {name: ([points[k]], [points[k + 1]], [0.0]) for k, name in enumerate(names)}
        return Body.create(names, capsules=capsules).with_link_spheres(spheres)

    def _links(self) -> ChainLinks:
        """``links``, or the default links ``base, link1, ..., linkm`` carried by the first
        ``k`` joints."""
        if self.links is not None:
            return self.links
        m = self.n_path_joints
        homes = np.broadcast_to(np.eye(4), (m + 1, 4, 4))
        return ChainLinks(homes, tuple(range(m + 1)), _default_link_names(m))

    def self_collision_pairs(self) -> tuple[tuple[int, int], ...]:
        """A URDF chain: every pair of links with geometry but adjacent ones (parent and child,
        looking through links without geometry) and those an SRDF disables (``with_srdf``);
        for a skeleton body, those not in contact at ``q = 0`` either. Otherwise links at
        least two apart, not in contact at ``q = 0``."""
        links = self.links
        if links is None or links.collision is None:
            return chain_self_pairs(self)
        if links.body:
            body, skeleton = self.collision_body(), False
        else:
            body, skeleton = _urdf_body(links, dict(links.spheres))
        pairs = self_collision_link_pairs(body, links.tree, links.disabled)
        if not skeleton and (links.spheres or body.num_spheres or body.capsule_radius.size == 0):
            return pairs
        # a skeleton (no <collision> elements): its short links touch at q = 0
        return chain_self_pairs(self, candidates=pairs)

    def with_link_spheres(self, spheres: Any) -> Chain:
        """This chain with the named links' collision geometry replaced by the user's own
        spheres: ``{link: (centers (k, 3), radii (k,) or one radius)}`` in that link's frame,
        finite, radii ``>= 0`` (a ``ValueError`` names the link otherwise). The chain keeps
        copies: editing the arrays afterwards does not change it."""
        links = self._links()
        own = link_spheres(spheres, tuple(links.names))
        merged = tuple({**dict(links.spheres), **own}.items())
        return self.replace(links=links.replace(spheres=merged))

    def with_body(self, body: Body) -> Chain:
        """This chain with ``body`` as its whole collision body (a spherised URDF's, cuRobo's
        spheres through ``Body.create``, or any other), in place of the URDF's
        ``<collision>`` elements, which are then not covered. ``body.links`` must be the chain's
        links in order (``collision_body().links``). The chain keeps host copies."""
        if not isinstance(body, Body):
            raise ValueError(f"body: expected a collision.Body, got {type(body).__name__}")
        links = self._links()
        if tuple(body.links) != tuple(links.names):
            raise ValueError(
                f"body: its links {tuple(body.links)} are not the chain's {tuple(links.names)}"
            )
        spheres, capsules = body.per_link()

        def frozen(parts: dict) -> tuple:
            copies = {name: tuple(np.array(x, dtype=np.float64) for x in arrays)
                      for name, arrays in parts.items()}  # fmt: skip
            for arrays in copies.values():
                for arr in arrays:
                    arr.setflags(write=False)
            return tuple(copies.items())

        return self.replace(links=links.replace(body=(frozen(spheres), frozen(capsules))))

    def with_link_radius(self, radius: float) -> Chain:
        """This chain (read from a URDF without ``<collision>`` elements) with the capsules of
        its skeleton body (link origin to each child joint's origin) of ``radius``."""
        if self.links is None or not self.links.source:
            raise ValueError("with_link_radius: the chain was not read from a URDF")
        if not np.isfinite(radius) or radius < 0:
            raise ValueError(f"radius must be finite and >= 0, got {radius}")
        return self.replace(links=self.links.replace(radius=float(radius)))

    def with_srdf(self, source: Any) -> Chain:
        """This chain (read from a URDF) with the link pairs an SRDF's
        ``<disable_collisions>`` names (path or XML text) left out of self-collision."""
        if self.links is None or not self.links.source:
            raise ValueError("with_srdf: the chain was not read from a URDF")
        disabled = tuple((a, b) for a, b, _ in read_srdf_disabled(source))
        return self.replace(links=self.links.replace(disabled=self.links.disabled + disabled))


def _urdf_body(links: ChainLinks, spheres: dict) -> tuple[Body, bool]:
    """The body of a chain read from a URDF, the links of ``spheres`` given the user's own,
    and whether the others' is the skeleton (the URDF has no ``<collision>`` elements)."""
    read = links.collision.body().body
    if read.links != tuple(links.names):
        raise ValueError("Chain.collision_body: the URDF's links differ from the chain's")
    if read.num_spheres + read.num_capsules == 0:
        return _urdf_skeleton(links).with_link_spheres(spheres), True
    return (read.with_link_spheres(spheres) if spheres else read), False


def _urdf_skeleton(links: ChainLinks) -> Body:
    """A URDF without ``<collision>`` elements: on every link a capsule of radius
    ``links.radius`` from its origin to each child joint's origin."""
    homes = np.asarray(links.homes, float)
    index = {name: i for i, name in enumerate(links.names)}
    ends: dict[str, list] = {}
    for parent, child, _ in links.tree:
        offset = np.linalg.solve(homes[index[parent]], homes[index[child]])[:3, 3]
        if np.linalg.norm(offset) > 0:
            ends.setdefault(parent, []).append(offset)
    radius = float(links.radius)
    capsules = {
        name: (np.zeros((len(e), 3)), np.stack(e), np.full(len(e), radius))
        for name, e in ends.items()
    }
    return Body.create(tuple(links.names), capsules=capsules)


def _default_link_names(m: int) -> tuple[str, ...]:
    return ("base", *(f"link{k + 1}" for k in range(m)))


@geometry
class ChainLinks(Geometry):
    """Every link of a URDF for a chain's collision body.

    Attributes:
        homes: each link's pose in the chain's base frame at ``theta = 0``, ``(L, 4, 4)``.
        moved_by: static, per link the number ``k`` of path joints that carry it (0 ... m).
        names: label, the link names (the order of ``collision_body().links``).
        source: label, the URDF (its resolved path, or its text) the chain was read from.
        tree: label, the URDF's joints ``(parent, child, type)`` (adjacency).
        spheres: label, the user's own spheres per link, ``((name, (centers, radii)), ...)``.
        disabled: label, link name pairs left out of self-collision (an SRDF's).
        radius: label, the skeleton's capsule radius for a URDF without ``<collision>``.
        collision: label, the URDF's collision geometry as read with the chain
            (``collision.UrdfCollision``: covered once, on the first ``collision_body()``).
        body: label, a whole body given by ``with_body``: ``(spheres, capsules)``, each
            ``((link, arrays), ...)`` as ``Body.per_link`` gives them; empty for none.
        held: label, the joints off the path not at 0, ``((name, position), ...)``
            (``from_urdf(..., fixed=...)`` and the joints that mimic those): ``homes`` places
            the links they carry there.
    """

    homes: Numeric = number(REAL, (-1, 4, 4))
    moved_by: tuple[int, ...] = static()
    names: tuple[str, ...] = label()
    source: str = label(default="")
    tree: tuple = label(default=())
    spheres: tuple = label(default=())
    disabled: tuple = label(default=())
    radius: float = label(default=0.0)
    collision: Any = label(default=None)
    body: tuple = label(default=())
    held: tuple = label(default=())


_NUMERIC = ("screws", "home", "multiplier", "offset", "lower", "upper", "velocity")


# ------------------------------------------------------------------------------ Jacobians
def _jacobian_impl(chain: Chain, q: Array, which: str) -> Array:
    return _kinematics.fk_and_jacobian(chain, q, which)[2]


# Large batches split across host threads (memory-bound: 36-42 outputs per element).
_jacobian_jit = Kernel(
    _jacobian_impl, static=("which",), batched={"q": 1}, policy=Policy(pad=True, threads=True)
)


def _checked(chain: Chain, q: ArrayLike) -> tuple[Chain, Array]:
    """The chain and ``q`` ``(..., n)`` in their common floating dtype, or a ``ValueError``."""
    if not isinstance(chain, Chain):
        raise ValueError(f"chain: expected a serial.Chain, got {type(chain).__name__}")
    return check_q(chain, q)


def check_q(chain: Chain, q: ArrayLike) -> tuple[Chain, Array]:
    """``chain`` and ``q`` in the promotion of their dtypes (and float); ``q`` of shape
    ``(..., n)``, else a ``ValueError`` naming ``q``."""
    q = jnp.asarray(q)
    n = chain.n_joints
    if q.ndim == 0 or q.shape[-1] != n:
        raise ValueError(
            f"q: expected shape (..., {n}) (last axis = the chain's {n} joints), "
            f"got {tuple(q.shape)}"
        )
    dtype = jnp.result_type(q, chain.dtype, float)
    return _validate.cast_leaves(chain, dtype), _validate.cast_leaves(q, dtype)


def space_jacobian(chain: Chain, q: ArrayLike) -> Array:
    """Space Jacobian ``J_s`` ``(..., 6, n)`` of a ``Chain`` at ``q`` ``(..., n)``:
    ``V_s = J_s q_dot`` with ``[V_s] = T_dot T^-1``, rows ``(omega, v)`` (``_kinematics``)."""
    chain, q = _checked(chain, q)
    return _jacobian_jit(chain, q, "space", batch=q.shape[:-1])


def body_jacobian(chain: Chain, q: ArrayLike) -> Array:
    """Body Jacobian ``J_b`` ``(..., 6, n)`` of a ``Chain`` at ``q`` ``(..., n)``:
    ``V_b = J_b q_dot`` with ``[V_b] = T^-1 T_dot``, rows ``(omega, v)``."""
    chain, q = _checked(chain, q)
    return _jacobian_jit(chain, q, "body", batch=q.shape[:-1])


def _tolerances(chain: Chain, dtype: Any, options: ChainIKOptions) -> tuple[Array, Array]:
    """``(orientation_tol, position_tol)`` as ``dtype`` arrays (traceable): the options', or
    the defaults ``max(1e-10, 1000 eps)`` (rad) and that times ``chain.length_scale()``."""
    default = max(1e-10, 1e3 * eps(dtype))
    rot = default if options.orientation_tol is None else options.orientation_tol
    pos = default * chain.length_scale() if options.position_tol is None else options.position_tol
    return jnp.asarray(rot, dtype), jnp.asarray(pos, dtype)
