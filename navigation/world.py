"""World files (``shared/FORMATS.md``): loading, validation and the world's forest of stars.

A world holds the workspace, the ground-truth obstacles, the regions of interest (the LTL
atomic propositions), the robot and lidar parameters, the default mission and its timed
changes. :func:`load_world` and :meth:`World.from_dict` parse the JSON format and reject invalid
input with :class:`~navigation.errors.WorldError`, whose ``.field`` holds the dotted/indexed
path of the offending field (``"obstacles[3].width"``, ``"regions.p1.radius"``,
``"robot.start"``) and whose message starts with that path (or its parent object, for a
missing or unknown squircle field: ``"obstacles[3]: missing field 'width'"``).

Validity rule (FORMATS.md): the start and every region disc, grown by the robot radius, lie in
free space inside the workspace, and the region discs are pairwise disjoint. With the exact
signed distance of :meth:`Squircle.distance`, a disc ``(c, r)`` is clear of an obstacle iff
``distance(c) >= r`` and inside the workspace iff ``-workspace.distance(c) >= r``.

Examples
--------
>>> w = load_world("simple")  # a packaged world, or any path to a world file
>>> len(w.obstacles), sorted(w.regions)
(4, ['a', 'b', 'c'])
>>> print(w.forest().describe().splitlines()[0])
forest of 4 obstacle(s): 3 interior tree(s), 0 attached to the workspace boundary, max depth 1
"""

from __future__ import annotations

import importlib.resources
import json
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from ._arrays import to_float
from .errors import WorldError
from .forest import Forest, build_forest
from .geometry import MAX_LENGTH, Squircle

__all__ = ["World", "Region", "RobotSpec", "LidarSpec", "Event", "EventMode", "load_world", "REGION_NAME",
           "disc_violations"]

#: Region names are the LTL atomic propositions (FORMATS.md "LTL syntax").
REGION_NAME = re.compile(r"[a-z][a-z0-9_]*\Z")
_RESERVED = frozenset({"true", "false"})


# ---------------------------------------------------------------------- small validators
def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(v, path: str, *, positive: bool = False, nonnegative: bool = False, length: bool = False) -> float:
    """A finite float (optionally > 0 or >= 0; a ``length`` or coordinate at most
    :data:`navigation.geometry.MAX_LENGTH` in magnitude); ``WorldError`` naming ``path`` otherwise."""
    if not _is_number(v) and not isinstance(v, np.floating | np.integer):
        raise WorldError(f"{path}: expected a number, got {v!r}", path)
    x = to_float(v)
    if not math.isfinite(x):
        raise WorldError(f"{path}: must be finite, got {v!r}", path)
    if positive and not x > 0:
        raise WorldError(f"{path}: must be > 0, got {x:g}", path)
    if nonnegative and not x >= 0:
        raise WorldError(f"{path}: must be >= 0, got {x:g}", path)
    if length and not abs(x) <= MAX_LENGTH:
        raise WorldError(f"{path}: must be at most {MAX_LENGTH:g} m in magnitude, got {x:g}", path)
    return x


def _point(v, path: str, n: int = 2) -> tuple[float, ...]:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, (list, tuple)) or len(v) != n:
        form = "[x, y]" if n == 2 else "[x, y, theta]"
        raise WorldError(f"{path}: expected {form} ({n} numbers), got {v!r}", path)
    return tuple(_number(x, f"{path}[{k}]", length=k < 2) for k, x in enumerate(v))


def _text(v, path: str) -> str:
    if not isinstance(v, str):
        raise WorldError(f"{path}: expected a string, got {v!r}", path)
    if not v.strip():
        raise WorldError(f"{path}: must not be empty", path)
    return v


def _obj(d, path: str, required: Sequence[str], optional: Sequence[str] = ()) -> Mapping:
    if not isinstance(d, Mapping):
        raise WorldError(f"{path}: expected an object, got {type(d).__name__}", path)
    for key in required:
        if key not in d:
            raise WorldError(f"{path}.{key}: missing field" if path else f"{key}: missing field",
                             f"{path}.{key}" if path else key)
    unknown = sorted(set(d) - set(required) - set(optional))
    if unknown:
        where = f"{path}.{unknown[0]}" if path else str(unknown[0])
        raise WorldError(f"{where}: unknown field (expected {', '.join(list(required) + list(optional))})", where)
    return d


