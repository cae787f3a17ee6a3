"""The online task executive: hybrid execution and joint online adaptation (paper 001 sections
4.1.4 and 4.2).

One stateful object, :class:`Executive`, turns ``(pose, scan)`` ticks into unicycle commands
``(v, omega)`` while it keeps every layer consistent with what the robot has seen::

    scan -> perception.ObstacleMap -> forest of stars (navigation.build_forest)
         -> roadmap (tamp.roadmap) -> harmonic trees (tamp.harmonic_tree)
         -> navigation-map costs / removed transitions (tamp.navmap) -> plan (MissionPlanner)
    plan -> current leg (harmonic tree from the pose to the next region)
         -> pursuit of the leg (eq. 24 on the bearing of the point 0.3 m ahead on it; the
            leg end's oriented field for the safety limit), or the oriented fields of the
            current and following waypoints -> eq. 24-25 command

Work is triggered by what changed, never done on every tick:

* a :class:`perception.MapUpdate` with ``changed`` rebuilds the forest (memoised per obstacle in
  ``navigation.build_forest``, so only the changed obstacles cost), drops the cached fields,
  and checks the current leg and every evaluated transition against the changed obstacles; a
  re-plan runs only when one of them is hit (or when the executive is ``blocked``);
* reaching a region advances the mission automaton and re-plans (the next leg);
* a mission event (``replace``, ``add``, ``urgent``; world-file ``events`` at their times or
  :meth:`Executive.request`) re-plans;
* regions added or moved at run time (:meth:`Executive.set_regions`, or ``regions=`` of
  :meth:`Executive.request`; validated against the known map, all or nothing) rebuild the
  planner's navigation map over the new region set, keeping the mission's progress and the
  trees between unmoved regions, and re-plan.

Planning is *lazy* (section 4.2.4 with the lazy evaluation of roadmap planners): the navigation
map starts fully connected with its straight-line costs, which are lower bounds of every tree
cost; the planner's plan is computed, the transitions it uses that have no harmonic tree yet
get one (their cost set, or the transition removed when no tree exists), and the plan is
computed again until it only uses evaluated transitions. The result is optimal for the tree
costs while only the transitions a plan could use are ever searched.

Hybrid execution (section 4.1.4): the current leg is the harmonic tree from the robot's pose
to the next region's centre; with ``ExecutiveConfig(pursuit=0)`` the executive tracks the
oriented field of the current waypoint and, through the switch of eq. 25, of the following one,
and moves to the next waypoint when the robot is within ``waypoint_tolerance`` of the current
one (the paper's scheme); by default it *pursues* the leg instead (below, "Pursuit"). The
region counts as reached when the robot's centre enters its disc.

Choices where the paper is vague, and why
-----------------------------------------
* **Pursuit** (not in the paper; ``ExecutiveConfig.pursuit``, 0.3 m; forty-second session).
  The fields of consecutive waypoints disagree near their goals: each turns the robot towards
  its own goal heading and the next one turns it back, so eq. 24-25 weave along a straight
  leg (turn-rate sign flips 1.1-3.1 per metre on the benchmark's 13 missions; the evaluation's
  flag is 1 per metre; docs/history.md "Where the chatter comes from"). The tree's path is
  a polyline whose segments the roadmap joined at the buffer, so the executive pursues it:
  eq. 24 (heading gate, saturation, the braking-aware safety limit on the forest's grown
  obstacles, rate limit; :func:`navigation.control.track_point`) on the bearing of the point
  ``pursuit`` metres of path ahead of the robot's projection on its segment (the leg's end at
  most: the region's centre, whose disc ends the leg). That point rounds a corner only along
  a line clear of the forest's obstacles (inflated by the robot radius) grown by
  :data:`PURSUIT_MARGIN` (2 cm: packed rows whose half-extents are widened, tested exactly by
  ``tamp.roadmap.segments_clear``); else
  the robot pursues the end of its segment (the corner), else the point ``pursuit`` ahead on
  its segment; that point (and only it) is also pursued when its line clears the inflated
  obstacles without the margin (forty-third session: in a passage whose free width leaves
  less than the margin beside the robot's offset from the path, every line failed the
  margin and the waypoint's field crawled and turned back at the entrance, ``cluttered20``'s
  0.27 m passage beside the east bar: 18 s lost, then the long way round), and when not
  even that line is clear (an estimate grew over the leg) it tracks the current waypoint's
  field as in the paper for that tick (a re-plan follows from the leg's own check). A
  waypoint counts as passed once the robot's projection is past the end of its segment or
  the robot is nearer the next segment. The fields keep the safety limit,
  the escape band, the legs that are no tree's path (a start inside a buffer zone), the route
  rescue and the baselines' OHPF. Measured (``python -m benchmarks.executive --random 60
  --jitter 4 --jobs 2``, 315 missions with unknown obstacles, against the fields on the same
  commit): within 1.25 x the full-knowledge tour 63/63 nominal (60/63) and 248/252 jittered
  (239/252), 1921.3 m (1955.4 m) in all, every mission completed without collision; on the 13
  benchmark missions turn-rate flips above 1 per metre on 1 (13). Look-ahead 0.2 and 0.45 m
  (before the clear-line test) gave 3 and 4 flagged of 13 (docs/executive.md).
  **The pursuit's heading gate** (``pursuit_gate``, 60 degrees; forty-third session): eq.
  24a's ``max(0, cos e)`` lets a robot leaving a region drive off at up to 90 degrees from
  the pursued point, along an arc off its path, in the rate-limited mode where the turn
  before moving off ("Turning onto a leg") does not apply; on ``office`` the arc from ``p2``
  ended 1 cm from a wall's grown face, where no line was clear by the margin and the
  waypoint's field swung the robot round it for 5 s. The pursuit scales ``v`` by
  ``max(0, (cos e - cos g) / (1 - cos g))`` instead: continuous, 1 on the point's bearing, 0
  beyond ``g`` (turn on the spot, as regulated pure pursuit does), never faster than eq.
  24a's gate (the safety limit is an upper bound, so lower speeds keep it). On the 13
  missions: 106.2 m against 108.1 m in all, ``office`` 13.56 m against 14.21 m; 45 degrees
  gave 104.9 m but 3 flagged of 13 (turning on the spot more often flips the turn rate).
* **Arrival heading.** The navigation map carries orientations, but the map's rotation term
  ``w |theta - theta'|`` does not depend on the travel direction, so the orientation the plan
  picks says nothing about how the robot arrives. The goal heading of a leg is the direction
  of the leg's last segment (the robot arrives straight, no swing around the region).
* **Roadmap updates.** ``Roadmap.with_obstacles`` handles additions, applied lazily from a
  keyed obstacle model (only the current version of an estimate is ever added). An estimate
  the map *updates* or *removes* is handled conservatively: the roadmap keeps avoiding the old
  shape too (a superset of the obstacles is safe); it is stale unless the new shape covers it,
  and when ``rebuild_after`` stale shapes pile up, or a transition is found blocked, the
  roadmap is rebuilt from the current obstacles.
* **Leg shortcuts.** The executed leg skips the tree waypoints whose neighbours see each other
  at the buffer: eq. 26 can make an out-and-back detour to turn at a vertex cheaper than a turn
  on the spot (``ExecutiveConfig.shortcut_legs``, :meth:`Executive._shortcut`).
* **Short edges.** The robot drives a leg's waypoints at most ``max_segment`` (0.4 m) apart:
  a longer segment of the tree's path gets evenly spaced waypoints on it (they lie on a
  segment the roadmap joined at the buffer, so they are in free space; any that is not, after
  a map change, is dropped like a tree waypoint). The paper tracks the oriented field of each
  tree vertex (eq. 23-25), but far from its goal that field's integral curve is not the
  tree's straight edge: the navigation transformation bends it (strongly next to walls and
  the workspace boundary, docs/control.md "Turn-rate chatter") and the dipole of eq. 23 swings
  the robot wide to meet the goal heading. Near its goal the sink dominates and the curve
  runs straight in, so with goals 0.4 m ahead the robot follows the edges, and the field
  keeps its role (safety limit, no local minimum between consecutive waypoints). Measured
  (``python -m benchmarks.executive``, 13 missions, unknown obstacles) against the tree's own
  waypoints: distance within 1.25 x the full-knowledge tour on 11/13 instead of 8/13, total
  distance 134.6 -> 115.2 m, total mission time 452 -> 348 s; 0.3, 0.5, 0.7 and 1.0 m gave
  11, 9, 9 and 8 of 13 (docs/executive.md).
* **Passing a waypoint.** An intermediate waypoint counts as passed within
  ``waypoint_tolerance`` (0.15 m) of it, or within ``pass_beyond`` (0.3 m) once the robot is
  beyond the line through it across its heading (the bisector of its two segments): a robot
  that misses the tolerance disc sideways no longer turns back to hit it (the dipole of eq. 23
  makes the field swing round to reach the waypoint along its heading). Measured on the
  benchmark's 13 missions: within 1.25 x the tour 11/13 -> 12/13, total distance 113.8 ->
  113.3 m, total mission time 343 -> 333 s, median chatter 2.95 -> 2.17 /m (0.3, 0.4 and 0.55
  m gave the same runs).
* **Turning onto a leg** (not in the paper). Eq. 24a's heading gate stops the robot only when
  it faces more than 90 degrees away from the tracked direction; at the start of a leg (at a
  region, or a re-planned leg while moving) a robot 60-90 degrees off drove a loop of radius
  ``v / omega`` before it was on its way. For ``align_time`` (2 s) after a leg is set, while
  the tracked direction is more than ``align_angle`` (60 degrees) from the heading, ``v`` is
  0 and the robot turns on the spot by eq. 24b; once within it, eq. 24 as usual. ``v = 0`` is
  always safe; the time bound keeps a robot whose controller is escaping a grown boundary
  (it creeps only while facing within 45 degrees of the field, docs/control.md) from being
  held: without it, ``random2`` stood turning 2 cm from an estimate for 300 s. Measured on the
  13 benchmark missions: within 1.25 x the tour 11/13 -> 13/13, total distance 111.8 ->
  109.8 m; on 20 more random worlds 18/20 -> 19/20, 145.5 -> 142.1 m; from jittered start
  poses (4 per world, with the seen passages) 43 -> 44 of 52, 463.7 -> 450.6 m
  (docs/executive.md, "How much one run says").
* **Tracked direction.** The executive's controller tracks the push-forward direction of
  each waypoint's field (``ControllerConfig(push_forward=True)``, docs/control.md), not the
  rotated gradient of eq. 20-23 that ``navigation.track`` follows by default: its integral
  curves have no folds away from grown boundaries, so the turn rate chatters less and the
  missions are faster. Measured over 146 runs with unknown obstacles (the executive
  benchmark's 104 jittered runs, the evaluation's 22 scenarios, 20 more random worlds;
  docs/executive.md "Tracked direction"): no collision either way, turn-rate chatter median
  2.63 -> 1.79 /m on the 22 scenarios, mission time -8 % over the jittered runs, the same
  distances. It was kept off until perception's estimates and the motion guard made it safe
  (it collided on ``office`` when measured on commit 89acdee, docs/control.md).
* **No progress** (not in the paper). The stall guard below only sees a robot that stands
  still; next to chained walls the transformation can make the controller *creep* (millimetres
  per second along a grown boundary, turning back and forth; docs/control.md), and a leg
  planned before an estimate grew can leave its waypoint a few centimetres past the grown
  corner the robot creeps along. When for ``stuck_time`` (6 s) the robot has not come
  ``stuck_progress`` (5 cm) closer to the waypoint it tracks than it has been since that
  waypoint was set, the executive re-plans from where it is (the same request as the stall
  guard's): the new leg comes from the current map and trees. Seen on ``office``: at 35 s the
  robot reached the left face of the wall hanging from the top boundary at x = 5.7, 7 cm
  above its grown bottom corner, with the waypoint 7 cm below it; it crept 0.3 m up the face
  and back for 25 s; with the watchdog it re-planned at 40.7 s and was in ``d1`` at 47.7 s.
  *Route rescue* (``route_rescue``, default on since the thirty-first session): the first
  time the watchdog fires on a waypoint, the tracker instead pursues a harmonic tree from the
  robot to that waypoint along its straight segments (``navigation.Tracker.rescue``,
  docs/control.md "Route rescue"; the tree on the executive's roadmaps,
  :meth:`Executive._rescue_route`), and the crawl guard's own loops and crawls ask for such a
  tree too; the next firing on the same waypoint re-plans. A re-planned leg is tracked with
  fields again, and they can fail the same way: on ``office`` from its sixteenth jittered start
  the field of a waypoint 0.19 m above a wall's grown top, heading along it, pointed down
  into the wall east of the waypoint; the motion guard held the robot at a return 1 cm outside
  the wall's estimate, and for 200 s the watchdog's re-plans sent it back (278 s for the
  mission; 56 s with the rescue). Over 48 jittered starts of ``office``: mission time 3550 ->
  3211 s, the longest 278 -> 111 s, 888 -> 848 m; ``cluttered20``, ``random1`` and
  ``random8`` within 2 % either way; the benchmark's 315 and 65 missions: the same nominal
  routes, jittered within 1.25 x 233 and 48 as before, 0.1-0.2 % longer.
* **Commitment.** A re-plan between regions (a map change hit the leg or a tree) discounts
  the transition from the robot to the region it is heading for by ``commit_discount``
  (20 %), its straight-line lower bound as well as its tree cost (so the lazy evaluation stays
  exact for the discounted costs): the robot turns to another region only when that plan is
  cheaper by more than the discount. As walls appear, the cheapest next region can change at
  every discovery; without the discount ``random8``'s robot turned between two regions eight
  times in 19 s (12.32 m; with the discount 10.83 m). The mission's automaton still decides
  which regions may come next (urgent requests, mission changes).
* **Deferred re-plans** (not in the paper; ``ExecutiveConfig.defer_fits``, 5; forty-fourth
  session). A tick's compute is perception, then a re-plan when one is due, then the
  command, and the issue's 20 ms is a bound on their sum. The two heavy parts often come
  together: a refit that shows a wall on the leg is what asks for the re-plan. When the tick's
  map update ran at least ``defer_fits`` squircle fits (``MapUpdate.fits``: about 1 ms each,
  and deterministic where a measured time is not, so runs stay reproducible), the re-plan
  waits for the next tick, never two ticks in a row. Meanwhile the robot brakes at the rate
  limit (:meth:`navigation.Tracker.brake`), slowed further by the motion guard against every
  return of the scan (the estimates' returns too, since no field's safety limit is evaluated
  on that tick). On ``random8`` the re-plan ticks over 20 ms went from 6 to 0 and, with
  perception's budget for pending refits, the tick CPU p95 from 21.3 to 14.7 ms. On the
  benchmark's 63 missions (``--random 60``) the tick target is met on 63 instead of 60, for
  1.6 % more mission time at the same distance (docs/history.md, executive "Forty-fourth session").
* **Legs from a region** (not in the paper; :data:`VIA_CENTRE_SLACK`, 0.2 m; forty-fourth
  session). The navigation map's cost of a transition is the tree between the two regions'
  centres, but the robot leaves a region from where it entered the disc, up to its radius
  from the centre, and a tree from there can leave by another way: the start may lie in an
  obstacle's buffer zone. On sweep world ``random698`` the tree from ``r4``'s centre to
  ``r2`` ran 2.8 m south-west, the tree from the robot 4.5 m east through ``r3``; entering
  ``r3`` re-planned, and the plan went back through ``r4`` for the cheap transition, for the
  rest of the 300 s. The leg from a region now runs through its centre and then along that
  transition's tree when the tree from the robot is longer by more than 0.2 m (or missing):
  the way to the centre lies inside the region disc, which perception keeps clear of the
  inflated estimates (FORMATS.md's region rule for the known obstacles), and the robot
  drives what the plan paid for.
* **Buffer fallback.** With the paper's 0.15 m buffer, passages narrower than
  ``2 (r + 0.15)`` are closed for the trees. A transition without a tree at ``buffer`` is
  retried at ``fallback_buffer`` before it is declared blocked. A transition whose tree at
  ``buffer`` is a long way round (its translation more than ``detour_ratio = 2`` times the
  straight line) also gets a tree at ``fallback_buffer``, and takes it when it is more than
  ``detour_ratio`` times shorter: on ``cluttered20`` the robot went from ``d3`` to ``d2``
  around the whole workspace (about 10 m) instead of through a 0.3 m gap (2.5 m). Measured
  with ``python -m benchmarks.executive`` on 13 worlds: ``cluttered20`` 24.4 m in 97 s ->
  11.4 m in 47 s; ``random2`` 7.7 -> 6.6 m (but 24 -> 37 s: the robot is slower in narrow
  passages); ``random1`` 14.2 -> 15.6 m (the narrow way turned out longer once discovered);
  the 10 others unchanged. The extra tree costs re-planning time only on such transitions.
  A passage the lidar has seen free (``perception.ObstacleMap.observed_free``) is taken on a
  smaller saving, ``seen_detour_ratio = 1.25`` on the trees' eq. 26 costs (docs/executive.md);
  a transition between regions keeps such a tree as a candidate, re-checked at every re-plan,
  until its passage is seen. *Hysteresis*: a re-plan on the way keeps a leg that came from the
  fallback roadmap while that roadmap's tree is merely shorter or cheaper (both ratios 1;
  the seen check still applies): the saving shrinks as the robot approaches the passage, and
  on ``office`` the robot at ``d3`` turned back and forth between the passage and the way
  round as the cost ratio crossed 1.25. Measured with ``python -m benchmarks.executive
  --jitter 8 --jobs 2``: within 1.25 x the tour 92 -> 96 of 104 runs, total 897.7 -> 890.2 m.
  *Boundary buffer* (opt-in, ``boundary_buffer``): the workspace boundary is known exactly,
  so a roadmap may keep less than its buffer from it (``RoadmapConfig.boundary_buffer``) and
  pass between an estimate and the boundary where the paper's buffer closes the way. At 0.03
  m it fixes ``random1`` (1.52 -> 1.21 x: a 0.52 m gap between a bar and the boundary) and
  ``random55`` (1.45 -> 1.14 x), but the routes along the boundary it opens compete with the
  fallback's passages and run through unexplored space: ``random42`` 1.08 -> 1.21 x,
  ``random53`` (jittered) 1.09 -> 1.26 x. Over ``python -m benchmarks.executive --random 60
  --jitter 4 --jobs 2`` it gives 290 of 315 runs within 1.25 x against 291, 1978.1 against
  1964.8 m (docs/history.md, executive, thirty-first session), so it is off by default.
  *Probe* (opt-in, ``probe_ratio``): a leg from the robot whose fallback tree is
  ``seen_detour_ratio`` times cheaper but unseen goes and looks when the saving exceeds
  ``probe_ratio`` times the way until the passage's first narrow point is within lidar range
  (the look's cost there and back if the passage is closed; 2 is even odds). At 2 it gives
  297 of 315 runs within 1.25 x against 291 on the 60 random worlds, but 58 of 65 against 60
  on the benchmark's 13 (``cluttered20`` 1.27 x nominal: a passage rightly probed, then
  closed for a moment by an estimate), and 4.4 % more mission time over both (the robot is
  slow in narrow passages); like ``detour_ratio`` 1.5 (twenty-ninth session), off by default.
* **Narrow passages** (not in the paper). The roadmaps' vertices sit ``offset`` (5 cm)
  outside the grown obstacles, so none may see through a passage only centimetres wide at
  ``fallback_buffer``: on ``random103`` (``python -m benchmarks.executive --sweep``) the
  estimates left a pocket round ``r1`` whose way out was such a passage, every roadmap had
  ``r1`` walled off, and the robot stopped, blocked, for good (nothing changes the map of a
  robot that stands still). When no roadmap connects a transition, the executive adds the
  passages' vertices (``Roadmap.gap_candidates``: midpoints between facing boundaries less
  than 0.15 m apart) to the fallback roadmap, once per roadmap version, and tries it again
  (``gap_searches`` counts them); a region is declared unreachable only if that fails too.
* **Going to look** (not in the paper; issue 6 asks to stop when blocked). A region the
  trees cannot reach *with the obstacles seen so far* may be reachable: the estimates of
  walls seen from one side fill their unseen side (perception's conservative completion),
  and a robot that stops sees nothing new, so it stayed blocked for good. On ``random520``
  (``--sweep``) two bars seen from above were estimated as one blob over ``r1``, which lies
  under them. Before stopping, the executive drives to the reachable point nearest to the
  region (a vertex of the fallback roadmap in the robot's component, nearest to its centre;
  ``look_tries`` = 3 points per region, each ``LOOK_SPACING`` from the others and from where
  the robot stood) and plans again there with what the lidar saw on the way. Only when
  every look fails is it ``blocked`` (stopped; it still resumes when a map update reopens a
  way). ``random520`` then completes (16.4 m); the walled-off corridor of the tests is
  blocked after three looks, at 11 s instead of 1.4 s.
* **Centred waypoints** (not in the paper). A tree through a passage narrower than the
  buffer allows (the fallback roadmap) turns at vertices ``fallback_buffer`` off the grown
  obstacles, i.e. 3 cm from the forest's boundary, where the navigation transformation is
  ill-conditioned and the tracked direction swings (docs/control.md): on ``office`` the
  robot stood turning for seconds beside a wall end 20 cm from its next waypoint. Every
  intermediate waypoint of a leg closer than ``buffer`` to the forest's boundary
  (``navigation.clearance.forest_clearance``) moves, within ``centre_reach`` (0.12 m: 64
  candidates on four rings), to where its clearance (capped at ``buffer``) minus a quarter
  of the move is largest, provided both of its segments stay clear at the fallback buffer
  (``Roadmap.visible``); in a gap this is its middle. Waypoints at ``buffer`` or more (the
  paper's trees) do not move. Measured with ``python -m benchmarks.executive --jitter 16
  --jobs 2`` (208 runs, with ``--set centre_reach=0`` for the code before): total distance
  1803.2 -> 1777.2 m, total mission time 5298 -> 5130 s, within 1.25 x the tour 191 -> 192
  of 208, 0 collisions and 208/208 completed both (reach 0.06: 1781.8 m, 5131 s, 190).
* **Reachable turns** (not in the paper). Eq. 24a drives at full speed whenever the robot
  faces within 90 degrees of the tracked direction; a waypoint close beside the robot (a leg
  set while passing a gap's entrance, 0.4 m to its left) is then overshot on a turn of
  radius ``v / omega_max`` (0.33 m at full speed) and approached again from the far side,
  next to the obstacle beyond. With ``turn_cap`` the speed is at most
  :func:`reachable_speed`: ``omega_max d / (2 sin a)`` for the distance ``d`` and bearing
  ``a`` of the tracked waypoint, the speed at which the circle through it tangent to the
  heading can be driven (lower speed is always safe). Measured with ``python -m
  benchmarks.executive --jitter 16 --jobs 2`` (208 runs, with ``--set turn_cap=false``
  for the code before): within 1.25 x 192 -> 195, total distance 1777.2 -> 1744.4 m,
  mission time 5130 -> 5083 s, 208/208 completed and 0 collisions both. In the rate-limited
  mode (the default controller since the twenty-seventh session) the cap cannot cut ``v`` at
  once: with ``turn_cap_rate_limited`` (twenty-ninth session) it goes to the tracker as
  ``v_cap`` (:func:`navigation.control.track`), a target the rate limit brakes towards at
  ``accel_max`` before ``v`` enters eq. 24b's feed-forward; the robot slows down before a
  waypoint it must turn sharply onto instead of circling past it (it was off in that mode
  before, docs/history.md, executive, twenty-ninth session).
* **Known obstacles** (``known_obstacles`` in the world file, or all with ``known=True``) are
  used as given; lidar returns on them are dropped before perception (a NaN range: no return
  and no free-space evidence). When the known obstacles grown by the robot radius are not a
  forest of stars (``cluttered20``: a cycle), the forest construction refuses them; they are
  then left to perception (discovered by the lidar), which repairs cycles by merging, and the
  status message says so.
* **Blocked.** When no accepting plan exists in the current navigation map the executive stops
  (``v = omega = 0``), reports ``blocked`` with the regions it cannot reach, and on every later
  map change rebuilds the roadmap, re-evaluates the removed transitions and re-plans.
* **Weights** (section 4.2.3, step III). The paper refits ``w`` from the "actual costs" of the
  traversed edges without defining them. The cost of eq. 26 is in metres (``d`` plus
  ``w |dtheta|``), so the measured cost of an edge is the distance the robot could have driven
  at full speed in the time it took: ``gamma* = v_max * dt``, ``dt`` from passing one waypoint
  to passing the next (turning and slowing down make it exceed ``d``). Only edges completed by
  passing their end waypoint count (not legs cut by a re-plan, the last edge into a region, or
  a waypoint passed by the stall guard). From ``refit_min_edges`` edges on, every new edge
  refits ``w* = (Q^T Q)^-1 Q^T (gamma* - d)`` over the last ``refit_window`` (1000) edges
  (``d``, ``Q`` of the edge as driven: its end poses; a window so that a robot patrolling for
  days neither keeps every edge nor refits over all of them: a mission of the benchmarks
  drives fewer), clipped to ``weight_bounds``; the navigation-map costs of every
  evaluated tree are then recomputed with ``w*`` (same paths, :meth:`HarmonicTree.recost`) and
  new trees are searched with ``w*``; the next re-plan uses them.

Commands are always finite and within ``v_max`` / ``omega_max``; a non-finite or malformed pose,
or a pose outside the workspace, stops the robot with state ``error``.
"""

