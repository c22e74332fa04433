"""Chains from screws: the product-of-exponentials description [Pineiro] as a builder.

A chain of ``m`` joints is given by its unit screw axes (rows ``(omega, v)``: for a revolute
joint ``omega`` is the unit axis and ``v = -omega x r`` for a point ``r`` on it, plus ``h
omega`` for a screw of pitch ``h``; for a prismatic joint ``omega = 0`` and ``v`` is the unit
direction) and its home configuration ``M`` (the tool pose at ``q = 0``), in one of two frames
([Pineiro], "Introducción")::

    space:  T(q) = exp([S_1] q_1) ... exp([S_m] q_m) M          (S_i in the base frame {s})
    body:   T(q) = M exp([B_1] q_1) ... exp([B_m] q_m)          (B_i in the tool frame {b})

with ``S_i = Ad(M) B_i``. ``from_screws`` builds the ``serial.Chain`` of either form (body
screws are converted to base-frame screws, so the chain's products differ from the body form's
by rounding only); its kinematics are written in ``serial._kinematics``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from jax.typing import ArrayLike

from .. import _validate
from .chain import Chain, check_screws_and_home

__all__ = ["FRAMES", "from_screws"]

FRAMES = ("space", "body")


def from_screws(
    screws: ArrayLike,
    home: ArrayLike,
    frame: str = "space",
    joint_names: Sequence[str] | None = None,
    joint_kinds: Sequence[str] | None = None,
    lower: ArrayLike | None = None,
    upper: ArrayLike | None = None,
    velocity: ArrayLike | None = None,
    base_link: str = "",
    tip_link: str = "",
    target: str = "pose",
) -> Chain:
    """The ``serial.Chain`` of unit screws ``(m, 6)`` and a home pose (module docstring).

    Args:
        screws: unit screw axes, one row per joint ``(omega, v)``, in ``frame``; a row is a
            unit screw when ``|omega| = 1`` (revolute) or ``omega = 0`` and ``|v| = 1``
            (prismatic), within 1e-6.
        home: the tool pose at ``q = 0`` (``M``), a rigid ``(4, 4)`` transform.
        frame: ``'space'`` (``S_i``, base frame) or ``'body'`` (``B_i``, home tool frame).
        joint_names, joint_kinds, lower, upper, velocity, base_link, tip_link, target: as
            ``Chain.create`` (``target="point"``: position-only targets).

    Raises:
        ValueError: a bad ``frame``, screws that are not unit screws, a ``home`` that is not
            rigid (naming ``screws`` / ``home``), or a malformed name, kind or limit.
    """
    frame = _validate.choice(frame, "frame", FRAMES)
    check_screws_and_home(screws, home)
    rows = np.asarray(screws, dtype=float)
    pose = np.asarray(home, dtype=float)
    if frame == "body":  # S_i = Ad(M) B_i = (R w, p x R w + R v), on the host in float64
        rot, p = pose[:3, :3], pose[:3, 3]
        w, v = rows[:, :3] @ rot.T, rows[:, 3:] @ rot.T
        rows = np.concatenate([w, np.cross(p, w) + v], axis=1)
    return Chain.create(
        rows,
        pose,
        joint_names=joint_names,
        joint_kinds=joint_kinds,
        lower=lower,
        upper=upper,
        velocity=velocity,
        base_link=base_link,
        tip_link=tip_link,
        target=target,
    )
