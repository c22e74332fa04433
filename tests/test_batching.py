"""jaxkin._batching: every way a batch is split gives the whole-batch answer.

The reference is always the same function run once on the whole batch (``set_num_threads(1)``
for host parts); thresholds are patched small so the tests stay fast.
"""

from __future__ import annotations

import threading

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxkin
from jaxkin import Jet, Status, _batching, delta, serial
from jaxkin._execute import Kernel, Policy
from tests.helpers import compilations, tree_allfinite

ROBOT = delta.Delta.paper()
CHUNK = _batching.CHUNK


# ------------------------------------------------------------------ chunks inside a kernel
@pytest.mark.parametrize(
    ("size", "layout"),
    [
        (1_000_000, (125, 8000)),  # a divisor in (CHUNK/2, CHUNK]: no padding
        (3 * CHUNK, (3, CHUNK)),
        (CHUNK + 37, (2, 4115)),  # no such divisor: two chunks, one padding element
    ],
)
def test_chunk_layout(size, layout):
    n_chunks, chunk = _batching._chunk_layout(size)
    assert (n_chunks, chunk) == layout
    assert n_chunks * chunk >= size and chunk <= CHUNK


def _pair(batch, seed=0):
    rng = np.random.default_rng(seed)
    return jnp.asarray(rng.normal(size=(*batch, 3))), jnp.asarray(rng.normal(size=batch))


@pytest.mark.parametrize("batch", [(CHUNK + 37,), (3, 4001), (17,)])
def test_map_chunks_equals_whole_batch(batch):
    """Elementwise fn of a pytree (one leaf with a trailing axis): same values, same shapes."""
    x, y = _pair(batch)

    def fn(tree):
        x, y = tree
        return {"norm": jnp.sqrt(jnp.sum(x * x, -1)) + y, "scaled": x * y[..., None]}

    chunked = _batching.map_chunks(fn, (x, y), batch)
    whole = fn((x, y))
    for key in whole:
        assert chunked[key].shape == whole[key].shape
        np.testing.assert_array_equal(chunked[key], whole[key])


# ------------------------------------------------------------------ host threads
@pytest.fixture
def small_parts(monkeypatch):
    """Parts of at least 16 elements, two threads (whatever the machine has)."""
    monkeypatch.setattr(_batching, "MIN_PART", 16)
    _batching.set_num_threads(2)
    yield
    _batching.set_num_threads(None)


@pytest.fixture
def parts_ran(monkeypatch):
    """A list that records the number of host-thread parts of every split call."""
    calls = []
    original = _batching.run_parts

    def spy(run, starts):
        calls.append(len(starts))
        return original(run, starts)

    monkeypatch.setattr(_batching, "run_parts", spy)
    return calls


def _whole(fn, *args, **kwargs):
    _batching.set_num_threads(1)
    try:
        return fn(*args, **kwargs)
    finally:
        _batching.set_num_threads(2)


@pytest.mark.parametrize(
    ("size", "threads", "part", "starts"),
    [
        (31, 2, 31, [0]),  # fewer than 2 * MIN_PART elements: one part
        (32, 2, 16, [0, 16]),
        (33, 2, 17, [0, 16]),  # odd: the last part overlaps its neighbour by one element
        (100, 3, 34, [0, 34, 66]),
        (100, 8, 17, [0, 17, 34, 51, 68, 83]),  # at most size // MIN_PART parts
    ],
)
def test_thread_layout(small_parts, size, threads, part, starts):
    _batching.set_num_threads(threads)
    assert _batching.thread_layout(size) == (part, starts)
    covered = set()
    for start in starts:
        covered |= set(range(start, start + part))
    assert covered == set(range(size)) and starts[-1] + part == size


@pytest.mark.parametrize(
    ("size", "n_parts", "multiple", "part", "starts"),
    [
        (10, 3, 1, 4, [0, 4, 6]),
        (10, 3, 2, 4, [0, 4, 6]),
        (10, 4, 4, 4, [0, 4, 6]),  # rounded up to the multiple: three parts are enough
        (8, 1, 2, 8, [0]),
        (8, 20, 2, 2, [0, 2, 4, 6]),  # never more parts than elements allow
    ],
)
def test_overlapping_parts(size, n_parts, multiple, part, starts):
    assert _batching.overlapping_parts(size, n_parts, multiple) == (part, starts)
    assert part % multiple == 0 and starts[-1] + part == size