from __future__ import annotations

import enum
import logging
import math
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from scipy.sparse.csgraph import connected_components

from navigation.clearance import forest_clearance
from navigation.control import ControllerConfig, safety_limit, switch_weight
from navigation.errors import ForestError, NavigationError, TampError, WorldError, check_numbers
from navigation.forest import build_forest
from navigation.geometry import Squircle, beta_rows, pack
from navigation.oriented import OrientedField, wrap_angle
from navigation.potential import NavigationFunction
from navigation.tracker import CrawlConfig, Tracker, _to_segment
from navigation.world import Region, World, configuration_space, disc_violations
from perception.errors import ScanError
from perception.fit import inflate, radial_error
from perception.map import ObstacleMap

from .errors import InvalidRequestError, NoPlanError, brief
from .harmonic_tree import NoTreePathError, RotationWeights, TreeFailure, plan_tree, rotation_terms
from .ltl import ops
from .navmap import MAX_REGIONS, START, Node
from .planner import MissionMode, MissionPlanner, Plan
from .roadmap import Roadmap, RoadmapConfig, _outside_all, _point_segment_distance, grown, segments_clear

__all__ = ["Executive", "ExecutiveConfig", "ExecutiveState", "TickResult", "RegionError", "RegionRule",
           "reachable_speed"]

log = logging.getLogger("tamp.executive")


class ExecutiveState(str, enum.Enum):
    """FORMATS.md ``status.state`` (the service publishes these values)."""

    IDLE = "idle"
    PLANNING = "planning"
    EXECUTING = "executing"
    DONE = "done"
    BLOCKED = "blocked"
    ERROR = "error"

    @classmethod
    def parse(cls, value) -> "ExecutiveState":
        """The state named ``value``; raises ``ValueError`` listing the valid ones."""
        if isinstance(value, cls):
            return value
        try:
            return cls(getattr(value, "value", value))
        except ValueError:
            valid = ", ".join(repr(s.value) for s in cls)
            raise ValueError(f"{value!r} is not a valid state, must be one of {valid}") from None


class RegionRule(str, enum.Enum):
    """The rule a run-time region breaks (:class:`RegionError`)."""

    FORMAT = "format"          #: not a valid region (name, centre, radius)
    WORKSPACE = "workspace"    #: its disc grown by the robot radius must lie inside the workspace
    FREE_SPACE = "free_space"  #: ... and clear of every known obstacle and obstacle estimate
    DISJOINT = "disjoint"      #: region discs must be pairwise disjoint
    ALPHABET = "alphabet"      #: the running mission cannot read a visit to it (see Executive.set_regions)
    COUNT = "count"            #: the change would hold more than tamp.navmap.MAX_REGIONS regions


class RegionError(InvalidRequestError):
    """A region that cannot be added or moved at run time (:meth:`Executive.set_regions`).

    Attributes
    ----------
    region : str
        The offending region's name (the message starts with ``regions.<name>:``).
    rule : RegionRule
    """

    def __init__(self, region: str, rule: RegionRule, message: str):
        self.region = region
        self.rule = RegionRule(rule)
        super().__init__(f"regions.{region}: {message} [rule: {self.rule.value}]")


#: a return within this radial error (m) of an estimate is covered by it (the motion guard)
_GUARD_COVER_TOL = 0.002
#: a leg from a region runs through its centre when the tree from the robot is longer than the
#: centre's by more than this (m; module doc, "Legs from a region")
VIA_CENTRE_SLACK = 0.2
GUARD_HOLD_TICKS = 10  #: ticks the motion guard holds the robot before it slides around the return
GUARD_SLIDE_TIME = 2.0  #: seconds of a slide (Executive._slid)
GUARD_SLIDE_SPEED = 0.1  #: m/s at most during a slide
GUARD_SAME_SPOT = 0.05  #: returns this close (m) count as the same spot for repeated holds
GUARD_PHANTOM_RADIUS = 0.002  #: radius (m) of the disc the roadmaps avoid at a return that held the robot twice
MESSAGES_KEPT = 500  #: notes ``Executive.messages`` keeps at least (the latest; bounded for a long run)
REPLANS_KEPT = 10000  #: latest re-plan times ``Executive.replan_times`` keeps at least (``replans`` counts them all)


