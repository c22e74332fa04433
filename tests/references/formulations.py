"""The RRR dyad solved three ways, batched in JAX, for the paper's Fig. 4 comparison.

1. Assur group closed form: ``jaxkin.dyad.solve`` (the library).
2. Relative coordinates: the link angles ``q = (phi1, phi2)`` (of A->C and B->C) by Newton on
   the loop closure ``A + l_ac e(phi1) - B - l_bc e(phi2) = 0``, started from a guess on the
   requested side (``phi1 = theta + mode * pi / 3``), which selects the assembly mode; then
   velocity and acceleration from the loop-closure Jacobian.
3. Natural coordinates: C itself by Newton on ``|C - A|^2 = l_ac^2, |C - B|^2 = l_bc^2`` from
   the closed-form solution plus Gaussian noise, retried with new noise while it converges to
   the other assembly mode (as the paper describes); rates from the constraint Jacobian.

Both Newton solvers run a fixed number of iterations in ``lax.fori_loop`` with explicit 2x2
(Cramer) solves. Benchmark-only code: not part of the library.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxkin import Jet, dyad

NEWTON_ITERATIONS = 12
NATURAL_NOISE = 0.1  # standard deviation of the initial-guess noise, times l_ac
NATURAL_RETRIES = 8


def _solve2(m00, m01, m10, m11, r0, r1):
    det = m00 * m11 - m01 * m10
    return (r0 * m11 - m01 * r1) / det, (m00 * r1 - r0 * m10) / det


def _split(jet: Jet):
    return [arr[..., k] for arr in (jet.p, jet.v, jet.a) for k in (0, 1)]


@jax.jit(static_argnames="mode")
def relative(a: Jet, b: Jet, l_ac, l_bc, mode: int = 1):
    """Returns (C Jet, phi Jet) by relative coordinates."""
    ax, ay, avx, avy, aax, aay = _split(a)
    bx, by, bvx, bvy, bax, bay = _split(b)
    theta = jnp.arctan2(by - ay, bx - ax)
    phi1 = theta + mode * jnp.pi / 3
    cx0, cy0 = ax + l_ac * jnp.cos(phi1), ay + l_ac * jnp.sin(phi1)
    phi2 = jnp.arctan2(cy0 - by, cx0 - bx)

    def step(_, q):
        p1, p2 = q
        c1, s1, c2, s2 = jnp.cos(p1), jnp.sin(p1), jnp.cos(p2), jnp.sin(p2)
        f0 = ax + l_ac * c1 - bx - l_bc * c2
        f1 = ay + l_ac * s1 - by - l_bc * s2
        d1, d2 = _solve2(-l_ac * s1, l_bc * s2, l_ac * c1, -l_bc * c2, -f0, -f1)
        return p1 + d1, p2 + d2

    phi1, phi2 = jax.lax.fori_loop(0, NEWTON_ITERATIONS, step, (phi1, phi2))
    c1, s1, c2, s2 = jnp.cos(phi1), jnp.sin(phi1), jnp.cos(phi2), jnp.sin(phi2)
    jac = (-l_ac * s1, l_bc * s2, l_ac * c1, -l_bc * c2)
    w1, w2 = _solve2(*jac, bvx - avx, bvy - avy)
    r0 = bax - aax + l_ac * c1 * w1 * w1 - l_bc * c2 * w2 * w2
    r1 = bay - aay + l_ac * s1 * w1 * w1 - l_bc * s2 * w2 * w2
    al1, _ = _solve2(*jac, r0, r1)
    c = jnp.stack([ax + l_ac * c1, ay + l_ac * s1], -1)
    c_v = jnp.stack([avx - l_ac * s1 * w1, avy + l_ac * c1 * w1], -1)
    c_a = jnp.stack(
        [aax - l_ac * (c1 * w1 * w1 + s1 * al1), aay + l_ac * (c1 * al1 - s1 * w1 * w1)], -1
    )
    return Jet(c, c_v, c_a), Jet(phi1, w1, al1)


@jax.jit(static_argnames="mode")
def natural(a: Jet, b: Jet, l_ac, l_bc, key, mode: int = 1):
    """Returns (C Jet, phi Jet, retries) by natural coordinates."""
    ax, ay, avx, avy, aax, aay = _split(a)
    bx, by, bvx, bvy, bax, bay = _split(b)
    exact = dyad.solve(Jet.constant(a.p), Jet.constant(b.p), l_ac, l_bc, mode).c.p

    def newton(c0):
        def step(_, c):
            x, y = c
            f0 = (x - ax) ** 2 + (y - ay) ** 2 - l_ac**2
            f1 = (x - bx) ** 2 + (y - by) ** 2 - l_bc**2
            dx, dy = _solve2(2 * (x - ax), 2 * (y - ay), 2 * (x - bx), 2 * (y - by), -f0, -f1)
            return x + dx, y + dy

        return jax.lax.fori_loop(0, NEWTON_ITERATIONS, step, c0)

    def wrong_side(c):
        cross = (bx - ax) * (c[1] - ay) - (by - ay) * (c[0] - ax)
        return jnp.sign(cross) != mode

    def guess(k):
        noise = jax.random.normal(k, (2, *ax.shape), ax.dtype) * (NATURAL_NOISE * l_ac)
        return exact[..., 0] + noise[0], exact[..., 1] + noise[1]

    def retry(state):
        c, k, tries = state
        k, sub = jax.random.split(k)
        again = wrong_side(c)
        fresh = newton(guess(sub))
        c = tuple(jnp.where(again, f, old) for f, old in zip(fresh, c, strict=True))
        return c, k, tries + 1

    def cond(state):
        c, _, tries = state
        return jnp.any(wrong_side(c)) & (tries < NATURAL_RETRIES)

    key, sub = jax.random.split(key)
    c, _, tries = jax.lax.while_loop(cond, retry, (newton(guess(sub)), key, 0))
    x, y = c
    jac = (x - ax, y - ay, x - bx, y - by)
    vx, vy = _solve2(*jac, jac[0] * avx + jac[1] * avy, jac[2] * bvx + jac[3] * bvy)
    r0 = jac[0] * aax + jac[1] * aay - ((vx - avx) ** 2 + (vy - avy) ** 2)
    r1 = jac[2] * bax + jac[3] * bay - ((vx - bvx) ** 2 + (vy - bvy) ** 2)
    accx, accy = _solve2(*jac, r0, r1)
    phi = jnp.arctan2(y - ay, x - ax)
    rx, ry = x - ax, y - ay
    r2 = rx * rx + ry * ry
    rvx, rvy = vx - avx, vy - avy
    phi_dot = (rx * rvy - ry * rvx) / r2
    phi_ddot = ((rx * (accy - aay) - ry * (accx - aax)) - 2 * phi_dot * (rx * rvx + ry * rvy)) / r2
    return (
        Jet(jnp.stack([x, y], -1), jnp.stack([vx, vy], -1), jnp.stack([accx, accy], -1)),
        Jet(phi, phi_dot, phi_ddot),
        tries,
    )
