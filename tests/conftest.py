"""Test configuration: float64 on (the library itself never touches global config), and JAX's
persistent compilation cache shared by the test processes, so that a program compiled once (by
another test or another worker with the same computation) is loaded rather than compiled
again. Tests that count compilations count ``jax.jit`` specialisations, which the cache does
not change."""

import os
import tempfile

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update(
    "jax_compilation_cache_dir",
    os.environ.get("JAXKIN_TEST_CACHE", os.path.join(tempfile.gettempdir(), "jaxkin-test-cache")),
)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)

# The slow tests: ``make test`` leaves them out (it must finish within five minutes on two
# cores), ``make test-slow`` runs them, and CI runs both. Each repeats, for another robot, more
# processes or a larger problem, what a test of the default run checks.
SLOW = (
    "tests/test_distributed.py::",
    "tests/test_optimize.py::test_other_robots_and_joint_space_ends",
    "tests/test_examples.py::test_optimise_scara",
    "tests/test_robot.py::test_round_trip_every_branch[poe-chain]",
    "tests/test_robot.py::test_round_trip_every_branch[dh-table]",
    "tests/test_robot.py::test_rates_round_trip[poe-chain]",
    "tests/test_robot.py::test_rates_round_trip[dh-table]",
    "tests/test_robot.py::test_plain_arrays_are_at_rest_and_errors_name_the_argument[poe-chain]",
    "tests/test_fuzz.py::",
    "tests/test_urdf.py::test_pose_paths_through_the_planner",
    "tests/test_robot.py::test_jit_vmap_and_no_recompilation[dh-table]",
    "tests/test_robot.py::test_plain_arrays_are_at_rest_and_errors_name_the_argument[dh-table]",
    "tests/test_plan.py::test_every_robot_with_default_arguments[dh-table]",
    "tests/test_plan.py::test_every_robot_best_branch",
    "tests/test_plan.py::test_sharded_equals_unsharded",
    "tests/test_optimize.py::test_adam_decreases_cost",
    "tests/test_robot.py::test_round_trip_every_branch[stanford]",
    "tests/test_robot.py::test_plain_arrays_are_at_rest_and_errors_name_the_argument[stanford]",
    "tests/test_urdf.py::test_ik_without_a_seed_solves_within_limits[ur5]",
    "tests/test_urdf.py::test_ik_without_a_seed_solves_within_limits[so101]",
    "tests/test_urdf.py::test_command_line_pose_files_of_a_urdf_arm",
    "tests/test_examples.py::test_fixed_point_accuracy",
    "tests/test_examples.py::test_urdf_arm",
    "tests/test_docs.py::test_block_runs[docs/planning.md-1]",
    "tests/test_docs.py::test_block_runs[docs/urdf.md-1]",
    "tests/test_docs.py::test_block_runs[docs/cli.md-1]",
    "tests/test_robot.py::test_rates_round_trip[stanford]",
    "tests/test_urdf.py::test_host_thread_parts_give_the_results_of_one_thread",
)


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.nodeid.startswith(SLOW):
            item.add_marker(pytest.mark.slow)
