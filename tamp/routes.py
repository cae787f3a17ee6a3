"""Rescue routes for a lone goal pose: the harmonic tree from the robot to the goal (paper 001
eq. 7-8, 26) on roadmaps of decreasing safety buffer.

:class:`navigation.Tracker` tracks one oriented field towards a goal pose. Next to chained walls
the field's integral curves can run in millimetre-wide trenches that the unicycle cannot follow
(docs/control.md, "Route rescue"): the robot then loops or keeps crawling. When its guard sees
that, the tracker asks a *route planner* for oriented waypoints from its pose to the goal and
pursues them along the tree's straight segments (or, with ``CrawlConfig(route_pursuit=False)``,
tracks them one field per waypoint with eq. 25's switch, as the executive does with the
harmonic trees of a mission, paper 001 section 4.1.4). :class:`TreeRoutes` is that planner:
:func:`tamp.plan_tree` on the visibility roadmap of the world (:class:`tamp.Roadmap`), at the
paper's buffer of 0.15 m first, then at 0.03 m (the executive's ``fallback_buffer``: passages
narrower than the paper's buffer allows), then at 0 (a robot held by the safety limit within
micrometres of a grown boundary has no safe edge to a vertex at any positive buffer).

Not in the paper, which tracks a single field with eq. 24 alone; the navigation layer does not
import this package, so the planner is handed to the tracker (``Tracker(..., route=...)``).
"""

from __future__ import annotations

import math

from navigation.errors import TampError, WorldError
from .harmonic_tree import NoTreePathError, RotationWeights, plan_tree
from .roadmap import Roadmap, RoadmapConfig

__all__ = ["TreeRoutes", "ROUTE_BUFFERS"]

#: Safety buffers (m) tried in turn: the paper's, the executive's fallback, none.
ROUTE_BUFFERS = (0.15, 0.03, 0.0)


class TreeRoutes:
    """Route planner for :class:`navigation.Tracker`: ``routes(pose, goal)`` returns the
    harmonic tree's waypoints after ``pose`` (the last one is ``goal``) as a tuple of
    ``(x, y, theta)``, or ``None`` when no roadmap connects them.

    Parameters
    ----------
    world : navigation.World
        Its obstacles (all of them, or only the known ones with ``known_only``) grown by the
        robot radius, as the fields the tracker follows.
    buffers : sequence of float
        Roadmap buffers tried in turn (:data:`ROUTE_BUFFERS`); each roadmap is built on first
        use and kept.
    n_headings : int
        Headings per roadmap position (:func:`tamp.plan_tree`).
    weights : RotationWeights, optional
        Eq. 26's rotation weights (default ``(0.1, 0.1)``).
    known_only : bool
        Plan around ``world.known`` only.

    Attributes
    ----------
    last_buffer : float or None
        The buffer of the last route returned (``None`` before any, or after a failure).
    """

    def __init__(self, world, buffers=ROUTE_BUFFERS, *, n_headings: int = 8,
                 weights: RotationWeights | None = None, known_only: bool = False):
        try:
            buffers = tuple(float(b) for b in buffers)
        except (TypeError, ValueError):
            raise TampError(f"buffers must be a sequence of numbers, got {buffers!r}") from None
        if not buffers or not all(math.isfinite(b) and b >= 0 for b in buffers):
            raise TampError(f"buffers must be one or more finite numbers >= 0, got {buffers!r}")
        self.world = world
        self.buffers = buffers
        self.n_headings = int(n_headings)
        self.weights = RotationWeights() if weights is None else weights
        self.known_only = bool(known_only)
        self._roadmaps: dict[float, Roadmap] = {}
        self._no_room: set[float] = set()  # buffers whose roadmap cannot be built (not retried)
        self.last_buffer: float | None = None

    def roadmap(self, buffer: float) -> Roadmap:
        """The roadmap at ``buffer`` (built on first use).

        Raises
        ------
        WorldError
            The workspace is too small for the robot radius plus ``buffer``.
        """
        rm = self._roadmaps.get(buffer)
        if rm is None:
            rm = self._roadmaps[buffer] = Roadmap.from_world(self.world, RoadmapConfig(buffer=buffer),
                                                              known_only=self.known_only)
        return rm

    def __call__(self, pose, goal) -> tuple | None:
        self.last_buffer = None
        for b in self.buffers:
            if b in self._no_room:
                continue
            try:
                tree = plan_tree(self.roadmap(b), pose, goal, self.weights, self.n_headings)
            except WorldError:  # no room for the buffer at all: skip it from now on
                self._no_room.add(b)
                continue
            except NoTreePathError:
                continue
            self.last_buffer = b
            return tuple(tuple(map(float, w)) for w in tree.waypoints[1:])
        return None
