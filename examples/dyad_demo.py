"""Solve a batch of RRR dyads [Noriega, sec. 2] and print a short summary.

A swinging crank drives point B around a circle while A stays at the origin; for 10,000
instants and both assembly modes jaxkin returns C, the angle phi of link AC and their rates,
with a status per instant. Writes no files. Run: ``python examples/dyad_demo.py``.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxkin import Jet, Status, dyad

jax.config.update("jax_enable_x64", True)  # an application choice; the library never sets it


def crank_path(t: np.ndarray, radius: float = 1.2, omega: float = 2.0) -> Jet:
    """B(t) = (1 + r cos(w t), r sin(w t)) with exact velocity and acceleration."""
    angle = omega * t
    p = np.stack([1.0 + radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
    v = np.stack([-radius * omega * np.sin(angle), radius * omega * np.cos(angle)], axis=-1)
    return Jet.of(p, v, -(omega**2) * (p - np.array([1.0, 0.0])))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", help="accepted for uniformity: this example writes nothing")
    parser.parse_args(argv)
    t = np.linspace(0.0, np.pi, 10_000)
    a = Jet.constant(np.zeros((t.size, 2)))
    b = crank_path(t)
    l_ac, l_bc = 1.0, 1.5
    print(f"RRR dyad: l_AC = {l_ac}, l_BC = {l_bc}, B on a circle of radius 1.2 about (1, 0)")
    for mode in (1, -1):
        res = jax.block_until_ready(dyad.solve(a, b, l_ac, l_bc, mode=mode))  # compiles
        start = time.perf_counter()
        res = jax.block_until_ready(dyad.solve(a, b, l_ac, l_bc, mode=mode))
        elapsed = time.perf_counter() - start
        status = np.asarray(res.status)
        counts = {s.name: int(np.sum(status == s)) for s in Status if np.any(status == s)}
        ok = status == Status.OK
        print(f"\nmode {mode:+d}: {t.size} instants solved in {elapsed * 1e3:.1f} ms (compiled)")
        print(f"  statuses: {counts}")
        print(
            f"  phi in [{np.degrees(res.phi.p[ok].min()):.1f}, "
            f"{np.degrees(res.phi.p[ok].max()):.1f}] deg, "
            f"max |phi_dot| = {np.abs(res.phi.v[ok]).max():.3f} rad/s, "
            f"max |phi_ddot| = {np.abs(res.phi.a[ok]).max():.3f} rad/s^2"
        )
        print(f"  min singularity margin sin^2(beta) on OK instants: {res.margin[ok].min():.4f}")
        i = int(np.argmax(ok))
        print(
            f"  t = {t[i]:.3f} s: C = ({res.c.p[i, 0]:.4f}, {res.c.p[i, 1]:.4f}), "
            f"C_dot = ({res.c.v[i, 0]:.4f}, {res.c.v[i, 1]:.4f})"
        )
        assert np.allclose(np.linalg.norm(res.c.p[ok], axis=-1), l_ac)
        assert np.allclose(np.linalg.norm(res.c.p[ok] - b.p[ok], axis=-1), l_bc)
    bad = dyad.solve(jnp.zeros((3, 2)), jnp.array([[2.0, 0], [9.0, 0], [jnp.nan, 0]]), 1.0, 1.0)
    print("\nfailure is data:", [Status(int(s)).name for s in bad.status])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
