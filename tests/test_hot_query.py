"""Hot single queries: a robot asked one element at a time gets its own program, the geometry
compiled in as constants, with the results and statuses of the batched path."""

import importlib.metadata

import jax
import jax.numpy as jnp
import numpy as np

import jaxkin
from jaxkin import scara, serial
from jaxkin._execute import handles, pipeline
from jaxkin._execute.handles import HotQueries
from jaxkin.jet import Jet
from jaxkin.result import FKResult
from jaxkin.status import Status
from tests.helpers import compilations


def _screw_chain():
    """A spatial 3R chain (not planar: every joint moves the tip differently)."""
    screws = np.array(
        [[0, 0, 1, 0, 0, 0], [0, 1, 0, -0.4, 0, 0], [0, 1, 0, -0.9, 0, 0.3]], dtype=float
    )
    home = np.eye(4)
    home[:3, 3] = [0.3, 0.0, 1.2]
    return serial.from_screws(screws, home)


def test_hot_scara_ik_and_fk_equal_the_batched_path(hot_after_two):
    """The hot program's joints, rates, margin and statuses equal the batch's element (4 ulp
    of the robot's size): reachable, unreachable and NaN targets, batch () and (1,). The IK's
    program has three outputs (the zero rates are constants) and no reduction: inside a fused
    loop of one element, a reduction costs every call a buffer that XLA's CPU runtime sets
    up anew (``_numerics.all_last``)."""
    robot = scara.Scara.paper()
    targets = jnp.asarray([[60.0, 70.0, 40.0], [500.0, 0.0, 40.0], [np.nan, 1.0, 2.0]])
    batched = jaxkin.ik(robot, targets)
    tol = 4 * np.finfo(np.float64).eps * float(robot.length_scale())
    for i in range(3):
        for shape in ((3,), (1, 3)):
            target = targets[i].reshape(shape)
            first = jaxkin.ik(robot, target)
            hot = jaxkin.ik(robot, target)  # from the second call on: the hot program
            assert type(hot) is type(first) and hot.q.p.shape == shape
            for got in (first, hot):
                assert int(got.status.reshape(())) == int(batched.status[i])
                for leaf, want in zip(jax.tree.leaves(got), jax.tree.leaves(batched), strict=True):
                    np.testing.assert_allclose(
                        np.asarray(leaf, float).reshape(np.shape(want)[1:]),
                        np.asarray(want[i], float),
                        rtol=0,
                        atol=tol,
                    )
    assert [int(s) for s in batched.status][2] == Status.INVALID_INPUT
    programs = [p for key, (_, p) in pipeline.HOT.programs.items() if key[1] == "ik"]
    assert len(programs) == 2  # one per input shape
    for program in programs:
        assert len(program.compiled.out_info) == 3
        assert " reduce(" not in program.compiled.as_text()
    q = batched.q.p[0]
    want = jaxkin.fk(robot, batched.q.p)
    for _ in range(2):
        got = jaxkin.fk(robot, q)
    assert isinstance(got, FKResult) and isinstance(got.x, Jet)
    np.testing.assert_allclose(got.x.p, want.x.p[0], rtol=0, atol=tol)
    np.testing.assert_array_equal(got.x.v, np.zeros(3))
    assert int(got.status) == int(want.status[0])


