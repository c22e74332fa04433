"""The hot single query's lane in ``jaxkin.ik`` / ``jaxkin.fk``: found before any input work,
it still refuses what the usual path refuses, and the ways of asking for the default options
share one program with the batched path's results."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import delta, scara
from jaxkin._execute import pipeline
from jaxkin.status import Status
from tests.helpers import compilations


def test_the_hot_lane_refuses_what_the_usual_path_refuses(hot_after_two):
    """Once a robot's single query is hot, calls that differ from it in the options' class,
    the branch, the robot or the target's shape still raise the usual ValueError, however
    often they are repeated (the lane's key holds what was checked when it was built)."""
    robot = scara.Scara.paper()
    target = jnp.asarray([60.0, 70.0, 40.0])
    for _ in range(3):
        jaxkin.ik(robot, target)
        jaxkin.fk(robot, target)
    assert len(pipeline.HOT.programs) == 2
    bad_calls = {
        "options": lambda: jaxkin.ik(robot, target, options=delta.Delta.IKOptions()),
        "fk options": lambda: jaxkin.fk(robot, target, options=scara.Scara.IKOptions()),
        "branch": lambda: jaxkin.ik(robot, target, branch=7),
        "robot": lambda: jaxkin.ik(object(), target),
        "fk robot": lambda: jaxkin.fk("scara", target),
        "shape": lambda: jaxkin.ik(robot, jnp.ones(2)),
        "option name": lambda: jaxkin.ik(robot, target, tolerance=1.0),
    }
    for call in bad_calls.values():
        for _ in range(3):
            with pytest.raises(ValueError):
                call()
    assert int(jaxkin.ik(robot, target).status) == Status.OK


def test_default_options_given_or_not_share_one_program(hot_after_two):
    """``ik(robot, t)``, ``ik(robot, t, options=IKOptions())``, ``ik(robot, t,
    method="analytic")`` and ``scara.ik(robot, t)`` each get the hot program (one compiled
    program between them) with the batched path's statuses and values (4 ulp of the robot's
    size: its geometry is folded into the program), for a reachable and an unreachable
    target, from a JAX and a NumPy array."""
    robot = scara.Scara.paper()
    targets = np.array([[60.0, 70.0, 40.0], [500.0, 0.0, 40.0]])
    batched = jaxkin.ik(robot, jnp.asarray(targets))
    tol = 4 * np.finfo(np.float64).eps * float(robot.length_scale())
    wants = [np.asarray(leaf) for leaf in jax.tree.leaves(batched)]
    statuses = [int(s) for s in batched.status]
    ways = (
        lambda t: jaxkin.ik(robot, t),
        lambda t: jaxkin.ik(robot, t, options=scara.Scara.IKOptions()),
        lambda t: jaxkin.ik(robot, t, method="analytic"),
        lambda t: scara.ik(robot, t),
    )
    for way in ways:
        for _ in range(3):
            way(jnp.asarray(targets[0]))
    assert len(pipeline.HOT.by_value) == 1
    with compilations() as count:
        for i in range(2):
            for way in ways:
                for target in (jnp.asarray(targets[i]), targets[i]):
                    for _ in range(3):
                        got = way(target)
                    assert type(got) is type(batched)
                    for leaf, want in zip(jax.tree.leaves(got), wants, strict=True):
                        assert isinstance(leaf, jax.Array) and leaf.dtype == want.dtype
                        np.testing.assert_allclose(
                            np.asarray(leaf, float), np.asarray(want[i], float), rtol=0, atol=tol
                        )
                    assert int(got.status) == statuses[i]
    assert count.n == 0
    # hot entries: default options as None, as an instance (twice: equal values), with the
    # branch given (scara.ik), each for a JAX and a NumPy input
    assert len(pipeline.HOT.programs) == 6
    assert statuses == [Status.OK, Status.UNREACHABLE]