@dataclass(frozen=True, slots=True)
class ExecutiveConfig:
    """Tuning of the executive (frozen, validated).

    Attributes
    ----------
    buffer : float
        Safety buffer of the harmonic-tree roadmap beyond the robot radius (paper: 0.15 m).
    fallback_buffer : float
        Buffer of the second roadmap a transition is retried on when the first has no path
        (``0`` disables the fallback).
    boundary_buffer : float or None
        Buffer of every roadmap from the workspace boundary, at most that roadmap's own buffer
        (module doc, "Buffer fallback"; measured, opt-in); ``None`` (default): the roadmap's
        own buffer, as in the paper.
    waypoint_tolerance : float
        Distance at which the current waypoint counts as passed (m); above the switch margin
        of eq. 25 (0.1 m) so that the blend has barely started when the waypoint changes.
    check_margin : float
        A changed obstacle invalidates a tree when one of its segments comes within
        ``robot radius + check_margin`` of it.
    rebuild_after : int
        Stale (updated or removed) shapes tolerated in the roadmap before it is rebuilt.
    n_orient, n_headings : int
        Orientations per region in the navigation map; headings per roadmap vertex.
    max_plan_rounds : int
        Rounds of lazy evaluation per re-plan (each evaluates the transitions of one plan).
    stall_ticks : int
        Ticks without motion after which the executive passes a close waypoint or re-plans.
    blocked_timeout : float
        How long (s) :func:`tamp.run.run_mission` waits in ``blocked`` before giving up
        (the executive itself waits forever).
    refit_weights : bool
        Refit the rotation weights of eq. 26 from the traversed edges (section 4.2.3, step III).
    refit_min_edges : int
        Traversed edges needed before the first refit.
    refit_window : int
        The refit uses the last this many traversed edges (a bounded memory for a long-running
        robot).
    weight_bounds : (float, float)
        Each refitted weight is clipped to this range (metres per radian).
    shortcut_legs : bool
        Skip the leg waypoints whose neighbours see each other at the buffer
        (:meth:`Executive._shortcut`): the tree's out-and-back detours to turn at a vertex.
    detour_ratio : float
        A transition that has a tree at ``buffer`` also gets one at ``fallback_buffer`` when
        its translation is more than ``detour_ratio`` times the straight-line distance; the
        fallback tree is taken when it is more than ``detour_ratio`` times shorter (a detour
        around a narrow passage that long is not worth the wider margin). ``0`` keeps the
        first tree found (the fallback only when there is no tree at ``buffer``).
    seen_detour_ratio : float
        The same with a smaller ratio for a narrow passage the lidar has seen: the fallback
        tree is also taken when it is more than ``seen_detour_ratio`` times shorter and at
        least ``seen_share`` of its stretch closer than ``buffer`` to an obstacle or the
        boundary lies in space observed free (``perception.ObstacleMap.observed_free``; with
        every obstacle known, always), the comparison on the trees' eq. 26 costs (a turn to
        another side of an obstacle counts). ``0`` disables it (otherwise at least 1).
    seen_share : float
        See ``seen_detour_ratio`` (in ``(0, 1]``).
    probe_ratio : float
        ``k`` of the probe (module doc, "Buffer fallback"; measured, opt-in): a leg from the
        robot takes a fallback tree ``seen_detour_ratio`` times cheaper whose passage has not
        been seen when its saving exceeds ``k`` times the way along it until the passage is
        within lidar range. ``0`` (default): off.
    look_tries : int
        Looks before ``blocked`` (module doc, "Going to look"): when a region cannot be reached
        with the obstacles seen so far, the robot first drives to the reachable point nearest
        to it, up to this many times per region from different points (3; 0: stop at once).
    stuck_time, stuck_progress : float
        Progress watchdog (module doc, "No progress"): when for ``stuck_time`` seconds the
        robot has not come ``stuck_progress`` metres closer to the waypoint it tracks than it
        has been since that waypoint was set, the executive re-plans from where it is.
        ``stuck_time = 0`` turns it off.
    centre_reach : float
        A leg's intermediate waypoint closer than ``buffer`` to an obstacle or the boundary
        moves by up to this distance (m) to where its clearance is largest (module doc,
        "Centred waypoints"). ``0`` keeps the trees' vertices.
    turn_cap : bool
        Cap ``v`` so that the robot can turn onto the waypoint it tracks
        (:func:`reachable_speed`; module doc, "Reachable turns"); in the rate-limited mode only
        with ``turn_cap_rate_limited``, as a target the rate limit brakes towards. Only while a
        waypoint's field is tracked: pursuing the leg (``pursuit``) aims at no waypoint.
    turn_cap_rate_limited : bool
        The turn cap in the rate-limited mode too (``v_cap`` of
        :meth:`navigation.Tracker.command`).
    align_angle, align_time : float
        Turning onto a leg: for up to ``align_time`` seconds after a leg is set, while the
        tracked direction is more than ``align_angle`` (radians, below ``pi / 2``) from the
        heading, ``v`` is 0 (the robot turns on the spot by eq. 24b); once within it, eq. 24 as
        usual. ``align_angle = 0`` turns this off; never in the rate-limited mode.
    guard_margin : float
        Motion guard (:meth:`Executive._guard`): a command whose next ``guard_horizon``
        seconds would bring the robot disc closer than ``guard_margin`` to a lidar return of
        the last scan that no estimate covers, and closer than it already is, has its speed
        reduced until it does not (turning is kept); the clusters of the estimates there are
        refitted at the next scan. ``None`` disables the guard.
    guard_noise : float
        With a noisy lidar the guard keeps ``guard_margin`` plus this many standard deviations
        of the lidar's range noise (``perception.PerceptionConfig.noise_std``): a single scan's
        returns scatter about the surface, and a hold that one scan asks for, the next scan's
        draw may release (``--sweep 100:200 --noise 0.05``: 10 contact steps with 0, none with
        1; docs/history.md, executive, fortieth session). No effect without noise.
    guard_horizon : float
        Seconds of motion the guard checks (a control period at 10 Hz).
    crawl_guard : navigation.CrawlConfig or None
        Engage the controller's stand-off, pulled in round convex corners, while the robot
        crawls (:mod:`navigation.tracker`: less than 0.1 m travelled in 3 s away from the
        tracked waypoint), and switches to wall following or the plain controller when it
        loops (since the twenty-fourth session, docs/control.md "Loops"); default
        ``CrawlConfig()``. ``None`` tracks with the plain controller. On by default since the
        twenty-third session (docs/executive.md): on
        ``python -m benchmarks.executive --random 60 --jitter 4`` it changed one of 63 nominal
        routes (``cluttered20`` 10.50 -> 10.43 m) and completed all 252 jittered missions
        (251 without: ``random44`` from start 1 circled for 290 s at a gap next to a chain),
        237 against 238 within 1.25 x their tour.
    route_rescue : bool
        With ``crawl_guard``: the progress watchdog's first firing on a waypoint, and the
        guard's loops and crawl engagements, make the tracker pursue a harmonic tree from the
        robot to the tracked waypoint along its straight segments (module doc, "No progress";
        ``navigation.Tracker``'s route rescue, docs/control.md "Route rescue"). Default on.
    speed_to_leg_end : bool
        Eq. 24a's speed factor from the path length still to go along the leg (through the
        remaining waypoints to the region) instead of the distance to the current waypoint
        (``beyond`` of :func:`navigation.track`): the robot slows down for the region, not for
        every waypoint of the tree (docs/executive.md: 16 % less mission time on the 13
        benchmark missions).
    controller : navigation.ControllerConfig or None
        Gains and modes of the unicycle controller (eq. 24-25); its ``v_max`` and ``omega_max``
        are replaced by the world's robot's. Default: the push-forward direction with the
        controller's default rate limit (``ControllerConfig(push_forward=True)``: every command
        within 0.1 m/s and 0.6 rad/s of the last, docs/control.md "Rate-limited mode"; module doc
        "Tracked direction"); ``ControllerConfig(push_forward=True, **navigation.control.UNLIMITED)``
        without the rate limit (with the turn cap and the turn onto a leg, which the rate
        limit excludes); ``None``: the controller's own defaults (the rotated gradient of
        eq. 20-23).
    max_segment : float
        Longest distance (m) between consecutive waypoints of a leg: longer segments of the
        tree's path get evenly spaced waypoints on them (module doc, "Short edges"); ``0``
        tracks the tree's own waypoints only.
    pass_beyond : float
        An intermediate waypoint also counts as passed when the robot is within this distance
        (m) of it and beyond the line through it across its heading (module doc, "Passing a
        waypoint"); ``0``: only ``waypoint_tolerance`` counts.
    pursuit : float
        Look-ahead (m) of the pursuit of the leg (module doc, "Pursuit"): the robot steers for
        the point this far along the tree's path ahead of it (0.3); ``0`` tracks each
        waypoint's oriented field with eq. 24-25 (the paper's execution).
    pursuit_gate : float
        Heading gate of the pursuit (radians, in ``(0, pi / 2]``; module doc, "Pursuit"): ``v``
        is eq. 24a's times ``max(0, (cos e - cos g) / (1 - cos g))`` for the heading error ``e``,
        so the robot turns on the spot while the pursued point is more than ``g`` off its
        heading (``pi / 3``); ``pi / 2`` is eq. 24a's own gate ``max(0, cos e)``.
    defer_fits : int
        A re-plan due on a tick whose map update ran at least this many squircle fits
        (``MapUpdate.fits``, about 1 ms each) waits for the next tick, and the robot brakes at
        the rate limit meanwhile (module doc, "Deferred re-plans"); never two ticks in a row.
        ``0``: never deferred.
    commit_discount : float
        A re-plan between regions discounts the transition from the robot to the region it is
        heading for by this fraction (module doc, "Commitment"): the robot turns to another
        region only when that plan is cheaper by more than the discount. ``0``: none.
    """

    buffer: float = 0.15
    fallback_buffer: float = 0.03
    boundary_buffer: float | None = None
    waypoint_tolerance: float = 0.15
    check_margin: float = 0.05
    rebuild_after: int = 8
    n_orient: int = 8
    n_headings: int = 8
    max_plan_rounds: int = 40
    blocked_timeout: float = 10.0
    stall_ticks: int = 20
    refit_weights: bool = True
    refit_min_edges: int = 4
    refit_window: int = 1000
    weight_bounds: tuple = (0.01, 1.0)
    shortcut_legs: bool = True
    detour_ratio: float = 2.0
    seen_detour_ratio: float = 1.25
    seen_share: float = 0.9
    probe_ratio: float = 0.0
    guard_margin: float | None = 0.005
    guard_noise: float = 1.0
    guard_horizon: float = 0.1
    crawl_guard: CrawlConfig | None = CrawlConfig()
    route_rescue: bool = True
    speed_to_leg_end: bool = True
    controller: ControllerConfig | None = ControllerConfig(push_forward=True)
    max_segment: float = 0.4
    commit_discount: float = 0.2
    pass_beyond: float = 0.3
    align_angle: float = math.pi / 3
    align_time: float = 2.0
    stuck_time: float = 6.0
    stuck_progress: float = 0.05
    centre_reach: float = 0.12
    turn_cap: bool = True
    turn_cap_rate_limited: bool = True
    look_tries: int = 3
    pursuit: float = 0.3
    pursuit_gate: float = math.pi / 3
    defer_fits: int = 5

    def __post_init__(self):
        check_numbers(self, ("buffer", "fallback_buffer", "check_margin", "blocked_timeout", "detour_ratio",
                             "seen_detour_ratio", "seen_share", "probe_ratio", "align_angle", "align_time", "guard_horizon", "guard_noise",
                             "max_segment", "pass_beyond", "stuck_time", "stuck_progress", "centre_reach", "pursuit"),
                      positive=False, error=TampError)
        for name in ("guard_margin", "boundary_buffer"):
            if getattr(self, name) is not None:
                check_numbers(self, (name,), positive=False, error=TampError)
        if not (isinstance(self.waypoint_tolerance, (int, float)) and self.waypoint_tolerance > 0):
            raise TampError(f"ExecutiveConfig.waypoint_tolerance must be > 0, got {self.waypoint_tolerance!r}")
        for name in ("rebuild_after", "n_orient", "n_headings", "max_plan_rounds", "stall_ticks", "refit_min_edges",
                     "refit_window"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise TampError(f"ExecutiveConfig.{name} must be a positive int, got {v!r}")
        if self.refit_window < self.refit_min_edges:
            raise TampError(f"ExecutiveConfig.refit_window ({self.refit_window}) must be at least refit_min_edges "
                            f"({self.refit_min_edges}): the refit needs that many edges")
        for name in ("look_tries", "defer_fits"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise TampError(f"ExecutiveConfig.{name} must be an int >= 0, got {v!r}")
        for name in ("refit_weights", "shortcut_legs", "turn_cap", "turn_cap_rate_limited", "route_rescue"):
            if not isinstance(getattr(self, name), bool):
                raise TampError(f"ExecutiveConfig.{name} must be a bool, got {getattr(self, name)!r}")
        try:
            lo, hi = (float(v) for v in self.weight_bounds)
        except (TypeError, ValueError):
            raise TampError(f"ExecutiveConfig.weight_bounds must be (low, high), got {self.weight_bounds!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
            raise TampError(f"ExecutiveConfig.weight_bounds must satisfy 0 < low <= high, got {self.weight_bounds!r}")
        object.__setattr__(self, "weight_bounds", (lo, hi))
        if self.crawl_guard is not None and not isinstance(self.crawl_guard, CrawlConfig):
            raise TampError(f"ExecutiveConfig.crawl_guard must be a navigation.CrawlConfig or None, "
                            f"got {type(self.crawl_guard).__name__}")
        if self.seen_detour_ratio and not self.seen_detour_ratio >= 1:
            raise TampError(f"ExecutiveConfig.seen_detour_ratio must be 0 or at least 1, got {self.seen_detour_ratio!r}")
        if self.align_angle >= math.pi / 2:
            raise TampError(f"ExecutiveConfig.align_angle must be below pi / 2 (eq. 24a's heading gate stops the "
                            f"robot beyond it anyway), got {self.align_angle!r}")
        if not (isinstance(self.pursuit_gate, (int, float)) and not isinstance(self.pursuit_gate, bool)
                and 0 < self.pursuit_gate <= math.pi / 2):
            raise TampError(f"ExecutiveConfig.pursuit_gate must be an angle in (0, pi / 2] radians, "
                            f"got {self.pursuit_gate!r}")
        if not (isinstance(self.seen_share, (int, float)) and 0 < self.seen_share <= 1):
            raise TampError(f"ExecutiveConfig.seen_share must be in (0, 1], got {self.seen_share!r}")
        if not (isinstance(self.commit_discount, (int, float)) and 0 <= self.commit_discount < 1):
            raise TampError(f"ExecutiveConfig.commit_discount must be in [0, 1), got {self.commit_discount!r}")
        if self.controller is not None and not isinstance(self.controller, ControllerConfig):
            raise TampError(f"ExecutiveConfig.controller must be a navigation.ControllerConfig or None, "
                            f"got {type(self.controller).__name__}")


@dataclass(frozen=True, slots=True)
class TickResult:
    """One tick's output: the command, the status (FORMATS.md fields) and what happened."""

    v: float
    omega: float
    status: dict
    replanned: bool = False
    map_changed: bool = False
    compute: float = 0.0  #: wall seconds spent in the tick


# ---------------------------------------------------------------------------------------------
class _Roads:
    """A roadmap for one buffer over the executive's obstacle model (``model``: key -> shape,
    known obstacles and perception estimates by id; shared, updated by the executive), brought
    up to date lazily when a tree is needed (:meth:`current`).

    The shapes new since the roadmap was made are added by ``Roadmap.with_obstacles``. A shape
    the model has replaced or removed stays in the roadmap (a superset of the obstacles is
    safe, only paths can get longer); it counts as *stale* unless it is replaced by a shape
    whose buffered squircle covers its own (an estimate that grew: the old shape blocks
    nothing the new one does not). An update that arrives before the roadmap took the
    previous version costs nothing: only the model's current shapes are ever added. More than
    ``rebuild_after`` stale shapes take every replaced or removed shape out
    (``Roadmap.without_obstacles``: the same vertices and edges as a rebuild, at a fraction of
    its cost); :meth:`reset` rebuilds it from the model.
    """

    def __init__(self, workspace: Squircle, radius: float, buffer: float, model: dict, rebuild_after: int,
                 boundary_buffer: float | None = None):
        self.workspace, self.radius = workspace, radius
        self.config = RoadmapConfig(buffer=buffer, boundary_buffer=(
            None if boundary_buffer is None or boundary_buffer >= buffer else boundary_buffer))
        self.model = model
        self.rebuild_after = rebuild_after
        self.rm: Roadmap | None = None
        self.applied: dict = {}  # key -> the shape of that key the roadmap has
        self.stale = 0  # replaced or removed shapes still in the roadmap and not covered
        self.superseded = 0  # every replaced or removed shape still in the roadmap
        self.rebuilds = 0
        self.removals = 0
        self.gapped: Roadmap | None = None  # the roadmap version that got its passages' vertices

    def add_gaps(self) -> bool:
        """Add the vertices of the narrow passages (``Roadmap.gap_candidates``) to the current
        roadmap, once per roadmap version, none within 1 mm of a vertex it has (a roadmap
        revised since its passages were added keeps them). Whether vertices were added."""
        rm = self.current()
        if self.gapped is rm:
            return False
        cand = rm.gap_candidates()
        if len(cand) and len(rm.points):
            d = np.linalg.norm(cand[:, None, :] - rm.points[None, :, :], axis=2).min(axis=1)
            cand = cand[d > 1e-3]
        if len(cand):
            self.rm = rm.with_obstacles((), extra=cand)
        self.gapped = self.rm
        return len(self.rm.points) > len(rm.points)

    def current(self) -> Roadmap:
        if self.rm is not None:
            new = {k: sq for k, sq in self.model.items() if self.applied.get(k) is not sq}
            gone = [k for k in self.applied if k not in self.model]
            replaced = [k for k in new if k in self.applied]
            stale = self.stale + len(gone)
            if stale <= self.rebuild_after and replaced:
                amount = self.radius + self.config.buffer
                stale += sum(not _covers(grown(new[k], amount), grown(self.applied[k], amount)) for k in replaced)
            if stale > self.rebuild_after:
                # take every replaced or removed shape out (exact: what they hid comes back)
                current = {id(sq) for sq in self.model.values()}
                old = [k for k, sq in enumerate(self.rm.obstacles) if id(sq) not in current]
                self.rm = self.rm.without_obstacles(old)
                if new:
                    self.rm = self.rm.with_obstacles(list(new.values()))
                self.applied = dict(self.model)
                self.stale = self.superseded = 0
                self.removals += 1
            else:
                if new:
                    self.rm = self.rm.with_obstacles(list(new.values()))
                for k in gone:
                    del self.applied[k]
                self.applied.update(new)
                self.stale = stale
                self.superseded += len(gone) + len(replaced)
        if self.rm is None:
            self.applied = dict(self.model)
            self.rm = Roadmap.build(self.workspace, list(self.model.values()), self.radius, self.config)
            self.stale = self.superseded = 0
            self.rebuilds += 1
        return self.rm

    @property
    def outdated(self) -> bool:
        """The roadmap avoids a shape the model has replaced or removed (or will, once the
        model's changes are applied)."""
        return self.rm is not None and (self.superseded > 0 or any(
            self.model.get(k) is not sq for k, sq in self.applied.items()))

    @property
    def behind(self) -> bool:
        """The model has shapes the roadmap does not have yet."""
        return self.rm is not None and any(self.applied.get(k) is not sq for k, sq in self.model.items())

    def reset(self) -> None:
        """Rebuild from the model when the roadmap is next needed."""
        self.rm, self.applied, self.stale, self.superseded = None, {}, 0, 0


def _covers(outer: Squircle, inner: Squircle, samples: int = 64) -> bool:
    """``inner``'s boundary (``samples`` points) lies in ``outer`` (approximately: used only
    to decide when a roadmap is worth rebuilding, never for safety)."""
    pts = inner.point_at(2.0 * np.pi * np.arange(samples) / samples)
    return bool(np.all(outer.beta(pts) <= 0.0))


LOOK_SPACING = 0.3  #: m a new look point keeps from the robot and from the points already looked from
LOOK_CANDIDATES = 8  #: nearest candidates tried for a tree per region
LOOK_LEGS = 4  #: look legs per look try at most (a re-plan on the way starts a new leg to the same point)


PURSUIT_MARGIN = 0.02  #: m added to the inflated obstacles' half-extents for the pursued line (module doc, "Pursuit")


def _pose3(pose) -> tuple[float | None, tuple[float, float, float]]:
    """``(stamp or None, (x, y, theta))`` from a pose message or three numbers; TampError."""
    stamp = None
    if isinstance(pose, Mapping):
        try:
            stamp = pose.get("stamp")
            vals = (pose["x"], pose["y"], pose["theta"])
        except KeyError as err:
            raise TampError(f"pose message misses field {err.args[0]!r}") from None
    else:
        vals = pose
    try:
        p = tuple(float(v) for v in vals)
    except (TypeError, ValueError):
        raise TampError(f"pose must be three finite numbers (x, y, theta), got {pose!r}") from None
    if len(p) != 3 or not all(math.isfinite(v) for v in p):
        raise TampError(f"pose must be three finite numbers (x, y, theta), got {pose!r}")
    if stamp is not None:
        try:
            stamp = float(stamp)
        except (TypeError, ValueError):
            stamp = None
    return stamp, p


class Executive:
    """Online task executive (paper 001 sections 4.1.4, 4.2); see the module docstring.

    Parameters
    ----------
    world : navigation.World
        Workspace, regions, robot, lidar, default ``task`` and ``events``. Its obstacles are
        *not* used except those known at start.
    task : str, optional
        LTL mission (default: the world's ``task``).
    known : bool
        ``True``: every obstacle of ``world`` is known at start (no perception). ``False``
        (default): only ``world.known_obstacles``.
    config : ExecutiveConfig, optional

    Raises
    ------
    TampError
        (``LtlSyntaxError``, ``UnknownRegionError``, ``UnsatisfiableError``, ...) a task the
        planner refuses; a ``world`` that is not a World.

    Use
    ---
    ``result = ex.tick(pose, scan=None, points=None, now=None)`` once per control period;
    ``result.v, result.omega`` is the command, ``result.status`` the FORMATS.md ``status``
    payload (a sensor message taken at another pose than the command's: ``sensor_pose=``).
    ``ex.observe(pose, scan=None, points=None, now=None)`` integrates a further sensor message
    between ticks. ``ex.request(formula, mode, regions=None)`` changes the mission at run time,
    ``ex.set_regions(regions)`` adds or moves regions.
    """

    def __init__(self, world: World, task: str | None = None, *, known: bool = False,
                 config: ExecutiveConfig | None = None):
        if not isinstance(world, World):
            raise TampError(f"world must be a navigation.World, got {type(world).__name__}")
        t0 = time.perf_counter()
        self.world = world
        self.config = cfg = config or ExecutiveConfig()
        self.radius = r = float(world.robot.radius)
        self.control = (ControllerConfig.from_robot(world.robot) if cfg.controller is None else
                        replace(cfg.controller, v_max=float(world.robot.v_max), omega_max=float(world.robot.omega_max)))
        # eq. 24-25, with the crawl guard when configured (navigation.tracker)
        self._tracker = Tracker(self.control, cfg.crawl_guard, route=self._rescue_route if cfg.route_rescue else None,
                                route_tolerance=cfg.waypoint_tolerance)
        self.rescues = 0  # routes the tracker asked for (ExecutiveConfig.route_rescue)
        # (leg, waypoint index) the watchdog last answered with a route: the leg itself, not its
        # id(), which a later leg can reuse once this one is freed
        self._rescued = None
        self.cspace_workspace, _ = configuration_space(world.workspace, (), r)
        self.messages: list[str] = []
        self.message = ""
        self.time = 0.0
        idx = range(len(world.obstacles)) if known else world.known_obstacles
        known_obs = [world.obstacles[i] for i in idx]
        self._known_inflated = [inflate(o, r) for o in known_obs]
        try:
            self.forest = build_forest(self.cspace_workspace, self._known_inflated)
        except ForestError as err:
            self._note(f"known obstacles grown by the robot radius are not a forest of stars ({err}); "
                       "they are left to perception (discovered by the lidar)")
            known_obs, self._known_inflated = [], []
            self.forest = build_forest(self.cspace_workspace, [])
        self.known = known_obs
        self._known_rows = pack([inflate(o, 0.02) for o in known_obs]) if known_obs else None
        all_known = known and len(known_obs) == len(world.obstacles)
        self.omap: ObstacleMap | None = None if all_known else ObstacleMap.from_world(world)
        # the lidar's range noise (standard deviation, m): the motion guard's extra margin
        self._range_noise = self.omap.config.noise_std if self.omap is not None else 0.0
        self.planner = MissionPlanner(world, task, n_orient=cfg.n_orient)
        self.task = self.planner.mission
        self.weights = RotationWeights()
        self.weight_fits = 0  #: refits of the rotation weights so far
        # the weight refit's traversed edges, one row each (section 4.2.3, step III):
        # translation d, the two rotation terms Q (eq. 26), measured cost gamma* = v_max * dt
        self._edges: deque[tuple[float, float, float, float]] = deque(maxlen=cfg.refit_window)
        self._edge_t0: float | None = None  # when the robot left the current edge's start
        # the obstacle model by key: ("known", index) and ("estimate", perception id)
        self._model: dict = {("known", i): o for i, o in enumerate(known_obs)}
        self._roads = [_Roads(world.workspace, r, cfg.buffer, self._model, cfg.rebuild_after, cfg.boundary_buffer)]
        if cfg.fallback_buffer < cfg.buffer and cfg.fallback_buffer >= 0:
            self._roads.append(_Roads(world.workspace, r, cfg.fallback_buffer, self._model, cfg.rebuild_after,
                                      cfg.boundary_buffer))
        self._known_letters = None
        # transitions: key (region a, region b) sorted -> tree or error; "@start" legs separately
        self._pair: dict[tuple[str, str], object] = {}
        # pair -> (its tree, a shorter fallback tree whose narrow passage was not seen free yet)
        self._unseen: dict[tuple[str, str], tuple] = {}
        self._align_until = -math.inf
        self._start_pair: dict[str, object] = {}
        # the roadmap (index into ``_roads``) each start pair's tree came from, and the
        # (region, roadmap) of the current leg: a re-plan keeps a leg on the fallback roadmap
        # while that roadmap's tree is no dearer (``_tree``'s ``keep``)
        self._start_road: dict[str, int] = {}
        self._leg_road: tuple[str, int] | None = None
        self._commit: str | None = None  # the region a re-plan between regions is committed to
        self.events = sorted(world.events, key=lambda e: e.time)
        self._next_event = 0
        self.state = ExecutiveState.IDLE
        self.plan: Plan | None = None
        self.target: str | None = None
        self.leg: tuple = ()
        self.wp = 0
        self._fields: dict = {}
        self._rows = None  # (forest, its obstacles packed, and widened for the pursuit's line tests)
        self._pursuable = False  # the leg is a tree's path (pursuit may follow it)
        self._pursued = False  # the last command pursued the leg (not a waypoint's field)
        self._need_plan = True
        start = np.array(world.robot.start[:2])
        self._stalled = 0
        # (leg, waypoint index, best distance, when it was reached): a new leg object or
        # waypoint starts a new record (:meth:`_watch`), so setting a leg need not reset it
        self._progress = None
        self._looking: str | None = None  # region the current leg goes to look at (module doc, "Going to look")
        self._looked: dict[str, list] = {}  # region -> the points the robot went to look from
        self._look_legs: dict[str, int] = {}  # region -> look legs started (re-plans included)
        self._pose: tuple[float, float, float] = tuple(float(v) for v in world.robot.start)
        self._inside = {n for n, reg in world.regions.items() if reg.contains(start)}
        node = self.planner.node.region
        self._at_region: str | None = node if node in self._inside else None
        self._arrived = self._at_region is not None
        #: arrivals at the accepting state of the plan's lasso (recurrent missions)
        self.accepting_visits = 0
        self.unreachable: tuple[str, ...] = ()  #: regions named by the last blocked report
        self.message = ""
        self.time = 0.0
        # measurements
        self.planning_time = 0.0
        self.replan_times: list[float] = []
        self.replan_cpu_times: list[float] = []  #: process CPU seconds per re-plan (robust to a loaded machine)
        self.initial_time: float | None = None
        self.setup_time = time.perf_counter() - t0
        self.replans = 0
        self.visited: list[str] = []
        self.map_changes = 0
        self._observed_change = False  # a map change by observe() that the next tick reports
        self.gap_searches = 0  #: transitions no roadmap connected, so the fallback roadmap's passages were searched
        self.trees_planned = 0
        self.guard_stops = 0  #: ticks whose speed the motion guard reduced
        self.deferred_plans = 0  #: re-plans deferred by a tick (ExecutiveConfig.defer_fits)
        self._deferred = False  # the last tick deferred its re-plan
        self._fits = 0  # squircle fits of this tick's map update
        self._guard_noted = -math.inf
        self._held = 0  # consecutive ticks the motion guard held the robot
        self._blocker = None  # the return that held it last
        self._slide = (-math.inf, 0.0)  # (until, turn sign) of a slide around that return
        self._slid_at: list = []  # the returns slides started at
        self._phantoms: list = []  # returns the roadmaps avoid (GUARD_PHANTOM_RADIUS discs)

    # ------------------------------------------------------------------ public
    def request(self, formula, mode=MissionMode.REPLACE, *, regions=None) -> Plan:
        """Change the mission (``replace`` / ``add`` / ``urgent``); re-plans at the next tick.

        ``regions`` (optional, name -> :class:`~navigation.world.Region` or
        ``{"center": [x, y], "radius": r}``) adds or moves regions first, exactly as
        :meth:`set_regions`, and the formula may name them. Nothing is changed unless both the
        regions and the mission are accepted.

        Raises
        ------
        RegionError
            A region breaks a rule of :meth:`set_regions` (an ``InvalidRequestError``).
        TampError
            The planner's errors (``LtlSyntaxError``, ``UnknownRegionError``,
            ``UnsatisfiableError``, ``NoPlanError``, ``InvalidRequestError``).

        In every case the previous mission, regions and plan stay active.
        """
        mode = MissionMode.parse(mode)
        staged = self._stage_regions(regions, keep_mission=mode is not MissionMode.REPLACE) if regions else None
        planner = staged["planner"] if staged is not None else self.planner
        plan = planner.request(formula, mode)
        if staged is not None:
            self._commit_regions(staged)
        self.task = self.planner.mission
        self.accepting_visits = 0
        if self.state in (ExecutiveState.DONE, ExecutiveState.BLOCKED):
            self.state = ExecutiveState.PLANNING
        self._need_plan = True
        return plan

    def set_regions(self, regions) -> tuple[str, ...]:
        """Add regions or move existing ones while the mission runs; returns the names that
        changed (a region given with its current centre and radius is left alone).

        Parameters
        ----------
        regions : mapping
            Name -> :class:`~navigation.world.Region` or ``{"center": [x, y], "radius": r}``.

        Rules (checked in this order for each new or moved region, against the map the
        executive knows now, FORMATS.md's world validity rule):

        * ``workspace``: the disc grown by the robot radius lies inside the workspace;
        * ``free_space``: it is clear of every known obstacle and every obstacle estimate;
        * ``disjoint``: the region disc is disjoint from every other region disc (after the
          change);
        * ``alphabet``: the running mission (and each pending urgent request) can read a visit
          to the new region. A mission is translated over the regions it was given; when they
          were all atomic propositions of its formula, its automaton (trimmed over their
          letters) may lack the transitions for a region outside the formula. A region that
          a current automaton state cannot read is refused; send it with mode ``replace``
          (the new mission is translated over the new regions);
        * ``count``: at most :data:`tamp.navmap.MAX_REGIONS` regions after the change (checked
          first, for the whole change).

        On success the planner's navigation map is rebuilt over the new regions (the mission's
        automaton and its current states, the pending urgent requests and the evaluated
        harmonic trees between unmoved regions are carried over; trees and costs touching a
        moved region are dropped and re-evaluated lazily), perception keeps the new discs free,
        and the executive re-plans at the next tick. The roadmaps hold obstacles only, so they
        are unchanged. A disc that comes to contain the robot counts as entered at the next
        tick (the trace reads it).

        Raises
        ------
        RegionError
            ``region`` and ``rule`` name the first violation; nothing is changed.
        """
        staged = self._stage_regions(regions, keep_mission=True)
        if staged is None:
            return ()
        self._commit_regions(staged)
        return tuple(staged["changed"])

    @property
    def regions(self) -> dict:
        """The current regions, name -> :class:`~navigation.world.Region`."""
        return self.world.regions

    @property
    def current_field(self) -> OrientedField | None:
        """The oriented field the controller tracks now (current waypoint of the leg, or the
        leg's end while the robot pursues the leg; current forest), or ``None`` when there is
        none yet. Never builds one: only the cache of the
        fields the last command used is read (for visualisation; ``.nf`` is its navigation
        function)."""
        if self.state is not ExecutiveState.EXECUTING or not self.leg or self.wp >= len(self.leg):
            return None
        # pursuing the leg, the controller tracks the leg end's field (its safety limit)
        wp = self.leg[-1] if self._pursued else self.leg[self.wp]
        return self._fields.get((wp, id(self.forest)))

    @property
    def obstacles(self) -> list[Squircle]:
        """Current obstacle model: known obstacles and perception estimates."""
        return list(self.known) + (self.omap.obstacles() if self.omap is not None else [])

    def status(self, stamp: float | None = None) -> dict:
        """FORMATS.md ``status`` payload."""
        wp = self.leg[self.wp] if self.leg and self.wp < len(self.leg) else None
        return {"stamp": self.time if stamp is None else float(stamp), "state": self.state.value,
                "task": self.task, "plan": self.plan.to_dict() if self.plan is not None else None,
                "target": self.target, "waypoint": [float(v) for v in wp] if wp is not None else None,
                "obstacles": len(self.obstacles), "message": self.message}

    def tick(self, pose, scan=None, points=None, now: float | None = None, *, sensor_pose=None) -> TickResult:
        """One control period: perception, updates as needed, command (see the module doc).

        ``scan`` or ``points`` (at most one sensor message) is integrated at ``sensor_pose``
        (the pose at its stamp, e.g. from a pose stream that runs ahead of the sensor) when
        given, else at ``pose``; the command is computed for ``pose``."""
        t0 = time.perf_counter()
        replanned = map_changed = False
        deferred, self._deferred, self._fits = self._deferred, False, 0
        try:
            stamp, p = _pose3(pose)
        except TampError as err:
            return self._stop(ExecutiveState.ERROR, f"bad pose: {err}", t0)
        self.time = float(now) if now is not None and math.isfinite(float(now)) else (
            stamp if stamp is not None else self.time)
        if not self.world.workspace.beta(np.array(p[:2])) < 0:
            return self._stop(ExecutiveState.ERROR, f"pose ({p[0]:.3f}, {p[1]:.3f}) is outside the workspace "
                                                    "(lost): stopped", t0)
        self._pose = p
        if self.state is ExecutiveState.ERROR:  # a valid pose again: recover
            self.state, self._need_plan = ExecutiveState.PLANNING, True
        # mission events
        while self._next_event < len(self.events) and self.events[self._next_event].time <= self.time:
            ev = self.events[self._next_event]
            self._next_event += 1
            try:
                self.request(ev.task, ev.mode.value)
                self._note(f"event at {ev.time:g} s: {ev.mode.value} {ev.task!r}")
            except TampError as err:
                self._note(f"event at {ev.time:g} s refused: {err}")
        # perception
        map_changed = self._perceive(pose if sensor_pose is None else sensor_pose, scan, points, now)
        map_changed, self._observed_change = map_changed or self._observed_change, False
        # progress: regions entered (the trace of the mission)
        self._track_regions(p)
        if self.state is ExecutiveState.DONE:
            return self._result(0.0, 0.0, t0, replanned, map_changed)
        if self._need_plan:
            k = self.config.defer_fits
            if k and self._fits >= k and not deferred:
                # a heavy map update: the re-plan waits for the next tick, the robot brakes
                # (module doc, "Deferred re-plans")
                self._deferred = True
                self.deferred_plans += 1
                v, w = self._brake(p)
                return self._result(v, w, t0, replanned, map_changed)
            self._replan(p)
            replanned = True
        if self.state is not ExecutiveState.EXECUTING:
            return self._result(0.0, 0.0, t0, replanned, map_changed)
        v, w = self._command(p)
        return self._result(v, w, t0, replanned, map_changed)

    # ------------------------------------------------------------------ run-time regions
    def _stage_regions(self, regions, *, keep_mission: bool):
        """Validate ``regions`` and build the planner over the new region set, without touching
        the executive; ``None`` when nothing changes. Raises :class:`RegionError`."""
        if not isinstance(regions, Mapping):
            raise InvalidRequestError(f"regions must be a mapping name -> region, got {type(regions).__name__}")
        old = self.world.regions
        new = dict(old)
        changed: list[str] = []
        for name, spec in regions.items():
            reg = _as_region(name, spec)
            cur = old.get(name)
            if cur is not None and tuple(cur.center) == tuple(reg.center) and cur.radius == reg.radius:
                continue
            new[name] = reg
            changed.append(name)
        if not changed:
            return None
        if len(new) > MAX_REGIONS:
            added = [n for n in changed if n not in old]
            raise RegionError(added[MAX_REGIONS - len(old)] if len(old) < MAX_REGIONS else added[0], RegionRule.COUNT,
                              f"{len(new)} regions after the change: the navigation map holds at most {MAX_REGIONS} "
                              f"(tamp.navmap.MAX_REGIONS)")
        self._check_regions(new, changed)
        moved = {n for n in changed if n in old}
        pose = self._pose

        def alphabet(text, buchi, states, letters, old_letters, urgent):
            if keep_mission or urgent:  # urgent requests survive every mode, replace included
                _check_alphabet(text, buchi, states, letters, old_letters, changed)

        planner = self.planner.with_regions(new, pose=pose, moved=moved, check=alphabet)
        return {"regions": new, "changed": changed, "moved": moved, "planner": planner, "pose": pose}

    def _check_regions(self, regions: dict, changed) -> None:
        """FORMATS.md's validity rule for the changed regions against the current map."""
        r = self.radius
        n_known = len(self.known)
        names = list(changed)
        centers = [regions[n].center for n in names]
        for k, rule, value in disc_violations(self.world.workspace, self.obstacles, centers,
                                              [regions[n].radius + r for n in names]):
            name, reg = names[k], regions[names[k]]
            need = reg.radius + r
            if rule == "workspace":
                raise RegionError(name, RegionRule.WORKSPACE,
                                  f"disc (radius {reg.radius:g}) grown by the robot radius {r:g} is not inside the "
                                  f"workspace (its centre is {value:.3g} m inside the boundary, {need:.3g} m needed)")
            j, d = value
            what = f"known obstacle {j}" if j < n_known else f"obstacle estimate {j - n_known}"
            raise RegionError(name, RegionRule.FREE_SPACE,
                              f"disc (radius {reg.radius:g}) grown by the robot radius {r:g} is not in free "
                              f"space: it overlaps {what} (centre {d:.3g} m from it, {need:.3g} m needed)")
        for name in names:
            reg = regions[name]
            for other, o in regions.items():
                if other != name and math.dist(reg.center, o.center) <= reg.radius + o.radius:
                    raise RegionError(name, RegionRule.DISJOINT,
                                      f"disc overlaps region {other!r} (regions must be pairwise disjoint)")

    def _commit_regions(self, staged) -> None:
        new, moved, planner, pose = staged["regions"], staged["moved"], staged["planner"], staged["pose"]
        self.world = replace(self.world, regions=new)
        self.planner = planner
        self.task = planner.mission
        # evaluated transitions between unmoved regions keep their trees and map costs
        for key in [k for k in self._pair if k[0] in moved or k[1] in moved]:
            del self._pair[key]
        self._start_pair.clear()
        self._apply_tree_costs()
        q = np.asarray(pose[:2], dtype=float)
        self._inside = {n for n in self._inside if n in new and new[n].contains(q)}
        if self._at_region is not None and (self._at_region in moved or self._at_region not in self._inside):
            self._at_region = None
        if self.omap is not None:  # perception keeps the region discs free
            self.omap.regions = [(np.asarray(reg.center, dtype=float), float(reg.radius)) for reg in new.values()]
        if self.state in (ExecutiveState.DONE, ExecutiveState.BLOCKED):
            self.state = ExecutiveState.PLANNING
        self._need_plan = True
        self._note("regions " + ", ".join(f"{n} {'moved to' if n in moved else 'added at'} "
                                          f"({new[n].center[0]:g}, {new[n].center[1]:g}) r {new[n].radius:g}"
                                          for n in staged["changed"]))

    # ------------------------------------------------------------------ helpers: output
    def _note(self, msg: str) -> None:
        self.message = msg
        self.messages.append(f"[{self.time:.1f}] {msg}")
        _keep_last(self.messages, MESSAGES_KEPT)
        log.info("executive: %s", msg)

    def _result(self, v, w, t0, replanned, map_changed) -> TickResult:
        v, w = float(v), float(w)
        if not (math.isfinite(v) and math.isfinite(w)):
            v, w = 0.0, 0.0
        v = min(max(v, -self.control.v_max), self.control.v_max)
        w = min(max(w, -self.control.omega_max), self.control.omega_max)
        # the controller's rate limit starts from what is sent (a stop, the motion guard's slower v)
        self._tracker.applied(self.time, v, w)
        return TickResult(v, w, self.status(), replanned, map_changed, time.perf_counter() - t0)

    def _stop(self, state, msg, t0) -> TickResult:
        self.state = state
        self._note(msg)
        return self._result(0.0, 0.0, t0, False, False)

    # ------------------------------------------------------------------ perception
    def observe(self, pose, scan=None, points=None, now: float | None = None) -> bool:
        """Integrate one sensor message (``scan`` or ``points``) taken at ``pose`` without
        computing a command: for a caller with more sensor messages than ticks (the service
        node when a scan waited for its pose). The map, forest and trees update as in
        :meth:`tick`; the next tick's result reports the map change. Bad input is dropped with
        a note, as in :meth:`tick`. Returns whether the map changed."""
        changed = self._perceive(pose, scan, points, now)
        self._observed_change = self._observed_change or changed
        return changed

    def _perceive(self, pose, scan, points, now) -> bool:
        """Perception step of :meth:`tick` / :meth:`observe`: the map update of a sensor
        message at ``pose`` and, when the map changed, section 4.2's updates."""
        if self.omap is None or (scan is None and points is None):
            return False
        try:
            _, p = _pose3(pose)
        except TampError as err:
            self._note(f"input dropped: sensor pose: {err}")
            return False
        try:
            if scan is not None:
                upd = self.omap.update_scan(self._filter_known(scan, p), pose if isinstance(pose, Mapping) else p,
                                            now=now)
            else:
                upd = self.omap.update_points(points, p, now=now)
        except ScanError as err:
            self._note(f"input dropped: {err}")
            return False
        self._fits = upd.fits
        if upd.changed:
            self._on_map_change(upd)
        return bool(upd.changed)

    def _filter_known(self, scan, p):
        """Beams whose return lies on a known obstacle become NaN (no return, no free evidence)."""
        if self._known_rows is None or not isinstance(scan, Mapping):
            return scan
        try:
            ranges = np.asarray(scan["ranges"], dtype=float)
            a = p[2] + float(scan["angle_min"]) + float(scan["angle_increment"]) * np.arange(len(ranges))
        except (KeyError, TypeError, ValueError):
            return scan  # let perception reject it with its message
        hit = np.isfinite(ranges) & (ranges < float(scan.get("range_max", np.inf)))
        x = p[0] + ranges * np.cos(a)
        y = p[1] + ranges * np.sin(a)
        on = np.zeros(len(ranges), bool)
        if hit.any():
            b = beta_rows(self._known_rows[:, None, :], x[hit][None, :], y[hit][None, :])
            on[hit] = (b <= 0).any(axis=0)
        if not on.any():
            return scan
        out = dict(scan)
        out["ranges"] = np.where(on, np.nan, ranges).tolist()
        return out

    def _on_map_change(self, upd) -> None:
        """Forest, fields, roadmaps and tree validity after a map update (section 4.2)."""
        t0 = time.perf_counter()
        self.map_changes += 1
        est = self.omap.estimates
        try:
            self.forest = build_forest(self.cspace_workspace, self._known_inflated + self.omap.inflated(),
                                       min_gap=self.omap.config.min_gap, min_overlap=self.omap.config.min_overlap)
            self._fields.clear()
        except ForestError as err:
            self._note(f"obstacle model refused by the forest construction ({err}); keeping the last forest")
        changed = [est[i].squircle for i in upd.added + upd.updated if i in est]
        stale = len(upd.updated) + len(upd.removed)
        for i in upd.added + upd.updated:
            if i in est:
                self._model[("estimate", i)] = est[i].squircle
        for i in upd.removed:
            self._model.pop(("estimate", i), None)
        self._invalidate(changed)
        if stale or self.state is ExecutiveState.BLOCKED:
            # shapes shrank or moved: blocked transitions may have reopened
            blocked = [k for k, t in self._pair.items() if isinstance(t, Exception)]
            for k in blocked:
                del self._pair[k]
                self.planner.restore_edge(*k)
            if self.state is ExecutiveState.BLOCKED:
                for roads in self._roads:
                    if roads.outdated:
                        roads.reset()
                self._need_plan = True
        self._map_time = time.perf_counter() - t0

    def _invalidate(self, changed) -> None:
        """Trees and the current leg that a changed shape (``changed``: squircles new to the
        obstacle model) now blocks lose their evaluation, and a re-plan is asked for."""
        if not changed:
            return
        # the current leg (from the waypoint being tracked on) and every evaluated tree
        paths = []
        if self.leg and self.state is ExecutiveState.EXECUTING:
            paths.append((None, None, np.array([w[:2] for w in self.leg[max(self.wp - 1, 0):]])))
        for store in (self._pair, self._start_pair):
            paths += [(store, key, tree.positions) for key, tree in store.items()
                      if not isinstance(tree, Exception)]
        paths += [(self._unseen, key, cand.positions) for key, (_, cand) in self._unseen.items()]
        paths = [(store, key, pts) for store, key, pts in paths if len(pts) >= 2]
        # a shape whose bounding disc grown by r + margin reaches no segment cannot hit one:
        # only the others are grown (``inflate``, about 1.5 ms a shape) for the exact test
        margin = self.radius + self.config.check_margin
        near = []
        if paths:
            a = np.concatenate([pts[:-1] for _, _, pts in paths])
            b = np.concatenate([pts[1:] for _, _, pts in paths])
            centres = np.array([sq.center for sq in changed], dtype=float)
            reach = np.array([sq.bounding_radius for sq in changed]) + margin
            dist = _point_segment_distance(centres, a, b)  # (segments, shapes)
            near = [sq for k, sq in enumerate(changed) if (dist[:, k] <= reach[k]).any()]
        if near:
            rows = pack([inflate(sq, margin) for sq in near])
            for store, key, pts in paths:
                if not segments_clear(rows, pts[:-1], pts[1:]).all():
                    if store is not self._unseen:  # (a blocked candidate is just dropped)
                        self._need_plan = True
                    if store is not None:  # an evaluated transition loses its evaluation
                        del store[key]

    # ------------------------------------------------------------------ progress
    @property
    def recurrent(self) -> bool:
        """The mission has no universal state (it is never done for good: a patrol)."""
        return not self.planner.done_states

    @property
    def completed(self) -> bool:
        """The mission is done, or, recurrent, its accepting state was reached twice (one round
        of its cycle): what :func:`tamp.run.run_mission` and the service's summary report."""
        return self.state is ExecutiveState.DONE or (self.recurrent and self.accepting_visits >= 2)

    def _mission_done(self) -> bool:
        if self.planner.pending_urgent:
            return False
        states = {q for _, q in self.planner.current}
        return bool(states & self.planner.done_states)

    def _track_regions(self, p) -> None:
        q = np.array(p[:2])
        now_inside = {n for n, reg in self.world.regions.items() if reg.contains(q)}
        entered = now_inside - self._inside
        self._inside = now_inside
        for name in sorted(entered, key=lambda n: n != self.target):
            self.visited.append(name)
            self._at_region = name
            self._arrived = True
            try:
                self.planner.advance(name)
            except TampError as err:
                self._note(f"advance({name}) failed: {err}")
            if self.state in (ExecutiveState.EXECUTING, ExecutiveState.PLANNING, ExecutiveState.IDLE):
                self._need_plan = True
        if self._at_region is not None and self._at_region not in now_inside:
            self._at_region = None

    # ------------------------------------------------------------------ planning
    def _tree(self, start, goal, turned_down: list | None = None, keep: int | None = None):
        """Harmonic tree of one transition (see :meth:`_tree_road`)."""
        return self._tree_road(start, goal, turned_down, keep)[0]

    def _tree_road(self, start, goal, turned_down: list | None = None, keep: int | None = None,
                   probe: bool = False):
        """Harmonic tree of one transition and the index of its roadmap in ``_roads``: on the
        first roadmap that has a path, unless the fallback roadmap's tree is more than
        ``detour_ratio`` times shorter, or more than ``seen_detour_ratio`` times cheaper (eq. 26)
        through a passage the lidar has seen free (:meth:`_seen_passage`; one turned down for
        want of sight is appended to ``turned_down``); see the module doc, "Buffer fallback".
        ``keep``: the roadmap the robot's current leg to ``goal`` came from; a fallback tree
        of that roadmap is kept when it is merely no longer or no dearer (ratios 1: hysteresis,
        module doc, "Buffer fallback"). The last error (and ``None``) when neither roadmap has
        a path."""
        err, best, best_k = None, None, None
        ratio, seen = self.config.detour_ratio, self.config.seen_detour_ratio
        direct = math.dist(start[:2], goal[:2])
        for k, roads in enumerate(self._roads):
            held = k == keep and k > 0
            r_k = 1.0 if held and ratio > 0 else ratio
            s_k = 1.0 if held and seen > 0 else seen
            consider = min((r for r in (r_k, s_k) if r > 0), default=0.0)
            if best is not None and (consider <= 0 or not best.translations.sum() > consider * direct):
                break  # no detours considered, or none can be ratio times shorter than the straight line
            try:
                self.trees_planned += 1
                tree = plan_tree(roads.current(), start, goal, self.weights, self.config.n_headings)
            except NoTreePathError as e:
                if best is None:
                    err = e
                    if e.reason is not TreeFailure.DISCONNECTED and roads is self._roads[-1]:
                        break
                continue
            length = tree.translations.sum()
            if best is None or (r_k > 0 and r_k * length < best.translations.sum()):
                best, best_k = tree, k
            elif s_k > 0 and s_k * tree.cost < best.cost:
                if self._seen_passage(tree) or (probe and self._worth_probing(tree, best)):
                    best, best_k = tree, k
                elif turned_down is not None:
                    turned_down.append(tree)
        if best is None and isinstance(err, NoTreePathError) and err.reason is TreeFailure.DISCONNECTED:
            # no roadmap connects them: the vertices may not see through a narrow passage
            # (module doc, "Narrow passages"); add its waists to the fallback roadmap, once
            roads = self._roads[-1]
            self.gap_searches += 1
            if roads.add_gaps():
                try:
                    self.trees_planned += 1
                    return plan_tree(roads.current(), start, goal, self.weights, self.config.n_headings), len(self._roads) - 1
                except NoTreePathError as e:
                    err = e
        return (best, best_k) if best is not None else (err, None)

    def _leg_keep(self, region: str) -> int | None:
        """The roadmap of the current leg when it leads to ``region`` and the robot is on its
        way (not at a region: a new leg there starts afresh)."""
        if (self._leg_road is None or self._leg_road[0] != region or self._at_region is not None
                or self.state is not ExecutiveState.EXECUTING):
            return None
        return self._leg_road[1]

    def _rescue_route(self, pose, goal):
        """The tracker's route rescue (``route_rescue``): the waypoints of a harmonic tree from
        ``pose`` to ``goal`` (the tracked waypoint) on the first of the executive's roadmaps
        that has one, or ``None``."""
        self.rescues += 1
        for roads in self._roads:
            try:
                tree = plan_tree(roads.current(), tuple(pose), tuple(goal), self.weights, self.config.n_headings)
            except NoTreePathError:
                continue
            return [tuple(float(x) for x in w) for w in tree.waypoints]
        return None

    def _worth_probing(self, tree, best) -> bool:
        """A leg from the robot may take the shorter fallback ``tree`` whose narrow passage has
        not been seen (``probe_ratio`` > 0): when its saving on ``best`` exceeds ``probe_ratio``
        times the way along it until the passage's first narrow point is within lidar range
        (what a look costs, there and back, if the passage turns out closed)."""
        k = self.config.probe_ratio
        if not k > 0 or self.omap is None:
            return False
        rm = self._roads[0].rm
        if rm is None or len(tree.waypoints) < 2:
            return False
        pts, narrow = _narrow_samples(rm, tree)
        narrow = np.flatnonzero(narrow)
        if not len(narrow):
            return False
        along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))))
        view = max(0.0, float(along[narrow[0]]) - float(self.world.lidar.range))
        return float(best.translations.sum() - tree.translations.sum()) > k * view

    def _seen_passage(self, tree) -> bool:
        """The stretch of ``tree``'s path closer than ``buffer`` to an obstacle or the boundary
        (inside the first roadmap's buffered squircles or outside its shrunk workspace), with
        the band ``radius + fallback_buffer`` wide on both sides of it outside the known
        shapes, lies in space the lidar has seen free, for at least ``seen_share`` of its
        samples (every 2 cm along the path; ``ExecutiveConfig.seen_detour_ratio``)."""
        if self.omap is None:
            return True  # every obstacle known
        rm = self._roads[0].rm  # as the last tree used it (bringing it up to date here would
        if rm is None:          # change when shapes reach the roadmap, not just this test)
            return False
        if len(tree.waypoints) < 2:
            return True  # no path to pass through
        pts, narrow = _narrow_samples(rm, tree)
        if not narrow.any():
            return True
        seg = np.diff(pts, axis=0)
        tang = seg / np.maximum(np.hypot(seg[:, 0], seg[:, 1]), 1e-12)[:, None]
        tang = np.concatenate((tang, tang[-1:]))  # each sample: the direction of its segment
        # the passage, not just the path: the band the robot disc sweeps, up to the fallback
        # clearance on both sides, where it is not inside a known shape (no unseen part of an
        # obstacle beside the path)
        nrm = np.stack((-tang[narrow, 1], tang[narrow, 0]), axis=1)
        band = pts[narrow]
        reach = self.radius + self.config.fallback_buffer
        band = np.concatenate([band] + [band + f * reach * nrm for f in (-1.0, -0.5, 0.5, 1.0)])
        keep = _outside_all(pack(list(rm.obstacles)), self.world.workspace, band)
        return float(np.mean(self.omap.observed_free(band[keep]))) >= self.config.seen_share if keep.any() else True

    def _center_pose(self, a, b):
        ca, cb = self.world.regions[a].center, self.world.regions[b].center
        h = math.atan2(cb[1] - ca[1], cb[0] - ca[0])
        return (ca[0], ca[1], h), (cb[0], cb[1], h)

    def _evaluate(self, u: Node, v: Node, p) -> bool:
        """Harmonic tree of the transition ``u -> v`` (regions); sets its map cost or removes
        it. Returns True when something was evaluated."""
        a, b = u.region, v.region
        if a == b:
            return False
        nm = self.planner.navmap
        if a == START:
            if b in self._start_pair:
                return False
            c = self.world.regions[b].center
            goal = (c[0], c[1], math.atan2(c[1] - p[1], c[0] - p[0]))
            res, self._start_road[b] = self._tree_road(p, goal, keep=self._leg_keep(b), probe=True)
            self._start_pair[b] = res
            if isinstance(res, NoTreePathError) and res.reason is TreeFailure.START_BLOCKED:
                # the robot stands where no tree can start (an estimate grown over its
                # position); the leg then heads for the region directly (_set_leg), so the
                # transition keeps the straight-line cost instead of walling the region off
                nm.set_cost(Node(START, 0), b, self._committed(math.dist(p[:2], c), b), symmetric=False)
            elif isinstance(res, Exception):
                nm.remove_edge(Node(START, 0), b, symmetric=False)
            else:
                # region name: the tree cost is the translational part, w |dtheta| is added
                nm.set_cost(Node(START, 0), b, self._committed(res.cost, b), symmetric=False)
            return True
        key = (a, b) if a < b else (b, a)
        if key in self._pair:
            return False
        s, g = self._center_pose(*key)
        down: list = []
        res = self._tree(s, g, down)
        self._pair[key] = res
        if down and not isinstance(res, Exception):
            self._unseen[key] = (res, down[-1])  # re-checked at every re-plan
        if isinstance(res, Exception):
            nm.remove_edge(key[0], key[1])
        else:
            nm.set_cost(key[0], key[1], res.cost)
        return True

    def _replan(self, p) -> None:
        """Lazy re-planning from the current state (section 4.2.4) and the next leg."""
        t0, c0 = time.perf_counter(), time.process_time()
        self._need_plan = False
        self.replans += 1
        prev_target = self.target
        try:
            self._plan_lazily(p)
        finally:
            dt = time.perf_counter() - t0
            self.planning_time += dt
            if self.initial_time is None:
                self.initial_time = dt + self.setup_time
                self.planning_time += self.setup_time
            else:
                self.replan_times.append(dt)
                self.replan_cpu_times.append(time.process_time() - c0)
                _keep_last(self.replan_times, REPLANS_KEPT)
                _keep_last(self.replan_cpu_times, REPLANS_KEPT)
        if self.state is ExecutiveState.EXECUTING and self.target != prev_target:
            log.info("executive: next region %s", self.target)

    def _recheck_unseen(self) -> None:
        """A transition whose shorter fallback tree was turned down because its narrow passage
        had not been seen free takes it once the lidar has seen it (``seen_detour_ratio``),
        while the transition still has the tree it was compared with and nothing new blocks
        the fallback (:meth:`_invalidate` drops it then)."""
        for key, (tree, cand) in list(self._unseen.items()):
            if self._pair.get(key) is not tree:
                del self._unseen[key]
            elif self._seen_passage(cand):
                del self._unseen[key]
                self._pair[key] = cand
                self.planner.navmap.set_cost(key[0], key[1], cand.cost)

    def _plan_lazily(self, p) -> None:
        self._recheck_unseen()
        if self._mission_done():
            self.state, self.leg, self.target = ExecutiveState.DONE, (), None
            self._note("mission completed")
            return
        planner = self.planner
        if self._at_region is None or planner.node.region != self._at_region:
            # between regions: the region being headed for (if any) is the commitment
            self._commit = self.target if (self.state is ExecutiveState.EXECUTING
                                           and self.target in self.world.regions) else None
            planner.set_position(p)
            self._start_pair.clear()
            if self._commit is not None:
                c = self.world.regions[self._commit].center
                planner.set_cost(Node(START, 0), self._commit,
                                 self._committed(math.dist(p[:2], c), self._commit), symmetric=False)
        else:
            self._commit = None
        blocked_once = False
        for _ in range(self.config.max_plan_rounds):
            try:
                plan = planner.plan()
            except NoPlanError as err:
                if not blocked_once and any(r.outdated or r.behind for r in self._roads):
                    # stale shapes may close a passage: rebuild from the current model, retry
                    blocked_once = True
                    for roads in self._roads:
                        roads.reset()
                    for k in [k for k, t in self._pair.items() if isinstance(t, Exception)]:
                        del self._pair[k]
                        planner.restore_edge(*k)
                    self._start_pair.clear()
                    if planner.node.region == START:
                        planner.set_position(p)
                    continue
                self._blocked(err, p)
                return
            route = (planner.node,) + plan.route + (plan.suffix[1:] if len(plan.suffix) > 1 else ())
            evaluated = False
            for u, v in zip(route[:-1], route[1:]):
                evaluated |= self._evaluate(u, v, p)
            if not evaluated:
                break
        self.plan = plan
        # a recurrent mission counts one accepting visit each time the robot arrives at the
        # lasso's accepting state (the prefix is just the current node)
        if self._arrived and len(plan.prefix) == 1 and not plan.urgent:
            self.accepting_visits += 1
        self._arrived = False
        target = next((n.region for n in plan.route + plan.suffix if n.region != planner.node.region), None)
        if target is None:
            self.state, self.leg, self.target = ExecutiveState.DONE, (), None
            self._note("mission completed (nothing left to visit)")
            return
        self._set_leg(p, target)

    def _set_leg(self, p, target) -> None:
        c = self.world.regions[target].center
        goal = (c[0], c[1], math.atan2(c[1] - p[1], c[0] - p[0]))
        res, road = self._start_pair.get(target), self._start_road.get(target)
        if res is None or isinstance(res, Exception) or self._at_region is not None:
            res, road = self._tree_road(p, goal, keep=self._leg_keep(target), probe=True)
        via = self._via_centre(p, target, res)
        if via is not None:
            self._leg_road = None
            self._drive_waypoints(target, via)
            return
        self._leg_road = (target, road) if road is not None else None
        if isinstance(res, NoTreePathError) and res.reason is TreeFailure.START_BLOCKED:
            # the robot is in the buffer zone of an estimate that the terminal rule cannot
            # relieve: head for the region directly (the field keeps it safe)
            wps = (tuple(p), goal)
        elif isinstance(res, Exception):
            self._blocked(NoPlanError(f"no harmonic tree from the robot to {target}: {res}", ((START, target),)), p)
            return
        else:
            self._drive(p, target, res)
            return
        self._go(target, _pass_through_headings(wps))

    def _via_centre(self, p, target, res):
        """At a region, the leg through its centre: the robot's position, then the waypoints of
        the tree of the transition to ``target`` (the tree the plan's cost comes from, from
        the region's centre), when ``res``, the tree from the robot's position, is missing or
        longer than that by more than :data:`VIA_CENTRE_SLACK`; else ``None`` (module doc,
        "Legs from a region"). The way to the centre runs inside the region disc, which
        perception keeps clear of the inflated estimates."""
        here = self._at_region
        if here is None or here == target:
            return None
        key = (here, target) if here < target else (target, here)
        pair = self._pair.get(key)
        if pair is None or isinstance(pair, Exception):
            return None
        c = self.world.regions[here].center
        via = math.dist(p[:2], c) + float(pair.translations.sum())
        if not isinstance(res, Exception) and float(res.translations.sum()) <= via + VIA_CENTRE_SLACK:
            return None
        wps = [tuple(float(x) for x in w) for w in pair.waypoints]
        if key[0] != here:  # the tree runs from the other region: driven backwards
            wps = [(x, y, wrap_angle(th + math.pi)) for x, y, th in reversed(wps)]
        return (tuple(float(x) for x in p),) + tuple(wps)

    def _drive(self, p, target, tree) -> None:
        """The leg along ``tree``'s waypoints (shortcut, subdivided, centred), towards ``target``."""
        self._drive_waypoints(target, tuple(tuple(float(x) for x in w) for w in tree.waypoints))

    def _drive_waypoints(self, target, wps) -> None:
        """The leg along the waypoints ``wps`` (shortcut, subdivided, centred), towards ``target``."""
        if self.config.shortcut_legs:
            wps = self._shortcut(wps)
        # edges longer than ``max_segment`` get evenly spaced intermediate waypoints (the
        # field of a near goal runs straight to it; module doc, "Short edges")
        if self.config.max_segment > 0:
            wps = _subdivide(wps, self.config.max_segment)
        # intermediate waypoints must lie in the forest's free space (the roadmap grows
        # obstacles by Squircle.grow, the forest by perception.inflate: they can differ
        # at the fallback buffer); drop those that do not, the field goes around
        mid = wps[1:-1]
        if mid:
            keep = self._free(np.array([w[:2] for w in mid]))
            mid = tuple(w for w, k in zip(mid, keep) if k)
        wps = (wps[0],) + mid + (wps[-1],)
        if self.config.centre_reach > 0:
            wps = self._centre(wps)
        # headings: the robot arrives at the goal along the last segment and passes an
        # intermediate waypoint along the bisector of its two segments (see the module doc)
        self._go(target, _pass_through_headings(wps), pursuable=True)

    def _go(self, target, wps, pursuable: bool = False) -> None:
        """Start the leg ``wps`` towards ``target``."""
        self._pursuable = pursuable
        self._looking = None
        self.leg = wps
        self.wp = 1 if len(wps) > 1 else 0
        # turn before moving off (module doc, "Turning onto a leg"); not in the rate-limited
        # mode, whose commands may not drop ``v`` at once
        self._align_until = (self.time + self.config.align_time
                             if self.config.align_angle > 0 and not self.control.accel_max > 0 else -math.inf)
        self._edge_t0 = self.time
        self._stalled = 0
        self.target = target
        if self.state is not ExecutiveState.EXECUTING:
            self._note(f"executing: next region {target}")
        self.state = ExecutiveState.EXECUTING

    def _shortcut(self, wps):
        """The leg's waypoints with those skipped whose neighbours see each other: from each kept
        waypoint the farthest later one joined by a safe segment (``Roadmap.visible`` of the
        first roadmap: clearance ``>= buffer`` from every obstacle the roadmap avoids).

        The tree minimises eq. 26, whose rotation terms charge the same turn differently at the
        start (``w1``) and at a vertex (split between ``w2`` on arrival and ``w1`` on leaving):
        with the refitted weights it can prefer driving to a vertex behind the robot and turning
        there to turning on the spot (office: 0.2-0.5 m out and back at three region exits).
        The unicycle turns on the spot either way, so the detour only adds distance; the
        shortcut path is never longer (triangle inequality).
        """
        n = len(wps)
        if n <= 2:
            return wps
        rm = self._roads[0].current()
        pts = np.array([w[:2] for w in wps])
        i, j = np.triu_indices(n, 2)
        vis = np.zeros((n, n), dtype=bool)
        vis[i, j] = rm.visible(pts[i], pts[j])
        keep = [0]
        while keep[-1] < n - 1:
            k = keep[-1]
            keep.append(next((m for m in range(n - 1, k + 1, -1) if vis[k, m]), k + 1))
        return tuple(wps[k] for k in keep)

    def _centre(self, wps):
        """The leg's intermediate waypoints closer than ``buffer`` to an obstacle or the
        boundary (in the forest: estimates inflated by the radius) moved by up to
        ``centre_reach`` to where the clearance is largest (up to ``buffer``), keeping both of
        their segments clear at the fallback buffer (module doc, "Centred waypoints")."""
        n = len(wps)
        if n <= 2:
            return wps
        buf, reach = self.config.buffer, self.config.centre_reach
        clear = forest_clearance(self.forest)
        out = list(wps)
        pts = np.array([w[:2] for w in wps], dtype=float)
        c0 = clear(pts[1:-1], buf)
        todo = [i + 1 for i in np.nonzero(c0 < buf)[0]]
        if not todo:
            return wps
        rm = self._roads[-1].current()
        for i in todo:
            q = pts[i]
            cand = q + _CENTRE_RING * reach
            ok = rm.visible(np.repeat(pts[i - 1:i], len(cand), axis=0), cand) & rm.visible(
                cand, np.repeat(pts[i + 1:i + 2], len(cand), axis=0))
            if not ok.any():
                continue
            cand = cand[ok]
            c = np.minimum(clear(cand, buf), buf)
            score = c - 0.25 * np.hypot(*(cand - q).T)
            k = int(np.argmax(score))
            if c[k] > float(c0[i - 1]) + 0.005:
                pts[i] = cand[k]
                out[i] = (float(cand[k][0]), float(cand[k][1])) + tuple(wps[i][2:])
        return tuple(out)

    def _blocked(self, err: NoPlanError, p=None) -> None:
        """Stop and report the regions the robot cannot reach (section 4.2.4 / issue 6)."""
        pairs = getattr(err, "blocked", ()) or ()
        names = sorted({n for pair in pairs for n in pair if n != START})
        if p is not None and names:
            unreachable = []
            for n in names:
                res = self._start_pair.get(n)
                if res is None:
                    c = self.world.regions[n].center
                    res = self._tree(p, (c[0], c[1], math.atan2(c[1] - p[1], c[0] - p[0])))
                if isinstance(res, Exception):
                    unreachable.append(n)
            names = unreachable or names
            if self._look(p, names):
                return
        self._looking = None
        self.state, self.leg, self.target = ExecutiveState.BLOCKED, (), None
        self.unreachable = tuple(names)
        self._note(f"blocked: cannot reach region(s) {', '.join(names) if names else '?'} "
                   f"with the obstacles seen so far; stopped ({err})")

    def _look(self, p, names) -> bool:
        """Drive to the reachable point nearest to an unreachable region to look (module doc,
        "Going to look"); False when every region in ``names`` has had its ``look_tries`` (or
        its legs, re-planned ones included, ran out) or no point near it has a tree from the
        robot."""
        tries = self.config.look_tries
        for name in names:
            if name not in self.world.regions or tries <= 0:
                continue
            looked = self._looked.setdefault(name, [])
            going = self._looking == name and bool(self.leg)
            if (len(looked) >= tries and not going) or self._look_legs.get(name, 0) >= LOOK_LEGS * tries:
                continue
            c = np.asarray(self.world.regions[name].center, dtype=float)
            current = np.asarray(self.leg[-1][:2], dtype=float) if going else None
            avoid = [q for q in looked if current is None or math.dist(q, current) > 1e-9] + [tuple(p[:2])]
            cand, comp = self._look_candidates(p, c, np.array(avoid, dtype=float))
            if current is not None:  # on the way to a look point: keep it while it has a tree
                cand, comp = np.concatenate([current[None], cand]), np.concatenate([[-1], comp])
            tried, cut = 0, set()  # roadmap components no tree from the robot reaches
            for q, k in zip(cand, comp):
                if tried >= LOOK_CANDIDATES:
                    break
                if k in cut:
                    continue
                tried += 1
                goal = (float(q[0]), float(q[1]), math.atan2(c[1] - q[1], c[0] - q[0]))
                tree, _ = self._tree_road(p, goal)
                if isinstance(tree, Exception):
                    if k >= 0 and isinstance(tree, NoTreePathError) and tree.reason is TreeFailure.DISCONNECTED:
                        cut.add(k)
                    continue
                if current is None or math.dist(q, current) > 1e-9:
                    looked.append((goal[0], goal[1]))
                    self._note(f"cannot reach {name} with the obstacles seen so far: going to look from "
                               f"({q[0]:.2f}, {q[1]:.2f}), {math.dist(q, c):.2f} m from it "
                               f"(look {len(looked)} of {tries})")
                self._look_legs[name] = self._look_legs.get(name, 0) + 1
                self._drive(p, name, tree)
                self._leg_road = None
                self._looking = name
                return True
        return False

    @property
    def looks(self) -> int:
        """Look points the robot set out for (module doc, "Going to look")."""
        return sum(len(v) for v in self._looked.values())

    def _look_candidates(self, p, c, avoid) -> tuple[np.ndarray, np.ndarray]:
        """Look points for a region centred at ``c`` and their roadmap components: the
        vertices of the fallback roadmap at least ``LOOK_SPACING`` from the points in
        ``avoid``, those in the components the robot sees first (a tree reaches them), then
        the others (a robot beside a passage it cannot take may see only the far side's
        vertices, or none from a buffer zone), each group nearest to ``c`` first."""
        rm = self._roads[-1].current()
        pts = rm.points
        if not len(pts):
            return np.zeros((0, 2)), np.zeros(0, dtype=int)
        n = len(pts)
        ncomp, lab = connected_components(rm.graph(), directed=False)
        seen = rm.visible(np.repeat(np.asarray(p[:2], dtype=float)[None], n, axis=0), pts)
        first = np.isin(lab, np.unique(lab[seen]))
        keep = np.linalg.norm(pts[:, None, :] - avoid[None], axis=2).min(axis=1) >= LOOK_SPACING
        order = np.lexsort((np.linalg.norm(pts - c, axis=1), ~first))
        order = order[keep[order]]
        return pts[order], lab[order]

    # ------------------------------------------------------------------ control
    def _free(self, pts: np.ndarray) -> np.ndarray:
        """Which of the points ``pts (N, 2)`` lie in the forest's free space (one pass over the
        workspace and the obstacles for all of them)."""
        return _outside_all(self._forest_rows()[0], self.forest.workspace, pts)

    def _field(self, wp) -> OrientedField | None:
        key = (wp, id(self.forest))
        f = self._fields.get(key)
        if f is None:
            try:
                f = OrientedField(NavigationFunction(self.forest, goal=wp[:2]), heading=wp[2])
            except NavigationError as err:
                self._note(f"waypoint {np.round(wp, 3).tolist()} not in free space ({err}); re-planning")
                self._need_plan = True
                return None
            if len(self._fields) > 64:
                self._fields.clear()
            self._fields[key] = f
        return f

    def _command(self, p) -> tuple[float, float]:
        q = np.array(p[:2])
        tol = self.config.waypoint_tolerance
        if self._looking is not None and self.wp == len(self.leg) - 1 and float(np.linalg.norm(q - self.leg[-1][:2])) < tol:
            # at the look point (module doc, "Going to look"): what the lidar saw on the way is
            # in the map; plan again from here (blocked for good after ``look_tries`` looks)
            self._looking = None
            self._need_plan = True
            return 0.0, 0.0
        while self.wp < len(self.leg) - 1 and self._passed(q, self.leg[self.wp], tol):
            self._edge_done(self.wp)
            self.wp += 1
        carrot = None
        if self.config.pursuit > 0 and self._pursuable and self.wp >= 1 and not self._tracker.route:
            carrot = self._carrot(q)
        self._watch(q)
        pursuing = self._pursued = carrot is not None
        # pursuing (module doc): eq. 24 on the bearing of the point ahead, the leg end's field
        # giving the safety limit and the escape band; else the current waypoint's field
        cur = self._field(self.leg[-1] if pursuing else self.leg[self.wp])
        if cur is None:
            return 0.0, 0.0
        rate_limited = self.control.accel_max > 0
        fol, cap = None, math.inf  # (pursuing, no waypoint is aimed at: no turn cap)
        if not pursuing:
            # the following waypoint's field only where eq. 25 gives it a weight: eta is exactly 0
            # farther than about 1 m from the current waypoint, where the blend returns the current
            # field's direction and the safety limit is the forest's (shared by both fields), i.e.
            # the command of ``track`` alone; a field is one navigation function (several ms), so
            # after a map change it is built when the robot comes near, not on the changing tick
            if self.wp + 1 < len(self.leg) and switch_weight(float(np.linalg.norm(q - cur.goal)), self.control) > 0.0:
                fol = self._field(self.leg[self.wp + 1])
            # reachable turns (module doc): in the rate-limited mode the cap goes in before the rate
            # limit, which brakes towards it; without that mode it is applied to the command below
            if self.config.turn_cap and (self.config.turn_cap_rate_limited or not rate_limited):
                cap = reachable_speed(p, self.leg[self.wp], self.control.omega_max)
        v_cap = cap if rate_limited else math.inf
        # crawl guard: the stand-off while the robot crawls (navigation.tracker)
        try:
            if pursuing:
                cmd = self._tracker.pursue(self.time, p, carrot[0], cur, beyond=carrot[1],
                                           gate=self.config.pursuit_gate)
            else:
                cmd = self._tracker.command(self.time, p, cur, fol, self._beyond(), v_cap=v_cap)
        except NavigationError as err:
            self._note(f"controller refused the pose: {err}")
            return 0.0, 0.0
        if self.time < self._align_until and cmd.v > 0.0:
            if abs(math.remainder(cmd.theta_gamma - p[2], 2 * math.pi)) > self.config.align_angle:
                cmd = replace(cmd, v=0.0)  # turn (eq. 24b) on the spot
            else:
                self._align_until = -math.inf  # aligned once: eq. 24 from here on
        if not rate_limited and cap < cmd.v:
            cmd = replace(cmd, v=cap)  # (module doc, "Reachable turns")
        v_cmd = self._guard(p, cmd.v, cmd.omega)
        # held: the guard changed the speed (it only ever does so to slow down) and left ~0
        self._held = self._held + 1 if v_cmd != cmd.v and v_cmd < 1e-3 else 0
        if v_cmd != cmd.v:
            cmd = replace(cmd, v=v_cmd)
        slide = self._slid(p, cur, cmd)
        if slide is not None:
            cmd = slide
        # stall guard: the blend of eq. 25 can cancel (the current waypoint's field asks to
        # swing around it, the following one to go on); after ``stall_ticks`` ticks without
        # motion move on to the next waypoint when close to the current one, else re-plan
        if abs(cmd.v) < 1e-3 and abs(cmd.omega) < 1e-2:
            self._stalled += 1
            if self._stalled >= self.config.stall_ticks:
                self._stalled = 0
                d = float(np.linalg.norm(q - self.leg[self.wp][:2]))
                if self.wp < len(self.leg) - 1 and d < 3 * tol:
                    self.wp += 1
                    self._edge_t0 = None  # a stalled edge is not a measurement
                    self._note(f"stalled {d:.2f} m from a waypoint: passing it")
                else:
                    self._need_plan = True
                    self._note("stalled: re-planning from here")
        else:
            self._stalled = 0
        return cmd.v, cmd.omega

    def _carrot(self, q):
        """Pursuit: ``(point, rest)``, the point ``pursuit`` metres of path ahead of the robot's
        projection on the leg (the leg's end at most) and the path length after it, pulled back
        to the end of the robot's segment, then to the path ahead on that segment, when the line
        from the robot to it is not clear of the inflated obstacles grown by the margin; the
        path ahead on the robot's segment also when its line clears the inflated obstacles
        alone; None when nothing is clear. Advances ``wp`` past the waypoints whose segment the
        robot has left."""
        L = self.config.pursuit
        leg = self.leg
        last = len(leg) - 1
        while self.wp < last:
            a, b = np.asarray(leg[self.wp - 1][:2]), np.asarray(leg[self.wp][:2])
            c = np.asarray(leg[self.wp + 1][:2])
            ab = b - a
            n2 = float(ab @ ab)
            u = float((q - a) @ ab) / n2 if n2 > 0 else 1.0
            if u >= 1.0 or _to_segment(q, b, c) < _to_segment(q, a, b):
                self._edge_done(self.wp)
                self.wp += 1
                continue
            break
        a, b = np.asarray(leg[self.wp - 1][:2]), np.asarray(leg[self.wp][:2])
        ab = b - a
        n2 = float(ab @ ab)
        u = min(1.0, max(0.0, float((q - a) @ ab) / n2)) if n2 > 0 else 1.0
        here = a + u * ab
        togo = L
        k = self.wp
        point = None
        while k <= last:
            nxt = np.asarray(leg[k][:2])
            d = float(np.hypot(*(nxt - here)))
            if d >= togo:
                point = here + (nxt - here) * (togo / d)
                rest = d - togo + sum(math.dist(leg[j][:2], leg[j + 1][:2]) for j in range(k, last))
                break
            togo -= d
            here = nxt
            k += 1
        if point is None:
            point, rest = np.asarray(leg[last][:2]), 0.0
        if self._clear_line(q, point):
            return point, rest
        if k == self.wp:  # the point is on the robot's own segment
            # not clear by the margin: a passage narrower than the margin leaves room for the
            # robot's offset from the path, or an estimate grew over the way ahead (the field)
            return (point, rest) if self._clear_line(q, point, exact=True) else None
        # round a corner only along a clear line: else the end of the robot's segment, else the
        # point ahead on that segment (by the margin, else by the inflated obstacles alone)
        rest = sum(math.dist(leg[j][:2], leg[j + 1][:2]) for j in range(self.wp, last))
        if self._clear_line(q, b):
            return b, rest
        ahead = a + min(1.0, u + L / math.sqrt(n2)) * ab if n2 > 0 else b
        if self._clear_line(q, ahead) or self._clear_line(q, ahead, exact=True):
            return ahead, rest + float(np.hypot(*(b - ahead)))
        return None

    def _forest_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """The forest's obstacles packed (:func:`navigation.geometry.pack`), and the same
        rows with :data:`PURSUIT_MARGIN` added to their half-extents; once per forest."""
        if self._rows is None or self._rows[0] is not self.forest:
            P = pack(list(self.forest.obstacles))
            wide = P.copy()
            wide[:, 4:6] += PURSUIT_MARGIN
            P.flags.writeable = wide.flags.writeable = False
            self._rows = (self.forest, P, wide)
        return self._rows[1], self._rows[2]

    def _clear_line(self, q, point, exact: bool = False) -> bool:
        """The segment from ``q`` to ``point`` misses every obstacle of the forest (known and
        estimated, inflated by the robot radius: what the fields and the safety limit avoid)
        grown by :data:`PURSUIT_MARGIN` (``exact``: not grown)."""
        P = self._forest_rows()[0 if exact else 1]
        if not len(P):
            return True
        return bool(segments_clear(P, np.asarray(q, float)[None], np.asarray(point, float)[None])[0])

    def _watch(self, q) -> None:
        """Progress watchdog (module doc, "No progress"): re-plan from here when the robot has
        not come ``stuck_progress`` closer to the tracked waypoint for ``stuck_time`` seconds."""
        cfg = self.config
        if cfg.stuck_time <= 0:
            return
        d = float(np.linalg.norm(q - np.asarray(self.leg[self.wp][:2])))
        prog = self._progress
        if prog is None or prog[0] is not self.leg or prog[1] != self.wp or d < prog[2] - cfg.stuck_progress:
            self._progress = (self.leg, self.wp, d, self.time)
            return
        if self.time - prog[3] >= cfg.stuck_time and d > cfg.waypoint_tolerance:
            self._progress = (self.leg, self.wp, d, self.time)
            done = self._rescued is not None and self._rescued[0] is self.leg and self._rescued[1] == self.wp
            if cfg.route_rescue and not done:
                # first time on this waypoint: follow a harmonic tree to it along its segments
                cur = self._field(self.leg[self.wp])
                if cur is not None and self._tracker.rescue(self.time, self._pose, cur):
                    self._rescued = (self.leg, self.wp)
                    self._note(f"no progress towards the waypoint {d:.2f} m away for {cfg.stuck_time:g} s: "
                               "following a harmonic tree to it")
                    return
            self._need_plan = True
            self._note(f"no progress towards the waypoint {d:.2f} m away for {cfg.stuck_time:g} s: "
                       "re-planning from here")

    def _passed(self, q, wp, tol: float) -> bool:
        """The robot at ``q`` has passed the intermediate waypoint ``wp``: within ``tol`` of it,
        or within ``pass_beyond`` of it and beyond the line through it across its heading."""
        d = q - np.asarray(wp[:2])
        r = float(np.hypot(d[0], d[1]))
        if r < tol:
            return True
        b = self.config.pass_beyond
        return b > 0 and r < b and float(d[0] * math.cos(wp[2]) + d[1] * math.sin(wp[2])) >= 0.0

    def _beyond(self) -> float:
        """Path length (m) of the leg after the current waypoint (``speed_to_leg_end``; else 0)."""
        if not self.config.speed_to_leg_end or self.wp + 1 >= len(self.leg):
            return 0.0
        pts = np.asarray([w[:2] for w in self.leg[self.wp:]], dtype=float)
        return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())

    def _slid(self, p, field, cmd):
        """Slide around a return the motion guard keeps holding the robot at (its estimates
        leave it outside and the refits do not cover it, so the field keeps leading the robot
        into it): after ``GUARD_HOLD_TICKS`` held ticks, for ``GUARD_SLIDE_TIME`` seconds the
        robot turns away from the return at half its turn rate and moves at up to
        ``GUARD_SLIDE_SPEED``, within the controller's safety limit and the guard. ``None``
        when not sliding."""
        until, sign = self._slide
        if self.time >= until:
            if self._held < GUARD_HOLD_TICKS or self._blocker is None:
                return None
            x, y, th = p
            rel = wrap_angle(math.atan2(self._blocker[1] - y, self._blocker[0] - x) - th)
            sign = -1.0 if rel > 0 else 1.0
            self._slide = (self.time + GUARD_SLIDE_TIME, sign)
            self._held = 0
            self._note(f"motion guard held the robot at ({self._blocker[0]:.3f}, {self._blocker[1]:.3f}): sliding around it")
            again = any(math.dist(b, self._blocker) < GUARD_SAME_SPOT for b in self._slid_at)
            if not again:  # one entry per spot
                self._slid_at.append(self._blocker)
            if again and not any(math.dist(b, self._blocker) < GUARD_SAME_SPOT for b in self._phantoms):
                # held at the same return after a slide: the field leads there because the
                # estimates leave it outside, so the trees must route around it
                self._phantoms.append(self._blocker)
                sq = Squircle(center=self._blocker, width=2 * GUARD_PHANTOM_RADIUS, height=2 * GUARD_PHANTOM_RADIUS)
                self._model[("guard", len(self._phantoms))] = sq
                self._invalidate([sq])
                self._need_plan = True
                self._note(f"the return at ({self._blocker[0]:.3f}, {self._blocker[1]:.3f}) held the robot again: "
                           "the harmonic trees avoid it from now on")
        w = sign * 0.5 * self.control.omega_max
        v = min(GUARD_SLIDE_SPEED, safety_limit(p[:2], (field,), self.control))
        return replace(cmd, v=self._guard_limit(p, v, w)[0], omega=w)

    def _guard(self, p, v: float, w: float) -> float:
        """The speed ``v`` (turn rate ``w``) limited so that the robot disc, over the next
        ``guard_horizon`` seconds of the arc (checked at four points along it), comes no closer
        than ``guard_margin`` (plus ``guard_noise`` times the lidar's range noise) to a lidar
        return of the last scan that no estimate covers (its
        radial error outside every estimate above 2 mm), unless it is moving away from them
        (the end of the arc no closer than now). The navigation function keeps the robot off
        the inflated estimates, which fit the returns only to ``refit_tol``; a face seen
        slightly outside its estimate would otherwise let the robot touch it. When the guard
        slows the robot, the clusters of the estimates there are refitted at the next scan
        (:meth:`perception.ObstacleMap.refit_near`); the return it slowed the robot for is
        kept for :meth:`_slid`."""
        v_lim, ret, d0 = self._guard_limit(p, v, w)
        if ret is None:
            return v
        self._blocker = (float(ret[0]), float(ret[1]))
        self.guard_stops += 1
        if self.omap.refit_near(ret, 0.1) and self.time - self._guard_noted >= 5.0:
            self._guard_noted = self.time
            self._note(f"motion guard: a return at ({ret[0]:.3f}, {ret[1]:.3f}) lies "
                       f"{d0 - self.radius:.3f} m from the robot disc: slowed down, refitting its estimate")
        return v_lim

    def _brake(self, p) -> tuple[float, float]:
        """The command of a tick that defers its re-plan: the rate limit's brake
        (:meth:`navigation.Tracker.brake`), slowed further by the motion guard against every
        return of the last scan, those the estimates cover too (no field's safety limit is
        evaluated on such a tick)."""
        v, w = self._tracker.brake(self.time)
        return self._guard_limit(p, v, w, every=True)[0], w

    def _guard_limit(self, p, v: float, w: float, every: bool = False):
        """The motion guard's speed for the command ``(v, w)`` (see :meth:`_guard`), without its
        bookkeeping: ``(v, None, None)`` when it does not slow the robot, else ``(slower v, the
        nearest uncovered return, its distance from the robot's centre)``. ``every``: the
        returns the estimates cover count too."""
        cfg = self.config
        if cfg.guard_margin is None or v == 0.0 or self.omap is None:
            return v, None, None
        pts = self.omap.last_returns
        if not len(pts):
            return v, None, None
        T = cfg.guard_horizon
        need = self.radius + cfg.guard_margin + cfg.guard_noise * self._range_noise
        reach = need + abs(v) * T
        x, y, th = p
        d = np.hypot(pts[:, 0] - x, pts[:, 1] - y)
        near = d < reach + 1e-9
        if not near.any():
            return v, None, None
        # only the returns its estimates leave outside (by more than 2 mm): the navigation
        # function already keeps the disc off the others (they lie in an estimate, which it keeps
        # the disc off), and a narrow passage between estimates must stay open
        q, d = pts[near], d[near]
        covered = np.zeros(len(q), bool)
        for sq in () if every else self.omap.obstacles():
            if math.hypot(sq.center[0] - x, sq.center[1] - y) <= sq.bounding_radius + reach:
                covered |= radial_error(sq, q) <= _GUARD_COVER_TOL
        q, d = q[~covered], d[~covered]
        if not len(q):
            return v, None, None
        i = int(np.argmin(d))  # the nearest uncovered return
        d0 = float(d[i])

        def worst(scale: float) -> float:
            """Smallest distance to the near returns at four points of the arc at ``scale v``."""
            t = T * np.array([0.25, 0.5, 0.75, 1.0])
            vv = scale * v
            if abs(w) > 1e-9:
                xs = x + vv / w * (np.sin(th + w * t) - math.sin(th))
                ys = y - vv / w * (np.cos(th + w * t) - math.cos(th))
            else:
                xs, ys = x + vv * t * math.cos(th), y + vv * t * math.sin(th)
            return float(np.min(np.hypot(q[:, 0, None] - xs, q[:, 1, None] - ys)))

        def ok(scale: float) -> bool:
            m = worst(scale)
            return m >= need or m >= d0 - 1e-12

        if ok(1.0):
            return v, None, None
        lo, hi = 0.0, 1.0  # ok(0): no translation
        for _ in range(8):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if ok(mid) else (lo, mid)
        return lo * v, q[i], d0

    # ------------------------------------------------------------------ rotation weights
    def _edge_done(self, k: int) -> None:
        """The robot passed waypoint ``k``: record edge ``k - 1 -> k`` and refit the weights."""
        t0, self._edge_t0 = self._edge_t0, self.time
        if t0 is None or k < 1 or not self.config.refit_weights:
            return
        a, b = self.leg[k - 1], self.leg[k]
        d = math.hypot(b[0] - a[0], b[1] - a[1])
        dt = self.time - t0
        if not (d > 0 and dt > 0 and math.isfinite(dt)):
            return
        q1, q2 = (float(x) for x in rotation_terms(a[:2], a[2], b[:2], b[2]))
        self._edges.append((d, q1, q2, self.control.v_max * dt))
        if len(self._edges) >= self.config.refit_min_edges:
            self._refit_weights()

    def _refit_weights(self) -> None:
        """Least-squares weights over the traversed edges (section 4.2.3, step III), then the
        map costs of every evaluated tree under them."""
        try:
            rows = np.array(self._edges)
            w = RotationWeights.fit(rows[:, 0], rows[:, 1:3], rows[:, 3])
        except TampError:
            return  # Q^T Q singular so far: keep the current weights
        lo, hi = self.config.weight_bounds
        w = RotationWeights(min(max(w.w1, lo), hi), min(max(w.w2, lo), hi))
        if w == self.weights:
            return
        self.weights = w
        self.weight_fits += 1
        self._apply_tree_costs()

    def _tree_cost(self, tree) -> float:
        """A tree's cost under the current weights (its own when it was searched with them)."""
        return tree.cost if tree.weights == self.weights else tree.recost(self.weights)

    def _apply_tree_costs(self) -> None:
        """Map costs of every evaluated transition under the current weights: its tree's cost,
        or the edge removed when it has no tree."""
        nm = self.planner.navmap
        for (a, b), tree in self._pair.items():
            if isinstance(tree, Exception):
                nm.remove_edge(a, b)
            else:
                nm.set_cost(a, b, self._tree_cost(tree))
        for b, tree in self._start_pair.items():
            if not isinstance(tree, Exception):
                nm.set_cost(Node(START, 0), b, self._committed(self._tree_cost(tree), b), symmetric=False)

    def _committed(self, cost: float, region: str) -> float:
        """``cost`` of the transition from the robot to ``region``, with the commitment
        discount when ``region`` is the region the robot was heading for when the re-plan began
        (module doc, "Commitment")."""
        if self._commit is None or region != self._commit:
            return cost
        return (1.0 - self.config.commit_discount) * cost


