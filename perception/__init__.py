"""Perception: lidar scans to squircle obstacles, and the obstacle map.

This package will own the conversion of planar laser scans (or world-frame surface points)
into squircle obstacle estimates, and ``ObstacleMap``, the one stateful object of this layer,
which merges those estimates over time for the planner.

Not implemented yet: it is delivered by a later issue (see the Status section of the README).
"""
