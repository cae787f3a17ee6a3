"""Rerun telemetry (``service.viz``): inert without a sink; with one, the navigation-function
heat map (free points only) and the oriented-field arrows are written at a low rate and read
back from the recording."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import navigation
from service.brain import ExecutiveBrain
from service.messages import PoseMsg
from service.viz import Telemetry

from .conftest import world_file


@pytest.fixture
def simple_brain():
    world = navigation.load_world(world_file("simple"))
    brain = ExecutiveBrain(world, "F a & F b", known=True)
    return world, brain


def _node(brain, stamp: float, x: float, y: float, theta: float):
    pose = PoseMsg(stamp, x, y, theta)
    return SimpleNamespace(brain=brain, pose=pose, command=(0.1, 0.0), _pose_at=lambda s: pose)


def _drive(brain, tel, world, seconds: float, dt: float = 0.1):
    """Tick the brain from the start pose (no motion needed) and log every tick."""
    x, y, th = world.robot.start
    for k in range(int(round(seconds / dt))):
        t = k * dt
        node = _node(brain, t, x, y, th)
        out = brain.tick(node.pose, now=t)
        tel.log_tick(node, out=out, status=out.status, compute=0.001)


def test_without_a_sink_nothing_is_built_or_evaluated(simple_brain, monkeypatch):
    import rerun as rr

    world, brain = simple_brain

    def boom(*a, **k):
        raise AssertionError("an archetype was built without a sink")

    for name in ("Points2D", "Arrows2D", "LineStrips2D", "Scalars", "TextLog", "TextDocument", "Clear"):
        monkeypatch.setattr(rr, name, boom)
    monkeypatch.setattr(brain, "field", boom)  # the heat map's source is never asked for
    monkeypatch.setattr(brain, "regions", boom)
    tel = Telemetry.from_options(record=None, viewer=None)
    assert not tel.enabled
    tel.log_world(world, true_obstacles=True)
    _drive(brain, tel, world, 3.0)
    assert not tel.times and not tel.field_times


def test_heat_map_and_arrows_are_recorded_at_a_low_rate_on_free_points(simple_brain, tmp_path):
    from rerun.chunk import RrdReader

    world, brain = simple_brain
    rrd = tmp_path / "nf.rrd"
    tel = Telemetry.from_options(record=rrd, recording_id="test-nf")
    tel.log_world(world)
    _drive(brain, tel, world, 5.0)  # 50 ticks, the robot stays at the start: one field
    fld = brain.field()
    assert fld is not None
    # arrows every 2 s of robot time (3), the one heat map in chunks of 500 points (4)
    assert len(tel.field_times) <= 8, len(tel.field_times)
    tel.close()
    rows: dict[str, list] = {}
    for chunk in RrdReader(str(rrd)).stream().collect().stream():
        rows.setdefault(str(chunk.entity_path), []).append(chunk.to_record_batch())
    assert "/world/nf" in rows and "/world/field" in rows, sorted(rows)
    n_rows = {k: sum(b.num_rows for b in v) for k, v in rows.items()}
    assert n_rows["/world/nf"] == 1 and 2 <= n_rows["/world/field"] <= 3, n_rows
    # every heat-map point is in the free space of the navigation function that was tracked
    pts = []
    for batch in rows["/world/nf"]:
        for name in batch.schema.names:
            if name.endswith("Points2D:positions"):
                for cell in batch.column(name).to_pylist():
                    if cell:
                        pts.extend(cell)
    pts = np.asarray(pts, float)
    assert len(pts) > 100
    assert fld.nf.is_free(pts).all()


def test_regions_added_at_run_time_are_logged_again(simple_brain, tmp_path):
    """The initial regions are at tick 0 and the changed set at a later tick (history kept)."""
    from rerun.chunk import RrdReader

    world, brain = simple_brain
    rrd = tmp_path / "regions.rrd"
    tel = Telemetry.from_options(record=rrd, recording_id="test-regions")
    tel.log_world(world)
    _drive(brain, tel, world, 0.3)
    brain.executive.set_regions({"d": {"center": [2.0, 0.4], "radius": 0.15}})
    _drive(brain, tel, world, 0.3)
    tel.close()
    logged = []  # (tick, sorted labels): the regions are temporal, so both sets are kept
    for chunk in RrdReader(str(rrd)).stream().collect().stream():
        if str(chunk.entity_path) == "/world/regions":
            batch = chunk.to_record_batch()
            assert "tick" in batch.schema.names, batch.schema.names  # not static
            ticks = batch.column("tick").to_pylist()
            for name in batch.schema.names:
                if name.endswith("labels"):
                    logged += [(tk, sorted(cell)) for tk, cell in zip(ticks, batch.column(name).to_pylist()) if cell]
    first = [tk for tk, lab in logged if lab == ["a", "b", "c"]]
    later = [tk for tk, lab in logged if lab == ["a", "b", "c", "d"]]
    assert first and later, logged
    assert min(first) == 0 and min(later) > max(first), logged


def _ticks_by_entity(rrd) -> dict:
    """entity path -> sorted ``tick`` values of its temporal rows (static rows as -1)."""
    from rerun.chunk import RrdReader

    out: dict[str, list] = {}
    for chunk in RrdReader(str(rrd)).stream().collect().stream():
        batch = chunk.to_record_batch()
        if "tick" in batch.schema.names:
            ticks = batch.column("tick").to_pylist()
        else:
            ticks = [-1] * batch.num_rows
        out.setdefault(str(chunk.entity_path), []).extend(ticks)
    return {k: sorted(v) for k, v in out.items() if not k.startswith("/__")}


def test_deferred_logging_waits_for_idle_time_and_records_the_same(simple_brain, tmp_path):
    """``log_tick(defer=True)`` only captures; ``idle`` logs the captured ticks in order with
    their own timelines, stops when interrupted, and the recording holds the same rows per
    entity and tick as logging at once."""
    import time

    world, brain = simple_brain
    direct, deferred = tmp_path / "direct.rrd", tmp_path / "deferred.rrd"
    tel = Telemetry.from_options(record=direct, recording_id="test-direct")
    tel.log_world(world)
    _drive(brain, tel, world, 5.0)
    tel.close()

    world, brain = navigation.load_world(world_file("simple")), None
    brain = ExecutiveBrain(world, "F a & F b", known=True)
    tel = Telemetry.from_options(record=deferred, recording_id="test-deferred")
    tel.log_world(world)
    x, y, th = world.robot.start
    for k in range(50):
        t = k * 0.1
        node = _node(brain, t, x, y, th)
        out = brain.tick(node.pose, now=t)
        tel.log_tick(node, out=out, status=out.status, compute=0.001, defer=True)
        if k == 2:
            assert tel.pending == 3 and not tel.times  # captured only
            assert tel.idle(time.monotonic() + 10.0, lambda: True) is False  # a scan is waiting: nothing done
            assert tel.pending == 3 and not tel.times
        if k % 5 == 4:  # idle time every few ticks (as between the ticks of the control loop)
            tel.idle(time.monotonic() + 10.0, lambda: False)
            assert tel.pending == 0
    assert tel.idle(time.monotonic() + 10.0) is True  # everything done
    assert tel.deferred == 50
    tel.close()
    a, b = _ticks_by_entity(direct), _ticks_by_entity(deferred)
    # the heat map completes at a different tick (chunks run in idle time, not one per tick)
    assert len(a.pop("/world/nf")) == len(b.pop("/world/nf")) == 1
    assert a.keys() == b.keys(), (sorted(a), sorted(b))
    for k in a:
        if k == "/world/field":  # arrows: same number of refreshes
            assert len(a[k]) == len(b[k]), (k, a[k], b[k])
        else:
            assert a[k] == b[k], (k, a[k], b[k])


def test_max_pending_bounds_the_backlog(simple_brain, tmp_path):
    """Without idle time (an overloaded loop) at most ``max_pending`` ticks wait; close() logs
    the rest."""
    world, brain = simple_brain
    tel = Telemetry.from_options(record=tmp_path / "b.rrd", recording_id="test-backlog")
    tel.max_pending = 4
    tel.log_world(world)
    x, y, th = world.robot.start
    for k in range(12):
        node = _node(brain, k * 0.1, x, y, th)
        out = brain.tick(node.pose, now=k * 0.1)
        tel.log_tick(node, out=out, status=out.status, compute=0.001, defer=True)
        assert tel.pending <= 4
    assert len(tel.times) == 8
    tel.close()
    assert len(tel.times) == 12


def test_the_trail_is_logged_in_pieces_each_once(simple_brain, tmp_path):
    """A long run's trail: full pieces of ``TRAIL_PIECE`` points are logged once under entities
    of their own, the growing piece at ``world/robot/trail``; together they are the whole path,
    and no row holds more than a piece (the recording grows linearly with the path)."""
    from rerun.chunk import RrdReader

    from service.viz import TRAIL_PIECE

    world, brain = simple_brain
    rrd = tmp_path / "trail.rrd"
    tel = Telemetry.from_options(record=rrd, recording_id="test-trail")
    tel.log_world(world)
    x, y, th = world.robot.start
    out = brain.tick(PoseMsg(0.0, x, y, th), now=0.0)
    # circles of radius 0.2 m round a point next to the start, poses 1.5 cm apart: each extends the trail
    path = [(x + 0.2 * np.cos(0.075 * k) - 0.2, y + 0.2 * np.sin(0.075 * k)) for k in range(int(2.5 * TRAIL_PIECE))]
    for k, (px, py) in enumerate(path):
        tel.log_tick(_node(brain, 0.1 * k, px, py, th), out=out, status=out.status, compute=0.001)
    tel.close()
    strips: dict[str, list] = {}
    for chunk in RrdReader(str(rrd)).stream().collect().stream():
        p = str(chunk.entity_path)
        if not p.startswith("/world/robot/trail"):
            continue
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith("LineStrips2D:strips"):
                strips.setdefault(p, []).extend(cell[0] for cell in batch.column(name).to_pylist() if cell)
    full = len(path) // (TRAIL_PIECE - 1)
    pieces = [f"/world/robot/trail/{k}" for k in range(full)]
    assert sorted(strips) == sorted(["/world/robot/trail"] + pieces), sorted(strips)
    assert all(len(strips[p]) == 1 and len(strips[p][0]) == TRAIL_PIECE for p in pieces)  # each logged once
    assert max(len(s) for v in strips.values() for s in v) <= TRAIL_PIECE
    # the pieces, then the last row of the growing piece, joined at their shared ends: the path
    drawn = [tuple(q) for q in strips[pieces[0]][0]]
    for p in pieces[1:] + ["/world/robot/trail"]:
        nxt = [tuple(q) for q in strips[p][-1]]
        assert nxt[0] == drawn[-1]
        drawn += nxt[1:]
    assert np.allclose(drawn, path)
