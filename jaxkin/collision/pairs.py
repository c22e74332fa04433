"""Self-collision: which link pairs to check, SRDF ``<disable_collisions>``, and distances.

The pairs checked are all pairs of links that carry geometry, minus adjacent links, minus the
pairs an SRDF disables (MoveIt's format: ``<disable_collisions link1=".." link2=".."
reason=".."/>``). Two links are adjacent when one is the other's parent in the kinematic tree,
looking through links without geometry (MoveIt's rule: the Panda's hand is adjacent to link 7
across the geometry-less flange link 8), where links joined by fixed joints count as one rigid
body (``adjacent_links``): a link fixed to another is adjacent to that link's neighbours.

``SelfPairs`` turns link pairs into the primitive pairs (sphere-sphere, sphere-capsule,
capsule-capsule) between them; ``self_distances`` evaluates them for placed primitives and
reduces them per link pair. ``propose_disabled`` samples configurations, as MoveIt's setup
assistant does, and proposes the pairs never or always in collision.
"""

from __future__ import annotations

import dataclasses
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from .._execute import Kernel
from . import distance as sd
from .body import Body
from .primitives import Capsules, Spheres

__all__ = [
    "SelfPairs",
    "adjacent_links",
    "propose_disabled",
    "read_srdf_disabled",
    "self_collision_link_pairs",
    "self_distances",
]


def read_srdf_disabled(source: str | os.PathLike) -> tuple[tuple[str, str, str], ...]:
    """The ``(link1, link2, reason)`` triples of an SRDF's ``<disable_collisions>`` (path or
    XML text)."""
    text = str(source)
    try:
        if text.lstrip().startswith("<"):
            root = ET.fromstring(text)
        else:
            if not Path(source).is_file():
                raise ValueError(f"source: no such SRDF file {text!r}")
            root = ET.parse(source).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"source: not well-formed SRDF XML ({exc})") from None
    out = []
    for element in root.iter("disable_collisions"):
        a, b = element.get("link1"), element.get("link2")
        if not a or not b:
            raise ValueError("source: a <disable_collisions> element lacks link1 or link2")
        out.append((a, b, element.get("reason", "")))
    return tuple(out)


def _links_with_geometry(body: Body) -> set[int]:
    return set(body.sphere_link) | set(body.capsule_link)


def adjacent_links(
    body: Body, joints: Iterable[tuple[str, str, str]], through_fixed: bool = True
) -> set[frozenset[str]]:
    """Adjacent pairs among the links with geometry, in the tree of ``joints`` (``(parent,
    child, type)``).

    Links joined by ``fixed`` joints move as one rigid body (with ``through_fixed``): every
    two links with geometry within one rigid body are adjacent, and so are those of a body
    and of its parent body across a moving joint, looking through bodies without geometry.
    A link fixed to the last link of an arm (the UR5's ``ee_link`` on ``wrist_3_link``) is
    then adjacent to the link before it (``wrist_2_link``), as its own link is: their covers
    touch at the joint in every configuration, so checking them would report every
    configuration in collision. With ``through_fixed=False``, only parent and child links
    (looking through links without geometry): the pairs MoveIt's setup assistant marks
    "Adjacent" in an SRDF (it finds the others, e.g. the Panda's hand and link 6, from
    samples and marks them "Never" or "Default").
    """
    index = {name: i for i, name in enumerate(body.links)}
    parent: dict[str, str] = {}
    kind: dict[str, str] = {}
    for p, c, t in joints:
        if p not in index or c not in index:
            raise ValueError(f"joints: link {p!r} or {c!r} is not in the body's links")
        parent[c], kind[c] = p, t

    def rigid_root(link: str) -> str:
        """The first link of ``link``'s rigid body (up through fixed joints)."""
        while through_fixed and kind.get(link) == "fixed" and link in parent:
            link = parent[link]
        return link

    members: dict[str, set[str]] = {}  # rigid body (its root) -> its links with geometry
    for i in _links_with_geometry(body):
        members.setdefault(rigid_root(body.links[i]), set()).add(body.links[i])
    pairs = set()
    for root, own in members.items():
        pairs |= {frozenset((a, b)) for a in own for b in own if a != b}
        up = parent.get(root)
        while up is not None and rigid_root(up) not in members:
            up = parent.get(rigid_root(up))
        if up is not None:
            pairs |= {frozenset((a, b)) for a in own for b in members[rigid_root(up)]}
    return pairs


