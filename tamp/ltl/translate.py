"""LTL -> Büchi translation (work in progress)."""
from .automaton import Buchi


def to_buchi(formula) -> Buchi:
    raise NotImplementedError