def _threaded(fn, static, batched):
    """``fn`` as a kernel whose large batches run in parts on the host threads."""
    return Kernel(
        fn, static=static, batched=dict.fromkeys(batched, 0), policy=Policy(pad=False, threads=True)
    )


def _toy(x, y, scale, mode):
    """Elementwise in the batch; ``scale`` is shared, ``mode`` static."""
    norm = jnp.sqrt(jnp.sum(x * x, axis=-1))
    return {"norm": norm * scale + mode * y, "scaled": x * y[..., None]}


@pytest.mark.parametrize("batch", [(41,), (7, 9)])
@pytest.mark.parametrize("threads", [2, 3])
def test_parts_equal_whole_batch(small_parts, batch, threads):
    x, y = _pair(batch)
    kernel = _threaded(_toy, ("mode",), ("x", "y"))
    _batching.set_num_threads(threads)
    with compilations() as count:
        parts = kernel(x, y, jnp.asarray(2.0), 3, batch=batch)
    whole = kernel.jitted(x, y, jnp.asarray(2.0), 3)
    assert count.compiled("_part_impl") == 1  # the parts ran (one shared compilation)
    for key in whole:
        assert parts[key].shape == whole[key].shape
        np.testing.assert_array_equal(parts[key], whole[key])


def test_parts_run_on_worker_threads(small_parts):
    seen = set()

    def kernel(x):
        jax.debug.callback(lambda: seen.add(threading.current_thread().name))
        return x * 2.0

    split = _threaded(kernel, (), ("x",))
    np.testing.assert_array_equal(split(jnp.arange(64.0), batch=(64,)), 2.0 * np.arange(64.0))
    assert len(seen) == 2 and all(name.startswith("jaxkin") for name in seen)


def test_whole_batch_when_splitting_does_not_apply(small_parts):
    calls = []

    def kernel(x, y):
        calls.append(x.shape)  # runs at trace time: one entry per compilation
        return x + y

    split = _threaded(kernel, (), ("x", "y"))
    x = jnp.ones((64, 2))
    with compilations() as count:
        out = [
            split(x, jnp.ones((1, 2)), batch=(64,)),  # y only broadcasts to the batch
            jax.jit(lambda x: split(x, x, batch=(64,)))(x),  # tracers inside a user's jit
        ]
        _batching.set_num_threads(1)
        out.append(split(x, x, batch=(64,)))  # one thread
    for result in out:
        np.testing.assert_array_equal(result, 2.0 * np.ones((64, 2)))
    assert calls and all(shape == (64, 2) for shape in calls)
    assert count.compiled("_part_impl") == 0


def test_errors_reach_the_caller(small_parts):
    def kernel(x):
        raise ValueError("bad part")

    with pytest.raises(ValueError, match="bad part"):
        _threaded(kernel, (), ("x",))(jnp.ones(64), batch=(64,))


def test_thread_count_setting(monkeypatch):
    assert jaxkin.set_num_threads is _batching.set_num_threads  # the public names
    assert jaxkin.num_threads is _batching.num_threads
    monkeypatch.setenv("JAXKIN_NUM_THREADS", "3")
    assert _batching.num_threads() == 3
    _batching.set_num_threads(5)
    assert _batching.num_threads() == 5
    _batching.set_num_threads(None)
    monkeypatch.setenv("JAXKIN_NUM_THREADS", "zero")
    with pytest.raises(ValueError, match="JAXKIN_NUM_THREADS"):
        _batching.num_threads()
    monkeypatch.delenv("JAXKIN_NUM_THREADS")
    assert _batching.num_threads() >= 1
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="positive int"):
            _batching.set_num_threads(bad)


