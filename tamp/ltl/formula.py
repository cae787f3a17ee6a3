"""The immutable LTL formula tree (hash-consed).

A :class:`Formula` is a node ``(op, args, name)``. Nodes are *interned*: building the same tree
twice returns the same object, so equality is identity and hashing is O(1). This matters for
the translator, which keeps sets of formulas as automaton states.

Operators (``op``):

=========  =====  ===============================================
``true``   0      constant true
``false``  0      constant false
``ap``     0      atomic proposition ``name`` (a region name)
``!``      1      negation
``X``      1      next
``F``      1      eventually
``G``      1      always
``&``      n>=2   conjunction (n-ary)
``|``      n>=2   disjunction (n-ary)
``->``     2      implication
``<->``    2      equivalence
``U``      2      until (strong)
``R``      2      release (dual of U)
``W``      2      weak until  (``a W b == (a U b) | G a``)
``M``      2      strong release (``a M b == b U (a & b)``)
=========  =====  ===============================================

Constructors here build the node exactly as asked (no simplification); the simplifying
constructors live in :mod:`tamp.ltl.rewrite`. Printing and parsing live in
:mod:`tamp.ltl.syntax`; ``str(f)`` prints FORMATS.md syntax that parses back to ``f``.
"""

from __future__ import annotations

import weakref

__all__ = [
    "Formula",
    "UNARY",
    "BINARY",
    "NARY",
    "TEMPORAL",
    "TRUE",
    "FALSE",
    "ap",
    "Not",
    "Next",
    "Eventually",
    "Always",
    "And",
    "Or",
    "Implies",
    "Equiv",
    "Until",
    "Release",
    "WeakUntil",
    "StrongRelease",
]

UNARY = frozenset({"!", "X", "F", "G"})
BINARY = frozenset({"->", "<->", "U", "R", "W", "M"})
NARY = frozenset({"&", "|"})
CONSTANTS = frozenset({"true", "false"})
TEMPORAL = frozenset({"X", "F", "G", "U", "R", "W", "M"})
_OPS = UNARY | BINARY | NARY | CONSTANTS | {"ap"}


class Formula:
    """One interned node of an LTL formula.

    Attributes
    ----------
    op : str
        Operator (see the module table).
    args : tuple of Formula
        Operands (empty for constants and atomic propositions).
    name : str
        Proposition name for ``op == "ap"``, else ``""``.
    size : int
        Number of nodes of the tree (operators and leaves).
    """

    __slots__ = ("op", "args", "name", "size", "_aps", "__weakref__")
    _table: "weakref.WeakValueDictionary[tuple, Formula]" = weakref.WeakValueDictionary()

    def __new__(cls, op: str, args: tuple = (), name: str = ""):
        key = (op, args, name)
        node = cls._table.get(key)
        if node is not None:
            return node
        if op not in _OPS:
            raise ValueError(f"unknown LTL operator {op!r}; expected one of {sorted(_OPS)}")
        args = tuple(args)
        n = len(args)
        if (op in UNARY and n != 1) or (op in BINARY and n != 2) or (op in NARY and n < 2) or (
            op in CONSTANTS or op == "ap"
        ) and n:
            raise ValueError(f"operator {op!r} cannot take {n} operand(s)")
        if any(not isinstance(a, Formula) for a in args):
            raise TypeError("operands of a Formula must be Formula objects")
        if op == "ap" and not name:
            raise ValueError("an atomic proposition needs a name")
        node = object.__new__(cls)
        object.__setattr__(node, "op", op)
        object.__setattr__(node, "args", args)
        object.__setattr__(node, "name", name if op == "ap" else "")
        object.__setattr__(node, "size", 1 + sum(a.size for a in args))
        object.__setattr__(node, "_aps", None)
        cls._table[(op, args, node.name)] = node
        return node

    def __setattr__(self, key, value):
        raise AttributeError("Formula objects are immutable")

    def __reduce__(self):
        return (Formula, (self.op, self.args, self.name))

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self

    # ---- queries -------------------------------------------------------------------------
    @property
    def aps(self) -> frozenset[str]:
        """Names of the atomic propositions that occur in the formula."""
        cached = self._aps
        if cached is None:
            if self.op == "ap":
                cached = frozenset((self.name,))
            else:
                cached = frozenset().union(*(a.aps for a in self.args))
            object.__setattr__(self, "_aps", cached)
        return cached

    @property
    def is_literal(self) -> bool:
        """True for an atomic proposition or a negated one."""
        return self.op == "ap" or (self.op == "!" and self.args[0].op == "ap")

    def subformulas(self):
        """All distinct subformulas, children before parents."""
        seen: dict[Formula, None] = {}

        def visit(f: Formula):
            if f in seen:
                return
            for a in f.args:
                visit(a)
            seen[f] = None

        visit(self)
        return list(seen)

    # ---- printing (delegated to the syntax module) ---------------------------------------
    def __str__(self) -> str:
        from .syntax import to_string

        return to_string(self)

    def __repr__(self) -> str:
        return f"parse({str(self)!r})"

    # ---- operator sugar (no simplification) ----------------------------------------------
    def __and__(self, other: "Formula") -> "Formula":
        return And(self, other)

    def __or__(self, other: "Formula") -> "Formula":
        return Or(self, other)

    def __invert__(self) -> "Formula":
        return Not(self)

    def __rshift__(self, other: "Formula") -> "Formula":
        return Implies(self, other)


TRUE = Formula("true")
FALSE = Formula("false")


def ap(name: str) -> Formula:
    """Atomic proposition ``name``."""
    return Formula("ap", (), name)


def Not(f: Formula) -> Formula:
    return Formula("!", (f,))


def Next(f: Formula) -> Formula:
    return Formula("X", (f,))


def Eventually(f: Formula) -> Formula:
    return Formula("F", (f,))


def Always(f: Formula) -> Formula:
    return Formula("G", (f,))


def _nary(op: str, fs) -> Formula:
    flat: list[Formula] = []
    for f in fs:
        if f.op == op:
            flat.extend(f.args)
        else:
            flat.append(f)
    if len(flat) == 1:
        return flat[0]
    if not flat:
        return TRUE if op == "&" else FALSE
    return Formula(op, tuple(flat))


def And(*fs: Formula) -> Formula:
    """Conjunction, flattened (``And(a, And(b, c))`` is one node with three operands)."""
    return _nary("&", fs)


def Or(*fs: Formula) -> Formula:
    """Disjunction, flattened."""
    return _nary("|", fs)


def Implies(a: Formula, b: Formula) -> Formula:
    return Formula("->", (a, b))


def Equiv(a: Formula, b: Formula) -> Formula:
    return Formula("<->", (a, b))


def Until(a: Formula, b: Formula) -> Formula:
    return Formula("U", (a, b))


def Release(a: Formula, b: Formula) -> Formula:
    return Formula("R", (a, b))


def WeakUntil(a: Formula, b: Formula) -> Formula:
    return Formula("W", (a, b))


def StrongRelease(a: Formula, b: Formula) -> Formula:
    return Formula("M", (a, b))
