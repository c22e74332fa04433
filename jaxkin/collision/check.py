"""Batched collision checks of a robot's configurations against a world and itself.

``check(robot, q, world)`` places the robot's body (``robot.collision_body()``, spheres and
capsules attached to links) at every configuration with the robot's own kernel
``robot.link_poses(q)`` and reduces, per configuration::

    clearance = min( min_{robot primitive p, obstacle o} d(p, o),
                     min_{(i, j) in robot.self_collision_pairs()} min_{p on i, p' on j} d(p, p') )

with ``d`` the exact signed distance (``collision.distance``: negative in penetration). A
configuration collides where ``clearance <= margin``. The pair that attains the clearance is
reported: a robot link and an obstacle (``kind``, ``index``), or two robot links.

The world and self clearances are reported apart too, each with its closest pair. The
reduction is one pass over the placed primitives in the rows layout (``fused.world_and_self``:
loops over the obstacles and the self pairs, configurations minor), run chunk by chunk over
large batches so that memory stays bounded; a world with leading batch axes goes through the
per-primitive queries (``world.nearest_obstacles``, ``pairs.self_distances``), which give the
same values.

Everything after the host-side set-up (the body and the pairs, read once per robot) is one
pure function of arrays, compiled once per shapes: moving, resizing or turning an obstacle, or
giving the body other radii, reuses the compilation. A configuration with NaN or inf gets
``status = INVALID_INPUT``, ``collides = True`` and a clearance of 0 (a finite placeholder)
without touching the other elements of the batch; so does one at which the robot does not
assemble (``Robot.placeable``: a Delta's rods that cannot reach the platform), with
``status = UNREACHABLE``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from .._batching import map_chunks
from .._execute import Handle, Kernel, Policy, batch_shape, builds, handle_dtype
from .._numerics import all_finite
from .._validate import finite_number, is_concrete
from ..status import NamedStatusRepr, Status
from . import fused
from .body import Body
from .pairs import SelfPairs, self_distances
from .protocol import CollisionRobot, conforms
from .rows import COMPILER_OPTIONS, place
from .world import World, nearest_obstacles

__all__ = [
    "ROBOT_WORLD",
    "SELF",
    "CheckResult",
    "SelfContact",
    "WorldContact",
    "chain_self_pairs",
    "check",
    "check_kernel",
    "clearances_kernel",
    "prepare",
]

# ``CheckResult.pair_kind``: what attains the clearance (-1: nothing to hit).
ROBOT_WORLD, SELF = 0, 1

# Configurations per step of the chunked check: the rows of ~65 spheres of 1024
# configurations stay in L2 (benchmarks/README.md: 2-4x the rate of 8192-configuration chunks)
CHECK_CHUNK = 1024

_OK, _INVALID_INPUT, _COLLISION = Status.OK, Status.INVALID_INPUT, Status.COLLISION
_UNREACHABLE = Status.UNREACHABLE


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class WorldContact:
    """The closest robot-world pair per configuration (shapes ``(...)``).

    Attributes:
        clearance: the smallest robot-world signed distance (the dtype's largest finite value
            with no obstacle or no robot primitive; 0 for a configuration not checked).
        link: the robot link (index into ``body.links``) of the closest pair, -1 for none.
        kind: ``int8`` ``collision.SPHERE/CAPSULE/BOX/HALFSPACE`` of the obstacle, -1 for none.
        index: the obstacle's index within its kind, -1 for none.
    """

    clearance: Array
    link: Array
    kind: Array
    index: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SelfContact:
    """The closest self-collision pair per configuration (shapes ``(...)``).

    Attributes:
        clearance: the smallest signed distance over the checked self pairs (the dtype's
            largest finite value with none; 0 for a configuration not checked).
        first, second: the pair's links (``first < second``, indices into ``body.links``),
            -1 for none.
    """

    clearance: Array
    first: Array
    second: Array


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class CheckResult(NamedStatusRepr):
    """Per configuration (shapes ``(...)``, the batch of ``q``).

    Attributes:
        clearance: smallest signed distance, robot-world and self (the dtype's largest finite
            value when there is nothing to hit; 0 for invalid input).
        collides: ``clearance <= margin``, or invalid input.
        status: ``int8`` ``jaxkin.Status``: ``OK``, ``COLLISION``, ``INVALID_INPUT`` or
            ``UNREACHABLE`` (joints at which the robot does not assemble).
        world: the closest robot-world pair and its clearance (``WorldContact``).
        self_collision: the closest self pair and its clearance (``SelfContact``).

    The closest pair overall (ties go to the world pair): ``pair_kind`` (``ROBOT_WORLD``,
    ``SELF`` or -1 with nothing to hit), ``link`` (the robot link), ``other`` (the
    obstacle's index within its kind, or the other link), ``obstacle_kind`` (-1 for a self
    pair).
    """

    clearance: Array
    collides: Array
    status: Array
    world: WorldContact
    self_collision: SelfContact

    @property
    def _self_closer(self) -> Array:
        return self.self_collision.clearance < self.world.clearance

    @property
    def pair_kind(self) -> Array:
        """``int8``: ``ROBOT_WORLD``, ``SELF``, or -1 (nothing to hit)."""
        none = (self.world.link < 0) & (self.self_collision.first < 0)
        kind = jnp.where(self._self_closer, SELF, ROBOT_WORLD)
        return jnp.where(none, -1, kind).astype(jnp.int8)

    @property
    def link(self) -> Array:
        """The robot link of the closest pair (the first of a self pair), -1 for none."""
        return jnp.where(self._self_closer, self.self_collision.first, self.world.link)

    @property
    def other(self) -> Array:
        """The obstacle's index within its kind, or the other link of a self pair."""
        return jnp.where(self._self_closer, self.self_collision.second, self.world.index)

    @property
    def obstacle_kind(self) -> Array:
        """``int8`` obstacle kind of a robot-world pair, -1 otherwise."""
        return jnp.where(self._self_closer, -1, self.world.kind).astype(jnp.int8)