def _prefixed(err: WorldError, prefix: str) -> WorldError:
    """Re-root an error raised by a component's own validation under ``prefix``."""
    sub = err.field or ""
    path = f"{prefix}.{sub}" if sub else prefix
    msg = str(err)
    if sub and msg.startswith(sub + ":"):
        msg = msg[len(sub) + 1:].lstrip()
    return WorldError(f"{path}: {msg}", path)


# ---------------------------------------------------------------------- components
class EventMode(str, Enum):
    """How a timed event changes the mission (FORMATS.md ``events[].mode``)."""

    URGENT = "urgent"
    ADD = "add"
    REPLACE = "replace"

    @classmethod
    def parse(cls, value, path: str = "mode") -> "EventMode":
        """The mode named ``value``; ``WorldError`` listing the valid modes otherwise."""
        if isinstance(value, cls):
            return value
        try:
            return cls(value)
        except ValueError:
            valid = ", ".join(f"'{m.value}'" for m in cls)
            raise WorldError(f"{path}: {value!r} is not a valid mode, must be one of {valid}", path) from None


@dataclass(frozen=True, slots=True)
class Region:
    """A region of interest: the disc ``|q - center| <= radius`` named by an atomic proposition."""

    name: str
    center: tuple[float, float]
    radius: float

    def __post_init__(self):
        if not isinstance(self.name, str) or not REGION_NAME.match(self.name) or self.name in _RESERVED:
            raise WorldError(f"name: region name {self.name!r} must match [a-z][a-z0-9_]* and not be "
                             f"'true' or 'false'", "name")
        object.__setattr__(self, "center", _point(self.center, "center"))
        object.__setattr__(self, "radius", _number(self.radius, "radius", positive=True, length=True))

    def contains(self, q) -> np.ndarray:
        """True where ``q`` ((2,) or (N, 2)) lies in the closed disc."""
        q = np.asarray(q, dtype=float)
        return np.linalg.norm(q - np.asarray(self.center), axis=-1) <= self.radius

    def to_dict(self) -> dict:
        return {"center": list(self.center), "radius": self.radius}


@dataclass(frozen=True, slots=True)
class RobotSpec:
    """Unicycle robot: disc ``radius`` (m), ``start`` pose ``(x, y, theta)``, speed limits."""

    radius: float
    start: tuple[float, float, float]
    v_max: float
    omega_max: float

    def __post_init__(self):
        object.__setattr__(self, "radius", _number(self.radius, "radius", nonnegative=True, length=True))
        start = self.start.tolist() if isinstance(self.start, np.ndarray) else self.start
        if isinstance(start, (list, tuple)) and len(start) == 2:
            start = (*start, 0.0)
        object.__setattr__(self, "start", _point(start, "start", 3))
        object.__setattr__(self, "v_max", _number(self.v_max, "v_max", positive=True))
        object.__setattr__(self, "omega_max", _number(self.omega_max, "omega_max", positive=True))

    def to_dict(self) -> dict:
        return {"radius": self.radius, "start": list(self.start), "v_max": self.v_max, "omega_max": self.omega_max}


