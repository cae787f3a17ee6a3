"""Guarantees of navigation.world: the shared worlds load, bad input is rejected by field name,
and worlds round-trip through their JSON form."""

from __future__ import annotations

import copy
import json
import math

import pytest

from navigation.errors import WorldError
from navigation.forest import Forest
from navigation.geometry import Squircle
from navigation.world import Event, EventMode, LidarSpec, Region, RobotSpec, World, load_world

from .conftest import world_file


@pytest.fixture(scope="module")
def simple_dict() -> dict:
    return json.loads(world_file("simple").read_text())


# ---------------------------------------------------------------------- shared worlds
class TestSharedWorlds:
    def test_simple(self):
        w = load_world(world_file("simple"))
        assert w.name == "simple"
        assert len(w.obstacles) == 4
        assert w.known_obstacles == (0, 1, 2, 3)
        assert set(w.regions) == {"a", "b", "c"}
        assert w.events == ()
        assert w.robot.start == (0.5, 2.5, 0.0)
        assert w.lidar.beams == 360 and isinstance(w.lidar.beams, int)

    def test_office(self):
        w = load_world(world_file("office"))
        assert (w.workspace.width, w.workspace.height) == (7.0, 4.0)
        assert len(w.obstacles) == 22
        assert w.known_obstacles == ()
        assert set(w.regions) == {"p1", "p2", "d1", "d2", "d3", "u1"}
        assert w.events == (Event(60.0, "F u1", EventMode.URGENT),)
        assert w.events[0].mode == "urgent"  # the enum compares equal to its JSON spelling

    def test_cluttered20(self):
        w = load_world(world_file("cluttered20"))
        assert len(w.obstacles) == 20
        assert list(w.regions) == ["d1", "d2", "d3", "d4"]
        assert w.task == "F d1 & F d2 & F d3 & F d4"
        assert w.known_obstacles == () and w.events == ()

    @pytest.mark.parametrize("name", ["simple", "office", "cluttered20"])
    def test_round_trip(self, name, tmp_path):
        w = load_world(world_file(name))
        assert World.from_dict(w.to_dict()) == w
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(w.to_dict(), indent=1))
        assert load_world(path) == w
        assert World.from_dict(json.loads(json.dumps(w.to_dict()))).to_dict() == w.to_dict()


# ---------------------------------------------------------------------- invalid input
def _set(d: dict, path: str, value) -> None:
    """Set (or delete, for value ``...``) the entry at a dotted/indexed ``path`` of ``d``."""
    keys: list = []
    for part in path.split("."):
        name, *idx = part.replace("]", "").split("[")
        keys.append(name)
        keys.extend(int(i) for i in idx)
    for k in keys[:-1]:
        d = d[k]
    if value is ...:
        del d[keys[-1]]
    else:
        d[keys[-1]] = value


INVALID = [
    # (path to change, new value (... deletes), expected field)
    ("robot", ..., "robot"),
    ("name", ..., "name"),
    ("task", ..., "task"),
    ("robot.v_max", ..., "robot.v_max"),
    ("obstacles[3].width", ..., "obstacles[3].width"),
    ("regions.a.radius", ..., "regions.a.radius"),
    ("name", 7, "name"),
    ("name", "", "name"),
    ("task", 3, "task"),
    ("workspace", [0, 0, 4, 3], "workspace"),
    ("obstacles", {"0": {}}, "obstacles"),
    ("obstacles[3].width", "wide", "obstacles[3].width"),
    ("obstacles[3].width", -0.2, "obstacles[3].width"),
    ("obstacles[1].center", [math.nan, 1.0], "obstacles[1].center"),
    ("obstacles[0].s", 1.5, "obstacles[0].s"),
    ("workspace.height", math.inf, "workspace.height"),
    ("regions.a.radius", -0.1, "regions.a.radius"),
    ("regions.a.radius", 0.0, "regions.a.radius"),
    ("regions.a.radius", math.nan, "regions.a.radius"),
    ("regions.a.center", [0.5], "regions.a.center"),
    ("regions.a.center", [0.5, math.inf], "regions.a.center[1]"),
    ("regions.a.colour", "red", "regions.a.colour"),
    ("regions", [], "regions"),
    ("robot.radius", -0.1, "robot.radius"),
    ("robot.radius", "big", "robot.radius"),
    ("robot.v_max", 0.0, "robot.v_max"),
    ("robot.v_max", -1.0, "robot.v_max"),
    ("robot.omega_max", math.nan, "robot.omega_max"),
    ("robot.start", [0.5], "robot.start"),
    ("robot.start", "home", "robot.start"),
    ("robot.start", [math.nan, 2.5, 0.0], "robot.start[0]"),
    ("robot.start", [0.5, 2.5, math.inf], "robot.start[2]"),
    ("lidar.range", math.inf, "lidar.range"),
    ("lidar.range", -1.0, "lidar.range"),
    ("lidar.fov", 7.0, "lidar.fov"),
    ("lidar.beams", 12.5, "lidar.beams"),
    ("lidar.beams", 0, "lidar.beams"),
    ("lidar.beams", True, "lidar.beams"),
    ("lidar.noise_std", -0.01, "lidar.noise_std"),
    ("lidar.rate_hz", 0, "lidar.rate_hz"),
    ("known_obstacles", [0, 7], "known_obstacles[1]"),
    ("known_obstacles", [-1], "known_obstacles[0]"),
    ("known_obstacles", [0, 0], "known_obstacles[1]"),
    ("known_obstacles", ["0"], "known_obstacles[0]"),
    ("known_obstacles", [1.0], "known_obstacles[0]"),
    ("known_obstacles", 3, "known_obstacles"),
    ("events", [{"time": 1.0, "task": "F a", "mode": "later"}], "events[0].mode"),
    ("events", [{"time": -1.0, "task": "F a", "mode": "add"}], "events[0].time"),
    ("events", [{"time": math.nan, "task": "F a", "mode": "add"}], "events[0].time"),
    ("events", [{"time": 1.0, "mode": "add"}], "events[0].task"),
    ("events", [{"time": 1.0, "task": "F a", "mode": "add"}, 5], "events[1]"),
    ("events", {"time": 1.0}, "events"),
    ("colour", "red", "colour"),
]