def self_collision_link_pairs(
    body: Body,
    joints: Iterable[tuple[str, str, str]],
    disabled: Iterable[tuple[str, ...]] = (),
) -> tuple[tuple[int, int], ...]:
    """Link index pairs ``(i, j)``, ``i < j``, to check: links with geometry, minus adjacent
    pairs (``adjacent_links``: fixed joints join rigid bodies), minus ``disabled`` (e.g.
    ``read_srdf_disabled(...)``; names not in the body raise)."""
    off = adjacent_links(body, joints)
    for entry in disabled:
        a, b = entry[0], entry[1]
        if a not in body.links or b not in body.links:
            raise ValueError(f"disabled: link {a!r} or {b!r} is not in the body's links")
        off.add(frozenset((a, b)))
    geo = sorted(_links_with_geometry(body))
    return tuple(
        (i, j)
        for k, i in enumerate(geo)
        for j in geo[k + 1 :]
        if frozenset((body.links[i], body.links[j])) not in off
    )


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class SelfPairs:
    """Primitive pairs between the checked link pairs (static index tuples).

    ``link_pairs[k] = (i, j)``; ``ss``: sphere-sphere pairs as two index tuples into the body's
    spheres, ``sc``: (sphere, capsule), ``cc``: (capsule, capsule); ``*_pair``: for each
    primitive pair, its link pair ``k``.
    """

    link_pairs: tuple[tuple[int, int], ...] = dataclasses.field(metadata={"static": True})
    ss: tuple[tuple[int, ...], tuple[int, ...]] = dataclasses.field(metadata={"static": True})
    sc: tuple[tuple[int, ...], tuple[int, ...]] = dataclasses.field(metadata={"static": True})
    cc: tuple[tuple[int, ...], tuple[int, ...]] = dataclasses.field(metadata={"static": True})
    ss_pair: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    sc_pair: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    cc_pair: tuple[int, ...] = dataclasses.field(metadata={"static": True})

    @classmethod
    def create(cls, body: Body, link_pairs: Iterable[tuple[int, int]]) -> SelfPairs:
        link_pairs = tuple((int(i), int(j)) for i, j in link_pairs)
        s_link, c_link = np.asarray(body.sphere_link, int), np.asarray(body.capsule_link, int)
        ss: tuple[list[int], list[int]] = ([], [])
        sc: tuple[list[int], list[int]] = ([], [])
        cc: tuple[list[int], list[int]] = ([], [])
        ssp: list[int] = []
        scp: list[int] = []
        ccp: list[int] = []

        def add(target, tag, which, left, right, k):
            for p in np.flatnonzero(left):
                for q in np.flatnonzero(right):
                    target[0].append(int(p))
                    target[1].append(int(q))
                    tag.append(k)

        for k, (i, j) in enumerate(link_pairs):
            add(ss, ssp, "ss", s_link == i, s_link == j, k)
            add(sc, scp, "sc", s_link == i, c_link == j, k)
            add(sc, scp, "sc", s_link == j, c_link == i, k)
            add(cc, ccp, "cc", c_link == i, c_link == j, k)
        as_tuples = lambda pair: (tuple(pair[0]), tuple(pair[1]))  # noqa: E731
        return cls(
            link_pairs,
            as_tuples(ss),
            as_tuples(sc),
            as_tuples(cc),
            tuple(ssp),
            tuple(scp),
            tuple(ccp),
        )

    @property
    def num_primitive_pairs(self) -> int:
        return len(self.ss_pair) + len(self.sc_pair) + len(self.cc_pair)


