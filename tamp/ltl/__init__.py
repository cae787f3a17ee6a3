"""Linear temporal logic for missions: syntax, Büchi automata, HOA v1 (paper 001 section 4.1.1).

Public names
------------
``parse(text)`` / ``str(formula)``
    FORMATS.md syntax to :class:`Formula` and back (:mod:`tamp.ltl.syntax`).
``to_buchi(formula, aps=None, *, exclusive=False)`` / ``exclusive_letters(n)``
    Pure-Python translation to a state-based Büchi automaton :class:`Buchi`
    (:mod:`tamp.ltl.translate`); ``exclusive=True`` reads only letters with at most one true
    proposition (disjoint regions).
``to_hoa(buchi)`` / ``from_hoa(text)``
    HOA v1 output and input (:mod:`tamp.ltl.hoa`).
``evaluate(formula, prefix, cycle)`` / ``accepts(buchi, prefix, cycle)``
    Exact semantics on ultimately periodic words ``u v^omega`` (:mod:`tamp.ltl.semantics`).

``python -m tamp.ltl "FORMULA"`` prints the automaton in HOA (FORMATS.md command-line contract).
"""

from .automaton import Buchi, Edge
from .bdd import Bdd
from .formula import Formula
from .hoa import from_hoa, to_hoa
from .semantics import accepts, evaluate
from .syntax import parse, to_string
from .translate import exclusive_letters, to_buchi

__all__ = [
    "Formula",
    "parse",
    "to_string",
    "to_buchi",
    "exclusive_letters",
    "Buchi",
    "Edge",
    "Bdd",
    "to_hoa",
    "from_hoa",
    "evaluate",
    "accepts",
]