@dataclass(frozen=True, slots=True)
class LidarSpec:
    """Planar lidar: ``range`` (m), ``fov`` (rad, centred on the heading), ``beams``,
    ``noise_std`` (m), ``rate_hz``."""

    range: float
    fov: float
    beams: int
    noise_std: float
    rate_hz: float

    def __post_init__(self):
        object.__setattr__(self, "range", _number(self.range, "range", positive=True, length=True))
        fov = _number(self.fov, "fov", positive=True)
        if fov > 2 * math.pi + 1e-6:
            raise WorldError(f"fov: must be at most 2 pi, got {fov:g}", "fov")
        object.__setattr__(self, "fov", fov)
        b = self.beams
        if isinstance(b, bool) or not isinstance(b, (int, np.integer)):
            if _is_number(b) and math.isfinite(b) and float(b).is_integer():
                b = int(b)
            else:
                raise WorldError(f"beams: expected a whole number, got {b!r}", "beams")
        if b < 1:
            raise WorldError(f"beams: must be >= 1, got {b}", "beams")
        object.__setattr__(self, "beams", int(b))
        object.__setattr__(self, "noise_std", _number(self.noise_std, "noise_std", nonnegative=True))
        object.__setattr__(self, "rate_hz", _number(self.rate_hz, "rate_hz", positive=True))

    def to_dict(self) -> dict:
        return {"range": self.range, "fov": self.fov, "beams": self.beams, "noise_std": self.noise_std,
                "rate_hz": self.rate_hz}


@dataclass(frozen=True, slots=True)
class Event:
    """A timed mission change: at ``time`` (s), apply ``task`` with ``mode``."""

    time: float
    task: str
    mode: EventMode

    def __post_init__(self):
        object.__setattr__(self, "time", _number(self.time, "time", nonnegative=True))
        object.__setattr__(self, "task", _text(self.task, "task"))
        object.__setattr__(self, "mode", EventMode.parse(self.mode, "mode"))

    def to_dict(self) -> dict:
        return {"time": self.time, "task": self.task, "mode": self.mode.value}


# ---------------------------------------------------------------------- world
_WORLD_REQUIRED = ("name", "workspace", "obstacles", "regions", "robot", "lidar", "task")
_WORLD_OPTIONAL = ("known_obstacles", "events")


