"""jaxkin._chunks: the chunk layout and map_chunks against the unchunked function."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxkin import _chunks


@pytest.mark.parametrize(
    ("size", "layout"),
    [
        (1_000_000, (125, 8000)),  # a divisor in (CHUNK/2, CHUNK]: no padding
        (3 * _chunks.CHUNK, (3, _chunks.CHUNK)),
        (_chunks.CHUNK + 37, (2, 4115)),  # no such divisor: two chunks, one padding element
    ],
)
def test_layout(size, layout):
    n_chunks, chunk = _chunks._layout(size)
    assert (n_chunks, chunk) == layout
    assert n_chunks * chunk >= size and chunk <= _chunks.CHUNK


@pytest.mark.parametrize("batch", [(24_000,), (_chunks.CHUNK + 37,), (3, 4001), (17,)])
def test_map_chunks_equals_whole_batch(batch):
    """Elementwise fn of a pytree (one leaf with a trailing axis): same values, same shapes."""
    rng = np.random.default_rng(0)
    x = jnp.asarray(rng.normal(size=(*batch, 3)))
    y = jnp.asarray(rng.normal(size=batch))

    def fn(tree):
        x, y = tree
        return {"norm": jnp.sqrt(jnp.sum(x * x, -1)) + y, "scaled": x * y[..., None]}

    chunked = _chunks.map_chunks(fn, (x, y), batch)
    whole = fn((x, y))
    for key in whole:
        assert chunked[key].shape == whole[key].shape
        np.testing.assert_array_equal(chunked[key], whole[key])


@pytest.mark.parametrize("batch", [(10,), (7,), (3, 5)])
def test_in_two_halves_equals_whole_batch(batch):
    """Even, odd (unequal halves) and 2-D batches; a scalar argument reaches both halves."""
    rng = np.random.default_rng(1)
    x = jnp.asarray(rng.normal(size=(*batch, 2)))
    y = jnp.asarray(rng.normal(size=batch))
    calls = []

    def fn(x, y, scale):
        calls.append(y.shape)
        return {"sum": x.sum(-1) * scale + y, "x": x * scale}

    halves = _chunks.in_two_halves(fn, (x, y, jnp.asarray(2.0)), batch)
    size = int(np.prod(batch))
    assert calls == [(size // 2,), (size - size // 2,)]
    whole = fn(x, y, 2.0)
    for key in whole:
        assert halves[key].shape == whole[key].shape
        np.testing.assert_array_equal(halves[key], whole[key])
