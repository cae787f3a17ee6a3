"""Squircle primitives of the simulator, over packed rows.

Rows are those of :func:`navigation.geometry.pack`: ``[cx, cy, cos(theta), sin(theta),
width/2, height/2, s]``. There is one implementation of each, in :mod:`navigation.geometry`:
:func:`~navigation.geometry.beta_rows` (FORMATS.md's ``beta``),
:func:`~navigation.geometry.point_at_rows` (the boundary parametrisation of
:meth:`~navigation.geometry.Squircle.point_at`) and :class:`~navigation.geometry.ExactDistance`
(the exact signed distance that :meth:`~navigation.geometry.Squircle.distance` also uses);
this module only re-exports them for the simulator's modules.
"""

from __future__ import annotations

from navigation.geometry import ExactDistance, beta_rows, point_at_rows

__all__ = ["beta_rows", "point_at_rows", "ExactDistance"]
