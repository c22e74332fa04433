"""Geometry validation: every field of every geometry, by constructor and by factory.

A value that is not a finite real number of the right shape (or not positive where a length)
raises a ``ValueError`` that names the field; ``True``, strings, ``None`` and complex values
are refused. JAX's own rebuilding of a geometry (pytree unflatten: gradients, tracers) is not
validated, so a gradient with respect to a length may be negative.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import delta, scara, serial
from jaxkin._geometry import BOUND, LENGTH, NONNEGATIVE, REAL

GEOMETRIES = {
    "Scara": (scara.Scara, dict(l_oa=150.0, l_ab=80.0, l_bc=50.0)),
    "Delta": (delta.Delta, dict(r_base=7.0, r_platform=2.5, l_arm=15.5, l_rod=30.0)),
    "Planar2R": (serial.Planar2R, dict(l1=1.0, l2=0.7)),
    "Planar3R": (serial.Planar3R, dict(l1=1.0, l2=0.7, l3=0.3)),
    "Anthropomorphic": (serial.Anthropomorphic, dict(l1=0.3, l2=0.25, l3=0.2)),
    "Cylindrical": (serial.Cylindrical, dict(h=0.5)),
    "Spherical": (serial.Spherical, dict(h=0.5)),
    "Puma560": (serial.Puma560, {}),
    "Stanford": (serial.Stanford, dict(d1=0.4, a2=0.3)),
    "DHTable": (serial.DHTable, dict(a=[0.0, 0.4], alpha=[1.5, 0.0], d=[0.5, 0.0])),
    "Chain": (
        serial.Chain,
        dict(
            screws=[[0.0, 0, 1, 0, 0, 0], [0.0, 0, 0, 0, 0, 1]],
            home=np.eye(4),
            multiplier=[1.0, 1.0],
            offset=[0.0, 0.0],
            lower=[-1.0, -np.inf],
            upper=[1.0, 0.5],
            velocity=[2.0, np.inf],
            follows=(0, 1),
            joint_kinds=("revolute", "prismatic"),
        ),
    ),
    "JointLimits": (jaxkin.JointLimits, dict(lower=[-1.0, -2.0], upper=[1.0, 2.0])),
}

REFUSED_ALWAYS = [True, "1.0", None, 1 + 2j, np.nan, [1.0, "x"]]


def _numeric_fields(cls):
    return [f for f in dataclasses.fields(cls) if "kind" in f.metadata]


def _cases():
    for name, (cls, _) in GEOMETRIES.items():
        for field in _numeric_fields(cls):
            yield pytest.param(name, field.name, id=f"{name}.{field.name}")


@pytest.mark.parametrize(("name", "field"), list(_cases()))
def test_every_field_is_validated_and_named(name, field):
    cls, kwargs = GEOMETRIES[name]
    meta = next(f for f in dataclasses.fields(cls) if f.name == field).metadata
    good = kwargs.get(field, next(f for f in dataclasses.fields(cls) if f.name == field).default)
    shape = np.shape(good)
    optional = next(f for f in dataclasses.fields(cls) if f.name == field).default is None
    bad_values = [v for v in REFUSED_ALWAYS if not (optional and v is None)]  # None: a default
    if meta["kind"] in (LENGTH, NONNEGATIVE, REAL):
        bad_values.append(np.full(shape, np.inf) if shape else np.inf)
    if meta["kind"] == LENGTH:
        bad_values += [np.zeros(shape), -np.ones(shape)]
    if meta["kind"] == NONNEGATIVE:
        bad_values.append(-1.0)
    if meta["shape"] == ():
        bad_values.append(np.ones(2))  # a scalar field given an array
    for bad in bad_values:
        with pytest.raises(ValueError, match=rf"{name}\.{field}"):
            cls(**{**kwargs, field: bad})
    cls(**kwargs)  # the good values pass


def test_factories_validate_like_constructors():
    with pytest.raises(ValueError, match=r"Scara\.l_ab"):
        scara.Scara.create(150.0, -80.0, 50.0)
    with pytest.raises(ValueError, match=r"Delta\.theta_min"):
        delta.Delta.paper().with_limits(1.0, 0.5)
    with pytest.raises(ValueError, match=r"Delta\.l_rod"):
        delta.Delta.paper().replace(l_rod=True)
    with pytest.raises(ValueError, match=r"DHTable\.alpha"):
        serial.DHTable.create(a=[0.0, 1.0], alpha=[0.0], d=[0.0, 0.0])
    with pytest.raises(ValueError, match=r"DHTable\.joint_types"):
        serial.DHTable.create(a=[0.0], alpha=[0.0], d=[0.0], joint_types="X")
    with pytest.raises(ValueError, match=r"Chain\.screws"):
        serial.Chain.create([[0.0, 0, 2, 0, 0, 0]], np.eye(4))
    with pytest.raises(ValueError, match=r"Chain\.home"):
        serial.Chain.create([[0.0, 0, 1, 0, 0, 0]], 2 * np.eye(4))
    with pytest.raises(ValueError, match=r"^screws: rows"):
        serial.from_screws([[0.0, 0, 2, 0, 0, 0]], np.eye(4))
    with pytest.raises(ValueError, match=r"frame must be one of"):
        serial.from_screws([[0.0, 0, 1, 0, 0, 0]], np.eye(4), frame="tool")
    with pytest.raises(ValueError, match=r"JointLimits"):
        jaxkin.JointLimits([1.0], [0.0])
    with pytest.raises(ValueError, match=r"limits\['theta1'\]"):
        scara.Scara(150.0, 80.0, 50.0, limits={"theta1": (1.0, "x")})
    with pytest.raises(ValueError, match=r"unknown joint"):
        scara.Scara(150.0, 80.0, 50.0, limits={"elbow": (0.0, 1.0)})


def test_bound_fields_accept_infinity():
    assert BOUND == dataclasses.fields(delta.Delta)[4].metadata["kind"]
    robot = delta.Delta(7.0, 2.5, 15.5, 30.0, -np.inf, 1.0)
    assert robot.theta_min == -np.inf


def test_jax_rebuilds_geometries_without_validation():
    """A gradient with respect to the lengths is a Scara holding any values (negative ones
    too), built by the pytree unflatten, not the constructor."""
    robot = scara.Scara.paper()
    target = jnp.array([[100.0, 20.0, 60.0]])

    def loss(r):
        return jnp.sum(scara.ik(r, target).q.p[..., 0])

    grad = jax.grad(loss)(robot)
    assert isinstance(grad, scara.Scara) and np.isfinite(float(grad.l_ab))
    negative = jax.tree.map(lambda x: -jnp.abs(jnp.asarray(x)) - 1.0, robot)
    assert float(negative.l_ab) < 0
    traced = jax.jit(lambda r: scara.Scara(r.l_oa, r.l_ab * 2, r.l_bc).l_ab)(robot)
    assert float(traced) == 160.0


def aligned(value, alignment=4096):
    """``value`` as a float64 NumPy array whose buffer starts on an ``alignment`` boundary,
    where ``jax.device_put`` may take it without a copy (CPU): an unaligned buffer is always
    copied, so an aliasing would show only now and then."""
    value = np.asarray(value, dtype=float)
    raw = np.empty(value.nbytes + alignment, np.uint8)
    start = -raw.ctypes.data % alignment
    out = raw[start : start + value.nbytes].view(np.float64).reshape(value.shape)
    out[...] = value
    return out


@pytest.mark.parametrize("name", GEOMETRIES)
def test_a_geometry_keeps_its_own_copy_of_the_callers_arrays(name):
    """Every numeric field given as a NumPy array (aligned, so that JAX could alias it): an
    edit of those arrays after the robot is built changes none of its values (a DHTable, a
    Chain and JointLimits held the caller's buffer: editing it moved the robot)."""
    cls, kwargs = GEOMETRIES[name]
    numeric = {f.name for f in _numeric_fields(cls)}
    given = {k: aligned(v) if k in numeric else v for k, v in kwargs.items()}
    robot = cls(**given)
    before = [np.array(leaf) for leaf in jax.tree.leaves(robot)]
    for key in numeric & set(given):
        given[key][...] = given[key] * 2.0 + 1.0
    for leaf, old in zip(jax.tree.leaves(robot), before, strict=True):
        np.testing.assert_array_equal(np.asarray(leaf), old)


def test_obstacles_keep_their_own_copy_of_the_callers_arrays():
    """Collision primitives built by ``create`` and a ``World`` of primitives built by their
    plain constructor from NumPy arrays: editing the arrays afterwards moves no obstacle (the
    world held the plain primitives' buffers)."""
    from jaxkin import collision

    arrays = [aligned(x) for x in (np.zeros((2, 3)), np.ones(2), np.ones((2, 3)))]
    made = [
        collision.Spheres.create(arrays[0], arrays[1]),
        collision.Capsules.create(arrays[0], arrays[2], arrays[1]),
        collision.Boxes.create(arrays[0], arrays[2]),
        collision.HalfSpaces.create(arrays[2], arrays[1]),
        collision.World.create(
            spheres=collision.Spheres(arrays[0], arrays[1]),
            capsules=collision.Capsules(arrays[0], arrays[2], arrays[1]),
        ),
    ]
    before = [np.array(leaf) for leaf in jax.tree.leaves(made)]
    for arr in arrays:
        arr[...] = arr * 2.0 + 1.0
    for leaf, old in zip(jax.tree.leaves(made), before, strict=True):
        np.testing.assert_array_equal(np.asarray(leaf), old)
