"""Task and motion planning: LTL missions on top of harmonic navigation.

This package owns LTL formulas (parsing and printing, FORMATS.md syntax), Büchi automata (HOA v1
in and out, :mod:`tamp.ltl`), the navigation map over regions x orientations
(:mod:`tamp.navmap`), its product with the mission automaton (:mod:`tamp.product`) and the lasso
planner with re-planning and run-time mission changes (:class:`MissionPlanner`,
:mod:`tamp.planner`; paper 001 sections 4.1.1, 4.2.4 and 5.2). Harmonic trees and the task
executive (``Executive``) that turns a plan into navigation goals come with later issues (see
the Status section of the README).
"""

from .planner import MissionMode, MissionPlanner, Plan

__all__ = ["MissionPlanner", "MissionMode", "Plan"]