def test_hot_chain_fk_equals_the_batched_path_and_compiles_once(hot_after_two):
    chain = _screw_chain()
    qs = jnp.asarray([[0.3, -0.5, 1.1], [1.0, 0.2, -0.4], [np.inf, 0.0, 0.0]])
    batched = jaxkin.fk(chain, qs)
    for i in range(3):
        jaxkin.fk(chain, qs[i])
        got = jaxkin.fk(chain, qs[i])
        np.testing.assert_allclose(got.x.p, batched.x.p[i], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(got.x.a, batched.x.a[i])
        assert int(got.status) == int(batched.status[i])
    with compilations() as count:
        for i in range(3):
            jax.block_until_ready(jaxkin.fk(chain, qs[i]).x.p)
    assert count.n == 0


def _panda():
    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    return serial.from_urdf(str(robots / "panda_description/urdf/panda.urdf"), "panda_hand")


def test_hot_panda_fk_equals_the_batched_path_runs_inline_and_compiles_once(hot_after_two):
    """The 7-joint chain of a URDF (with its link bodies): one configuration, through the
    single-query program and then the hot one, equals the batch's element (4 ulp of the
    robot's size; the joints in a loop there, unrolled in the batch: the same operations),
    statuses included (a NaN joint: INVALID_INPUT, the pose at q = 0); batch () and (1,).
    The hot program stays below the 1000 flops under which XLA's CPU client runs a program
    on the calling thread (above it, every call waits for a worker thread), and its later
    calls compile nothing."""
    panda = _panda()
    qs = np.array(
        [[0.1, -0.3, 0.2, -1.8, 0.1, 1.6, 0.4], [2.5, 1.2, -2.0, -0.2, 2.8, 3.5, -2.6], [0.0] * 7]
    )
    qs[2, 3] = np.nan
    batched = jaxkin.fk(panda, jnp.asarray(qs))
    at_zero = jaxkin.fk(panda, jnp.zeros((2, 7))).x.p[0]
    tol = 4 * np.finfo(np.float64).eps * float(panda.length_scale())
    for i in range(3):
        for shape in ((7,), (1, 7)):
            q = jnp.asarray(qs[i]).reshape(shape)
            for _ in range(2):  # the single-query program, then the hot one
                got = jaxkin.fk(panda, q)
                assert got.x.p.shape == (*shape[:-1], 4, 4)
                np.testing.assert_allclose(
                    np.asarray(got.x.p).reshape(4, 4), batched.x.p[i], rtol=0, atol=tol
                )
                np.testing.assert_array_equal(got.x.v, np.zeros((*shape[:-1], 4, 4)))
                assert int(got.status.reshape(())) == int(batched.status[i])
    assert int(batched.status[2]) == Status.INVALID_INPUT
    np.testing.assert_allclose(batched.x.p[2], at_zero, rtol=0, atol=tol)
    programs = [p for key, (_, p) in pipeline.HOT.programs.items() if key[1] == "fk"]
    assert len(programs) == 2  # one per input shape
    for program in programs:
        cost = program.compiled.cost_analysis()
        assert (cost[0] if isinstance(cost, list) else cost)["flops"] < 1000
    with compilations() as count:
        for i in range(3):
            jax.block_until_ready(jaxkin.fk(panda, jnp.asarray(qs[i])).x.p)
            jax.block_until_ready(jaxkin.fk(panda, qs[i]).x.p)  # a NumPy array: its own key
            jax.block_until_ready(jaxkin.fk(panda, qs[i]).x.p)
    assert count.n == 0


def test_scara_ik_at_rest_equals_the_rates_path():
    """At rest the SCARA IK solves positions only (no rate formulas): joints, statuses and
    margin equal the analytic path given the same targets with explicit zero rates (4 ulp of
    the robot's size): reachable, unreachable, on the outer boundary, NaN, and out of a
    joint's limits."""
    robot = scara.Scara.paper()
    reach = float(robot.l_ab + robot.l_bc)
    targets = jnp.asarray(
        [[60.0, 70.0, 40.0], [500.0, 0.0, 40.0], [reach, 0.0, 10.0], [np.nan, 1.0, 2.0]]
    )
    limited = scara.Scara.create(
        l_oa=robot.l_oa,
        l_ab=robot.l_ab,
        l_bc=robot.l_bc,
        limits={"theta1": (-0.1, 0.1)},
    )
    tol = 4 * np.finfo(np.float64).eps * float(robot.length_scale())
    for r in (robot, limited):
        at_rest = jaxkin.ik(r, targets)
        moving = jaxkin.ik(r, Jet(targets, jnp.zeros_like(targets), jnp.zeros_like(targets)))
        np.testing.assert_array_equal(at_rest.status, moving.status)
        for got, want in ((at_rest.q.p, moving.q.p), (at_rest.margin, moving.margin)):
            np.testing.assert_allclose(got, want, rtol=0, atol=tol)
        np.testing.assert_array_equal(at_rest.q.v, np.zeros((4, 3)))
        np.testing.assert_array_equal(at_rest.q.a, np.zeros((4, 3)))
    statuses = [int(s) for s in jaxkin.ik(robot, targets).status]
    assert statuses == [
        Status.OK,
        Status.UNREACHABLE,
        Status.SINGULAR_EXTENDED,
        Status.INVALID_INPUT,
    ]
    assert int(jaxkin.ik(limited, targets).status[0]) == Status.OUT_OF_LIMITS


def test_hot_programs_belong_to_one_robot_object(hot_after_two):
    """Another robot (other lengths) is never answered by the first one's program; inputs
    inside ``jit`` and Jets take the usual path."""
    first, second = scara.Scara.paper(), scara.Scara(150.0, 60.0, 50.0)
    q = jnp.asarray([0.4, -0.7, 10.0])
    for _ in range(3):
        a, b = jaxkin.fk(first, q).x.p, jaxkin.fk(second, q).x.p
    np.testing.assert_allclose(a, jaxkin.fk(first, q[None]).x.p[0], rtol=0, atol=1e-13)
    np.testing.assert_allclose(b, jaxkin.fk(second, q[None]).x.p[0], rtol=0, atol=1e-13)
    assert not np.allclose(a, b)
    traced = jax.jit(lambda x: jaxkin.fk(first, x).x.p)(q)
    np.testing.assert_allclose(traced, a, rtol=0, atol=1e-13)
    jet = jaxkin.fk(first, Jet(q, jnp.ones(3), jnp.zeros(3)))
    assert np.any(np.asarray(jet.x.v) != 0)


def test_input_dependence_follows_nested_calls():
    def fn(x):
        inner = jax.jit(lambda y: (y * 2.0, jnp.zeros(3)))
        moving, zeros = inner(x)
        return {"moving": moving, "zeros": zeros, "one": jnp.ones(2), "sum": x + zeros}

    traced = jax.jit(fn).trace(jnp.ones(3))
    flags = handles._input_dependent(traced.jaxpr.jaxpr)
    names = [str(path[0].key) for path, _ in jax.tree_util.tree_flatten_with_path(fn(1.0))[0]]
    assert dict(zip(names, flags, strict=True)) == {
        "moving": True,
        "one": False,
        "sum": True,
        "zeros": False,
    }
    program = handles.Handle(fn, (jnp.ones(3),))
    out = program(jnp.arange(3.0))
    np.testing.assert_array_equal(out["moving"], [0.0, 2.0, 4.0])
    np.testing.assert_array_equal(out["zeros"], np.zeros(3))
    np.testing.assert_array_equal(out["one"], np.ones(2))


def test_batches_never_push_hot_programs_out(hot_after_two, monkeypatch):
    """Keys without a program (batches, here of several sizes) are kept apart from the
    programs, so a table of one program keeps it however many batch shapes come."""
    monkeypatch.setattr(pipeline, "HOT", HotQueries(size=1))
    robot = scara.Scara.paper()
    q = jnp.asarray([0.4, -0.7, 10.0])
    for _ in range(2):
        jaxkin.fk(robot, q)
    (program,) = [entry[1] for entry in pipeline.HOT.programs.values()]
    for n in (2, 3, 5, 6, 9):
        for _ in range(2):
            jaxkin.fk(robot, jnp.tile(q, (n, 1)))
    assert [entry[1] for entry in pipeline.HOT.programs.values()] == [program]
    assert len(pipeline.HOT.none) <= 4


def test_a_robot_rebuilt_with_the_same_values_shares_the_hot_program(hot_after_two):
    """A caller that builds its robot anew (same values) gets the program already compiled
    for an equal robot: nothing compiles once the first object's program exists."""
    target = jnp.asarray([60.0, 70.0, 40.0])
    first = scara.Scara.paper()
    for _ in range(3):  # the second call builds the hot program
        jaxkin.ik(first, target)
    with compilations() as count:
        for _ in range(3):
            robot = scara.Scara.paper()
            for _ in range(3):  # its second call finds the equal robot's program
                result = jaxkin.ik(robot, target)
    assert count.n == 0
    assert int(result.status) == Status.OK
    assert len(pipeline.HOT.by_value) == 1