def _as_region(name, spec) -> Region:
    """A :class:`Region` from a Region or ``{"center", "radius"}``; RegionError (format)."""
    if isinstance(spec, Region):
        if spec.name != name:
            raise RegionError(str(name), RegionRule.FORMAT, f"region named {spec.name!r} given under {name!r}")
        return spec
    try:
        if not isinstance(spec, Mapping):
            raise WorldError(f"expected {{\"center\": [x, y], \"radius\": r}}, got {type(spec).__name__}")
        return Region(name, spec["center"], spec["radius"])
    except KeyError as err:
        raise RegionError(str(name), RegionRule.FORMAT, f"missing field {err.args[0]!r}") from None
    except WorldError as err:
        raise RegionError(str(name), RegionRule.FORMAT, str(err)) from None


def _check_alphabet(text, buchi, states, letters, old_letters, changed) -> None:
    """RegionError (alphabet) when a letter new to ``buchi`` (a new region outside its formula)
    has no successor from a state reachable from ``states`` (see Executive.set_regions)."""
    fresh = set(letters) - set(old_letters)
    if not fresh or not states:
        return
    seen, todo = set(states), list(states)
    while todo:
        q = todo.pop()
        for e in buchi.edges[q]:
            if e.dst not in seen and ops.edge_usable(e.guard, letters):
                seen.add(e.dst)
                todo.append(e.dst)
    for mask in fresh:
        if any(not buchi.successors(q, mask) for q in seen):
            name = next((n for n in changed if buchi.mask([n]) == mask), changed[0])
            raise RegionError(name, RegionRule.ALPHABET,
                              f"the running mission {brief(text)} was translated over regions that are all in its "
                              "formula and cannot read a visit to a region outside it; send the region with "
                              "mode 'replace' (the whole mission)")


