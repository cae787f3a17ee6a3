"""Rerun streaming of the running service (``--record PATH.rrd``, ``--viewer ADDR``, ``--serve PORT``).

:class:`Telemetry` is the one wrapper around a ``rerun.RecordingStream``. Its sinks: a file, a
viewer the stream pushes to (Rerun keeps what the viewer has not taken in memory, without a
bound), and a gRPC server the service hosts for viewers to join at any time, keeping at most
``serve_memory`` of the newest data. Built without a sink (:meth:`Telemetry.disabled`, or
:meth:`Telemetry.from_options` with none of them) every method returns at once, before any archetype is built (ecosystem note: an
unguarded ``rr.log`` of 1000 points costs ~0.1 ms even with Rerun off).

Entity paths (2-D world frame, metres)::

    world/workspace            LineStrips2D   workspace boundary               (static)
    world/regions              Points2D       region discs with their names    (on change; the
                                              initial set at tick 0, so the history is kept)
    world/obstacles/true       LineStrips2D   ground truth (simulation only)   (static)
    world/obstacles/estimated  LineStrips2D   the service's obstacle estimate  (on change)
    world/lidar                Points2D       lidar returns, world frame       (per scan)
    world/robot                Points2D+Arrows2D  pose and heading             (per tick)
    world/robot/trail          LineStrips2D   path so far: its last piece      (per tick)
    world/robot/trail/<k>      LineStrips2D   its earlier pieces, ``TRAIL_PIECE`` points each
                                              (once each: a long run's recording grows
                                              linearly, not quadratically)
    world/path                 LineStrips2D   current leg of the harmonic tree (on change)
    world/path/vertices        Points2D       its waypoints (tree vertices)
    world/goal                 Arrows2D       current waypoint pose (goal of the oriented field)
    world/nf                   Points2D       heat map of the navigation function the controller
                                              tracks (free points of a coarse grid; low rate)
    world/field                Arrows2D       oriented-field directions on free points around the
                                              robot and the current waypoint (low rate)
    status/state               TextLog        state changes and messages
    status/plan                TextDocument   task, plan prefix/suffix, target
    plots/v, plots/omega       Scalars        command
    plots/tick_ms              Scalars        node compute per tick
    plots/planning_ms          Scalars        brain compute of ticks that re-planned

Timelines: ``tick`` (sequence) and ``sim_time`` (the robot clock, from pose stamps). A
blueprint lays out the map, the navigation-function view (heat map, arrows, outlines, robot),
the time series and the text views.

The heat map and the arrows come from the brain's ``field()`` (the oriented field of the
waypoint the executive tracks, never built for the purpose; ``None`` when there is none). They
are refreshed at most every ``field_period`` seconds of robot time (default 2 s): the arrows at
each refresh (they follow the robot), the heat map only when the field changed since the last
one (a new waypoint or a new forest after a map change). The evaluation is vectorised
(``field.field`` on at most ``arrow_grid**2`` points; ``nf.evaluate(G, 0)`` on about
``heat_points`` grid points, ``heat_chunk`` of them per piece of work, so that no piece carries
the whole heat map). ``Telemetry.times`` / ``Telemetry.field_times`` keep the cost (per logged
tick / per piece of navigation-function work).

Deferred logging (``log_tick(..., defer=True)``, what :meth:`service.node.ServiceNode.run`
uses): the tick only *captures* what it must log (references to the pose, scan, command,
status, leg, regions, obstacle estimate and field of that tick, ~0.04 ms); building the
archetypes, ``rr.log`` and the navigation-function work run later in :meth:`Telemetry.idle`,
which the control loop calls while it waits for the next period. It does one captured tick or
one navigation-function piece at a time (an arrow refresh or a heat-map chunk, ~1-3 ms) and
returns as soon as a scan or points message has arrived, so no Rerun work runs on the tick that
computes a command, and a scan that arrives meanwhile waits at most for the piece in progress.
Everything captured is logged, in tick order, with the timelines of its own tick; at most
``max_pending`` captured ticks wait (beyond that, the oldest are logged within the tick, as
without deferral). Without ``defer`` (a caller that drives :meth:`log_tick` itself, as the
tests do) each tick is logged at once, with one navigation-function piece per tick.
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque

import numpy as np

from navigation.errors import ServiceError

__all__ = ["Telemetry"]

log = logging.getLogger("service.viz")
_OUTLINE = 96  # boundary samples per squircle
TRAIL_PIECE = 200  # trail points per logged piece (world/robot/trail/<k>)
# viridis at 0, 0.25, 0.5, 0.75, 1 (low potential dark blue, high yellow)
_VIRIDIS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)


def _colormap(t: np.ndarray, alpha: int = 200) -> np.ndarray:
    """RGBA uint8 ``(N, 4)`` of values ``t`` in ``[0, 1]`` (viridis, linear between 5 stops)."""
    t = np.clip(np.nan_to_num(t, nan=1.0), 0.0, 1.0) * (len(_VIRIDIS) - 1)
    k = np.minimum(t.astype(int), len(_VIRIDIS) - 2)
    f = (t - k)[:, None]
    rgb = _VIRIDIS[k] * (1 - f) + _VIRIDIS[k + 1] * f
    return np.hstack([rgb, np.full((len(t), 1), alpha)]).astype(np.uint8)


def _ranks(v: np.ndarray) -> np.ndarray:
    """Ranks of ``v`` scaled to ``[0, 1]`` (histogram equalisation: a navigation function is
    close to its maximum almost everywhere, so a linear scale shows little but the goal)."""
    t = np.empty(len(v))
    t[np.argsort(v, kind="stable")] = np.linspace(0.0, 1.0, len(v)) if len(v) > 1 else 0.0
    return t


def _grid(lo, hi, n_points: int) -> tuple[np.ndarray, float]:
    """A square grid of about ``n_points`` points over the box ``lo..hi``; ``(points (N, 2), step)``."""
    size = np.maximum(np.asarray(hi, float) - np.asarray(lo, float), 1e-6)
    step = math.sqrt(float(size[0] * size[1]) / max(n_points, 1))
    xs = np.arange(lo[0] + step / 2, hi[0], step)
    ys = np.arange(lo[1] + step / 2, hi[1], step)
    return np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2), step


def _outlines(squircles) -> list[np.ndarray]:
    out = []
    for sq in squircles:
        if isinstance(sq, dict):
            from navigation.geometry import Squircle

            sq = Squircle.from_dict(sq)
        pts = sq.boundary_points(_OUTLINE)
        out.append(np.vstack([pts, pts[:1]]))
    return out


def _check_port_free(host: str, port: int, what: str) -> None:
    """Rerun's server only logs a port in use from its own thread; find out before starting it."""
    import socket

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        try:
            s.bind((host, port))
        except OSError as err:
            raise ServiceError(f"rerun: cannot {what}: {err.strerror or err}") from None


