"""The optimiser's obstacle and self-collision costs for a URDF chain, the body bound on the
host by ``optimize`` (no ``robot=``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jaxkin import collision, costs, optimize, paths, serial

UR5 = Path(__file__).resolve().parents[1] / "examples" / "ur5.urdf"


def test_bind_fills_the_body_once_on_the_host():
    chain = serial.from_urdf(UR5, "tool0").with_link_radius(0.04)
    term = costs.Obstacles.create(spheres=([[0.4, 0.0, 0.4]], [0.1]), self_collision=True)
    assert term.body is None and term.pairs is None
    cost = costs.bind(costs.compose((1.0, costs.acceleration), (1.0, term)), chain)
    bound = cost.data_terms[0]
    body, pairs = collision.prepare(chain, True)
    assert bound.body is body and bound.pairs is pairs and pairs.link_pairs
    assert costs.bind(bound, chain) is bound  # already bound: as it is


@pytest.mark.slow
def test_chain_optimisation_keeps_clear_of_an_obstacle():
    """A UR5 chain (capsule skeleton, radius 4 cm) swinging its base joint through a ball
    that the straight joint-space line hits: optimised with the obstacle and self-collision
    term given no robot (``optimize`` binds the chain's body on the host), every sample of
    the best path is clear of the ball by ``collision.check``; the straight line is not."""
    chain = serial.from_urdf(UR5, "tool0").with_link_radius(0.04)
    q_start = np.array([-1.0, -1.2, 1.4, 0.0, 0.0, 0.0])
    q_goal = np.array([1.0, -1.2, 1.4, 0.0, 0.0, 0.0])
    q_mid = 0.5 * (q_start + q_goal)
    tool = np.asarray(chain.link_poses(q_mid[None]))[0, -1, :3, 3]
    ball = collision.World.create(spheres=collision.Spheres.create([tool], 0.08))
    line = q_start + np.linspace(0.0, 1.0, 40)[:, None] * (q_goal - q_start)
    assert np.min(np.asarray(collision.check(chain, line, ball).clearance)) < 0.0
    term = costs.Obstacles.create(world=ball, safety=0.05, self_collision=True)
    cost = costs.compose((1.0, costs.acceleration), (1e4, term))
    guesses = paths.straight_line_guess(q_start, q_goal, 3, n_guesses=4, noise=0.3, seed=0)
    res = optimize.optimize(
        chain,
        q_start,
        q_goal,
        guesses,
        n_samples=40,
        steps=150,
        cost=cost,
        rest_to_rest=True,
        space="joint",
        controls="joint",
    )
    best = int(res.best)
    q = np.asarray(res.evaluation.q.p)[best]
    np.testing.assert_allclose(q[[0, -1]], [q_start, q_goal], atol=1e-12)
    assert np.min(np.asarray(collision.check(chain, q, ball).clearance)) > 0.0