def test_delta_fk_in_parts_equals_whole_batch(small_parts, parts_ran):
    """The real kernel: Newton iterations, statuses, rates, a warm start, bad elements."""
    rng = np.random.default_rng(3)
    p = np.stack([rng.uniform(-8, 8, 101), rng.uniform(-8, 8, 101), rng.uniform(-38, -22, 101)], -1)
    theta = np.array(delta.ik(ROBOT, p).q.p)
    theta[4] = np.nan
    theta[-1] = [np.pi, 0.0, 0.0]  # cannot be assembled (fk_closed_form: UNREACHABLE)
    jet = Jet.of(theta, rng.normal(size=theta.shape), rng.normal(size=theta.shape))
    guess = p + rng.normal(scale=0.5, size=p.shape)
    results = []
    for args, kwargs in [((jet,), {}), ((theta,), {"guess": guess})]:
        parts_ran.clear()
        parts = delta.fk(ROBOT, *args, **kwargs)
        assert parts_ran and parts_ran[0] >= 2  # the batch ran in parts
        whole = _whole(delta.fk, ROBOT, *args, **kwargs)
        for a, b in zip(jax.tree.leaves(parts), jax.tree.leaves(whole), strict=True):
            assert a.shape == b.shape and a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)
        results.append(parts)
    status = np.asarray(results[0].status)
    assert status[4] == Status.INVALID_INPUT and status[-1] == Status.NOT_CONVERGED
    assert np.sum(status == Status.OK) >= 95
    assert tree_allfinite(results)


def test_chain_fk_and_jacobians_in_parts_equal_whole_batch(small_parts, parts_ran, monkeypatch):
    """A chain's FK (at rest, its zero rates then written outside the kernel; and with rates)
    and both Jacobians, split in parts, equal the whole batch bit for bit."""
    monkeypatch.setattr(_batching, "SHARED_ZEROS_MIN", 16)
    chain = serial.from_dh(serial.Puma560().dh_table())
    rng = np.random.default_rng(4)
    q = rng.uniform(-2, 2, (101, 6))
    q[7] = np.nan
    jet = Jet.of(q, rng.normal(size=q.shape), rng.normal(size=q.shape))
    at_rest = jaxkin.fk(chain, q)
    assert parts_ran and parts_ran[0] >= 2  # the batch ran in parts
    calls = [
        (jaxkin.fk, q),
        (jaxkin.fk, jet),
        (serial.space_jacobian, q),
        (serial.body_jacobian, q),
    ]
    for fn, arg in calls:
        parts, whole = fn(chain, arg), _whole(fn, chain, arg)
        for a, b in zip(jax.tree.leaves(parts), jax.tree.leaves(whole), strict=True):
            assert a.shape == b.shape and a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)
    assert len(parts_ran) == 1 + len(calls)  # every call ran in parts
    status = np.asarray(at_rest.status)
    assert status[7] == Status.INVALID_INPUT and np.all(np.delete(status, 7) == Status.OK)
    assert not np.any(at_rest.x.v) and not np.any(at_rest.x.a)
    moving = jaxkin.fk(chain, jet)
    np.testing.assert_allclose(at_rest.x.p, moving.x.p, rtol=0, atol=1e-14)


def test_host_chunks_cover_every_element_with_one_shape():
    seen = []
    for start, stop, index in _batching.host_chunks(10, 4):
        assert len(index) == 4 and np.all(index[: stop - start] == np.arange(start, stop))
        assert np.all(index[stop - start :] == start)  # padding repeats a real element
        seen.extend(range(start, stop))
    assert seen == list(range(10))
    assert [len(i) for *_, i in _batching.host_chunks(5, 64)] == [8]  # next power of two


# ------------------------------------------------------------------ padded small batches
@pytest.mark.parametrize(
    ("size", "padded"),
    [(0, 0), (1, 64), (64, 64), (65, 128), (4096, 4096), (4097, 4097), (10**6, 10**6)],
)
def test_padded_size(size, padded):
    assert _batching.padded_size(size) == padded
    # from 1 (the planner's candidates): powers of two up to the same bound
    power = 1 << (size - 1).bit_length() if size else 0
    assert _batching.padded_size(size, 1) == (power if size <= 4096 else size)


def _dyad_inputs(batch, seed):
    rng = np.random.default_rng(seed)
    a = Jet.of(*(rng.normal(size=(*batch, 2)) for _ in range(3)))
    b = Jet.of(*(rng.normal(size=(*batch, 2)) + [1.0, 0.0] for _ in range(3)))
    return a, b


