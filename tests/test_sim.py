"""Guarantees of the simulator (``service.sim``): exact lidar, exact arcs, saturation, swept
collision detection that never lets the robot disc through an obstacle, the bus message
shapes, and clear errors on bad input. Fixed seeds throughout.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from navigation.errors import HarmonicTampError, OutsideFreeSpaceError, ServiceError
from navigation.geometry import Squircle
from navigation.world import LidarSpec, RobotSpec, World
from service.sim import (
    ClearanceMap,
    CollisionStartError,
    CommandError,
    LidarConfig,
    PoseError,
    RayCaster,
    SimConfig,
    Simulator,
    arc_pose,
    wrap_angle,
)
from tests.conftest import random_world, shared_world
from tests.worldgen import random_free_points

SHARED = ("simple", "office", "cluttered20")
RANDOM_SEEDS = range(30)


# ---------------------------------------------------------------------- independent references
def _beta(sq: Squircle, x, y):
    """FORMATS.md beta, written out again (independent of the implementation)."""
    c, s = math.cos(sq.theta), math.sin(sq.theta)
    dx, dy = x - sq.center[0], y - sq.center[1]
    u = 2.0 * (c * dx + s * dy) / sq.width
    w = 2.0 * (-s * dx + c * dy) / sq.height
    u2, w2 = u * u, w * w
    return 0.5 * (u2 + w2 + np.sqrt(np.maximum(u2 * u2 + w2 * w2 + (2.0 - 4.0 * sq.s ** 2) * u2 * w2, 0.0))) - 1.0


def _reference_ranges(world: World, origin, angles, max_range: float) -> np.ndarray:
    """Brute force: bisection on beta along each ray (inf = no return before ``max_range``).

    Workspace: beta < 0 at the origin and > 0 far out, one crossing (beta is convex along a
    ray): plain bisection. Obstacle: golden-section search for the minimum of the convex
    ``beta`` on ``[0, max_range]``; a crossing exists iff that minimum is <= 0, and the entry
    is then found by bisection on ``[0, t_min]``.
    """
    o = np.asarray(origin, float)
    d = np.stack((np.cos(angles), np.sin(angles)), axis=1)

    def along(sq, t, rows=slice(None)):
        return _beta(sq, o[0] + t * d[rows, 0], o[1] + t * d[rows, 1])

    ws = world.workspace
    lo, hi = np.zeros(len(d)), np.full(len(d), 2.0 * math.hypot(ws.width, ws.height))
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        inside = along(ws, mid) < 0
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    best = 0.5 * (lo + hi)
    g = (math.sqrt(5.0) - 1.0) / 2.0
    for sq in world.obstacles:
        a, b = np.zeros(len(d)), np.full(len(d), max_range)
        for _ in range(75):
            x1, x2 = b - g * (b - a), a + g * (b - a)
            left = along(sq, x1) < along(sq, x2)
            a, b = np.where(left, a, x1), np.where(left, x2, b)
        tmin = 0.5 * (a + b)
        hit = along(sq, tmin) <= 0
        if not hit.any():
            continue
        rows = np.nonzero(hit)[0]
        lo, hi = np.zeros(rows.size), tmin[rows]
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            out = along(sq, mid, rows) > 0
            lo, hi = np.where(out, mid, lo), np.where(out, hi, mid)
        best[rows] = np.minimum(best[rows], 0.5 * (lo + hi))
    return np.where(best >= max_range, np.inf, best)


def _assert_same_ranges(got, ref):
    assert np.array_equal(np.isfinite(got), np.isfinite(ref)), "return / no-return disagree"
    fin = np.isfinite(ref)
    assert np.all(np.abs(got[fin] - ref[fin]) <= 1e-6), float(np.max(np.abs(got[fin] - ref[fin])))


def _check_lidar(world: World, n_poses: int, seed: int):
    rng = np.random.default_rng(seed)
    caster = RayCaster(world.workspace, world.obstacles)
    cfg = LidarConfig.from_spec(world.lidar)
    returns = 0
    for q in random_free_points(world, n_poses, rng):
        ang = rng.uniform(-math.pi, math.pi) + cfg.angles()
        got = caster.cast(q, ang, cfg.range)
        ref = _reference_ranges(world, q, ang, cfg.range)
        _assert_same_ranges(got, ref)
        returns += int(np.isfinite(ref).sum())
    assert returns > 0


# ---------------------------------------------------------------------- lidar
@pytest.mark.parametrize("name", SHARED)
def test_lidar_matches_bruteforce_on_shared_worlds(name):
    _check_lidar(shared_world(name), 8, seed=11)


@pytest.mark.parametrize("seed", RANDOM_SEEDS)
def test_lidar_matches_bruteforce_on_random_worlds(seed):
    _check_lidar(random_world(seed), 2, seed=100 + seed)


def test_lidar_long_range_sees_the_workspace_boundary():
    world = shared_world("cluttered20")
    caster = RayCaster(world.workspace, world.obstacles)
    q = np.array(world.robot.start[:2])
    ang = np.linspace(-math.pi, math.pi, 90, endpoint=False)
    _assert_same_ranges(caster.cast(q, ang, 20.0), _reference_ranges(world, q, ang, 20.0))
    assert np.all(np.isfinite(caster.cast(q, ang, 20.0)))  # closed workspace: every beam returns


def test_beam_layout_conventions():
    full = LidarConfig(1.0, 6.283185, 360)  # as written in the world files
    assert full.full_circle and full.angle_min == -math.pi
    assert full.angle_increment == pytest.approx(2 * math.pi / 360, abs=1e-15)
    a = full.angles()
    assert a[-1] == pytest.approx(math.pi - 2 * math.pi / 360) and np.all(np.diff(a) > 0)
    fan = LidarConfig(1.0, math.pi, 181)
    assert fan.angle_min == -math.pi / 2 and fan.angles()[-1] == pytest.approx(math.pi / 2)
    assert fan.angles()[90] == pytest.approx(0.0, abs=1e-15)
    one = LidarConfig(1.0, 0.5, 1)
    assert one.angle_min == 0.0 and one.angle_increment == 0.0 and one.angles().tolist() == [0.0]


def test_beam_zero_looks_along_the_heading():
    world = shared_world("simple")
    sim = Simulator(world, seed=0, lidar=LidarConfig(10.0, 0.2, 3))
    x, y, _ = sim.pose
    for heading in (0.0, 1.0, -2.5):
        sim.reset((x, y, heading))
        r = sim.true_ranges()
        ref = _reference_ranges(world, (x, y), np.array([heading]), 10.0)
        assert r[1] == pytest.approx(ref[0], abs=1e-9)


def test_scan_message_shape_and_no_return_encoding():
    sim = Simulator(shared_world("office"), seed=0)
    msg = sim.scan_message()
    assert set(msg) == {"stamp", "angle_min", "angle_increment", "range_min", "range_max", "ranges"}
    text = json.dumps(msg, allow_nan=False)  # strict JSON: no inf / nan anywhere
    ranges = np.array(json.loads(text)["ranges"])
    true = sim.true_ranges()
    assert len(ranges) == 360 and msg["range_max"] == 1.0 and msg["range_min"] == 0.0
    none = ~np.isfinite(true)
    assert none.any() and (~none).any()
    assert np.all(ranges[none] == msg["range_max"])  # the contract: >= range_max is no return
    assert np.all(ranges[~none] < msg["range_max"])
    assert np.allclose(ranges[~none], true[~none], atol=0, rtol=0)  # noise-free world
    pts = sim.points_message()
    assert set(pts) == {"stamp", "points"} and len(pts["points"]) == int((~none).sum())
    p = np.array(pts["points"])
    x, y, th = sim.pose
    a = th + sim.lidar.angles()[~none]
    assert np.allclose(p, np.stack((x + true[~none] * np.cos(a), y + true[~none] * np.sin(a)), 1), atol=1e-12)
    # the returned points lie on the boundary of some squircle
    b = np.min([np.abs(_beta(sq, p[:, 0], p[:, 1])) for sq in (*sim.world.obstacles, sim.world.workspace)], axis=0)
    assert np.all(b < 1e-9)


def test_noise_statistics_and_seeding():
    world = shared_world("simple")
    lidar = LidarConfig(1.5, 2 * math.pi, 360, noise_std=0.02)
    sim = Simulator(world, seed=42, lidar=lidar)
    true = sim.true_ranges()
    keep = np.isfinite(true) & (true < 1.5 - 0.2)  # far from range_max: no censoring
    err = np.concatenate([sim.scan()[keep] - true[keep] for _ in range(200)])
    assert err.size > 10_000
    assert abs(err.mean()) < 3 * 0.02 / math.sqrt(err.size) + 1e-4
    assert err.std() == pytest.approx(0.02, rel=0.03)
    a = Simulator(world, seed=7, lidar=lidar).scan()
    b = Simulator(world, seed=7, lidar=lidar).scan()
    c = Simulator(world, seed=8, lidar=lidar).scan()
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.array_equal(np.isfinite(true), np.isfinite(sim.true_ranges()))


def test_noise_never_makes_a_range_negative():
    world = shared_world("simple")
    sim = Simulator(world, seed=3, lidar=LidarConfig(1.5, 2 * math.pi, 360, noise_std=1.0))
    scans = np.array([sim.scan() for _ in range(50)])
    assert np.all(scans[np.isfinite(scans)] >= 0.0) and np.any(scans == 0.0)
    msg = sim.scan_message()
    assert min(msg["ranges"]) >= 0.0 and max(msg["ranges"]) <= msg["range_max"]


# ---------------------------------------------------------------------- kinematics
def _rk4(pose, v, omega, dt, n=2000):
    s = np.array(pose, float)

    def f(z):
        return np.array([v * math.cos(z[2]), v * math.sin(z[2]), omega])

    h = dt / n
    for _ in range(n):
        k1 = f(s)
        k2 = f(s + 0.5 * h * k1)
        k3 = f(s + 0.5 * h * k2)
        k4 = f(s + h * k3)
        s = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return s


@pytest.mark.parametrize("omega", [0.0, 1e-12, 1e-7, -3e-5, 0.3, -1.5, 4.0])
def test_exact_arc_matches_rk4(omega):
    rng = np.random.default_rng(5)
    for _ in range(5):
        pose = (*rng.uniform(-3, 3, 2), rng.uniform(-math.pi, math.pi))
        v = rng.uniform(-1, 1)
        got = arc_pose(pose, v, omega, 0.1)
        ref = _rk4(pose, v, omega, 0.1)
        assert got[:2] == pytest.approx(ref[:2], abs=1e-12)
        assert wrap_angle(got[2] - ref[2]) == pytest.approx(0.0, abs=1e-12)
        assert -math.pi < got[2] <= math.pi


def test_wrap_angle_range():
    a = np.array([-math.pi, math.pi, 3 * math.pi, -3 * math.pi, 0.0, -1e-18, 7.0, -7.0])
    w = wrap_angle(a)
    assert np.all(w > -math.pi) and np.all(w <= math.pi)
    assert np.allclose(np.cos(w), np.cos(a)) and np.allclose(np.sin(w), np.sin(a))
    assert wrap_angle(-math.pi) == math.pi and [wrap_angle(float(x)) for x in a] == pytest.approx(w.tolist())


def test_simulator_steps_follow_exact_arcs_over_time():
    world = shared_world("cluttered20")
    sim = Simulator(world, seed=0, dt=0.05)
    start = sim.pose
    sim.step((0.2, 0.7))
    for _ in range(9):
        sim.step()  # the command is held
    ref = _rk4(start, 0.2, 0.7, 0.5, n=5000)
    assert sim.pose[:2] == pytest.approx(ref[:2], abs=1e-11)
    assert sim.time == pytest.approx(0.5) and sim.metrics.steps == 10
    assert sim.metrics.distance == pytest.approx(0.1) and not sim.metrics.collisions


def test_saturation_and_clip_reporting():
    world = shared_world("simple")  # v_max 0.5, omega_max 1.5
    sim = Simulator(world, seed=0)
    r = sim.step((0.2, 0.1))
    assert not r.clipped and r.command == (0.2, 0.1)
    r = sim.step((2.0, -9.0))
    assert r.clipped and r.command == (0.5, -1.5) and r.requested == (2.0, -9.0)
    r = sim.step((-0.7, 0.0))
    assert r.clipped and r.command == (-0.5, 0.0)
    assert sim.metrics.clipped_commands == 2
    start = sim.pose
    r = sim.step((0.0, 100.0))
    assert r.command == (0.0, 1.5) and r.pose[:2] == start[:2]
    assert wrap_angle(r.pose[2] - start[2]) == pytest.approx(0.15)


# ---------------------------------------------------------------------- collisions
def _world(obstacles, start, *, radius=0.1, v_max=0.5, size=(4.0, 3.0)):
    ws = Squircle((size[0] / 2, size[1] / 2), size[0], size[1], 0.0, 0.99)
    return World("test", ws, tuple(obstacles), (), {}, RobotSpec(radius, start, v_max, 1.5),
                 LidarSpec(1.0, 2 * math.pi, 36, 0.0, 10.0), "true")


def test_robot_driven_into_a_wall_stops_before_it():
    wall = Squircle((2.0, 1.5), 0.2, 2.0, 0.0, 0.99)  # faces x = 1.9
    sim = Simulator(_world([wall], (0.5, 1.5, 0.0)), seed=0)
    events = []
    for _ in range(60):
        r = sim.step((0.5, 0.0))
        if r.collision:
            events.append(r.collision)
    assert events, "the wall was not detected"
    first = events[0]
    assert first.obstacle == 0 and first.command == (0.5, 0.0)
    # contact when the disc front reaches x = 1.9: centre at 1.8, after 2.6 s
    assert first.time == pytest.approx(2.6, abs=1e-5)
    x = sim.pose[0]
    assert 1.8 - 3e-4 < x < 1.8 and wall.distance(sim.pose[:2]) - 0.1 > 0
    assert 0 < sim.clearance < 3e-4 and sim.metrics.min_clearance > 0
    assert len(sim.metrics.collisions) == len(events) and sim.metrics.distance == pytest.approx(x - 0.5)
    r = sim.step((-0.5, 0.0))  # backing off works
    assert r.collision is None and sim.pose[0] == pytest.approx(x - 0.05)


def test_robot_into_the_workspace_boundary_names_it():
    sim = Simulator(_world([], (3.0, 1.5, 0.0)), seed=0)
    for _ in range(30):
        r = sim.step((0.5, 0.0))
        if r.collision:
            break
    assert r.collision is not None and r.collision.obstacle == "workspace"
    assert -sim.world.workspace.distance(sim.pose[:2]) - 0.1 > 0


@pytest.mark.parametrize("offset", np.linspace(0.0, 0.95, 9))
def test_thin_wall_is_never_skipped_at_max_speed(offset):
    # a 4 mm wall; one step at v_max = 10 m/s travels 1 m, both step ends are free
    wall = Squircle((2.0, 1.5), 0.004, 2.5, 0.0, 0.99)
    start_x = 0.97 - offset
    sim = Simulator(_world([wall], (start_x, 1.5, 0.0), radius=0.0, v_max=10.0), seed=0)
    for _ in range(5):
        r = sim.step((10.0, 0.0))
        assert sim.pose[0] < 1.998
        if r.collision:
            break
    assert r.collision is not None and r.collision.obstacle == 0
    assert 1.998 - 2e-4 < sim.pose[0] < 1.998  # stopped within 2 stop margins of the contact


def _disc_outside_everything(world: World, centres: np.ndarray, radius: float) -> bool:
    ang = np.linspace(0, 2 * math.pi, 48, endpoint=False)
    rim = (centres[:, None, :] + radius * np.stack((np.cos(ang), np.sin(ang)), 1)[None]).reshape(-1, 2)
    pts = np.vstack((rim, centres))
    ok = _beta(world.workspace, pts[:, 0], pts[:, 1]) < 0
    for sq in world.obstacles:
        ok &= _beta(sq, pts[:, 0], pts[:, 1]) > 0
    return bool(ok.all())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_driving_never_penetrates(seed):
    world = random_world(seed)
    rng = np.random.default_rng(seed)
    sim = Simulator(world, seed=seed)
    r_robot = world.robot.radius
    collided = 0
    for k in range(150):
        if k % 15 == 0:
            cmd = (rng.uniform(-0.2, 0.6), rng.uniform(-0.5, 0.5))
        before = sim.pose
        r = sim.step(cmd)
        # independent check along the executed part of the arc (dense samples, beta on the rim)
        t = np.linspace(0.0, 0.1, 41)
        travelled = np.hypot(r.pose[0] - before[0], r.pose[1] - before[1])
        arc = np.array([arc_pose(before, r.command[0], r.command[1], ti) for ti in t])
        full = np.hypot(arc[-1, 0] - before[0], arc[-1, 1] - before[1])
        if r.collision is not None:
            collided += 1
            arc = arc[np.hypot(arc[:, 0] - before[0], arc[:, 1] - before[1]) <= travelled + 1e-12] \
                if full > 0 else arc[:1]
        assert _disc_outside_everything(world, arc[:, :2], r_robot)
        assert r.clearance > 0
    assert sim.metrics.min_clearance > 0 and len(sim.metrics.collisions) == collided
    assert collided > 0  # the random commands do hit something


def test_clearance_is_exact():
    world = shared_world("office")
    cmap = ClearanceMap(world.workspace, world.obstacles, 0.1)
    rng = np.random.default_rng(9)
    q = rng.uniform((0, 0), (7, 4), (60, 2))
    c, owner = cmap.clearance(q)
    dists = np.stack([o.distance(q) for o in world.obstacles] + [-world.workspace.distance(q)], 1)
    ref = dists.min(1) - 0.1
    near = ref > -0.05  # geometry's distance may lose accuracy deep inside a squircle
    assert np.all(np.abs(c - ref)[near] <= 1e-9)
    best = np.argmin(dists, 1)
    assert np.all(np.where(best == len(world.obstacles), -1, best)[near] == owner[near])
    c_far, _ = cmap.clearance(q, far=0.05)
    assert np.all(c_far <= c + 1e-12) and np.all(np.abs(c_far - c)[c < 0.05] <= 1e-12)


# ---------------------------------------------------------------------- messages and errors
def test_pose_and_cmd_vel_messages():
    sim = Simulator(shared_world("simple"), seed=0)
    msg = sim.pose_message()
    assert msg == {"stamp": 0.0, "x": 0.5, "y": 2.5, "theta": 0.0}
    assert sim.apply_cmd_vel({"stamp": 1.0, "v": 0.4, "omega": 0.0, "extra": "ignored"}) == (0.4, 0.0)
    sim.step()
    assert sim.pose_message()["x"] == pytest.approx(0.54) and sim.pose_message()["stamp"] == pytest.approx(0.1)
    sim.apply_cmd_vel(json.dumps({"stamp": 1.1, "v": 0.0, "omega": 1.0}))
    sim.apply_cmd_vel(b'{"stamp": 1.2, "v": 0.1, "omega": 1}')
    assert sim.command == (0.1, 1.0)
    json.dumps(sim.metrics.to_dict(), allow_nan=False)


@pytest.mark.parametrize("message, field", [
    ({"v": 0.1, "omega": 0.0}, "stamp"),
    ({"stamp": 0.0, "omega": 0.0}, "v"),
    ({"stamp": 0.0, "v": "fast", "omega": 0.0}, "v"),
    ({"stamp": 0.0, "v": 0.1, "omega": float("nan")}, "omega"),
    ({"stamp": 0.0, "v": float("inf"), "omega": 0.0}, "v"),
    ({"stamp": 0.0, "v": True, "omega": 0.0}, "v"),
    ({"stamp": None, "v": 0.1, "omega": 0.0}, "stamp"),
    ([0.1, 0.0], None),
    ("{not json", None),
    ('{"stamp": 0, "v": NaN, "omega": 0}', "v"),
    (b"\xff\xfe", None),
])
def test_malformed_cmd_vel_is_refused_and_changes_nothing(message, field):
    sim = Simulator(shared_world("simple"), seed=0)
    sim.set_command(0.2, 0.1)
    with pytest.raises(CommandError, match="cmd_vel") as info:
        sim.apply_cmd_vel(message)
    assert info.value.field == field
    assert isinstance(info.value, ServiceError) and isinstance(info.value, ValueError)
    assert sim.command == (0.2, 0.1)


@pytest.mark.parametrize("cmd", [(float("nan"), 0.0), (0.1, float("inf")), (None, 0.0), (0.1,), "go"])
def test_bad_commands_are_refused(cmd):
    sim = Simulator(shared_world("simple"), seed=0)
    with pytest.raises(CommandError):
        sim.step(cmd)
    assert sim.pose == (0.5, 2.5, 0.0) and sim.time == 0.0


@pytest.mark.parametrize("pose", [(float("nan"), 1.0, 0.0), (1.0, 1.0, float("inf")), (1.0, 1.0), "here", None])
def test_non_finite_or_malformed_poses_are_refused(pose):
    world = shared_world("simple")
    with pytest.raises(PoseError, match="pose"):
        Simulator(world, pose=pose) if pose is not None else Simulator(world).reset(pose=5)
    sim = Simulator(world)
    with pytest.raises(PoseError):
        sim.reset((1.0, float("nan"), 0.0))
    assert sim.pose == (0.5, 2.5, 0.0)


def test_start_in_collision_is_refused():
    world = shared_world("simple")
    inside = world.obstacles[0].center
    with pytest.raises(CollisionStartError, match=r"obstacles\[0\]") as info:
        Simulator(world, pose=(*inside, 0.0))
    err = info.value
    assert err.obstacle == 0 and err.clearance < 0
    assert isinstance(err, OutsideFreeSpaceError) and isinstance(err, HarmonicTampError)
    with pytest.raises(CollisionStartError, match="workspace"):
        Simulator(world, pose=(0.05, 1.5, 0.0))  # disc crosses the boundary (radius 0.1)
    with pytest.raises(CollisionStartError):
        Simulator(world, pose=(50.0, 50.0, 0.0))
    o = world.obstacles[0]  # touching counts as a collision
    b = o.boundary_points(64)[0]
    n = (b - o.c) / np.linalg.norm(b - o.c)
    q = b + n * 0.1
    q = q + n * (0.1 - o.distance(q))
    with pytest.raises(CollisionStartError):
        Simulator(world, pose=(*q, 0.0))


def test_config_is_validated():
    with pytest.raises(ServiceError):
        SimConfig(dt=0.0)
    with pytest.raises(ServiceError):
        SimConfig(dt=float("nan"))
    with pytest.raises(ServiceError):
        LidarConfig(1.0, 7.0, 10)
    assert Simulator(shared_world("simple"), dt=0.02).dt == 0.02


def test_benchmark_quick_writes_results(tmp_path, capsys):
    from benchmarks import sim as bench

    out = tmp_path / "results"
    assert bench.main(["--quick", "--out", str(out), "--shared", "cluttered20", "--sizes"]) == 0
    data = json.loads((out / "sim.json").read_text())
    assert data["benchmark"] == "sim" and data["quick"] is True
    assert {"scan_360", "step_free", "step_contact"} <= set(data["metrics"])
    table = (out / "sim.md").read_text()
    assert "| cluttered20 |" in table and (table.count("PASS") + table.count("FAIL")) >= 1
    assert capsys.readouterr().out.strip() == table.strip()
