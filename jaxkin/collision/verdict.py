"""The collision verdict alone: per configuration, does the robot touch the world or itself?

``collides(robot, q, world)`` answers what a sampling-based planner asks, ``check(...).collides``,
without the clearance's value or its pair, and so without a square root or a double ``where``
per pair. With ``R = r + r' + margin`` for two spheres (centres ``c``, ``c'``)::

    |c - c'| - r - r' <= margin   <=>   |c - c'|^2 <= R^2        (R >= 0; never when R < 0)

a sphere against a box (``u`` the centre in the box frame, ``e_i = |u_i| - h_i``,
``s = min(R, 0)``, ``R = r + margin``)::

    d <= margin   <=>   sum_i max(e_i - s, 0)^2 <= max(R, 0)^2

(outside the box ``d`` is the distance to it, inside ``max_i e_i - r``: for ``R >= 0`` the
left side is the squared distance, for ``R < 0`` it is zero exactly when every ``e_i <= R``;
the squared tolerance below then allows ``e_i`` up to ``R + sqrt(slack)``), a sphere against a
capsule through the squared point-segment distance, against a half-space the plane's linear
form, against a cylinder its exact signed distance; a robot capsule goes through the exact
signed distances of ``collision.distance``.

Layout (``collision.rows``): forward kinematics and placement write each placed coordinate as
a row of the chunk's configurations, in the dtype of ``q``. One loop step per obstacle tests
every robot sphere (or capsule) against it, a block ``(n, B)`` reduced by halving; one step
per ``rows.PAIR_CHUNK`` self pairs likewise. The loops end as soon as every configuration of
the chunk is known to collide (a single configuration: at its first colliding obstacle or
pair). The program's size does not grow with the numbers of primitives, obstacles or pairs.
A body of many spheres (a mesh cover: the default body from a URDF) goes through its groups'
bounding spheres first instead (``collision.culled``): the same tests, run only for the blocks
of configurations whose bounds come close. With ``frame_bounds`` (the motion planner's states)
each obstacle is first tested against one bounding sphere per frame of the robot's spheres
(``rows.FrameBounds``, ``(g, R)`` with ``|c - g| <= R - r`` for each of its spheres), every
configuration of the chunk at once, and the loop passes over the obstacles no bound comes
near. Each test is a signed distance (or its square) of the sphere's centre less its radius,
1-Lipschitz in the centre, so a sphere the fine test flags lies in a bound the coarse test
flags when its radius is widened by the fine test's slack (``sqrt`` of it for a squared test)
and ``4 tol`` for its own rounding: the verdicts are the same.
A large concrete batch runs as one part per host thread.

Rounding: the verdict is conservative by a tolerance ``tol = 16 eps (1 + X)`` (``eps`` of the
dtype, ``X`` the largest coordinate magnitude of the configuration's placed primitives and of
the obstacle tested, so an obstacle far away loosens no other test; for self pairs the
robot's alone): every configuration whose exact clearance is ``<= margin`` is flagged. A
flagged one has a linear test (half-space, capsule) ``<= margin + tol``, or a squared one
``d^2 <= R^2 + tol (2 R_max + tol)`` (``R`` above taken as ``R + tol`` for the largest
``R_max`` of that obstacle's tests), so its clearance is at most ``margin + tol (2 R_max +
tol) / (2 R)``. The exact check and the verdict round their placed coordinates differently,
so configurations that close to contact can only be flagged, never missed.

NaN or inf in a configuration gives ``collides = True`` and ``INVALID_INPUT`` for that
element alone (``UNREACHABLE`` where the robot does not assemble, ``Robot.placeable``).
Moving or resizing an obstacle reuses the compilation (array data).
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
from .._execute import Handle, Kernel, Policy, builds, compiled
from .._execute.handles import HotQueries
from .._numerics import all_finite
from ..status import NamedStatusRepr, Status
from . import culled
from . import distance as sd
from .body import Body
from .check import check_kernel, checked_arguments, handle_setup, single, world_batched
from .pairs import SelfPairs
from .protocol import CollisionRobot
from .rows import (
    CAPSULE_CHUNK,
    COMPILER_OPTIONS,
    FrameBounds,
    Placed,
    loop_pairs,
    loop_world,
    place,
    place_bounded,
    tree_min,
)
from .world import World

__all__ = ["TOLERANCE", "VERDICT_CHUNK", "Verdict", "collides", "collides_kernel", "verdict_rows"]

# Configurations per step: the placed rows and the temporaries of ~65 spheres stay in L2
VERDICT_CHUNK = 512
# The rounding tolerance in units of eps (1 + X) (module docstring)
TOLERANCE = 16.0


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Verdict(NamedStatusRepr):
    """Per configuration (shapes ``(...)``, the batch of ``q``).

    Attributes:
        collides: the configuration touches the world or itself (clearance ``<= margin``,
            module docstring for rounding), or is not finite.
        status: ``int8`` ``jaxkin.Status``: ``OK``, ``COLLISION``, ``INVALID_INPUT`` or
            ``UNREACHABLE`` (joints at which the robot does not assemble).
    """

    collides: Array
    status: Array


def _threshold(radius: Array) -> Array:
    """``R^2`` where ``R >= 0``, else -1 (no squared distance reaches it)."""
    return jnp.where(radius >= 0, radius * radius, -1.0)


def _sphere_test(x: list[Array], r: Array, margin: Array, c, ro) -> Array:
    """Squared excess of spheres (rows ``x``, radii ``r``) over a sphere obstacle. The
    obstacle's entries (``c[i]``, ``ro``) are scalars or arrays broadcasting against ``x``."""
    d2 = (x[0] - c[0]) ** 2 + (x[1] - c[1]) ** 2 + (x[2] - c[2]) ** 2
    return d2 - _threshold(r + ro + margin)


