"""Results print their status codes by name (``status.NamedStatusRepr``)."""

import importlib
import pkgutil

import jax
import numpy as np

import jaxkin
from jaxkin import collision, scara
from jaxkin.motion.planner import MotionPlan
from jaxkin.motion.status import MotionStatus
from jaxkin.status import NamedStatusRepr, Status, named_codes


def test_ik_result_names_its_statuses():
    robot = scara.Scara.paper()
    targets = np.array([[110.0, -50.0, 40.0], [900.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    result = jaxkin.ik(robot, targets)
    codes = np.asarray(result.status)
    expected = ", ".join(Status(int(c)).name for c in codes)
    assert expected == "OK, UNREACHABLE, INVALID_INPUT"
    assert f"status=Array([{expected}], dtype=int8)" in repr(result)
    assert "margin=Array(" in repr(result)  # the other fields as the dataclass prints them


def test_collision_check_names_collision():
    robot = scara.Scara(150.0, 80.0, 50.0, link_radius=4.0)
    world = collision.World.create(spheres=collision.Spheres.create([[130.0, 0.0, 150.0]], 10.0))
    q = np.array([[0.0, 0.0, 10.0], [np.pi / 2, 0.0, 10.0]])
    result = collision.check(robot, q, world)
    np.testing.assert_array_equal(result.status, [Status.COLLISION, Status.OK])
    assert "status=Array([COLLISION, OK], dtype=int8)" in repr(result)
    verdict = collision.collides(robot, q, world)
    assert repr(verdict).startswith("Verdict(collides=Array([ True, False], dtype=bool), status=")
    assert "status=Array([COLLISION, OK], dtype=int8)" in repr(verdict)


def test_traced_results_and_other_values_print_as_before():
    robot = scara.Scara.paper()
    seen = []

    @jax.jit
    def solve(x):
        result = jaxkin.ik(robot, x)
        seen.append(repr(result))  # a tracer: its own repr
        return result.status

    solve(np.array([[110.0, -50.0, 40.0]]))
    assert "status=JitTracer(int8[1])" in seen[0]
    assert named_codes(np.array([0.5]), Status) is None  # floats are no codes
    assert named_codes(None, Status) is None
    # a number that is no code stays a number; two dimensions as numpy prints them
    assert named_codes(np.array([[0, 11], [99, 7]], np.int8), Status) == (
        "array([[OK, COLLISION],\n       [99, OUT_OF_LIMITS]], dtype=int8)"
    )


def test_motion_plan_names_both_of_its_enums():
    plan = MotionPlan(
        status=np.array([MotionStatus.SOLVED, MotionStatus.NO_PATH], np.int8),
        path=np.zeros((2, 1, 2)),
        path_count=np.ones(2, np.int32),
        simplified=np.zeros((2, 1, 2)),
        simplified_count=np.ones(2, np.int32),
        smooth=np.ones(2, bool),
        goal=np.zeros((2, 2)),
        iterations=np.zeros(2, np.int32),
        certified=np.ones(2, bool),
        trajectory=None,
        duration=np.zeros(2),
        timing_status=np.array([Status.OK, Status.UNTIMEABLE], np.int8),
    )
    text = repr(plan)
    assert "status=array([SOLVED, NO_PATH], dtype=int8)" in text
    assert "timing_status=array([OK, UNTIMEABLE], dtype=int8)" in text


def test_every_result_class_with_a_status_prints_names():
    """Every public dataclass of the package with a ``status`` field uses the named repr
    (a subclass that is a dataclass of its own too)."""
    for info in pkgutil.walk_packages(jaxkin.__path__, "jaxkin."):
        if info.name.startswith(("jaxkin.cli", "jaxkin.plot", "jaxkin.viewer")):
            continue
        importlib.import_module(info.name)
    missing, checked = [], 0
    for cls in _subclasses(object):
        fields = getattr(cls, "__dataclass_fields__", {})
        module = getattr(cls, "__module__", "") or ""
        if "status" not in fields or not module.startswith("jaxkin") or cls.__name__[0] == "_":
            continue
        checked += 1
        if cls.__repr__ is not NamedStatusRepr.__repr__:
            missing.append(f"{module}.{cls.__qualname__}")
    assert missing == [] and checked >= 15  # IKResult, Evaluation, CheckResult, ...


def _subclasses(cls):
    seen, stack = set(), [cls]
    while stack:
        current = stack.pop()
        try:
            subs = current.__subclasses__()
        except TypeError:  # type's own __subclasses__ is unbound on type
            subs = []
        for sub in subs:
            if sub not in seen:
                seen.add(sub)
                stack.append(sub)
    return seen