def chain_self_pairs(
    robot: Any, apart: int = 2, candidates: Any = None
) -> tuple[tuple[int, int], ...]:
    """Self-collision pairs of a robot whose links form a chain in ``body.links`` order: links
    at least ``apart`` positions apart (or the given ``candidates``), both with geometry, not
    in contact at ``q = 0`` (links that share a joint's centre, as a spherical wrist's do,
    would always collide): their distance there more than 64 ulp of the robot's size
    (``length_scale``), so that links that touch are left out whatever the round-off."""
    body = robot.collision_body()
    geometric = sorted(set(body.sphere_link) | set(body.capsule_link))
    if candidates is None:
        candidates = [(i, j) for i in geometric for j in geometric if j - i >= apart]
    candidates = list(candidates)
    if not candidates:
        return ()
    pairs = SelfPairs.create(body, candidates)
    home = robot.link_poses(jnp.zeros(robot.n_joints, body.sphere_radius.dtype))
    spheres, capsules = body.place(home)
    distance = self_distances(spheres, capsules, pairs)
    if not is_concrete(distance):  # the pairs are static: chosen from values
        raise ValueError(
            f"robot: {type(robot).__name__}'s self-collision pairs leave out the links in "
            "contact at q = 0, so they need its geometry as values, not traced (pass "
            "self_collision=False to differentiate in its link_radius or lengths)"
        )
    distances = np.asarray(distance)
    touching = 64.0 * np.finfo(distances.dtype).eps * float(robot.length_scale())
    return tuple(p for p, d in zip(candidates, distances, strict=True) if d > touching)


def prepare(robot: CollisionRobot, self_collision: bool = True) -> tuple[Body, SelfPairs]:
    """Host side, once per robot: its body and the primitive pairs of its self-collision
    link pairs (none when ``self_collision`` is False)."""
    cached = robot.__dict__.get("_collision_prepared", {})
    if self_collision in cached:
        return cached[self_collision]
    body = robot.collision_body()
    if not isinstance(body, Body):
        raise ValueError(
            f"robot: {type(robot).__name__}.collision_body() must return a collision.Body, "
            f"got {type(body).__name__}"
        )
    link_pairs = robot.self_collision_pairs() if self_collision else ()
    prepared = (body, SelfPairs.create(body, link_pairs))
    if not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(body)):
        # kept on the (frozen) robot: a URDF body's mesh covers are computed once
        object.__setattr__(robot, "_collision_prepared", {**cached, self_collision: prepared})
    return prepared