def _capsule_test(x: list[Array], r: Array, margin: Array, a, b, ro) -> Array:
    """Squared excess over a capsule obstacle: the squared point-segment distance."""
    d = [b[i] - a[i] for i in range(3)]
    dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    inv = jnp.where(dd > 0, 1.0 / jnp.where(dd > 0, dd, 1.0), 0.0)
    rel = [x[i] - a[i] for i in range(3)]
    t = jnp.clip((rel[0] * d[0] + rel[1] * d[1] + rel[2] * d[2]) * inv, 0.0, 1.0)
    d2 = (rel[0] - t * d[0]) ** 2 + (rel[1] - t * d[1]) ** 2 + (rel[2] - t * d[2]) ** 2
    return d2 - _threshold(r + ro + margin)


def _box_test(x: list[Array], r: Array, margin: Array, c, rot, h) -> Array:
    """Squared excess over a box (module docstring); ``rot[i, k]`` the rotation's entries."""
    # u_k = x . R_k - c . R_k: the rows are read directly, each e_k is used once
    big = r + margin
    shift = jnp.minimum(big, 0.0)
    terms = []
    for k in range(3):
        ck = c[0] * rot[0, k] + c[1] * rot[1, k] + c[2] * rot[2, k]
        u = x[0] * rot[0, k] + x[1] * rot[1, k] + x[2] * rot[2, k] - ck
        terms.append(jnp.maximum(jnp.abs(u) - h[k] - shift, 0.0) ** 2)
    return terms[0] + terms[1] + terms[2] - jnp.where(big >= 0, big * big, 0.0)


def _halfspace_test(x: list[Array], r: Array, margin: Array, n, o) -> Array:
    """Linear excess over a half-space ``n . x <= o``."""
    return x[0] * n[0] + x[1] * n[1] + x[2] * n[2] - o - r - margin


def _rows(x: Array) -> list[Array]:
    return [x[0], x[1], x[2]]


def _points(rows: Array) -> Array:
    return jnp.stack([rows[0], rows[1], rows[2]], axis=-1)


def _norm_inf(x: Array) -> Array:
    """The largest entry's magnitude of an obstacle's field."""
    return jnp.max(jnp.abs(x))


def _sphere_kinds(world: World) -> list[tuple[Any, bool, tuple[Array, ...], Any]]:
    """``(test, squared, arrays (m, ...), scale)`` per non-empty obstacle kind for the robot's
    spheres: ``scale(obstacle)`` its largest coordinate magnitude and (squared tests) the
    radius it adds to ``R``."""
    w = world
    kinds = [
        (_sphere_test, True, (w.spheres.center, w.spheres.radius),
         lambda o: (_norm_inf(o[0]), o[1])),
        (_capsule_test, True, (w.capsules.a, w.capsules.b, w.capsules.radius),
         lambda o: (jnp.maximum(_norm_inf(o[0]), _norm_inf(o[1])), o[2])),
        (_box_test, True, (w.boxes.center, w.boxes.rotation, w.boxes.half_extents),
         lambda o: (_norm_inf(o[0]) + _norm_inf(o[2]), 0.0)),
        (_halfspace_test, False, (w.halfspaces.normal, w.halfspaces.offset),
         lambda o: (jnp.abs(o[1]), 0.0)),
        (_cylinder_test, False, _cylinder_fields(w), _cylinder_scale),
    ]  # fmt: skip
    return [kind for kind in kinds if kind[2][0].shape[0]]