def _pad_by_hand(x, padded):
    flat = np.reshape(x, (-1, x.shape[-1]))
    return np.concatenate([flat, np.repeat(flat[-1:], padded - len(flat), axis=0)])


def test_small_batches_of_any_shape_share_one_padded_compilation():
    """(3, 5), (15,) and (2, 7) run as 64 elements: one compilation of the kernel (a new shape
    compiles only the small padding and cut), and each element is what that program gives for
    it in a batch padded by hand (repeating the last element)."""
    from jaxkin import dyad

    kernel = dyad._solve_jit.jitted
    for k, batch in enumerate([(3, 5), (15,), (2, 7)]):
        a, b = _dyad_inputs(batch, k)
        with compilations() as count:
            result = dyad.solve(a, b, 1.3, 1.1)
        # the first shape compiles the kernel
        assert k == 0 or count.compiled(kernel.__name__) == 0
        size = int(np.prod(batch))
        by_hand = [jax.tree.map(lambda x: _pad_by_hand(x, 64), jet) for jet in (a, b)]
        padded = kernel(*by_hand, 1.3, 1.1, 1, "analytic")
        for got, want in zip(jax.tree.leaves(result), jax.tree.leaves(padded), strict=True):
            assert got.shape == (*batch, *want.shape[1:]) and got.dtype == want.dtype
            np.testing.assert_array_equal(got, np.reshape(want[:size], got.shape))
        # Against the kernel compiled for the exact shape: the same to a few ulp.
        exact = kernel(a, b, 1.3, 1.1, 1, "analytic")
        np.testing.assert_array_equal(result.status, exact.status)
        np.testing.assert_allclose(result.c.a, exact.c.a, rtol=1e-14, atol=1e-14)


def test_padding_broadcasts_batched_arguments_and_leaves_the_rest_alone(monkeypatch):
    """Arguments whose batch shapes differ are broadcast before padding; a batched geometry,
    a large batch, and a call under jit run unpadded; the caller's arrays are not changed."""
    from jaxkin import dyad, scara

    rng = np.random.default_rng(3)
    a = rng.normal(size=(4, 1, 2))
    b = rng.normal(size=(5, 2)) + [1.0, 0.0]
    l_ac = rng.uniform(1.0, 2.0, size=(4, 5))
    kept = a.copy(), b.copy(), l_ac.copy()
    result = dyad.solve(a, b, l_ac, 1.1)
    exact = dyad._solve_jit.jitted(
        Jet.constant(a), Jet.constant(b), jnp.asarray(l_ac), 1.1, 1, "analytic"
    )
    assert result.c.p.shape == (4, 5, 2)
    np.testing.assert_allclose(result.c.p, exact.c.p, rtol=1e-14, atol=1e-14)
    for given, copy in zip((a, b, l_ac), kept, strict=True):
        np.testing.assert_array_equal(given, copy)

    def no_padding(*_):
        raise AssertionError("padded a call that should run as it is")

    monkeypatch.setattr(_batching, "pad_leaf", no_padding)
    traced = jax.jit(lambda a: dyad.solve(a, b, l_ac, 1.1).c.p)(a)
    np.testing.assert_allclose(traced, exact.c.p, rtol=1e-14, atol=1e-14)

    robots = scara.Scara(l_oa=1.5, l_ab=jnp.array([0.8, 0.9, 1.0]), l_bc=0.5)
    d = jnp.array([[0.9, 0.3, 1.0], [1.0, -0.2, 1.2], [0.7, 0.7, 1.1]])
    solved = scara.ik(robots, d)  # batch (3,) from the geometry: run as it is
    np.testing.assert_allclose(jaxkin.fk(robots, solved.q).x.p, d, rtol=0, atol=1e-13)

    size = _batching.PAD_MAX + 1
    large = dyad.position(np.zeros((size, 2)), np.ones((size, 2)), 1.0, 1.0)
    assert large.c.shape == (size, 2)


