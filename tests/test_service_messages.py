"""Message validation: every input key refuses bad payloads with a typed error naming the key."""

from __future__ import annotations

import json
import math

import pytest

from service import messages as m
from service.errors import MessageError, TaskErrorCode, TaskRejected

POSE = {"stamp": 1.0, "x": 0.5, "y": 2.5, "theta": 0.0}
SCAN = {"stamp": 1.0, "angle_min": -math.pi, "angle_increment": 0.1, "range_min": 0.0, "range_max": 1.5,
        "ranges": [1.0, 1.5, 0.7]}
POINTS = {"stamp": 1.0, "points": [[1.0, 2.0], [1.5, 2.0]]}
PARSERS = {"pose": (m.parse_pose, POSE), "scan": (m.parse_scan, SCAN), "points": (m.parse_points, POINTS)}

GARBAGE = [b"\xff\xfe\x00garbage", b"", b"not json", b"[1, 2, 3]", b"42", b'"text"', b"null", b"{" * 100000]


@pytest.mark.parametrize("key", PARSERS)
def test_valid_message_parses(key):
    parse, good = PARSERS[key]
    assert parse(json.dumps(good).encode()).stamp == 1.0


@pytest.mark.parametrize("key", PARSERS)
@pytest.mark.parametrize("payload", GARBAGE, ids=range(len(GARBAGE)))
def test_garbage_is_a_message_error(key, payload):
    parse, _ = PARSERS[key]
    with pytest.raises(MessageError) as info:
        parse(payload)
    assert info.value.key == key and str(info.value).startswith(f"{key}: ")


def _numeric_fields(msg):
    return [k for k, v in msg.items() if isinstance(v, (int, float))]


@pytest.mark.parametrize("key", PARSERS)
@pytest.mark.parametrize("bad", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_header_numbers_are_refused(key, bad):
    parse, good = PARSERS[key]
    for field in _numeric_fields(good):
        text = json.dumps(dict(good, **{field: 12345.5})).replace("12345.5", bad)
        with pytest.raises(MessageError, match=field):
            parse(text.encode())


@pytest.mark.parametrize("key", PARSERS)
def test_missing_and_wrongly_typed_fields_name_the_field(key):
    parse, good = PARSERS[key]
    for field in good:
        with pytest.raises(MessageError, match=field):
            parse(json.dumps({k: v for k, v in good.items() if k != field}))
        with pytest.raises(MessageError, match=field):
            parse(json.dumps(dict(good, **{field: "x" if field != "stamp" else True})))


def test_scan_ranges_must_be_a_flat_list_of_numbers():
    for ranges in ([[1.0, 2.0]], [1.0, "a"], [True], [], {"a": 1}):
        with pytest.raises(MessageError, match="ranges"):
            m.parse_scan(dict(SCAN, ranges=ranges))


def test_non_finite_ranges_are_no_returns_not_errors():
    text = json.dumps(dict(SCAN, ranges=[1.0, 7.0, 0.5])).replace("7.0", "NaN")
    assert m.parse_scan(text).beams == 3


def test_non_finite_points_drop_the_message():
    text = json.dumps(dict(POINTS, points=[[1.0, 2.0], [1.0, 7.5]])).replace("7.5", "Infinity")
    with pytest.raises(MessageError, match="non-finite"):
        m.parse_points(text)
    with pytest.raises(MessageError, match=r"shape \(N, 2\)"):
        m.parse_points(dict(POINTS, points=[[1.0, 2.0, 3.0]]))


@pytest.mark.parametrize("payload, field", [
    (b"\xff", "UTF-8"), (b"[]", "object"), ({"mode": "add"}, "formula"), ({"formula": ""}, "formula"),
    ({"formula": 3}, "formula"), ({"formula": "F a", "mode": "later"}, "mode"),
    ({"formula": "F a", "extra": 1}, "extra"), ({"formula": "F a", "regions": []}, "regions"),
    ({"formula": "F a", "regions": {"d": {"center": [0, 0]}}}, "regions.d"),
    ({"formula": "F a", "regions": {"D": {"center": [0, 0], "radius": 1}}}, "regions.D"),
])
def test_task_request_shape_errors_are_invalid_request(payload, field):
    if isinstance(payload, dict):
        payload = json.dumps(payload)
    with pytest.raises(TaskRejected, match=field) as info:
        m.parse_task_request(payload)
    assert info.value.code is TaskErrorCode.INVALID_REQUEST
    reply = info.value.to_reply()
    assert reply["ok"] is False and reply["error"]["code"] == "invalid_request"


def test_task_request_defaults_and_regions():
    req = m.parse_task_request(json.dumps({"formula": "F a", "regions": {"d": {"center": [1, 2], "radius": 0.2}}}))
    assert req.mode.value == "replace" and req.regions["d"].center == (1.0, 2.0)


def test_builders_emit_strict_json():
    assert json.loads(m.encode(m.cmd_vel_message(1.0, 0.2, -0.1))) == {"stamp": 1.0, "v": 0.2, "omega": -0.1}
    st = m.status_message(2.0, "executing", task="F a", plan={"prefix": ["a"], "suffix": ["a"]}, target="a",
                          waypoint=(1.0, 2.0, 0.5), obstacles=3)
    assert set(m.STATUS_FIELDS) <= set(json.loads(m.encode(st)))
    with pytest.raises(ValueError, match="state"):
        m.status_message(0.0, "running")
    with pytest.raises(ValueError, match="v must be finite"):
        m.cmd_vel_message(0.0, math.nan, 0.0)


def test_points_messages_reach_perception_and_the_robot_completes_on_them_alone():
    """``points`` instead of ``scan`` (FORMATS.md): the brain hands perception a points
    *message*. Until the forty-eighth session it handed over the bare array, which perception
    refused, so every points message on the bus was dropped and the map never grew."""
    import math

    import navigation
    from service.brain import ExecutiveBrain
    from service.sim import Simulator

    from .conftest import world_file

    world = navigation.load_world(world_file("simple"))
    brain = ExecutiveBrain(world, "F a & F b")
    sim = Simulator(world, seed=0)
    messages = []
    for _ in range(1500):
        pm = m.parse_pose(json.dumps(sim.pose_message()))
        pts = m.parse_points(json.dumps(sim.points_message()))
        out = brain.tick(pm, points=pts, scan_pose=pm, now=pm.stamp)
        assert math.isfinite(out.v) and math.isfinite(out.omega)
        messages.append(out.status["message"])
        if out.status["state"] == "done":
            break
        sim.step((out.v, out.omega))
    assert out.status["state"] == "done", messages[-5:]
    assert not any("input dropped" in msg for msg in messages), [x for x in messages if "dropped" in x][:3]
    assert len(brain._ex.obstacles) > 0 and not sim.metrics.collisions
