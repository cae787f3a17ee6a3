"""Randomised bad input at the service's boundary (seeded): every mutated message is parsed or
refused with the typed error naming its key, and the executive behind the bus keeps answering
finite commands to poses and scans that parse but make no sense.

The hand-picked cases are in ``test_service_messages.py`` and ``test_service_bus.py``; these
mutate valid messages at random (a field dropped, replaced by any JSON value, nested junk,
numbers beyond the float range, truncated text), which found an ``OverflowError`` on integers
like ``1e400`` written out as digits and a 37 GiB allocation for a lidar claiming a 1e8 m range.
"""

from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest

import navigation
from perception import ObstacleMap
from service import messages as m
from service.brain import ExecutiveBrain
from service.errors import MessageError, TaskRejected
from service.sim import Simulator

from .conftest import world_file

POSE = {"stamp": 1.0, "x": 0.5, "y": 2.5, "theta": 0.0}
SCAN = {"stamp": 1.0, "angle_min": -math.pi, "angle_increment": 0.1, "range_min": 0.0, "range_max": 1.5,
        "ranges": [1.0, 1.5, 0.7]}
POINTS = {"stamp": 1.0, "points": [[1.0, 2.0], [1.5, 2.0]]}
TASK = {"formula": "F a & F b", "mode": "add", "regions": {"a": {"center": [1.0, 1.0], "radius": 0.2}}}
CASES = {"pose": (m.parse_pose, POSE, MessageError), "scan": (m.parse_scan, SCAN, MessageError),
         "points": (m.parse_points, POINTS, MessageError), "task": (m.parse_task_request, TASK, TaskRejected)}
HUGE = 10 ** 400  # valid JSON (digits), beyond the float range


def _junk(rng: random.Random, depth: int = 0):
    """Any JSON value (and a few numbers JSON can carry but floats cannot)."""
    makers = [
        lambda: None, lambda: True, lambda: rng.randint(-10 ** 30, 10 ** 30),
        lambda: rng.choice([HUGE, -HUGE, 1e308, -1e308, 0, -0.0, 1e-320, -1]),
        lambda: rng.uniform(-1e6, 1e6), lambda: "", lambda: "x" * rng.randint(1, 40),
        lambda: "\u00e9\u2603\x00", lambda: rng.choice(["NaN", "inf", "F a"]),
        lambda: [[rng.random(), rng.random()] for _ in range(rng.randint(0, 3))],
    ]
    if depth < 3:
        makers += [lambda: [_junk(rng, depth + 1) for _ in range(rng.randint(0, 4))],
                   lambda: {str(_junk(rng, depth + 1)): _junk(rng, depth + 1) for _ in range(rng.randint(0, 3))},
                   lambda: {"center": _junk(rng, depth + 1), "radius": _junk(rng, depth + 1)}]
    return rng.choice(makers)()


def _mutate(rng: random.Random, msg: dict) -> bytes:
    msg = json.loads(json.dumps(msg))
    for _ in range(rng.randint(1, 3)):
        keys = list(msg)
        op = rng.randrange(4)
        if op == 0 and keys:
            msg[rng.choice(keys)] = _junk(rng)
        elif op == 1 and keys:
            del msg[rng.choice(keys)]
        elif op == 2:
            msg[str(_junk(rng))] = _junk(rng)
        elif keys:
            k = rng.choice(keys)
            if isinstance(msg[k], list) and msg[k]:
                msg[k][rng.randrange(len(msg[k]))] = _junk(rng)
            elif isinstance(msg[k], dict) and msg[k]:
                msg[k][rng.choice(list(msg[k]))] = _junk(rng)
    text = json.dumps(msg)  # NaN / Infinity allowed: senders write them
    if rng.random() < 0.1:
        text = text[:rng.randrange(len(text) + 1)]
    return text.encode("utf-8", "surrogatepass")


@pytest.mark.parametrize("key", CASES)
def test_mutated_messages_parse_or_are_refused_with_the_keys_error(key):
    parse, good, error = CASES[key]
    rng = random.Random(f"fuzz-{key}")
    refused = 0
    for _ in range(2500):
        payload = _mutate(rng, good)
        try:
            parse(payload)
        except error as err:
            refused += 1
            if error is MessageError:
                assert err.key == key and str(err).startswith(f"{key}: "), err
            else:
                assert err.code.value == "invalid_request" and str(err), err
    assert 500 < refused < 2500  # both outcomes exercised


@pytest.mark.parametrize("key, field", [("pose", "x"), ("pose", "stamp"), ("scan", "range_max"),
                                        ("scan", "angle_increment"), ("points", "stamp")])
def test_an_integer_beyond_the_float_range_is_a_non_finite_field(key, field):
    parse, good, _ = CASES[key]
    text = json.dumps(dict(good, **{field: 12345.5})).replace("12345.5", str(HUGE))
    with pytest.raises(MessageError, match=f"{field}.*finite"):
        parse(text.encode())