def _assert_names(err: WorldError, field: str) -> None:
    assert err.field == field
    assert str(err).startswith(field + ":") or (field.rpartition(".")[0] in str(err)
                                                and field.rpartition(".")[2] in str(err)), str(err)


@pytest.mark.parametrize("path, value, field", INVALID, ids=[f"{p}={v!r}" for p, v, _ in INVALID])
def test_invalid_field_is_named(simple_dict, path, value, field):
    d = copy.deepcopy(simple_dict)
    _set(d, path, value)
    with pytest.raises(WorldError) as info:
        World.from_dict(d)
    _assert_names(info.value, field)


@pytest.mark.parametrize("name", ["A1", "1a", "a-b", "", "true", "false", "a b"])
def test_bad_region_names(simple_dict, name):
    d = copy.deepcopy(simple_dict)
    d["regions"][name] = d["regions"].pop("c")
    with pytest.raises(WorldError) as info:
        World.from_dict(d)
    assert info.value.field == f"regions.{name}"
    assert "[a-z][a-z0-9_]*" in str(info.value)


def test_event_mode_rejection_lists_the_choices():
    with pytest.raises(WorldError, match="must be one of 'urgent', 'add', 'replace'"):
        EventMode.parse("soon", "events[0].mode")


# ---------------------------------------------------------------------- validity rule
class TestValidityRule:
    def _expect(self, d: dict, field: str, *words: str) -> None:
        with pytest.raises(WorldError) as info:
            World.from_dict(d)
        assert info.value.field == field
        assert str(info.value).startswith(field + ":")
        for word in words:
            assert word in str(info.value)

    def test_region_inside_an_obstacle(self, simple_dict):
        d = copy.deepcopy(simple_dict)
        d["regions"]["b"]["center"] = [2.6, 0.9]  # obstacle 2
        self._expect(d, "regions.b", "obstacles[2]")

    def test_region_clear_but_not_with_the_robot_radius(self, simple_dict):
        d = copy.deepcopy(simple_dict)
        # obstacle 0 is the disc of radius 0.2 at (1.0, 1.5); region radius 0.15, robot 0.1
        d["regions"]["a"]["center"] = [1.0 + 0.2 + 0.15 + 0.05, 1.5]
        self._expect(d, "regions.a", "robot radius 0.1", "obstacles[0]")
        d["regions"]["a"]["center"] = [1.0 + 0.2 + 0.15 + 0.1 + 1e-6, 1.5]
        World.from_dict(d)

    def test_region_near_the_workspace_boundary(self, simple_dict):
        d = copy.deepcopy(simple_dict)
        d["regions"]["a"]["center"] = [0.2, 0.5]  # 0.2 m from the left wall < 0.15 + 0.1
        self._expect(d, "regions.a", "not inside the workspace")
        d["regions"]["a"]["center"] = [-1.0, 0.5]
        self._expect(d, "regions.a", "not inside the workspace")

    def test_start_in_an_obstacle_or_outside(self, simple_dict):
        d = copy.deepcopy(simple_dict)
        d["robot"]["start"] = [2.6, 1.0, 0.0]
        self._expect(d, "robot.start", "obstacles[2]")
        d["robot"]["start"] = [0.05, 1.0, 0.0]
        self._expect(d, "robot.start", "not inside the workspace")

    def test_regions_must_be_disjoint(self, simple_dict):
        d = copy.deepcopy(simple_dict)
        d["regions"]["c"]["center"] = [3.5, 2.25]  # 0.25 from b, radii 0.15 + 0.15
        self._expect(d, "regions.c", "regions.b")

    def test_with_obstacles_does_not_recheck_validity(self):
        w = load_world(world_file("simple"))
        blob = Squircle(w.regions["a"].center, 1.0, 1.0)
        w2 = w.with_obstacles([*w.obstacles, blob])
        assert len(w2.obstacles) == 5 and w2.known_obstacles == (0, 1, 2, 3, 4)
        with pytest.raises(WorldError):
            w2.validate()