def _primitive_pair_distances(spheres: Spheres, capsules: Capsules, pairs: SelfPairs) -> jax.Array:
    """Signed distances of every primitive pair, ``(..., P)`` in the order ss, sc, cc."""
    parts = []
    idx = lambda t: np.asarray(t, dtype=np.int32)  # noqa: E731
    if pairs.ss_pair:
        i, j = idx(pairs.ss[0]), idx(pairs.ss[1])
        parts.append(
            sd.sphere_sphere(
                spheres.center[..., i, :],
                spheres.radius[..., i],
                spheres.center[..., j, :],
                spheres.radius[..., j],
            )
        )
    if pairs.sc_pair:
        i, j = idx(pairs.sc[0]), idx(pairs.sc[1])
        parts.append(
            sd.sphere_capsule(
                spheres.center[..., i, :],
                spheres.radius[..., i],
                capsules.a[..., j, :],
                capsules.b[..., j, :],
                capsules.radius[..., j],
            )
        )
    if pairs.cc_pair:
        i, j = idx(pairs.cc[0]), idx(pairs.cc[1])
        parts.append(
            sd.capsule_capsule(
                capsules.a[..., i, :],
                capsules.b[..., i, :],
                capsules.radius[..., i],
                capsules.a[..., j, :],
                capsules.b[..., j, :],
                capsules.radius[..., j],
            )
        )
    if not parts:
        batch = spheres.radius.shape[:-1]
        return jnp.zeros((*batch, 0), spheres.radius.dtype)
    return jnp.concatenate(parts, axis=-1)


def self_distances(spheres: Spheres, capsules: Capsules, pairs: SelfPairs) -> jax.Array:
    """The smallest signed distance of each checked link pair, ``(..., len(link_pairs))``.

    ``spheres``, ``capsules``: the body's primitives placed in the world (``Body.place``). A
    link pair without primitives on both sides gets the dtype's largest finite value.
    """
    d = _primitive_pair_distances(spheres, capsules, pairs)
    tag = np.asarray(pairs.ss_pair + pairs.sc_pair + pairs.cc_pair, dtype=np.int32)
    n = len(pairs.link_pairs)
    big = jnp.finfo(d.dtype).max
    # one column per link pair: the minimum over its primitive pairs (a masked min, P x n)
    member = np.zeros((len(tag), n), dtype=bool)
    member[np.arange(len(tag)), tag] = True
    return jnp.min(jnp.where(member, d[..., :, None], big), axis=-2, initial=big)


def propose_disabled(
    body: Body,
    link_poses: Callable[[jax.Array], jax.Array],
    samples: ArrayLike,
    link_pairs: Iterable[tuple[int, int]] | None = None,
    chunk: int = 4096,
) -> dict[str, list[tuple[str, str]]]:
    """Link pairs to disable from sampled configurations (MoveIt setup assistant's rule).

    Args:
        body: the robot's body.
        link_poses: maps configurations ``(n, dof)`` to link poses ``(n, len(links), 4, 4)``.
        samples: configurations ``(n, dof)`` (e.g. uniform within the joint limits).
        link_pairs: the pairs to test (default: every pair of links with geometry).
        chunk: configurations per evaluation.

    Returns:
        ``{"never": [...], "always": [...]}``: name pairs never in collision (signed distance
        > 0 in every sample) and always in collision (<= 0 in every sample).
    """
    configurations = np.asarray(samples)
    if configurations.ndim != 2 or len(configurations) == 0:
        raise ValueError(
            f"samples: expected shape (n, dof) with n >= 1, got {configurations.shape}"
        )
    if link_pairs is None:
        geo = sorted(_links_with_geometry(body))
        link_pairs = [(i, j) for k, i in enumerate(geo) for j in geo[k + 1 :]]
    pairs = SelfPairs.create(body, link_pairs)

    def extremes_of(q):
        spheres, capsules = body.place(link_poses(q))
        d = self_distances(spheres, capsules, pairs)
        return jnp.min(d, axis=0), jnp.max(d, axis=0)

    extremes = Kernel(extremes_of)  # one program for this call's chunks

    lows, highs = [], []
    for start in range(0, len(configurations), chunk):
        part = configurations[start : start + chunk]
        if len(part) < chunk and start > 0:  # keep one shape: pad with the first sample
            part = np.concatenate([part, np.repeat(part[:1], chunk - len(part), axis=0)])
        a, b = (np.asarray(x) for x in extremes(jnp.asarray(part)))
        lows.append(a)
        highs.append(b)
    lo, hi = np.min(lows, axis=0), np.max(highs, axis=0)
    names = [(body.links[i], body.links[j]) for i, j in pairs.link_pairs]
    return {
        "never": [n for n, d in zip(names, lo, strict=True) if d > 0],
        "always": [n for n, d in zip(names, hi, strict=True) if d <= 0],
    }