def _cylinder_test(x: list[Array], r: Array, margin: Array, *cylinder: Array) -> Array:
    """Linear excess over a cylinder: the exact signed distance (a square root: no squared
    form keeps the rim's rounding bounded) less the margin."""
    return sd.sphere_cylinder(jnp.stack(x, axis=-1), r, *cylinder) - margin


def _cylinder_fields(w: World) -> tuple[Array, ...]:
    c = w.cylinders
    return (c.center, c.axis, c.radius, c.half_length)


def _cylinder_scale(o: tuple) -> tuple[Array, float]:
    """A cylinder's largest coordinate magnitude: its centre's plus its extent."""
    return _norm_inf(o[0]) + o[2] + o[3], 0.0


def _capsule_kinds(world: World) -> list[tuple[Any, tuple[Array, ...], Any]]:
    """``(distance, arrays, scale)`` per non-empty obstacle kind for the robot's capsules."""
    w = world
    kinds = [
        (lambda a, b, r, o: sd.sphere_capsule(o[0], o[1], a, b, r),
         (w.spheres.center, w.spheres.radius), lambda o: _norm_inf(o[0])),
        (lambda a, b, r, o: sd.capsule_capsule(a, b, r, *o),
         (w.capsules.a, w.capsules.b, w.capsules.radius),
         lambda o: jnp.maximum(_norm_inf(o[0]), _norm_inf(o[1]))),
        (lambda a, b, r, o: sd.capsule_box(a, b, r, *o),
         (w.boxes.center, w.boxes.rotation, w.boxes.half_extents),
         lambda o: _norm_inf(o[0]) + _norm_inf(o[2])),
        (lambda a, b, r, o: sd.capsule_halfspace(a, b, r, *o),
         (w.halfspaces.normal, w.halfspaces.offset), lambda o: jnp.abs(o[1])),
        (lambda a, b, r, o: sd.capsule_cylinder(a, b, r, *o), _cylinder_fields(w),
         lambda o: _cylinder_scale(o)[0]),
    ]  # fmt: skip
    return [kind for kind in kinds if kind[1][0].shape[0]]


def verdict_rows(
    placed: Placed,
    world: World,
    pairs: SelfPairs | None,
    margin: Array,
    hit: Array,
    bounds: FrameBounds | None = None,
) -> Array:
    """The verdict ``(B,)`` of a placed chunk: ``hit`` (configurations already settled: not
    finite, or not assembled) or any test that flags a collision (module docstring). Each
    test's excess over its bound (``<= 0``: flagged) is reduced over the primitives and the
    obstacles of a loop step; the loops end once every configuration of the chunk is
    flagged."""
    dtype = placed.spheres.dtype
    eps = jnp.finfo(dtype).eps
    robot_scale = placed.scale()
    margin_plus = jnp.maximum(margin, 0.0)

    def settled(hit: Array) -> Array:
        return jnp.all(hit)

    def flagged(hit: Array, excess: Array) -> Array:
        return hit | (tree_min(excess) <= 0.0)

    def tolerance(scale: Any) -> Array:
        """``(B,)``: the rounding tolerance of tests against an obstacle of ``scale``."""
        return TOLERANCE * eps * (1.0 + jnp.maximum(robot_scale, scale))

    if placed.spheres.shape[1]:
        x, r = _rows(placed.spheres), placed.sphere_radius
        r_max = jnp.max(r)
        for test, squared, arrays, scale_of in _sphere_kinds(world):

            def slack(obstacle, scale_of=scale_of, squared=squared):
                """The obstacle's scale, and how far past its bound a flagged test may be."""
                scale, radius = scale_of(obstacle)
                tol = tolerance(scale)
                if not squared:
                    return scale, tol
                return scale, tol * (2.0 * (r_max + radius + margin_plus) + tol)

            def excess(obstacle, j, test=test, slack=slack):
                return test(x, r, margin, *obstacle) - slack(obstacle)[1]

            visit = None
            if bounds is not None:

                def visit(obstacle, hit, test=test, slack=slack, squared=squared):
                    """Whether a bound comes near: the radius widened by the fine test's
                    slack and by the coarse test's own rounding (module docstring)."""
                    scale, bound = slack(obstacle)
                    coarse = TOLERANCE * eps * (1.0 + jnp.maximum(bounds.scale, scale))
                    widen = (jnp.sqrt(bound) if squared else bound) + 4.0 * coarse
                    near = test(_rows(bounds.center), bounds.reach + widen, margin, *obstacle)
                    return jnp.any((near <= 0.0) & ~hit)

            hit = loop_world(excess, arrays, hit, flagged, stop=settled, visit=visit)
    if placed.capsule_a.shape[1]:
        a, b, r = _points(placed.capsule_a), _points(placed.capsule_b), placed.capsule_radius
        for distance, arrays, scale_of in _capsule_kinds(world):

            def exact(obstacle, j, distance=distance, scale_of=scale_of):
                return distance(a, b, r, obstacle) - margin - tolerance(scale_of(obstacle))

            hit = loop_world(exact, arrays, hit, flagged, stop=settled, chunk=CAPSULE_CHUNK)
    return _self_verdict(placed, pairs, margin, hit, tolerance(0.0), settled)