# candidate offsets of a centred waypoint (``Executive._centre``): rings at 1/4 .. 4/4 of the
# reach, 16 directions each
_CENTRE_RING = np.concatenate([f * np.stack((np.cos(a), np.sin(a)), axis=1)
                               for f in (0.25, 0.5, 0.75, 1.0)
                               for a in [np.linspace(0, 2 * np.pi, 16, endpoint=False)]])


def reachable_speed(pose, point, omega_max: float) -> float:
    """The largest speed at which a unicycle at ``pose (x, y, theta)`` turning at
    ``omega_max`` can drive the circle through ``point (x, y, ...)`` tangent to its heading:
    ``omega_max * d / (2 sin a)`` for the distance ``d`` and the bearing ``a`` of the point off
    the heading (``a`` capped at 90 degrees; ``inf`` straight ahead)."""
    dx, dy = point[0] - pose[0], point[1] - pose[1]
    a = min(abs(math.remainder(math.atan2(dy, dx) - pose[2], 2 * math.pi)), math.pi / 2)
    sa = math.sin(a)
    return omega_max * math.hypot(dx, dy) / (2 * sa) if sa > 1e-9 else math.inf


def _narrow_samples(rm, tree):
    """Samples of ``tree``'s path every 2 cm and which of them are closer than ``rm``'s
    buffer to an obstacle or the boundary (not :meth:`Roadmap.safe_points`)."""
    pts = np.array([w[:2] for w in _subdivide(tree.waypoints, 0.02)], dtype=float)
    return pts, ~rm.safe_points(pts)