@dataclass(frozen=True, slots=True)
class World:
    """A world file (FORMATS.md). Build with :func:`load_world` or :meth:`from_dict`.

    Direct construction checks types and ranges; the geometric validity rule (start and region
    discs in free space, regions disjoint) is checked by :meth:`validate`, which the loaders
    call. :meth:`with_obstacles` (online maps) does not re-check it.
    """

    name: str
    workspace: Squircle
    obstacles: tuple[Squircle, ...]
    known_obstacles: tuple[int, ...]
    regions: dict[str, Region]
    robot: RobotSpec
    lidar: LidarSpec
    task: str
    events: tuple[Event, ...] = ()
    _forests: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "name", _text(self.name, "name"))
        if not isinstance(self.workspace, Squircle):
            raise WorldError(f"workspace: expected a Squircle, got {type(self.workspace).__name__}", "workspace")
        obstacles = tuple(self.obstacles)
        for k, o in enumerate(obstacles):
            if not isinstance(o, Squircle):
                raise WorldError(f"obstacles[{k}]: expected a Squircle, got {type(o).__name__}", f"obstacles[{k}]")
        object.__setattr__(self, "obstacles", obstacles)
        known = tuple(self.known_obstacles)
        seen: set[int] = set()
        for k, i in enumerate(known):
            path = f"known_obstacles[{k}]"
            if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
                raise WorldError(f"{path}: expected an obstacle index, got {i!r}", path)
            if not 0 <= i < len(obstacles):
                raise WorldError(f"{path}: obstacle index {i} out of range (the world has {len(obstacles)} "
                                 f"obstacle(s))", path)
            if i in seen:
                raise WorldError(f"{path}: obstacle {i} listed twice", path)
            seen.add(int(i))
        object.__setattr__(self, "known_obstacles", tuple(int(i) for i in known))
        if not isinstance(self.regions, Mapping):
            raise WorldError(f"regions: expected a mapping name -> Region, got {type(self.regions).__name__}",
                             "regions")
        for key, reg in self.regions.items():
            if not isinstance(reg, Region) or reg.name != key:
                raise WorldError(f"regions.{key}: expected a Region named {key!r}", f"regions.{key}")
        object.__setattr__(self, "regions", dict(self.regions))
        if not isinstance(self.robot, RobotSpec):
            raise WorldError(f"robot: expected a RobotSpec, got {type(self.robot).__name__}", "robot")
        if not isinstance(self.lidar, LidarSpec):
            raise WorldError(f"lidar: expected a LidarSpec, got {type(self.lidar).__name__}", "lidar")
        object.__setattr__(self, "task", _text(self.task, "task"))
        events = tuple(self.events)
        for k, e in enumerate(events):
            if not isinstance(e, Event):
                raise WorldError(f"events[{k}]: expected an Event, got {type(e).__name__}", f"events[{k}]")
        object.__setattr__(self, "events", events)

    # ------------------------------------------------------------------ IO
    @classmethod
    def from_dict(cls, d) -> "World":
        """Parse and validate a FORMATS.md world object.

        Raises
        ------
        WorldError
            Naming the offending field (missing, wrong type, non-finite, out of range, or
            violating the validity rule).
        """
        d = _obj(d, "", _WORLD_REQUIRED, _WORLD_OPTIONAL)
        name = _text(d["name"], "name")
        workspace = Squircle.from_dict(d["workspace"], "workspace")
        obs_list = d["obstacles"]
        if not isinstance(obs_list, list):
            raise WorldError(f"obstacles: expected a list of squircles, got {type(obs_list).__name__}", "obstacles")
        obstacles = tuple(Squircle.from_dict(o, f"obstacles[{k}]") for k, o in enumerate(obs_list))

        known = d.get("known_obstacles", [])
        if not isinstance(known, list):
            raise WorldError(f"known_obstacles: expected a list of obstacle indices, got {known!r}", "known_obstacles")

        regs = d["regions"]
        if not isinstance(regs, Mapping):
            raise WorldError(f"regions: expected an object name -> {{center, radius}}, got {type(regs).__name__}",
                             "regions")
        regions: dict[str, Region] = {}
        for key, r in regs.items():
            path = f"regions.{key}"
            if not isinstance(key, str) or not REGION_NAME.match(key) or key in _RESERVED:
                raise WorldError(f"{path}: region name {key!r} must match [a-z][a-z0-9_]* (an LTL atomic "
                                 f"proposition) and not be 'true' or 'false'", path)
            r = _obj(r, path, ("center", "radius"))
            center = _point(r["center"], f"{path}.center")
            radius = _number(r["radius"], f"{path}.radius", positive=True, length=True)
            regions[key] = Region(key, center, radius)

        rb = _obj(d["robot"], "robot", ("radius", "start", "v_max", "omega_max"))
        start = rb["start"]
        if isinstance(start, list) and len(start) == 2:
            start = [*start, 0.0]
        robot = RobotSpec(_number(rb["radius"], "robot.radius", nonnegative=True, length=True), _point(start, "robot.start", 3),
                          _number(rb["v_max"], "robot.v_max", positive=True),
                          _number(rb["omega_max"], "robot.omega_max", positive=True))

        ld = _obj(d["lidar"], "lidar", ("range", "fov", "beams", "noise_std", "rate_hz"))
        vals = {k: _number(ld[k], f"lidar.{k}") for k in ("range", "fov", "noise_std", "rate_hz")}
        if not _is_number(ld["beams"]):
            raise WorldError(f"lidar.beams: expected a whole number, got {ld['beams']!r}", "lidar.beams")
        try:
            lidar = LidarSpec(vals["range"], vals["fov"], ld["beams"], vals["noise_std"], vals["rate_hz"])
        except WorldError as err:
            raise _prefixed(err, "lidar") from None

        task = _text(d["task"], "task")
        ev_list = d.get("events", [])
        if not isinstance(ev_list, list):
            raise WorldError(f"events: expected a list, got {type(ev_list).__name__}", "events")
        events = []
        for k, e in enumerate(ev_list):
            path = f"events[{k}]"
            e = _obj(e, path, ("time", "task", "mode"))
            time = _number(e["time"], f"{path}.time", nonnegative=True)
            etask = _text(e["task"], f"{path}.task")
            mode = EventMode.parse(e["mode"], f"{path}.mode")
            events.append(Event(time, etask, mode))

        world = cls(name, workspace, obstacles, tuple(known), regions, robot, lidar, task, tuple(events))
        world.validate()
        return world

    def to_dict(self) -> dict:
        """The FORMATS.md JSON object (defaults written out); ``from_dict`` inverts it."""
        return {
            "name": self.name,
            "workspace": self.workspace.to_dict(),
            "obstacles": [o.to_dict() for o in self.obstacles],
            "known_obstacles": list(self.known_obstacles),
            "regions": {k: r.to_dict() for k, r in self.regions.items()},
            "robot": self.robot.to_dict(),
            "lidar": self.lidar.to_dict(),
            "task": self.task,
            "events": [e.to_dict() for e in self.events],
        }

    # ------------------------------------------------------------------ validity
    def validate(self) -> None:
        """Check the validity rule of FORMATS.md.

        The start disc (robot radius) and every region disc grown by the robot radius lie in
        free space inside the workspace; region discs are pairwise disjoint.

        Raises
        ------
        WorldError
            ``field`` is ``"robot.start"`` or ``"regions.<name>"``.
        """
        rr = self.robot.radius
        discs = [("robot.start", f"robot disc (radius {rr:g}) at {self.robot.start[:2]}", self.robot.start[:2], rr)]
        for key, reg in self.regions.items():
            discs.append((f"regions.{key}", f"disc grown by robot radius {rr:g}", reg.center, reg.radius + rr))
        centers = np.array([c for _, _, c, _ in discs], dtype=float)
        radii = np.array([r for _, _, _, r in discs])

        for k, rule, value in disc_violations(self.workspace, self.obstacles, centers, radii):
            path, what = discs[k][0], discs[k][1]
            if rule == "workspace":
                raise WorldError(f"{path}: {what} is not inside the workspace (its centre is {value:.3g} m "
                                 f"inside the boundary, {radii[k]:g} m needed)", path)
            raise WorldError(f"{path}: {what} overlaps obstacles[{value[0]}]", path)
        names = list(self.regions)
        for b in range(len(names)):
            for a in range(b):
                ra, rb = self.regions[names[a]], self.regions[names[b]]
                if math.dist(ra.center, rb.center) <= ra.radius + rb.radius:
                    raise WorldError(f"regions.{names[b]}: disc overlaps regions.{names[a]} (regions must be "
                                     f"pairwise disjoint)", f"regions.{names[b]}")

    # ------------------------------------------------------------------ derived worlds
    @property
    def known(self) -> tuple[Squircle, ...]:
        """The obstacles known at start (``known_obstacles``)."""
        return tuple(self.obstacles[i] for i in self.known_obstacles)

    def with_obstacles(self, obstacles: Sequence[Squircle], known: Sequence[int] | None = None) -> "World":
        """A copy with ``obstacles`` replaced (e.g. by an online map's estimates).

        ``known`` defaults to all the new obstacles (a map only holds obstacles it knows). The
        validity rule is not re-checked: an estimate may well cover a region disc.
        """
        obstacles = tuple(obstacles)
        known = tuple(range(len(obstacles))) if known is None else tuple(known)
        return replace(self, obstacles=obstacles, known_obstacles=known)

    def forest(self, inflation: float = 0.0, **options) -> Forest:
        """The forest of stars of the obstacles grown by ``inflation`` (workspace shrunk by it).

        ``options`` (``min_gap``, ``min_overlap``) go to :func:`~navigation.forest.build_forest`.
        Results are cached per ``(inflation, options)``.

        Raises
        ------
        ForestError
            The grown obstacles do not form a forest of stars.
        WorldError
            ``inflation`` is negative, not finite, or too large for the workspace.
        """
        r = _number(inflation, "inflation", nonnegative=True)
        key = (r, tuple(sorted(options.items())))
        cached = self._forests.get(key)
        if cached is None:
            cached = build_forest(*configuration_space(self.workspace, self.obstacles, r), **options)
            self._forests[key] = cached
        return cached