class Telemetry:
    """Rerun output of the service; inert when it has no sink. Use :meth:`from_options`.

    ``field_period`` (robot seconds between heat-map / arrow refreshes), ``heat_points`` (grid
    points of the heat map over the workspace), ``heat_chunk`` (heat-map points evaluated per
    tick), ``arrow_grid`` (arrows along the long side of the box around the robot and its
    waypoint) set the cost of the navigation-function views. ``times`` and ``field_times`` hold
    the wall seconds of the last calls of :meth:`log_tick` and of its navigation-function work
    (arrow refreshes and heat-map chunks)."""

    def __init__(self, rec=None, *, field_period: float = 2.0, heat_points: int = 2000, heat_chunk: int = 500,
                 arrow_grid: int = 12, max_pending: int = 50):
        self._rec = rec
        self.field_period = float(field_period)
        self.heat_points = int(heat_points)
        self.heat_chunk = max(int(heat_chunk), 1)
        self.arrow_grid = int(arrow_grid)
        self.max_pending = max(int(max_pending), 0)
        self.times: deque = deque(maxlen=100000)
        self.field_times: deque = deque(maxlen=10000)
        self.deferred = 0            # ticks whose logging ran in idle time (:meth:`idle`)
        self._pending: deque = deque()  # captured ticks not logged yet
        self._field = None          # the field of the last heat map
        self._heat_job = None       # a heat map being evaluated, ``heat_chunk`` points per piece
        self._arrow_job = None      # (field, pose) of an arrow refresh due
        self._field_t = -math.inf   # robot time of the last refresh
        self._heat_grid = None      # (points, step) over the workspace
        self._workspace = None      # the world's workspace (for the heat-map grid)
        self._regions = None        # regions last logged
        self._tick = 0
        self._trail: list[tuple[float, float]] = []  # the piece of the trail being drawn
        self._trail_pieces = 0  # full pieces logged (world/robot/trail/<k>)
        self._last_state = None
        self._last_plan = None
        self._last_leg = None
        self._estimated_captured = False
        self._failed = False

    @property
    def enabled(self) -> bool:
        return self._rec is not None

    @classmethod
    def disabled(cls) -> "Telemetry":
        return cls(None)

    @classmethod
    def from_options(cls, *, record=None, viewer=None, serve: tuple[str, int] | None = None,
                     serve_memory: str = "256MiB", app_id: str = "tamp-service",
                     recording_id: str | None = None) -> "Telemetry":
        """A stream to ``record`` (an ``.rrd`` path), ``viewer`` (a gRPC address such as
        ``rerun+http://127.0.0.1:9876/proxy``, or ``HOST:PORT``) and/or a gRPC server the
        service hosts at ``serve = (ip, port)`` keeping at most ``serve_memory`` (a Rerun size
        such as ``"256MiB"``; the oldest data goes first); disabled when none.

        Raises :class:`ServiceError` for a path that cannot be written, an address Rerun
        refuses, a port already in use or a bad memory size."""
        if record is None and viewer is None and serve is None:
            return cls.disabled()
        import rerun as rr

        what = " and ".join(([f"record to {record}"] if record is not None else [])
                            + ([f"stream to {viewer}"] if viewer is not None else [])
                            + ([f"serve on {serve[0]}:{serve[1]}"] if serve is not None else []))
        if serve is not None:
            _check_port_free(*serve, what)
        rec = rr.RecordingStream(app_id, recording_id=recording_id)
        try:
            sinks = []
            if record is not None:
                sinks.append(rr.FileSink(str(record)))
            if viewer is not None:
                url = viewer if "://" in viewer else f"rerun+http://{viewer}/proxy"
                sinks.append(rr.GrpcSink(url))
            if serve is not None:
                sinks.append(rr.GrpcServerSink(serve[0], serve[1], server_memory_limit=str(serve_memory)))
            rec.set_sinks(*sinks)
        except (RuntimeError, ValueError) as err:  # an unwritable path, an address or a size Rerun refuses
            raise ServiceError(f"rerun: cannot {what}: {err}") from None
        tel = cls(rec)
        tel._blueprint()
        return tel

    def _blueprint(self) -> None:
        import rerun.blueprint as rrb

        bp = rrb.Blueprint(
            rrb.Horizontal(
                rrb.Vertical(
                    rrb.Spatial2DView(origin="world", name="map", contents=["+ $origin/**", "- /world/nf"]),
                    rrb.Spatial2DView(origin="world", name="navigation function",
                                      contents=["+ /world/nf", "+ /world/field", "+ /world/workspace",
                                                "+ /world/obstacles/estimated", "+ /world/regions",
                                                "+ /world/robot", "+ /world/goal", "+ /world/path"]),
                    row_shares=[3, 2],
                ),
                rrb.Vertical(
                    rrb.TimeSeriesView(origin="plots", name="command and timing"),
                    rrb.TextDocumentView(origin="status/plan", name="plan"),
                    rrb.TextLogView(origin="status/state", name="state"),
                ),
                column_shares=[3, 2],
            ),
            collapse_panels=True,
        )
        self._rec.send_blueprint(bp)

    def close(self) -> None:
        """Log what is pending, flush (at most 5 s) and disconnect. A sink that cannot take
        everything (a viewer that is gone or never answered) costs an error line, not the run."""
        if self._rec is not None:
            self.flush_pending()
            try:
                try:
                    self._rec.flush(timeout_sec=5.0)
                except TypeError:
                    self._rec.flush()
            except RuntimeError as err:
                log.error("rerun: not every message reached the recording's sinks: %s", err)
            finally:
                self._rec.disconnect()
                self._rec = None

    # ------------------------------------------------------------------ static scene
    def log_world(self, world, *, true_obstacles: bool = False) -> None:
        """Workspace (and, in simulation, the ground-truth obstacles) as static data; the regions
        at tick 0."""
        if self._rec is None:
            return
        import rerun as rr

        rec = self._rec
        rec.log("world/workspace", rr.LineStrips2D(_outlines([world.workspace]), colors=[[200, 200, 200]]),
                static=True)
        # the regions are temporal (they can change at run time): the initial set from the start
        rec.set_time("tick", sequence=0)
        rec.set_time("sim_time", duration=0.0)
        self._log_regions(world.regions)
        if true_obstacles and world.obstacles:
            rec.log("world/obstacles/true", rr.LineStrips2D(_outlines(world.obstacles), colors=[[120, 120, 120]]),
                    static=True)

    def _log_regions(self, regions) -> None:
        """Region discs at the current time, when the set changed (the viewer shows the set in
        force at the selected time)."""
        import rerun as rr

        key = tuple((n, tuple(r.center), r.radius) for n, r in regions.items())
        if key == self._regions:
            return
        self._regions = key
        names = list(regions)
        if names:
            self._rec.log("world/regions", rr.Points2D([regions[n].center for n in names],
                                                        radii=[regions[n].radius for n in names],
                                                        labels=names, colors=[[80, 160, 255, 90]]))
        else:
            self._rec.log("world/regions", rr.Clear(recursive=False))

    # ------------------------------------------------------------------ per tick
    def log_tick(self, node, *, scan=None, points=None, out=None, status=None, compute: float = 0.0,
                 defer: bool = False) -> None:
        """Everything that changed in one control period of ``node`` (a ServiceNode).

        With ``defer`` the tick is only captured; :meth:`idle` (or :meth:`flush_pending`, or
        the next ticks beyond ``max_pending``) logs it. Without, it is logged now, with one
        piece of navigation-function work."""
        if self._rec is None:
            return
        try:
            self._pending.append(self._capture(node, scan, points, out, status, compute))
        except Exception as err:  # visualisation must never take the service down
            self._fail("tick not captured", err)
            return
        if not defer:
            self.flush_pending()
            self._nf_step()
        else:
            while len(self._pending) > self.max_pending:
                self._log_next()

    def idle(self, deadline: float, interrupted=None) -> bool:
        """Deferred logging until ``time.monotonic() >= deadline`` or ``interrupted()`` is true
        (checked between records and navigation-function pieces); the captured ticks first, in
        order, then the navigation-function work. Returns whether nothing is left to do."""
        if self._rec is None:
            return True
        while not (interrupted is not None and interrupted()) and time.monotonic() < deadline:
            if self._pending:
                self._log_next()
                self.deferred += 1
            elif not self._nf_step():
                return True
        return not self._pending and self._heat_job is None and self._arrow_job is None

    def flush_pending(self) -> None:
        """Log every captured tick now (navigation-function work stays pending)."""
        while self._pending:
            self._log_next()

    @property
    def pending(self) -> int:
        """Captured ticks not logged yet."""
        return len(self._pending)

    def _fail(self, what: str, err: BaseException) -> None:
        if not self._failed:
            self._failed = True
            log.warning("rerun: %s: %s (further errors at debug level)", what, err)
        else:
            log.debug("rerun: %s: %s", what, err)

    def _capture(self, node, scan, points, out, status, compute) -> dict:
        """What tick ``node`` must log, as references (the brain's state moves on)."""
        brain = node.brain
        pose = node.pose
        r = {"pose": pose, "scan": scan, "points": points, "command": node.command, "compute": compute,
             "status": status, "planning": out.compute if out is not None and out.replanned else None,
             "obstacles": None, "leg": None, "regions": None, "field": None}
        if scan is not None and pose is not None:
            r["scan_pose"] = node._pose_at(scan.stamp) or pose
        if out is not None and (out.map_changed or not self._estimated_captured):
            self._estimated_captured = True
            try:
                r["obstacles"] = list(brain.obstacles())
            except Exception as err:
                log.debug("estimated obstacles not logged: %s", err)
        leg_fn = getattr(brain, "leg", None)
        if leg_fn is not None:
            r["leg"] = leg_fn()
        regions_fn = getattr(brain, "regions", None)
        if regions_fn is not None:
            r["regions"] = regions_fn()
        field_fn = getattr(brain, "field", None)
        if field_fn is not None and pose is not None:
            r["field"] = (field_fn(),)  # a 1-tuple: "asked, no field" is (None,)
            if self._workspace is None:  # (a brain without a world gets arrows but no heat map)
                self._workspace = getattr(getattr(brain, "world", None), "workspace", None)
        return r

    def _log_next(self) -> None:
        r = self._pending.popleft()
        t0 = time.perf_counter()
        try:
            self._log_record(r)
        except Exception as err:  # visualisation must never take the service down
            self._fail("tick not logged", err)
        finally:
            self.times.append(time.perf_counter() - t0)

    def _log_record(self, r: dict) -> None:
        import rerun as rr

        rec = self._rec
        self._tick += 1
        rec.set_time("tick", sequence=self._tick)
        pose = r["pose"]
        if pose is not None:
            rec.set_time("sim_time", duration=float(pose.stamp))
            rec.log("world/robot", rr.Points2D([[pose.x, pose.y]], radii=[0.05], colors=[[255, 140, 0]]),
                    rr.Arrows2D(origins=[[pose.x, pose.y]], vectors=[[0.25 * math.cos(pose.theta),
                                                                      0.25 * math.sin(pose.theta)]]))
            if not self._trail or math.dist(self._trail[-1], (pose.x, pose.y)) > 0.01:
                self._trail.append((pose.x, pose.y))
                if len(self._trail) >= TRAIL_PIECE:
                    # a full piece is logged once, under an entity of its own; the growing
                    # piece starts again from its last point
                    rec.log(f"world/robot/trail/{self._trail_pieces}",
                            rr.LineStrips2D([self._trail], colors=[[255, 140, 0]]))
                    self._trail_pieces += 1
                    self._trail = self._trail[-1:]
                if len(self._trail) > 1:
                    rec.log("world/robot/trail", rr.LineStrips2D([self._trail], colors=[[255, 140, 0]]))
        scan, points = r["scan"], r["points"]
        if scan is not None and pose is not None:
            from perception.ingest import parse_scan

            pts = parse_scan(scan.message, r["scan_pose"].pose).points
            rec.log("world/lidar", rr.Points2D(pts, radii=[0.01], colors=[[255, 60, 60]]))
        elif points is not None:
            rec.log("world/lidar", rr.Points2D(points.points, radii=[0.01], colors=[[255, 60, 60]]))
        v, w = r["command"]
        rec.log("plots/v", rr.Scalars(v))
        rec.log("plots/omega", rr.Scalars(w))
        rec.log("plots/tick_ms", rr.Scalars(1e3 * r["compute"]))
        if r["planning"] is not None:
            rec.log("plots/planning_ms", rr.Scalars(1e3 * r["planning"]))
        if r["obstacles"] is not None:
            try:
                rec.log("world/obstacles/estimated", rr.LineStrips2D(_outlines(r["obstacles"]),
                                                                     colors=[[40, 200, 90]]))
            except Exception as err:
                log.debug("estimated obstacles not logged: %s", err)
        if r["leg"] is not None:
            leg, k = r["leg"]
            key = (len(leg), k, tuple(map(tuple, leg[:1])) if leg else ())
            if key != self._last_leg:
                self._last_leg = key
                if leg:
                    arr = np.asarray(leg, dtype=float)
                    rec.log("world/path", rr.LineStrips2D([arr[:, :2]], colors=[[160, 90, 255]]))
                    rec.log("world/path/vertices", rr.Points2D(arr[:, :2], radii=[0.03], colors=[[160, 90, 255]]))
                    g = arr[min(k, len(arr) - 1)]
                    th = g[2] if len(g) > 2 else 0.0
                    rec.log("world/goal", rr.Arrows2D(origins=[g[:2]], vectors=[[0.3 * math.cos(th), 0.3 * math.sin(th)]],
                                                      colors=[[255, 0, 200]]))
                else:
                    rec.log("world/path", rr.Clear(recursive=True))
        status = r["status"]
        if status is not None:
            st = (status.get("state"), status.get("message"))
            if st != self._last_state:
                self._last_state = st
                level = "WARN" if st[0] in ("blocked", "error") or str(st[1]).startswith("warning") else "INFO"
                rec.log("status/state", rr.TextLog(f"{st[0]}: {st[1]}", level=level))
            plan = (status.get("task"), str(status.get("plan")), status.get("target"))
            if plan != self._last_plan:
                self._last_plan = plan
                p = status.get("plan") or {}
                text = (f"**task** `{plan[0]}`\n\n**target** {plan[2]}\n\n"
                        f"**prefix** {' -> '.join(p.get('prefix', []))}\n\n"
                        f"**suffix** {' -> '.join(p.get('suffix', []))}")
                rec.log("status/plan", rr.TextDocument(text, media_type="text/markdown"))
        if r["regions"] is not None:
            self._log_regions(r["regions"])
        if r["field"] is not None and self._heat_job is None \
                and float(pose.stamp) - self._field_t >= self.field_period:
            self._arrow_job = (r["field"][0], pose)  # the newest due refresh wins

    def _nf_step(self) -> bool:
        """One piece of navigation-function work (an arrow refresh, else one heat-map chunk);
        returns whether there was any."""
        try:
            if self._arrow_job is not None:
                fld, pose = self._arrow_job
                self._arrow_job = None
                self._log_field(fld, pose)
                return True
            if self._heat_job is not None:
                self._heat_step()
                return True
        except Exception as err:  # visualisation must never take the service down
            self._heat_job = None
            log.debug("navigation function not logged: %s", err)
            return True
        return False

    def _heat_step(self) -> None:
        """Evaluate the next ``heat_chunk`` grid points of the pending heat map; log it when
        complete (spreads the evaluation over a few ticks)."""
        import rerun as rr

        t0 = time.perf_counter()
        job = self._heat_job
        nf, k = job["field"].nf, job["k"]
        grid, step = self._heat_grid
        end = min(k + self.heat_chunk, len(grid))
        ev = nf.evaluate(grid[k:end], 0)
        job["value"][k:end], job["free"][k:end] = ev.value, ev.free
        job["k"] = end
        if end == len(grid):
            self._heat_job = None
            free = job["free"]
            self._rec.log("world/nf", rr.Points2D(grid[free], radii=[0.5 * step],
                                                  colors=_colormap(_ranks(job["value"][free])), draw_order=-10.0))
        self.field_times.append(time.perf_counter() - t0)

    def _log_field(self, fld, pose) -> None:
        """Arrows of ``fld`` around the robot and the current waypoint; a heat map of
        ``fld.nf`` queued when ``fld`` is new (see the module docstring)."""
        if fld is None:
            return
        import rerun as rr

        t0 = time.perf_counter()
        rec = self._rec
        self._field_t = float(pose.stamp)
        nf = fld.nf
        if fld is not self._field:
            self._field = fld
            if self._heat_grid is None and self._workspace is not None:
                pts = self._workspace.boundary_points(_OUTLINE)
                self._heat_grid = _grid(pts.min(axis=0), pts.max(axis=0), self.heat_points)
            if self._heat_grid is not None:
                n = len(self._heat_grid[0])
                self._heat_job = {"field": fld, "k": 0, "value": np.zeros(n), "free": np.zeros(n, bool)}
        robot = np.array([pose.x, pose.y])
        goal = np.asarray(fld.goal, float)
        lo = np.minimum(robot, goal) - 0.5
        hi = np.maximum(robot, goal) + 0.5
        span = float(max(hi - lo))
        n = max(self.arrow_grid, 2)
        step = span / n
        xs = np.arange(lo[0] + step / 2, hi[0], step)
        ys = np.arange(lo[1] + step / 2, hi[1], step)
        pts = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
        pts = pts[nf.is_free(pts)]
        if len(pts):
            vec = fld.field(pts)
            norm = np.linalg.norm(vec, axis=1, keepdims=True)
            ok = norm[:, 0] > 1e-12
            vec = np.where(ok[:, None], vec / np.where(ok[:, None], norm, 1.0), 0.0) * (0.7 * step)
            rec.log("world/field", rr.Arrows2D(origins=pts[ok], vectors=vec[ok], colors=[[230, 230, 230]],
                                               radii=[0.008]))
        else:
            rec.log("world/field", rr.Clear(recursive=False))
        self.field_times.append(time.perf_counter() - t0)