def test_planner_candidates_and_newton_histories_are_padded_along_their_batch_axis(
    monkeypatch,
):
    """The planner pads its candidates (5 and 7 share one program, of 8 candidates: each is
    a whole path, not padded to 64; a path's samples are not a batch axis); the Newton IK's
    history keeps its step axis first."""
    from jaxkin import paths, plan, scara
    from jaxkin._execute import Kernel

    run_at = []  # the batch shapes the planner's kernel runs at
    run_whole = Kernel.whole

    def recording_whole(self, args, kwargs, batch):
        if self is plan._evaluate_jit:
            run_at.append(batch)
        return run_whole(self, args, kwargs, batch)

    monkeypatch.setattr(Kernel, "whole", recording_whole)

    robot = scara.Scara.paper()
    rng = np.random.default_rng(6)
    t = np.linspace(0.0, 1.0, 9)[:, None]
    start = rng.uniform([60.0, -20.0, 40.0], [90.0, 20.0, 80.0], (7, 1, 3))
    path = paths.path_from_samples(start + t * [10.0, 5.0, -5.0], dt=0.1)
    parts = [jax.tree.map(lambda x, n=n: x[:n], path) for n in (5, 7)]
    results = [plan.evaluate(robot, parts[0])]
    with compilations() as count:
        results.append(plan.evaluate(robot, parts[1]))
    # 7 candidates reuse the program compiled for 5
    assert count.compiled(plan._evaluate_jit.jitted.__name__) == 0
    assert run_at == [(8,), (8,)]
    for part, got in zip(parts, results, strict=True):
        limits, weights = plan.robot_limits(robot, None), np.ones(3)
        want = plan._evaluate_jit.jitted(robot, part.jet, limits, part.dt, weights, 1, "task")
        n = part.shape[0]
        assert got.q.p.shape == (n, 9, 3) and got.costs.total.shape == (n,)
        np.testing.assert_array_equal(got.status, want.status)
        np.testing.assert_allclose(got.q.a, want.q.a, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.costs.total, want.costs.total, rtol=1e-12)

    # Newton IK: (3, 5) runs as 64; against the 64-element program called unpadded.
    arm = serial.from_dh(serial.Puma560().dh_table())
    q = rng.uniform(-1.0, 1.0, (64, 6))
    target = jaxkin.fk(arm, q).x.p
    whole = serial.ik_newton(arm, target, q + 0.05, max_iter=6)
    q0 = (q[:15] + 0.05).reshape(3, 5, 6)
    got = serial.ik_newton(arm, target[:15].reshape(3, 5, 4, 4), q0, max_iter=6)
    assert got.history.shape == (7, 3, 5, 6) and got.q.shape == (3, 5, 6)
    np.testing.assert_array_equal(got.history, whole.history[:, :15].reshape(7, 3, 5, 6))
    np.testing.assert_array_equal(got.iterations, whole.iterations[:15].reshape(3, 5))


def test_accelerator_choices_are_keyed_on_the_backend(monkeypatch):
    """On a GPU or TPU backend: no host-thread split (unless asked for), larger planner calls,
    and XLA's own trigonometric functions instead of the CPU's polynomial forms."""
    from jaxkin import _trig

    x = np.linspace(-50.0, 50.0, 1001)
    assert _batching.num_threads() >= 1 and not _batching.on_accelerator()
    assert _batching.plan_chunk_samples() == _batching.PLAN_CHUNK_SAMPLES
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert _batching.on_accelerator() and _batching.num_threads() == 1
    assert _batching.plan_chunk_samples() == _batching.ACCELERATOR_CHUNK_SAMPLES
    _batching.set_num_threads(2)
    try:
        assert _batching.num_threads() == 2
    finally:
        _batching.set_num_threads(None)
    sin, cos = _trig.sincos(x)
    np.testing.assert_array_equal(sin, jnp.sin(x))
    np.testing.assert_array_equal(cos, jnp.cos(x))
    np.testing.assert_array_equal(_trig.sin_alone(x), jnp.sin(x))
    np.testing.assert_array_equal(_trig.cos_alone(x), jnp.cos(x))
    np.testing.assert_array_equal(_trig.atan2(x, x[::-1]), jnp.arctan2(x, x[::-1]))