def world_batched(world: World) -> bool:
    """True when the obstacles carry leading batch axes (the rows layout takes one world)."""
    return world.batched()


def check_kernel(
    robot: CollisionRobot,
    body: Body,
    pairs: SelfPairs,
    q: Array,
    world: World,
    margin: ArrayLike = 0.0,
) -> CheckResult:
    """The pure kernel of ``check`` (traceable, any leading batch axes of ``q``).

    One pass per chunk of configurations (``_batching.map_chunks``: at most ``CHECK_CHUNK``
    configurations at a time, so memory stays bounded for any batch): forward kinematics,
    placement, then the world and self clearances (``fused.world_and_self``). A world with
    leading batch axes goes through the per-primitive queries instead.
    """
    dtype = q.dtype
    batch = q.shape[:-1]
    body, world = body.astype(dtype), world.astype(dtype)
    if world_batched(world) or math.prod(batch) == 0 or not (body.num_spheres + body.num_capsules):
        return _check_per_primitive(robot, body, pairs, q, world, margin)
    prim_link = jnp.asarray(np.asarray(body.sphere_link + body.capsule_link, dtype=np.int32))
    link_pairs = np.asarray(pairs.link_pairs or [(-1, -1)], dtype=np.int32)
    n_obstacles = max(1, sum(len(a[0]) for _, _, a in fused.obstacle_kinds(world)))
    self_pairs = pairs if pairs.link_pairs else None
    margin = jnp.asarray(margin, dtype)

    def one(q: Array) -> CheckResult:
        valid = all_finite(q)
        q_safe = jnp.where(valid[..., None], q, jnp.zeros((), dtype))
        placed = robot.placeable(q_safe)
        parts = fused.world_and_self(place(robot, body, q_safe), world, self_pairs)
        code = parts.world_code
        prim = jnp.clip(code // n_obstacles, 0, max(len(prim_link) - 1, 0))
        kind, index = fused.obstacle_of(world, code % n_obstacles)
        none = code < 0
        world_contact = WorldContact(
            parts.world,
            jnp.where(none, -1, prim_link[prim]),
            jnp.where(none, -1, kind),
            jnp.where(none, -1, index),
        )
        pair = fused.self_link_pair(self_pairs, parts.own_code)
        own = pair < 0
        safe = jnp.clip(pair, 0, len(link_pairs) - 1)
        self_contact = SelfContact(
            parts.own,
            jnp.where(own, -1, jnp.asarray(link_pairs[:, 0])[safe]),
            jnp.where(own, -1, jnp.asarray(link_pairs[:, 1])[safe]),
        )
        return _verdict(valid, placed, world_contact, self_contact, margin)

    flat = q.reshape((-1, q.shape[-1]))
    out = map_chunks(one, flat, flat.shape[:-1], CHECK_CHUNK)
    return jax.tree.map(lambda x: x.reshape((*batch, *x.shape[1:])), out)


def clearances_kernel(
    robot: Any, body: Body, pairs: SelfPairs, q: Array, world: World, skip_copies: bool = False
) -> tuple[Array, Array, Array]:
    """Per configuration ``q (..., n)``: each robot primitive's signed distance to the world
    ``(..., S + C)`` (spheres, then capsules; the dtype's largest finite value with no
    obstacle), each checked link pair's smallest self distance ``(..., len(link_pairs))``,
    and whether ``q`` is finite and the robot assembles there ``(...)`` (where it is not, the
    distances are a placeholder's): the pure kernel conservative advancement reads
    (``fused.primitive_clearances``, chunk by chunk; ``skip_copies`` as there)."""
    dtype = q.dtype
    batch = q.shape[:-1]
    body, world = body.astype(dtype), world.astype(dtype)
    self_pairs = pairs if pairs.link_pairs else None

    def one(q: Array) -> tuple[Array, Array, Array]:
        valid = all_finite(q)
        q_safe = jnp.where(valid[..., None], q, jnp.zeros((), dtype))
        placed = place(robot, body, q_safe)
        prims, own = fused.primitive_clearances(placed, world, self_pairs, skip_copies)
        return prims.T, own.T, valid & robot.placeable(q_safe)

    flat = q.reshape((-1, q.shape[-1]))
    out = map_chunks(one, flat, flat.shape[:-1], CHECK_CHUNK)
    return jax.tree.map(lambda x: x.reshape((*batch, *x.shape[1:])), out)


def _check_per_primitive(
    robot: CollisionRobot,
    body: Body,
    pairs: SelfPairs,
    q: Array,
    world: World,
    margin: ArrayLike = 0.0,
) -> CheckResult:
    """``check_kernel`` through the per-primitive queries (``nearest_obstacles`` and
    ``self_distances``): for a world with leading batch axes, and the reference of the
    rows pass in the tests."""
    dtype = q.dtype
    valid = all_finite(q)
    q_safe = jnp.where(valid[..., None], q, 0.0)
    placed = robot.placeable(q_safe)
    body, world = body.astype(dtype), world.astype(dtype)
    spheres, capsules = body.place(robot.link_poses(q_safe).astype(dtype))
    near_s, near_c = nearest_obstacles(spheres, capsules, world)
    big = jnp.finfo(dtype).max
    batch = q.shape[:-1]

    # robot-world: the closest robot primitive and its obstacle
    prim_link = np.asarray(body.sphere_link + body.capsule_link, dtype=np.int32)
    none = jnp.full(batch, -1, jnp.int32)
    if len(prim_link):
        d_world = jnp.concatenate([near_s.distance, near_c.distance], axis=-1)
        kinds = jnp.concatenate([near_s.kind, near_c.kind], axis=-1)
        index = jnp.concatenate([near_s.index, near_c.index], axis=-1)
        p = jnp.argmin(d_world, axis=-1)
        world_clear = jnp.take_along_axis(d_world, p[..., None], -1)[..., 0]
        nothing = world_clear >= big
        world_contact = WorldContact(
            world_clear,
            jnp.where(nothing, -1, jnp.asarray(prim_link)[p]),
            jnp.where(nothing, -1, jnp.take_along_axis(kinds, p[..., None], -1)[..., 0]),
            jnp.where(nothing, -1, jnp.take_along_axis(index, p[..., None], -1)[..., 0]),
        )
    else:
        world_contact = WorldContact(jnp.full(batch, big, dtype), none, none, none)

    # self: the closest checked link pair
    if pairs.link_pairs:
        d_self = self_distances(spheres, capsules, pairs)
        k = jnp.argmin(d_self, axis=-1)
        link_pairs = np.asarray(pairs.link_pairs, dtype=np.int32)
        self_contact = SelfContact(
            jnp.take_along_axis(d_self, k[..., None], -1)[..., 0],
            jnp.asarray(link_pairs[:, 0])[k],
            jnp.asarray(link_pairs[:, 1])[k],
        )
    else:
        self_contact = SelfContact(jnp.full(batch, big, dtype), none, none)
    return _verdict(valid, placed, world_contact, self_contact, jnp.asarray(margin, dtype))


def _verdict(
    valid: Array,
    placed: Array,
    world: WorldContact,
    own: SelfContact,
    margin: Array,
) -> CheckResult:
    """The ``CheckResult`` of the closest pairs: a configuration that is not finite
    (``INVALID_INPUT``), or at which the robot does not assemble (``placed`` False:
    ``UNREACHABLE``), gets clearances 0, collides and no pair; the others collide at a
    clearance ``<= margin``."""
    known = valid & placed
    zero = jnp.zeros((), world.clearance.dtype)
    world = WorldContact(
        jnp.where(known, world.clearance, zero),
        jnp.where(known, world.link, -1).astype(jnp.int32),
        jnp.where(known, world.kind, -1).astype(jnp.int8),
        jnp.where(known, world.index, -1).astype(jnp.int32),
    )
    own = SelfContact(
        jnp.where(known, own.clearance, zero),
        jnp.where(known, own.first, -1).astype(jnp.int32),
        jnp.where(known, own.second, -1).astype(jnp.int32),
    )
    clearance = jnp.minimum(world.clearance, own.clearance)
    collides = ~known | (clearance <= margin)
    status = jnp.where(collides, _COLLISION, _OK)
    status = jnp.where(~valid, _INVALID_INPUT, jnp.where(~placed, _UNREACHABLE, status))
    return CheckResult(clearance, collides, status.astype(jnp.int8), world, own)


# Small batches padded (one compilation per size class), one configuration as it is
_check_jit = Kernel(
    check_kernel,
    batched={"q": 1},
    policy=Policy(pad=True, compiler_options=COMPILER_OPTIONS),
)


def _check_robot(robot: Any) -> CollisionRobot:
    """``robot`` if it has the members of the collision protocol (``CollisionRobot``;
    ``prepare`` checks the body it returns)."""
    if not conforms(robot):
        raise ValueError(
            "robot: expected a robot with the collision protocol's n_joints, "
            "collision_body(), link_poses(), link_frame_rows(), placeable() and "
            f"self_collision_pairs() (every jaxkin robot), got {type(robot).__name__}"
        )
    return robot


def _as_q(robot: CollisionRobot, q: Any, name: str = "q") -> Array:
    if not isinstance(q, jax.Array):
        q = np.asarray(q)
    # complex q would lose its imaginary part, boolean q is no joint coordinate
    if not (jnp.issubdtype(q.dtype, jnp.floating) or jnp.issubdtype(q.dtype, jnp.integer)):
        raise ValueError(f"{name}: expected real joint coordinates, got dtype {q.dtype}")
    if not jnp.issubdtype(q.dtype, jnp.floating):
        q = q.astype(jnp.result_type(float))
    if isinstance(q, np.ndarray):  # handed to the compiled program as it is: no program per
        q = q.astype(jax.dtypes.canonicalize_dtype(q.dtype), copy=False)  # shape, no extra copy
    if q.ndim < 1 or q.shape[-1] != robot.n_joints:
        raise ValueError(
            f"{name}: expected shape (..., {robot.n_joints}) for {type(robot).__name__}, "
            f"got {q.shape}"
        )
    return q


def _check_world(world: Any) -> World:
    if not isinstance(world, World):
        raise ValueError(f"world: expected a collision.World, got {type(world).__name__}")
    return world


def _check_margin(margin: Any) -> Any:
    """A concrete ``margin`` as a finite real number (a float); a traced one unchanged (the
    caller's ``jit`` or ``vmap``)."""
    if not is_concrete(margin):
        return margin
    # a NaN or -inf margin would report every configuration free (clearance <= margin False)
    return finite_number(margin, "margin")


def check(
    robot: CollisionRobot,
    q: ArrayLike,
    world: World,
    margin: float = 0.0,
    self_collision: bool = True,
) -> CheckResult:
    """Check configurations ``q`` ``(..., n_joints)`` of ``robot`` against ``world`` and
    itself (module docstring).

    Args:
        robot: any robot of the collision protocol (``CollisionRobot``: every jaxkin robot).
        q: joint coordinates, any leading batch axes (may be traced: ``check`` works under
            ``jit`` and ``vmap``).
        world: a ``collision.World`` (array data: moving obstacles does not recompile).
        margin: a configuration collides where its clearance is ``<= margin`` (length units;
            one finite number, or traced).
        self_collision: check the robot's ``self_collision_pairs()`` too.

    Returns:
        ``CheckResult`` with shapes ``(...)``.

    Raises:
        ValueError: ``q`` of the wrong trailing shape or not real, a world that is not a
            ``World``, a margin that is not one finite number, a robot without a collision
            body.
    """
    robot, body, pairs, q, world, margin = checked_arguments(
        robot, q, world, margin, self_collision
    )
    batch = q.shape[:-1]
    pad = single(batch) and not world.batched()
    return _check_jit(robot, body, pairs, q, world, margin, batch=batch, pad=pad)


def single(batch: tuple[int, ...]) -> bool:
    """Whether a batch of configurations is padded: not one configuration (the single query
    runs as it is)."""
    return math.prod(batch) != 1


def checked_arguments(
    robot: Any, q: ArrayLike, world: Any, margin: Any, self_collision: bool
) -> tuple[CollisionRobot, Body, SelfPairs, Array, World, Any]:
    """The boundary of the public checks: the robot checked, ``q`` as an array of its joint
    count, the world and a concrete margin checked, the robot's body and self pairs
    (``prepare``); ``ValueError`` naming the argument otherwise. Returns ``(robot, body,
    pairs, q, world, margin)``."""
    robot = _check_robot(robot)
    q = _as_q(robot, q)
    world = _check_world(world).bucketed()  # a world within its buckets: no compilation
    margin = _check_margin(margin)
    body, pairs = prepare(robot, self_collision)
    return robot, body, pairs, q, world, margin


@dataclasses.dataclass(frozen=True)
class HandleSetup:
    """What a compiled handle of a check holds (``handle_setup``): the robot, its body and
    self pairs, the margin, the dtype and batch shape of the configurations it takes, the
    world's layout and the world packed into one array (``World.packed``), and ``rebind``
    (another world of the same layout, packed; ``Handle.rebound``)."""

    robot: Any
    body: Body
    pairs: SelfPairs
    margin: Any
    dtype: np.dtype
    batch: tuple[int, ...]
    layout: tuple
    packed: Array
    rebind: Any

    def world(self, flat: Array) -> World:
        """The world of this layout from a packed array (inside the handle's program)."""
        return World.unpacked(flat, self.layout)

    def configurations(self) -> np.ndarray:
        """Zero configurations of the handle's shape and dtype (the example it compiles)."""
        return np.zeros((*self.batch, self.robot.n_joints), self.dtype)

    def configuration_handle(self, kernel: Any) -> Handle:
        """The handle of ``kernel(robot, body, pairs, q, world, margin)`` (``check_kernel``,
        ``collides_kernel``) over configurations ``q``, the world bound as data."""

        def run(q: Array, flat: Array) -> Any:
            return kernel(self.robot, self.body, self.pairs, q, self.world(flat), self.margin)

        return Handle(
            run,
            (self.configurations(),),
            bound=(self.packed,),
            rebind=self.rebind,
            compiler_options=COMPILER_OPTIONS,
        )


def handle_setup(
    robot: Any, world: Any, batch: Any, margin: Any, self_collision: bool, dtype: Any
) -> HandleSetup:
    """The boundary of a check's compiled handle, done once: the robot, world, margin,
    batch and dtype checked (``ValueError`` naming the argument), the body and self pairs
    prepared, the world packed."""
    robot = _check_robot(robot)
    world = _check_world(world).bucketed()
    margin = _check_margin(margin)
    body, pairs = prepare(robot, self_collision)
    dtype = handle_dtype(dtype)
    layout = world.layout()

    def rebind(other: Any) -> tuple[Array]:
        other = _check_world(other).bucketed()
        if other.layout() != layout:
            raise ValueError(
                "world: another layout than the handle's (the same kinds of obstacles, their "
                "numbers in the same multiples of collision.OBSTACLE_BUCKET; or a new handle)"
            )
        return (jax.device_put(other.packed(dtype)),)

    packed = rebind(world)[0]
    return HandleSetup(
        robot, body, pairs, margin, dtype, batch_shape(batch), layout, packed, rebind
    )


@builds(check)
def _check_handle(
    robot: Any,
    world: World,
    batch: Any = 1,
    margin: float = 0.0,
    self_collision: bool = True,
    dtype: Any = None,
) -> Handle:
    """``compiled(collision.check, robot, world, batch=1, margin=0.0, self_collision=True,
    dtype=None)``: ``handle(q)`` for configurations ``(*batch, n_joints)`` in ``dtype`` (JAX's
    default float for None), the robot's body, self pairs and margin compiled in, the world
    passed as one packed array (``handle.rebound(world)`` takes another world of the same
    layout without compiling); the ``CheckResult`` of ``check`` on the same input."""
    setup = handle_setup(robot, world, batch, margin, self_collision, dtype)
    return setup.configuration_handle(check_kernel)