def _keep_last(items: list, n: int) -> None:
    """Bound a log a long-running executive appends to: past ``2 n`` entries, keep the last
    ``n`` (amortised O(1) per append)."""
    if len(items) > 2 * n:
        del items[:-n]


def _subdivide(wps, max_len: float):
    """The poses ``wps`` with every segment longer than ``max_len`` cut into the fewest equal
    parts of at most ``max_len``: the new points lie on the segment, with its end's heading (the
    headings of a leg are set afterwards by :func:`_pass_through_headings`)."""
    out = [tuple(wps[0])]
    for a, b in zip(wps, wps[1:]):
        n = max(1, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / max_len - 1e-9))
        out.extend((a[0] + k / n * (b[0] - a[0]), a[1] + k / n * (b[1] - a[1]), b[2]) for k in range(1, n))
        out.append(tuple(b))
    return tuple(out)


def _pass_through_headings(wps):
    """Goal heading along the last segment; intermediate headings along the bisector of the
    incoming and outgoing segments; the start pose unchanged."""
    if len(wps) < 2:
        return tuple(wps)
    out = [wps[0]]
    for k in range(1, len(wps)):
        (x0, y0, _), (x1, y1, _) = wps[k - 1], wps[k]
        a_in = math.atan2(y1 - y0, x1 - x0)
        if k == len(wps) - 1:
            h = a_in
        else:
            x2, y2, _ = wps[k + 1]
            a_out = math.atan2(y2 - y1, x2 - x1)
            h = math.atan2(math.sin(a_in) + math.sin(a_out), math.cos(a_in) + math.cos(a_out))
        out.append((x1, y1, h))
    return tuple(out)


