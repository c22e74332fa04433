"""L-BFGS with a backtracking line search of one evaluation per update, in optax's shape.

``LBFGS(memory, linesearch_steps)`` is used like an ``optax.GradientTransformationExtraArgs``
on the parameters of ONE problem (``jax.vmap`` it over independent problems: each keeps its
own memory and line search)::

    state = method.init(params)  # or init(params, grads): the first search prepared
    updates, state = method.update(grads, state, params, value=f, value_fn=fn)
    params = optax.apply_updates(params, updates)  # state.params: the same, not rounded

where ``f`` and ``grads`` are the cost and gradient at ``params`` (the point the last update
accepted) and ``value_fn`` the cost. Each update evaluates ``value_fn`` and its gradient at
ONE trial point ``x + alpha d`` and either accepts it (``updates = alpha d``; the state's
``params``, ``value`` and ``grad`` are then the trial and its cost and gradient) or refuses it
(``updates = 0``; the next update tries a shorter step along the same ``d``). So a batch of
problems advances one evaluation per update each, and none waits for another's line search.
``params + updates`` is the accepted point up to the rounding of the sum; the state's
``params`` is the point evaluated, exactly (``jaxkin.optimize`` takes it from there).

The direction is ``d = -H g`` by the two-loop recursion over the stored pairs ``(s, y)`` with
``H0 = (s.y / y.y) I`` of the newest pair [Nocedal & Wright 2006, alg. 7.4]; a pair with
``s.y <= eps |s| |y|`` is not stored, so ``H`` stays positive definite, and ``d = -g`` when the
recursion gives no descent direction. The trial ``x + alpha d`` is accepted when it meets the
Armijo condition ``f(x + alpha d) <= f(x) + 1e-4 alpha g.d`` (a non-finite trial is refused);
else ``alpha`` shrinks by the minimiser of the quadratic through ``f(x)``, ``g.d`` and the
trial, clipped to [0.1, 0.5] of ``alpha``. ``alpha`` starts at 1, and at ``0.1 / |g|`` (a tenth
of the parameters' unit) on the first search and after steepest descent. After
``linesearch_steps`` refused trials the memory is cleared and the search starts again by
steepest descent from ``x``; when that search fails too the state says ``gave_up``. The next
search's direction and first step are prepared at the end of each update (from the accepted
point's gradient); the first by ``init(params, grad)`` when it is given the gradient, else by
the first update from its ``grads`` (the same search, rounded in another program).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from jax import Array

__all__ = ["LBFGS", "LBFGSState", "Memory"]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Memory:
    """The stored pairs of one problem (``n``: the parameters' size; ``m``: ``LBFGS.memory``).

    Attributes:
        s, y: the pairs' steps and gradient changes, ``(m, n)``; the newest at
            ``(pairs - 1) % m``.
        rho: ``1 / s.y`` of each pair, ``(m,)``.
        pairs: pairs stored so far, ``int32``.
        gamma: ``H0``'s scale ``s.y / y.y`` of the newest pair (1 with none).
    """

    s: Array
    y: Array
    rho: Array
    pairs: Array
    gamma: Array

    @classmethod
    def empty(cls, m: int, n: int, dtype: Any) -> Memory:
        zeros = jnp.zeros((m, n), dtype)
        return cls(zeros, zeros, jnp.zeros(m, dtype), jnp.zeros((), jnp.int32), jnp.ones((), dtype))

    def stored(self, step: Array, change_g: Array, accept: Array) -> Memory:
        """With the pair ``(step, change_g)`` of an accepted step stored (over the oldest when
        full), but without positive curvature ``s.y > eps |s| |y|``."""
        m = self.rho.shape[-1]
        sy = jnp.sum(step * change_g, axis=-1)
        yy = jnp.sum(change_g * change_g, axis=-1)
        size = jnp.sqrt(jnp.sum(step * step, axis=-1) * yy)
        store = accept & (sy > jnp.finfo(step.dtype).eps * size) & (yy > 0)
        one_hot = (jnp.arange(m) == self.pairs % m) & store
        return Memory(
            jnp.where(one_hot[:, None], step[None, :], self.s),
            jnp.where(one_hot[:, None], change_g[None, :], self.y),
            jnp.where(one_hot, 1.0 / jnp.where(store, sy, 1.0), self.rho),
            self.pairs + store.astype(jnp.int32),
            jnp.where(store, sy / jnp.where(store, yy, 1.0), self.gamma),
        )

    def descent(self, g: Array) -> Array:
        """``-H g`` by the two-loop recursion over the stored pairs."""
        memory = self.rho.shape[-1]
        pairs = self.pairs
        q, alphas = g, []
        for j in range(memory):  # newest first
            i = (pairs - 1 - j) % memory
            valid = j < jnp.minimum(pairs, memory)
            a = jnp.where(valid, self.rho[i] * jnp.dot(self.s[i], q), 0.0)
            q = q - a * self.y[i]
            alphas.append(a)
        r = self.gamma * q
        for j in reversed(range(memory)):
            i = (pairs - 1 - j) % memory
            valid = j < jnp.minimum(pairs, memory)
            b = self.rho[i] * jnp.dot(self.y[i], r)
            r = r + jnp.where(valid, alphas[j] - b, 0.0) * self.s[i]
        return -r


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class LBFGSState:
    """One problem's L-BFGS state (``n``: the parameters' size).

    Attributes:
        memory: the stored pairs (``Memory``).
        direction: the line search's direction ``d``, ``(n,)``.
        alpha: the length of its next trial step.
        tries: refused trials of the line search, ``int32``.
        started: a line search was prepared (False after ``init`` without a gradient: the
            first update starts it, steepest descent with a step of ``0.1 / |g|``).
        restarted: the memory was cleared after a failed line search and no step has been
            taken since.
        params: the accepted parameters after this update (the point ``value`` and ``grad``
            were evaluated at).
        value: their cost.
        grad: its gradient, the parameters' shape.
        accepted: this update took a step.
        gave_up: this update's line search failed right after a restart (no descent).
    """

    memory: Memory
    direction: Array
    alpha: Array
    tries: Array
    started: Array
    restarted: Array
    params: Array
    value: Array
    grad: Array
    accepted: Array
    gave_up: Array


def _first_step(grad_norm: Array) -> Array:
    """``0.1 / |g|`` (a tenth of the parameters' unit along ``-g``), at most 1."""
    return jnp.where(grad_norm > 0.1, 0.1 / jnp.where(grad_norm > 0, grad_norm, 1.0), 1.0)


@dataclasses.dataclass(frozen=True)
class LBFGS:
    """L-BFGS with a backtracking line search, one evaluation per update (module docstring):
    ``memory`` pairs, at most ``linesearch_steps`` trials per line search. Hashable: a method
    described by value compiles once."""

    memory: int = 10
    linesearch_steps: int = 20

    def init(self, params: Array, grad: Array | None = None) -> LBFGSState:
        """The state at ``params`` before any update, its memory empty. With ``grad``, the
        gradient at ``params``, the first line search is prepared here (as every later one is,
        at the end of an update); without it (optax's ``init(params)``) the first update
        prepares it from its ``grads``."""
        n, dtype = params.size, params.dtype
        false = jnp.zeros((), bool)
        direction, alpha, started = jnp.zeros(n, dtype), jnp.ones((), dtype), false
        if grad is not None:  # steepest descent, a tenth of the unit
            g = grad.reshape(-1)
            direction, alpha = -g, _first_step(jnp.sqrt(jnp.sum(g * g, axis=-1)))
            started = jnp.ones((), bool)
        return LBFGSState(
            memory=Memory.empty(self.memory, n, dtype),
            direction=direction,
            alpha=alpha,
            tries=jnp.zeros((), jnp.int32),
            started=started,
            restarted=false,
            params=params,
            value=jnp.zeros((), dtype),
            grad=jnp.zeros_like(params),
            accepted=false,
            gave_up=false,
        )

    def update(
        self,
        updates: Array,
        state: LBFGSState,
        params: Array,
        *,
        value: Array,
        value_fn: Callable[[Array], Array],
        **extra_args: Any,
    ) -> tuple[Array, LBFGSState]:
        """One trial of the line search from ``params`` (module docstring).

        Args:
            updates: the gradient of the cost at ``params`` (optax's name for it).
            state: the state the last update (or ``init``) returned.
            params: the parameters the last update accepted (any shape).
            value: the cost at ``params``.
            value_fn: the cost of parameters of ``params``' shape (differentiable).

        Returns:
            ``(updates, state)``: the step to the accepted trial (zeros when it was refused)
            and the new state, whose ``params``, ``value`` and ``grad`` are the accepted point,
            its cost and gradient.
        """
        del extra_args  # optax's other extra arguments (grad) are not needed
        x, g, f = params.reshape(-1), updates.reshape(-1), value
        # the first update starts the first search: steepest descent, a tenth of the unit
        first = _first_step(jnp.sqrt(jnp.sum(g * g, axis=-1)))
        d = jnp.where(state.started, state.direction, -g)
        alpha = jnp.where(state.started, state.alpha, first)

        trial = x + alpha * d
        f_t, g_t = jax.value_and_grad(value_fn)(trial.reshape(params.shape))
        g_t = g_t.reshape(-1)
        slope = jnp.sum(g * d, axis=-1)  # < 0: a descent direction
        finite = jnp.isfinite(f_t) & jnp.all(jnp.isfinite(g_t), axis=-1)
        accept = finite & (f_t <= f + 1e-4 * alpha * slope)
        # refused: the minimiser of the quadratic through f, the slope and the trial
        curvature = f_t - f - slope * alpha
        ratio = -slope * alpha / (2.0 * jnp.where(curvature > 0, curvature, 1.0))
        shrink = jnp.where(finite & (curvature > 0), jnp.clip(ratio, 0.1, 0.5), 0.1)
        tries = state.tries + 1
        exhausted = ~accept & (tries >= self.linesearch_steps)
        gave_up = exhausted & state.restarted
        restart = exhausted & ~state.restarted  # clear the memory, steepest descent from x

        # accepted: store the pair (skipped without positive curvature), next direction
        memory = state.memory.stored(trial - x, g_t - g, accept)
        x_next = jnp.where(accept, trial, x)
        f_next = jnp.where(accept, f_t, f)
        g_next = jnp.where(accept, g_t, g)
        direction = memory.descent(g_next)
        downhill = jnp.sum(direction * g_next, axis=-1) < 0
        direction = jnp.where(downhill, direction, -g_next)
        grad_norm = jnp.sqrt(jnp.sum(g_next * g_next, axis=-1))
        # a failed search: the memory cleared, steepest descent from x with a first step
        steepest = _first_step(grad_norm)
        cleared = Memory.empty(self.memory, x.size, x.dtype)
        new = LBFGSState(
            memory=jax.tree.map(lambda c, k: jnp.where(restart, c, k), cleared, memory),
            direction=jnp.where(restart, -g_next, jnp.where(accept, direction, d)),
            alpha=jnp.where(
                restart,
                steepest,
                jnp.where(accept, jnp.where(downhill, 1.0, steepest), alpha * shrink),
            ),
            tries=jnp.where(accept | restart, 0, tries),
            started=jnp.ones((), bool),
            restarted=jnp.where(accept, False, state.restarted | restart),
            params=x_next.reshape(params.shape),
            value=f_next,
            grad=g_next.reshape(params.shape),
            accepted=accept,
            gave_up=gave_up,
        )
        taken = jnp.where(accept, alpha * d, jnp.zeros_like(d))
        return taken.reshape(params.shape), new