# ---------------------------------------------------------------------- files
class TestFiles:
    def test_packaged_world_by_name(self):
        try:
            w = load_world("simple")
        except WorldError:
            pytest.skip("no packaged worlds in navigation/data/worlds")
        assert w == load_world(world_file("simple"))

    def test_missing_file(self, tmp_path):
        with pytest.raises(WorldError, match="cannot read"):
            load_world(tmp_path / "nope.json")

    def test_json_syntax_error_gives_line_and_column(self, tmp_path):
        p = tmp_path / "bad.json"
        p.write_text('{\n "name": "x",\n "task": \n}\n')
        with pytest.raises(WorldError, match=r"line 4, column 1"):
            load_world(p)

    def test_not_an_object(self, tmp_path):
        p = tmp_path / "list.json"
        p.write_text("[1, 2]")
        with pytest.raises(WorldError, match="one JSON object"):
            load_world(p)

    @pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
    def test_non_finite_json_literals(self, simple_dict, tmp_path, literal):
        text = json.dumps(simple_dict).replace('"width": 0.8', f'"width": {literal}', 1)
        assert literal in text
        p = tmp_path / "nan.json"
        p.write_text(text)
        with pytest.raises(WorldError) as info:
            load_world(p)
        assert info.value.field == "obstacles[1].width"

    def test_duplicate_keys(self, tmp_path):
        p = tmp_path / "dup.json"
        p.write_text('{"name": "a", "name": "b"}')
        with pytest.raises(WorldError, match="duplicate key") as info:
            load_world(p)
        assert info.value.field == "name"

    def test_defaults(self, simple_dict):
        d = copy.deepcopy(simple_dict)
        del d["known_obstacles"]
        for o in d["obstacles"]:
            o.pop("theta")
            o.pop("s")
        d["robot"]["start"] = [0.5, 2.5]
        w = World.from_dict(d)
        assert w.known_obstacles == () and w.events == ()
        assert all(o.theta == 0.0 and o.s == 0.99 for o in w.obstacles)
        assert w.robot.start == (0.5, 2.5, 0.0)


# ---------------------------------------------------------------------- components and forests
class TestComponents:
    def test_direct_construction_validates_ranges(self):
        with pytest.raises(WorldError) as info:
            RobotSpec(-1.0, (0, 0, 0), 1.0, 1.0)
        assert info.value.field == "radius"
        with pytest.raises(WorldError):
            LidarSpec(1.0, 1.0, 0, 0.0, 10.0)
        with pytest.raises(WorldError):
            Region("Bad", (0, 0), 1.0)
        with pytest.raises(WorldError):
            Event(0.0, "F a", "sometimes")
        assert Event(1, "F a", "add").mode is EventMode.ADD
        assert Region("a", (0, 0), 0.5).contains([[0.3, 0.4], [0.5, 0.5]]).tolist() == [True, False]

    def test_forest_is_cached_per_inflation(self):
        w = load_world(world_file("simple"))
        f0 = w.forest()
        assert isinstance(f0, Forest)
        assert w.forest(0.0) is f0
        f1 = w.forest(0.05)
        assert f1 is not f0 and w.forest(0.05) is f1
        assert all(a.width > b.width for a, b in zip(f1.obstacles, f0.obstacles))
        assert f1.workspace.width < f0.workspace.width
        with pytest.raises(WorldError):
            w.forest(-0.1)

    def test_with_obstacles_copies(self):
        w = load_world(world_file("simple"))
        w.forest()
        w2 = w.with_obstacles(w.obstacles[:2], known=[1])
        assert w2.obstacles == w.obstacles[:2] and w2.known_obstacles == (1,)
        assert len(w.obstacles) == 4 and len(w2.forest()) == 2
        assert w.forest() is not w2.forest()
        assert w.known == w.obstacles
