"""Task and motion planning: LTL missions on top of harmonic navigation.

This package will own LTL formulas (parsing and printing, FORMATS.md syntax), Büchi automata
(HOA v1 in and out), the product with the region abstraction, harmonic trees, and the task
executive (``Executive``) that turns a mission into a sequence of navigation goals.

Not implemented yet: it is delivered by later issues (see the Status section of the README).
"""
