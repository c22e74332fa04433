"""A SCARA practical case: stations on a square plate, both elbow solutions ([UANL]).

The problem ([UANL], "Caso práctico"). A SCARA robot has a column
``l1 = 3 m`` (the height of the arm plane above the floor, ``l_oa`` in jaxkin), an arm
``l2 = 3 m`` (``l_ab``) and a forearm ``l3 = 2 m`` (``l_bc``). Its tool point (TCP) must visit
each corner and the centre of a horizontal square plate 2 m wide, lying at height 2 m and set
1 m off both the x and y axes. So the plate covers ``[1, 3] x [1, 3]`` m in the plane ``z = 2``
m and the five stations are::

    corner 1 (1, 1, 2)   corner 2 (3, 1, 2)   corner 3 (3, 3, 2)   corner 4 (1, 3, 2)
    centre   (2, 2, 2)

Geometry. The arm works in the horizontal plane z = l1 = 3 m; the prismatic joint lowers the
tool by ``q3 = l1 - Pz = 1 m`` at every station ([UANL]: q3 positive downward, Pz = l1 - q3;
this is [Noriega, eq. 14], l3 = z_A - z_D). In the plan view the arm and forearm form a
triangle with the shoulder-to-TCP distance ``r = sqrt(Px^2 + Py^2)``: every station has
``|l2 - l3| = 1 <= r <= l2 + l3 = 5`` (r from 1.41 m at corner 1 to 4.24 m at corner 3), so
each is reachable with two mirror-image elbows, reflected across the line from the shoulder
to the TCP. Corner 1 is closest to the inner boundary r = 1 (the arm almost folded back).

Joint conventions printed here are [UANL]'s: q1 the arm's angle from +x, wrapped to
(-180, 180] degrees; q2 the usual relative elbow angle, from the arm to the forearm,
counter-clockwise positive (= ``-theta2`` of [Noriega, eq. 15], which jaxkin returns;
``jaxkin.scara.relative_elbow_angle`` converts); q3 in metres. jaxkin's branch +1 puts the
elbow to the left of the shoulder->TCP line (q2 < 0), branch -1 to the right (q2 > 0).

Check. The source prints the table's header (Estación, Px, Py, Pz, q1, q2, q3; Esquina 1-4,
Centro) without values, so there is nothing printed to compare with. Instead the script
recomputes every row with the source's own closed form ([UANL, eqs. 36-37]:
``cos beta = (l2^2 + r^2 - l3^2) / (2 l2 r)``, ``cos phi = (l2^2 + l3^2 - r^2) / (2 l2 l3)``,
``q1 = atan2(Py, Px) -/+ beta``, ``q2 = +/-(180 deg - phi)``, ``q3 = l1 - Pz``) and the forward
kinematics, and prints the largest disagreement (it is at rounding level).

Run: ``jaxkin demo scara-practical-case`` or ``python examples/scara_practical_case.py``.
"""

from __future__ import annotations

import argparse
import math

import jax
import numpy as np

from jaxkin import Status, scara

# Examples may set global config (the library never does): float64 for table-grade values.
jax.config.update("jax_enable_x64", True)

L1, L2, L3 = 3.0, 3.0, 2.0  # column, arm, forearm (m)
PLATE_Z = 2.0
STATIONS = {
    "corner 1": (1.0, 1.0),
    "corner 2": (3.0, 1.0),
    "corner 3": (3.0, 3.0),
    "corner 4": (1.0, 3.0),
    "centre": (2.0, 2.0),
}


def closed_form(px: float, py: float, pz: float, elbow_sign: int) -> tuple[float, ...]:
    """[UANL, eqs. 36-37] (degrees): elbow_sign = +1 for q2 > 0, -1 for q2 < 0."""
    r = math.hypot(px, py)
    alpha = math.atan2(py, px)
    beta = math.acos((L2**2 + r**2 - L3**2) / (2 * L2 * r))
    phi = math.acos((L2**2 + L3**2 - r**2) / (2 * L2 * L3))
    q1 = alpha - elbow_sign * beta
    q2 = elbow_sign * (math.pi - phi)
    return math.degrees(q1), math.degrees(q2), L1 - pz


def wrap(angle: np.ndarray) -> np.ndarray:
    """Wrap angles (rad) to (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", help="accepted for uniformity: this example writes nothing")
    parser.parse_args(argv)
    robot = scara.Scara(L1, L2, L3)
    names = list(STATIONS)
    d = np.array([[*STATIONS[n], PLATE_Z] for n in names])
    worst = 0.0
    for branch in robot.branches:
        res = scara.ik(robot, d, branch=branch)
        res.raise_if_failed()
        q1 = np.degrees(wrap(np.asarray(res.q.p[:, 0])))  # jaxkin's theta1 is unwrapped
        q2 = np.degrees(np.asarray(scara.relative_elbow_angle(res.q.p[:, 1])))
        q3 = np.asarray(res.q.p[:, 2])
        side = "left of shoulder->TCP, q2 < 0" if branch == 1 else "right of shoulder->TCP, q2 > 0"
        print(f"\nElbow solution, branch {branch:+d} ({side})")
        print(
            f"{'station':9s} {'Px':>5s} {'Py':>5s} {'Pz':>5s} {'q1 (deg)':>10s} "
            f"{'q2 (deg)':>10s} {'q3 (m)':>8s}"
        )
        for i, name in enumerate(names):
            px, py, pz = d[i]
            print(
                f"{name:9s} {px:5.2f} {py:5.2f} {pz:5.2f} {q1[i]:10.4f} {q2[i]:10.4f} {q3[i]:8.4f}"
            )
            ref = closed_form(px, py, pz, elbow_sign=-branch)
            worst = max(
                worst, *(abs(a - b) for a, b in zip((q1[i], q2[i], q3[i]), ref, strict=True))
            )
        assert np.all(np.asarray(res.status) == Status.OK)
        round_trip = np.max(np.abs(np.asarray(scara.fk(robot, res.q.p).x.p) - d))
        worst = max(worst, float(round_trip))
    print(
        f"\nlargest difference from the closed form (deg, m) and in fk(ik(P)) - P (m): {worst:.2e}"
    )
    print("(the source's table has headers only, no values to compare with)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