def _self_verdict(
    placed: Placed, pairs: SelfPairs | None, margin: Array, hit: Array, tol: Array, settled
) -> Array:
    """``hit`` or a self pair that flags a collision (squared tests for sphere pairs, exact
    distances with a capsule)."""
    if pairs is None or not pairs.link_pairs:
        return hit
    s, s_r = placed.spheres, placed.sphere_radius
    c_a, c_b, c_r = placed.capsule_a, placed.capsule_b, placed.capsule_radius
    reach = 2.0 * (jnp.max(s_r) if s_r.size else 0.0) + jnp.maximum(margin, 0.0)
    slack = tol * (2.0 * reach + tol)

    def ss(i: Array, j: Array) -> Array:
        d2 = sum((s[k, i] - s[k, j]) ** 2 for k in range(3))
        return tree_min(d2 - _threshold(s_r[i] + s_r[j] + margin))

    def sc(i: Array, j: Array) -> Array:
        a, b = _points(c_a[:, j]), _points(c_b[:, j])
        return tree_min(sd.sphere_capsule(_points(s[:, i]), s_r[i], a, b, c_r[j]) - margin)

    def cc(i: Array, j: Array) -> Array:
        a, b = _points(c_a[:, i]), _points(c_b[:, i])
        d = sd.capsule_capsule(a, b, c_r[i], _points(c_a[:, j]), _points(c_b[:, j]), c_r[j])
        return tree_min(d - margin)

    for test, (first, second), bound in (
        (ss, pairs.ss, slack),
        (sc, pairs.sc, tol),
        (cc, pairs.cc, tol),
    ):
        hit = loop_pairs(
            test,
            first,
            second,
            hit,
            lambda hit, tags, value, bound=bound: hit | (value <= bound),  # type: ignore[misc]
            settled,
        )
    return hit


def collides_kernel(
    robot: CollisionRobot,
    body: Body,
    pairs: SelfPairs,
    q: Array,
    world: World,
    margin: ArrayLike = 0.0,
    frame_bounds: bool = False,
) -> Verdict:
    """The pure kernel of ``collides`` (traceable, any leading batch axes of ``q``), chunk by
    chunk (``VERDICT_CHUNK`` configurations). A world with leading batch axes goes through
    ``check_kernel``. ``frame_bounds`` (static) passes over the obstacles that no frame's
    bound of its spheres comes near (module docstring): the same verdicts."""
    dtype = q.dtype
    batch = q.shape[:-1]
    body, world = body.astype(dtype), world.astype(dtype)
    if world_batched(world) or math.prod(batch) == 0 or not (body.num_spheres + body.num_capsules):
        exact = check_kernel(robot, body, pairs, q, world, margin)
        return Verdict(exact.collides, exact.status)
    margin = jnp.asarray(margin, dtype)
    self_pairs = pairs if pairs.link_pairs else None
    groups = culled.groups_of(body, self_pairs)
    bounded = frame_bounds and body.num_spheres > 0

    def one(q: Array) -> Verdict:
        valid = all_finite(q)
        q_safe = jnp.where(valid[..., None], q, jnp.zeros((), dtype))
        placed = robot.placeable(q_safe)
        if groups is None and bounded:
            at, bounds = place_bounded(robot, body, q_safe)
            hit = verdict_rows(at, world, self_pairs, margin, ~(valid & placed), bounds)
        elif groups is None:
            hit = verdict_rows(
                place(robot, body, q_safe), world, self_pairs, margin, ~(valid & placed)
            )
        else:
            hit = culled.verdict_rows(
                robot, body, groups, q_safe, world, margin, ~(valid & placed),
                _sphere_kinds(world), TOLERANCE,
            )  # fmt: skip
        status = jnp.where(hit, Status.COLLISION, Status.OK)
        status = jnp.where(~placed, Status.UNREACHABLE, status)
        status = jnp.where(~valid, Status.INVALID_INPUT, status).astype(jnp.int8)
        return Verdict(hit, status)

    flat = q.reshape((-1, q.shape[-1]))
    out = map_chunks(one, flat, flat.shape[:-1], VERDICT_CHUNK)
    return jax.tree.map(lambda x: x.reshape(batch), out)


