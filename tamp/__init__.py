"""Task and motion planning: LTL missions on top of harmonic navigation.

This package owns LTL formulas (parsing and printing, FORMATS.md syntax), Büchi automata (HOA v1
in and out, :mod:`tamp.ltl`), the navigation map over regions x orientations
(:mod:`tamp.navmap`), its product with the mission automaton (:mod:`tamp.product`), the lasso
planner with re-planning and run-time mission changes (:class:`MissionPlanner`,
:mod:`tamp.planner`; paper 001 sections 4.1.1, 4.2.4 and 5.2), and harmonic trees of oriented
waypoints between task poses on a visibility roadmap (:mod:`tamp.roadmap`,
:mod:`tamp.harmonic_tree`; eq. 7-8, 26 and section 4.2.3), also as rescue routes for
:class:`navigation.Tracker` (:mod:`tamp.routes`).
"""

from .harmonic_tree import HarmonicTree, NoTreePathError, RotationWeights, plan_tree, revise_trees
from .planner import MissionMode, MissionPlanner, Plan
from .roadmap import Roadmap, RoadmapConfig
from .routes import TreeRoutes

__all__ = ["MissionPlanner", "MissionMode", "Plan", "HarmonicTree", "NoTreePathError", "RotationWeights",
           "plan_tree", "revise_trees", "Roadmap", "RoadmapConfig", "TreeRoutes"]
from .executive import Executive, ExecutiveConfig, ExecutiveState  # noqa: E402

__all__ += ["Executive", "ExecutiveConfig", "ExecutiveState"]  # tamp.run stays a module (python -m tamp.run)
