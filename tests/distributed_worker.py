"""One process of ``tests/test_distributed.py``, or its one-process reference.

``python -m tests.distributed_worker OUT`` with ``JAX_COORDINATOR_ADDRESS``,
``JAX_NUM_PROCESSES`` and ``JAX_PROCESS_ID`` set joins the processes through the command line's
``--distributed`` (jaxkin is imported first, as a user's script would) and writes
``OUT/process-<id>.npz``; ``run(OUT, distributed=False)`` computes the same in one process. The
planner, ``plan.best``, the Delta's workspace, the optimiser and the ``workspace`` and ``ik``
subcommands run on fixed inputs. The planner's and the sweeps' calls get the same batch per
device in both runs (chunks of 2 candidates, of 4096 voxels), so their arithmetic is the same;
the optimiser's loop and the ``ik`` rows run on 2 guesses (12 rows) per process against 4 (24)
in one. Global arrays are gathered (``process_allgather``) before they are saved, and facts
about their layout are saved beside them.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import jax
import numpy as np

from jaxkin import Jet, cli, delta, optimize, paths, plan, scara, workspace
from jaxkin.cli import files

ROBOT = scara.Scara.paper()
N, T = 4, 12  # candidates and samples; the optimiser's paths have the same shape
DT = 0.1
START, GOAL = np.array([100.0, -60.0, 50.0]), np.array([100.0, 60.0, 70.0])
DELTA = delta.Delta.paper()
# The paper's box at 4x and 2x its voxel edge: 26 x 26 x 23 voxels (nx even: the mask is
# split over two processes) and 51 x 51 x 46 (nx odd: replicated); one chunk shape.
RESOLUTIONS = (4 * DELTA.workspace_box()[1], 2 * DELTA.workspace_box()[1])
SWEEP_CHUNK = 4096


def spiral(rows: np.ndarray) -> Jet:
    """Candidates ``rows`` of a family of scaled spirals (each one's rows alone)."""
    t = np.arange(T) * DT
    scale = 0.8 + 0.1 * rows[:, None]
    x = 100 + 20 * scale * np.sin(t)
    y = -20 * scale * np.cos(t)
    z = np.broadcast_to(50 + 10 * t, x.shape)
    return paths.path_from_samples(np.stack([x, y, z], -1), DT)


def _host(x) -> np.ndarray:
    """The whole of an array on this process (gathered when it spans processes)."""
    if isinstance(x, jax.Array) and not x.is_fully_addressable:
        from jax.experimental import multihost_utils

        return np.asarray(multihost_utils.process_allgather(x, tiled=True))
    return np.asarray(x)


def _save_tree(out: dict, name: str, tree) -> None:
    """Leaves of ``tree`` as host arrays, and whether each was split over both processes."""
    for i, leaf in enumerate(jax.tree.leaves(tree)):
        if isinstance(leaf, jax.Array) and leaf.ndim:
            rows = {shard.data.shape[0] for shard in leaf.addressable_shards}
            out[f"{name}.{i}.held_rows"] = np.asarray(max(rows))
            out[f"{name}.{i}.devices"] = np.asarray(len(leaf.sharding.device_set))
        out[f"{name}.{i}"] = _host(leaf)


def _process_local_path() -> Jet:
    """The N candidates as global arrays, each process making only its own rows."""
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    per = N // jax.process_count()
    mine = spiral(np.arange(per * jax.process_index(), per * (jax.process_index() + 1)))
    sharding = NamedSharding(Mesh(np.asarray(jax.devices()), ("rows",)), PartitionSpec("rows"))
    return Jet(
        *(
            jax.make_array_from_process_local_data(sharding, np.asarray(x), (N, T, 3))
            for x in (mine.p, mine.v, mine.a)
        )
    )


def _holds_every_candidate() -> bool:
    """Whether this process holds all N candidates of any live array."""
    for array in jax.live_arrays():
        if array.ndim and array.shape[0] == N:
            if any(shard.data.shape[0] == N for shard in array.addressable_shards):
                return True
    return False


def run(out_dir: Path, distributed: bool) -> dict[str, np.ndarray]:
    """Everything, in one process or as one of several; the results as host arrays."""
    out_dir.mkdir(parents=True, exist_ok=True)
    flag = ["--distributed"] if distributed else []
    writes = []
    atomic_write = files.atomic_write

    def counted(path, *args, **kwargs):
        writes.append(str(path))
        return atomic_write(path, *args, **kwargs)

    files.atomic_write = counted
    try:
        # The first JAX call: joins the processes (from the environment) when distributed.
        workspace_argv = ["workspace", "delta", "--robot", "paper", "--resolution"]
        workspace_argv += [str(RESOLUTIONS[0]), "--chunk-size", str(SWEEP_CHUNK), "-q"]
        assert cli.main([*workspace_argv, "-o", str(out_dir / "ws.npz"), *flag]) == 0
        out: dict[str, np.ndarray] = {"processes": np.asarray(jax.process_count())}

        # The planner on process-local rows: nobody holds every candidate.
        path = _process_local_path() if distributed else spiral(np.arange(N))
        ev = plan.evaluate(ROBOT, path, dt=DT, chunk_size=2)
        out["holds_every_candidate"] = np.asarray(_holds_every_candidate())
        _save_tree(out, "local", ev)
        out["local.best"], out["local.best_totals"] = plan.best(ev, 3)
        del path, ev

        # Host data, the same on every process: N rows, and N - 1 (not a multiple of 2).
        for n in (N, N - 1):
            ev = plan.evaluate(ROBOT, spiral(np.arange(n)), dt=DT, chunk_size=2)
            _save_tree(out, f"host{n}", ev)
            out[f"host{n}.best"], out[f"host{n}.best_totals"] = plan.best(ev, 3)

        for resolution in RESOLUTIONS:
            sweep = workspace.sweep(DELTA, resolution=resolution, chunk_size=SWEEP_CHUNK)
            name = f"ws{sweep.mask.shape[0]}"
            _save_tree(out, f"{name}.mask", sweep.mask)
            out[f"{name}.count"] = np.asarray(sweep.n_reachable)
            out[f"{name}.volume"] = np.asarray(sweep.volume)
            out[f"{name}.slice_areas"] = sweep.slice_areas

        guesses = paths.straight_line_guess(START, GOAL, 3, n_guesses=4, noise=10.0, seed=1)
        adam = optimize.Adam(1e-2)  # compiles in half the time of L-BFGS's line search
        result = optimize.optimize(
            ROBOT, START, GOAL, guesses, n_samples=T, steps=8, optimizer=adam
        )
        _save_tree(out, "optimize", result)

        trajectory = spiral(np.arange(2))
        table = np.c_[
            np.tile(np.arange(T) * DT, 2), np.repeat([0, 1], T), trajectory.p.reshape(-1, 3)
        ]
        # One copy per process: both write into the same directory, and a copy rewritten while
        # the other process reads it is seen empty
        source = out_dir / f"spiral-{jax.process_index()}.csv"
        np.savetxt(source, table, delimiter=",", header="t,candidate,x,y,z", comments="")
        ik_argv = ["ik", "scara", "--robot", "paper", "-i", str(source), "-q"]
        assert cli.main([*ik_argv, "-o", str(out_dir / "ik.csv"), *flag]) == 0
    finally:
        files.atomic_write = atomic_write
    out["writes"] = np.asarray(len(writes))
    return out


def main() -> None:
    jax.config.update("jax_enable_x64", True)
    cache = os.environ.get("JAXKIN_TEST_CACHE")
    if cache:
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
    out_dir = Path(sys.argv[1])
    out = run(out_dir, distributed=True)
    np.savez(out_dir / f"process-{jax.process_index()}.npz", **out)
    jax.distributed.shutdown()


if __name__ == "__main__":
    main()