# Fewest configurations per host-thread part (docs/performance.md)
VERDICT_MIN_PART = 2048
_collides_jit = Kernel(
    collides_kernel,
    static=("frame_bounds",),
    batched={"q": 1},
    policy=Policy(
        pad=True, threads=True, min_part=VERDICT_MIN_PART, compiler_options=COMPILER_OPTIONS
    ),
)


# Single states asked again and again (a planner's loop): a compiled handle each
HOT_STATES = HotQueries()


def _hot_state(robot: Any, q: Any, world: Any, margin: Any, self_collision: Any) -> Any:
    """The compiled handle that answers this single configuration's query once the same
    query (the same robot and world objects, margin, ``self_collision``, shape and dtype of
    ``q``) was asked ``_batching.HOT_AFTER`` times (``HotQueries``), else None. Only an array
    ``q`` of one configuration in its canonical floating dtype and a plain margin take this
    lane; arguments the handle refuses leave the query on the usual path, which says what
    is wrong (as ``jaxkin.ik``'s hot queries do)."""
    if not isinstance(q, np.ndarray | jax.Array) or isinstance(q, jax.core.Tracer):
        return None  # a list, or inside a caller's jit
    if q.ndim not in (1, 2) or q.size != q.shape[-1]:
        return None  # not one configuration
    if q.shape[-1] != getattr(robot, "n_joints", None):
        return None  # the usual path says what is wrong
    if type(margin) not in (float, int) or type(self_collision) is not bool:
        return None
    dtype = q.dtype
    if dtype.kind != "f" or dtype != jax.dtypes.canonicalize_dtype(dtype):
        return None
    x64 = jax.config.jax_enable_x64  # type: ignore[attr-defined]  # jax's Config types no options
    key = (id(robot), id(world), q.shape, dtype.str, float(margin), self_collision, x64)

    def build() -> tuple[Any, Handle] | None:
        if any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(world)):
            return None  # a world traced by a caller's jit has no handle
        try:
            handle = compiled(
                collides,
                robot,
                world,
                batch=q.shape[:-1],
                margin=float(margin),
                self_collision=self_collision,
                dtype=dtype,
            )
        except ValueError:
            return None  # bad arguments: the usual path says what is wrong
        return world, handle

    entry = HOT_STATES.get(key, robot, build)
    if entry is None or entry[0] is not world:  # another world under a reused id: the usual path
        return None
    return entry[1]


def collides(
    robot: CollisionRobot,
    q: ArrayLike,
    world: World,
    margin: float = 0.0,
    self_collision: bool = True,
) -> Verdict:
    """Per configuration ``q`` ``(..., n_joints)``: does ``robot`` touch ``world`` or itself
    (module docstring)? The verdict of ``check(robot, q, world, margin).collides`` without
    the clearance or its pair: the arguments and errors of ``check``; a ``Verdict`` with
    shapes ``(...)``. A concrete batch of at least ``2 VERDICT_MIN_PART`` configurations
    runs as one part per host thread (``jaxkin.set_num_threads``). The same single
    configuration's query asked again and again (a planner's loop) is answered by a compiled
    handle of its own after ``_batching.HOT_AFTER`` calls (``jaxkin.compiled``)."""
    hot = _hot_state(robot, q, world, margin, self_collision)
    if hot is not None:
        return hot(q)
    robot, body, pairs, q, world, margin = checked_arguments(
        robot, q, world, margin, self_collision
    )
    batch = q.shape[:-1]
    pad = single(batch) and not world.batched()
    return _collides_jit(robot, body, pairs, q, world, margin, batch=batch, pad=pad)


@builds(collides)
def _collides_handle(
    robot: Any,
    world: World,
    batch: Any = 1,
    margin: float = 0.0,
    self_collision: bool = True,
    dtype: Any = None,
) -> Handle:
    """``compiled(collision.collides, robot, world, batch=1, margin=0.0,
    self_collision=True, dtype=None)``: ``handle(q)`` for configurations ``(*batch,
    n_joints)``, the ``Verdict`` of ``collides`` on the same input (the arguments as for
    ``check``'s handle; ``handle.rebound(world)`` for another world of the same layout)."""
    setup = handle_setup(robot, world, batch, margin, self_collision, dtype)
    return setup.configuration_handle(collides_kernel)
