"""Navigation core: squircles, forests of stars, the transformation chain and harmonic
navigation functions (paper 001 eq. 1-2, 9-19), and gradient descent on them.

Public entry points::

    world = navigation.load_world("office")            # or a path to a world JSON file
    nf = navigation.NavigationFunction(world, goal=(6.4, 3.3))
    nf.value(q), nf.gradient(q), nf.hessian(q)         # q of shape (2,) or (N, 2)
    navigation.descend(nf, start)                      # normalised-gradient descent

``navigation.OnlineWorld`` is the versioned obstacle set of a discovered world (added, updated
and removed obstacles, incremental navigation-function updates, paper 001 section 4.2.2).
``navigation.OrientedField(nf, heading)`` is the oriented field of eq. 20-23 (arrival with a
chosen heading); ``navigation.track`` / ``track_waypoints`` are the unicycle controller of
eq. 24-25; ``navigation.Tracker`` wraps them with the crawl guard (the controller's stand-off
while the robot crawls). Later layers own perception
(``perception``), missions (``tamp``) and the bus (``service``).
"""

from .control import Command, ControllerConfig, track, track_point, track_waypoints
from .descent import DescentResult, descend, descend_many
from .errors import (
    ForestError,
    HarmonicTampError,
    NavigationError,
    OutsideFreeSpaceError,
    PointsError,
    WorldError,
)
from .forest import Forest, build_forest
from .geometry import Squircle
from .online import OnlineWorld, WorldChange
from .oriented import OrientedEval, OrientedField
from .potential import NavEval, NavigationFunction, NavParams
from .tracker import CrawlConfig, CrawlGuard, Tracker
from .world import World, load_world

__all__ = [
    "Command",
    "ControllerConfig",
    "CrawlConfig",
    "CrawlGuard",
    "DescentResult",
    "Forest",
    "ForestError",
    "HarmonicTampError",
    "NavEval",
    "NavParams",
    "NavigationError",
    "NavigationFunction",
    "OnlineWorld",
    "OrientedEval",
    "OrientedField",
    "OutsideFreeSpaceError",
    "PointsError",
    "Squircle",
    "Tracker",
    "World",
    "WorldChange",
    "WorldError",
    "build_forest",
    "descend",
    "descend_many",
    "load_world",
    "track",
    "track_point",
    "track_waypoints",
]