def test_integers_beyond_the_float_range_in_lists_are_infinities():
    # a range beyond the float range is no return, as Infinity is
    text = json.dumps(dict(SCAN, ranges=[1.0, 12345.5, 0.7])).replace("12345.5", str(HUGE))
    scan = m.parse_scan(text.encode())
    assert scan.beams == 3
    text = json.dumps(dict(POINTS, points=[[1.0, 2.0], [12345.5, 2.0]])).replace("12345.5", str(-HUGE))
    with pytest.raises(MessageError, match="non-finite"):
        m.parse_points(text.encode())
    text = json.dumps(dict(TASK, regions={"c": {"center": [1.0, 1.0], "radius": 12345.5}})).replace("12345.5", str(HUGE))
    with pytest.raises(TaskRejected, match="radius.*finite"):
        m.parse_task_request(text.encode())
    with pytest.raises(navigation.WorldError, match="finite"):
        navigation.world.Region("c", [1.0, 1.0], HUGE)


def test_the_simulator_and_world_files_refuse_integers_beyond_the_float_range(tmp_path):
    from service.sim.errors import CommandError

    world = navigation.load_world(world_file("simple"))
    sim = Simulator(world, seed=0)
    cmd = json.dumps({"stamp": 0.0, "v": 12345.5, "omega": 0.0}).replace("12345.5", str(HUGE))
    with pytest.raises(CommandError, match="finite"):
        sim.apply_cmd_vel(cmd)
    spec = json.loads(world_file("simple").read_text())
    spec["robot"]["radius"] = 12345.5
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(spec).replace("12345.5", str(HUGE)))
    with pytest.raises(navigation.WorldError, match="radius.*finite"):
        navigation.load_world(path)


def _paths(o, pre=()):
    yield pre
    if isinstance(o, dict):
        for k, v in o.items():
            yield from _paths(v, pre + (k,))
    elif isinstance(o, list):
        for i, v in enumerate(o[:3]):
            yield from _paths(v, pre + (i,))


def test_mutated_world_files_load_or_are_refused_with_a_world_error():
    """A world file with any field replaced by any JSON value (or dropped) loads or raises a
    ``HarmonicTampError`` naming the field; and the worlds that load build their navigation
    function (a 1e-300 m wide obstacle divided by zero there)."""
    import copy

    base = json.loads(world_file("office").read_text())
    paths = list(_paths(base))[1:]
    rng = random.Random("fuzz-world")
    loaded = refused = 0
    for _ in range(400):
        d = copy.deepcopy(base)
        for _ in range(rng.randint(1, 2)):
            p = rng.choice(paths)
            o = d
            try:
                for k in p[:-1]:
                    o = o[k]
                if rng.random() < 0.2 and isinstance(o, dict):
                    del o[p[-1]]
                else:
                    o[p[-1]] = _junk(rng)
            except (KeyError, IndexError, TypeError):
                pass  # an earlier mutation removed the way there
        try:
            navigation.World.from_dict(d)
            loaded += 1
        except navigation.HarmonicTampError as err:
            assert str(err)
            refused += 1
    assert loaded >= 5 and refused > 200
    for width in (1e-300, 1e-12):
        d = copy.deepcopy(base)
        d["obstacles"][3]["width"] = width
        try:
            world = navigation.World.from_dict(d)
        except navigation.WorldError as err:
            assert width < navigation.geometry.MIN_SIZE and "width" in str(err)
            continue
        nf = navigation.NavigationFunction(world, world.regions["d1"].center, inflation=world.robot.radius)
        assert np.isfinite(nf.value(np.array([[1.0, 0.5]]))).all()


def test_a_negative_simulator_seed_is_a_simulator_error():
    from service.sim.errors import SimulatorError

    world = navigation.load_world(world_file("simple"))
    for seed in (-1, 1.5, "0", True):
        with pytest.raises(SimulatorError, match="seed"):
            Simulator(world, seed=seed)
    Simulator(world, seed=np.random.default_rng(3))
    Simulator(world, seed=None)


def test_beam_angles_that_overflow_are_refused_not_nan_returns():
    with pytest.raises(MessageError, match="angle_increment.*overflow"):
        m.parse_scan(json.dumps(dict(SCAN, angle_min=1e308, angle_increment=1e308)).encode())