def configuration_space(workspace: Squircle, obstacles, inflation: float) -> tuple[Squircle, list[Squircle]]:
    """The workspace shrunk and the obstacles grown by ``inflation`` (a disc robot's radius).

    Raises
    ------
    WorldError
        ``inflation`` is not a finite number >= 0 (field ``inflation``), or the workspace is
        too small to shrink by it (field ``workspace``).
    """
    r = _number(inflation, "inflation", nonnegative=True)
    if not r:
        return workspace, list(obstacles)
    try:
        ws = workspace.grow(-r)
    except ValueError as err:
        raise WorldError(f"workspace: cannot shrink by inflation {r:g}: {err}", "workspace") from None
    return ws, [o.grow(r) for o in obstacles]


# ---------------------------------------------------------------------- loading
def _no_duplicates(pairs):
    d = {}
    for k, v in pairs:
        if k in d:
            raise WorldError(f"{k}: duplicate key in a JSON object", k)
        d[k] = v
    return d


def _builtin_world(name: str):
    """The packaged world file ``navigation/data/worlds/<name>.json``, or None."""
    if not re.fullmatch(r"[A-Za-z0-9_\-]+", name):
        return None
    res = importlib.resources.files("navigation") / "data" / "worlds" / f"{name}.json"
    return res if res.is_file() else None