def test_a_lidar_claiming_an_absurd_range_marks_the_same_free_cells_as_one_within_the_grid():
    """Free space is marked along each beam up to its range; a 1e8 m range (or ``range_max``)
    used to allocate the samples of the whole length (37 GiB). Beyond the grid's diagonal a beam
    adds no cell, so the map is the same as with the ranges clipped there."""
    world = navigation.load_world(world_file("simple"))
    sim = Simulator(world, seed=0)
    pose, scan = sim.pose_message(), sim.scan_message()
    n = len(scan["ranges"])
    maps = []
    for rmax, r in ((1e9, 1e8), (30.0, 25.0)):
        omap = ObstacleMap.from_world(world)
        omap.update_scan(dict(scan, range_max=rmax, ranges=[r] * n), pose)
        maps.append(omap)
    assert maps[0]._free.any()
    np.testing.assert_array_equal(maps[0]._free, maps[1]._free)


def test_the_executive_answers_finite_commands_to_nonsense_that_parses():
    """Poses jumping or outside the workspace, scans with no returns, negative or absurd ranges,
    degenerate beam spacings, and random task requests (token soup, regions anywhere) between
    the simulator's own messages: every tick returns finite commands, every request is answered
    or refused with a task error, and the robot still drives its mission."""
    world = navigation.load_world(world_file("simple"))
    brain = ExecutiveBrain(world, "F a & F b")
    sim = Simulator(world, seed=0)
    rng = random.Random(7)
    tokens = ["F", "G", "X", "U", "R", "!", "&", "|", "->", "(", ")", "a", "b", "c", "zz", "true", " ", "&&", "9x", "\u00e9"]
    states = set()
    for _ in range(120):
        pose, scan = sim.pose_message(), sim.scan_message()
        r = rng.random()
        if r < 0.15:
            pose = dict(pose, x=rng.choice([-100.0, 1e12, pose["x"] + rng.uniform(-3, 3)]), y=rng.uniform(-2, 8))
        elif r < 0.35:
            n = len(scan["ranges"])
            scan = rng.choice([dict(scan, ranges=[None] * n), dict(scan, ranges=[rng.uniform(-1, 5) for _ in range(n)]),
                               dict(scan, ranges=[1e-9] * n), dict(scan, angle_increment=rng.choice([0.0, -0.1, 1e6])),
                               dict(scan, range_max=1e9, ranges=[1e8] * n)])
        elif r < 0.42:
            req = {"formula": "".join(rng.choice(tokens) for _ in range(rng.randint(1, 10))),
                   "mode": rng.choice(["replace", "add", "urgent"])}
            if rng.random() < 0.4:
                req["regions"] = {rng.choice(["c", "a"]): {"center": [rng.uniform(-2, 8), rng.uniform(-2, 8)],
                                                           "radius": rng.choice([0.2, 1e-9, 50.0])}}
            try:
                assert isinstance(brain.request_task(m.parse_task_request(json.dumps(req))), dict)
            except TaskRejected:
                pass
        pm, sm = m.parse_pose(json.dumps(pose)), m.parse_scan(json.dumps(scan))
        out = brain.tick(pm, scan=sm, scan_pose=pm, now=pm.stamp)
        assert math.isfinite(out.v) and math.isfinite(out.omega), out
        states.add(out.status["state"])
        sim.step((out.v, out.omega))
    assert not sim.metrics.collisions
    assert "error" in states and "executing" in states  # the bad poses were seen, and recovered from


@pytest.mark.parametrize("formula", ["!" * 5000 + "a", "(" * 3000 + "a" + ")" * 3000, "X " * 2000 + "a"])
def test_a_task_nested_thousands_deep_is_refused_as_a_parse_error(formula):
    """RecursionError escaped the task handler before (tamp.ltl.syntax.MAX_NESTING)."""
    brain = ExecutiveBrain(navigation.load_world(world_file("simple")), "F a")
    with pytest.raises(TaskRejected) as info:
        brain.request_task(m.parse_task_request(json.dumps({"formula": formula, "mode": "replace"})))
    assert info.value.code.value == "parse_error" and "nested deeper" in str(info.value)


def test_error_replies_quote_a_huge_mission_briefly():
    """A request may carry megabytes of formula; errors quote about 120 characters of it and
    list at most 20 unknown names (the planner's texts are the normalised formula, so a
    repeated conjunct is quoted once)."""
    from tamp.errors import UnsatisfiableError, brief

    assert brief("F a") == "'F a'" and brief("F a & " * 1000) == repr(("F a & " * 1000)[:120]) + "... (6000 characters)"
    err = UnsatisfiableError(" & ".join(f"F r{i}" for i in range(5000)), "detail")
    assert len(str(err)) < 300 and str(err).endswith("(detail)")
    brain = ExecutiveBrain(navigation.load_world(world_file("simple")), "F a")
    names = " & ".join(f"F z{i}" for i in range(500))
    with pytest.raises(TaskRejected) as info:
        brain.request_task(m.parse_task_request(json.dumps({"formula": names, "mode": "replace"})))
    assert info.value.code.value == "unknown_region" and "(480 more)" in str(info.value) and len(str(info.value)) < 600