def disc_violations(workspace: Squircle, obstacles: Sequence[Squircle], centers, radii):
    """The discs ``(centers[k], radii[k])`` that break FORMATS.md's validity rule: the first
    problem of each disc, in disc order, as ``(k, "workspace", depth)`` (not inside the
    workspace: its centre is ``depth`` m inside the boundary, less than the radius) or
    ``(k, "free_space", (j, distance))`` (overlaps obstacle ``j``, its centre ``distance`` m from
    it). One checker for the world files (:meth:`World.validate`) and the regions changed at
    run time (the executive)."""
    centers = np.asarray(centers, dtype=float).reshape(-1, 2)
    radii = np.asarray(radii, dtype=float).reshape(-1)
    depth = -np.atleast_1d(workspace.distance(centers)) if len(centers) else np.zeros(0)
    dist = np.full((len(centers), len(obstacles)), np.inf)
    for j, o in enumerate(obstacles):
        near = np.nonzero(np.linalg.norm(centers - o.c, axis=1) <= o.bounding_radius + radii)[0]
        if near.size:
            dist[near, j] = np.atleast_1d(o.distance(centers[near]))
    for k in range(len(centers)):
        if depth[k] < radii[k]:
            yield k, "workspace", float(depth[k])
            continue
        bad = np.nonzero(dist[k] < radii[k])[0]
        if bad.size:
            yield k, "free_space", (int(bad[0]), float(dist[k, bad[0]]))


def load_world(path: str | os.PathLike) -> World:
    """Load and validate a world file.

    ``path`` is a file path, or the bare name of a world shipped in ``navigation/data/worlds``
    (``"simple"``, ``"office"``, ``"cluttered20"``) when no such file exists.

    Raises
    ------
    WorldError
        The file is missing or unreadable (``field`` None), is not valid JSON (the message gives
        the line and column), or describes an invalid world (``field`` names the culprit).
    """
    label = os.fspath(path)
    builtin = None if os.path.exists(label) or not isinstance(path, str) else _builtin_world(path)
    try:
        if builtin is not None:
            raw = builtin.read_bytes()
        else:
            with open(path, "rb") as fh:
                raw = fh.read()
    except OSError as err:
        raise WorldError(f"{label}: cannot read world file: {err.strerror or err}") from err
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise WorldError(f"{label}: world file is not UTF-8 text ({err.reason} at byte {err.start})") from err
    try:
        data = json.loads(text, object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as err:
        raise WorldError(f"{label}: invalid JSON at line {err.lineno}, column {err.colno}: {err.msg}") from err
    if not isinstance(data, dict):
        raise WorldError(f"{label}: a world file holds one JSON object, got {type(data).__name__}")
    return World.from_dict(data)
