"""Negation normal form and language-preserving simplification of LTL formulas.

:func:`simplify` returns an equivalent formula in negation normal form (negations only on
atomic propositions; ``->``, ``<->``, ``W`` and ``M`` expanded) built with the simplifying
constructors below. They apply standard rewrite rules (Somenzi & Bloem 2000, Etessami &
Holzmann 2000, as used by Spot and ltl2ba), for instance::

    F F a = F a          G G a = G a          F X a = X F a        G X a = X G a
    F G F a = G F a      G F G a = F G a      F(a U b) = F b       G(a R b) = G b
    true U a = F a       false R a = G a      a U b = b  if a implies b
    X a & X b = X(a & b) G a & G b = G(a & b) F a | F b = F(a | b)
    a & b = a  if a implies b (syntactically)  a | b = b  if a implies b

plus constant folding and complementary literals. Operands of ``&`` and ``|`` are
de-duplicated and sorted, so equivalent conjunctions of the same parts are the same object —
the translator uses conjunctions as automaton states.

:func:`implies` is a sound, incomplete syntactic implication check (``implies(f, g)`` True
means every word satisfying ``f`` satisfies ``g``).
"""

from __future__ import annotations

from functools import lru_cache

from .formula import FALSE, TRUE, Formula

__all__ = [
    "simplify",
    "nnf",
    "implies",
    "negate",
    "sort_key",
    "mk_and",
    "mk_or",
    "mk_not_ap",
    "mk_next",
    "mk_eventually",
    "mk_always",
    "mk_until",
    "mk_release",
    "is_cosafe",
    "is_safe",
]

_MAX_IMPLIES_DEPTH = 12
#: entries each memo of a pure function keeps (least recently used first out): formulas are
#: hash-consed and a memo keeps its keys alive, so an unbounded one grew by about 3.5 KB per
#: distinct mission a long-running service was sent (thirty-third session)
MEMO_SIZE = 4096


def _key(f: Formula):
    return (f.size, str(f))


sort_key = lru_cache(maxsize=MEMO_SIZE)(_key)


@lru_cache(maxsize=MEMO_SIZE)
def _implies(f: Formula, g: Formula, depth: int) -> bool:
    if f is g or g is TRUE or f is FALSE:
        return True
    if depth > _MAX_IMPLIES_DEPTH:
        return False
    d = depth + 1
    fo, go = f.op, g.op
    if go == "&":
        return all(_implies(f, x, d) for x in g.args)
    if fo == "|":
        return all(_implies(x, g, d) for x in f.args)
    if fo == "&" and any(_implies(x, g, d) for x in f.args):
        return True
    if go == "|" and any(_implies(f, x, d) for x in g.args):
        return True
    if fo == "G" and _implies(f.args[0], g, d):  # G y -> y
        return True
    if fo == "R" and _implies(f.args[1], g, d):  # a R b -> b
        return True
    if fo in ("U",) and _implies(f.args[0], g, d) and _implies(f.args[1], g, d):
        return True
    if go == "F":
        x = g.args[0]
        if _implies(f, x, d):
            return True
        if fo in ("F", "G", "X") and _implies(f.args[0], g if fo != "G" else x, d):
            # F y -> F x if y -> F x ; G y -> F x if y -> x ; X y -> F x if y -> F x
            return True
        if fo == "U" and _implies(f.args[1], g, d):
            return True
    if go == "G":
        x = g.args[0]
        if fo == "G" and _implies(f.args[0], x, d):
            return True
        if fo == "R" and f.args[0] is FALSE and _implies(f.args[1], x, d):
            return True
    if go == "X":
        x = g.args[0]
        if fo == "X" and _implies(f.args[0], x, d):
            return True
        if fo == "G" and _implies(f, x, d):  # G y -> X G y
            return True
    if go == "U":
        a, b = g.args
        if _implies(f, b, d):
            return True
        if fo == "U" and _implies(f.args[0], a, d) and _implies(f.args[1], b, d):
            return True
        if fo == "F" and a is TRUE and _implies(f.args[0], b, d):
            return True
    if go == "R":
        a, b = g.args
        if _implies(f, a, d) and _implies(f, b, d):
            return True
        if fo == "G" and _implies(f.args[0], b, d):
            return True
        if fo == "R" and _implies(f.args[0], a, d) and _implies(f.args[1], b, d):
            return True
    return False


def implies(f: Formula, g: Formula) -> bool:
    """Sound syntactic implication on NNF formulas: True only if ``f`` implies ``g``."""
    return _implies(f, g, 0)


def _complement_literal(f: Formula) -> Formula | None:
    if f.op == "ap":
        return Formula("!", (f,))
    if f.op == "!" and f.args[0].op == "ap":
        return f.args[0]
    return None


def _nary(op: str, items) -> Formula:
    unit, zero = (TRUE, FALSE) if op == "&" else (FALSE, TRUE)
    flat: list[Formula] = []
    stack = list(items)[::-1]
    while stack:
        x = stack.pop()
        if x.op == op:
            stack.extend(x.args[::-1])
        elif x is zero:
            return zero
        elif x is not unit:
            flat.append(x)
    uniq = list(dict.fromkeys(flat))
    present = set(uniq)
    for x in uniq:
        c = _complement_literal(x)
        if c is not None and c in present:
            return zero
    # merge X's, and G's (for &) / F's (for |)
    merge_op = "G" if op == "&" else "F"
    xs = [x for x in uniq if x.op == "X"]
    ms = [x for x in uniq if x.op == merge_op]
    rest = [x for x in uniq if x.op != "X" and x.op != merge_op]
    if len(xs) > 1:
        rest.append(mk_next(_nary(op, [x.args[0] for x in xs])))
    else:
        rest.extend(xs)
    if len(ms) > 1:
        inner = _nary(op, [x.args[0] for x in ms])
        rest.append(mk_always(inner) if op == "&" else mk_eventually(inner))
    else:
        rest.extend(ms)
    if len(rest) != len(uniq):
        return _nary(op, rest)  # merging may enable more rules
    # absorption by syntactic implication: in a conjunction drop the weaker, in a
    # disjunction drop the stronger operand.
    keep: list[Formula] = []
    for i, x in enumerate(uniq):
        redundant = False
        for j, y in enumerate(uniq):
            if i == j:
                continue
            if op == "&":
                hit = implies(y, x) and not (implies(x, y) and j > i)
            else:
                hit = implies(x, y) and not (implies(y, x) and j > i)
            if hit:
                redundant = True
                break
        if not redundant:
            keep.append(x)
    if op == "&":
        for x in keep:
            for y in keep:
                if x is not y and implies(x, negate(y)):
                    return FALSE
    if not keep:
        return unit
    if len(keep) == 1:
        return keep[0]
    keep.sort(key=sort_key)
    return Formula(op, tuple(keep))


def mk_and(*items: Formula) -> Formula:
    return _nary("&", items)


def mk_or(*items: Formula) -> Formula:
    return _nary("|", items)


def mk_not_ap(a: Formula) -> Formula:
    if a.op != "ap":
        raise ValueError("mk_not_ap expects an atomic proposition")
    return Formula("!", (a,))


def mk_next(a: Formula) -> Formula:
    if a is TRUE or a is FALSE:
        return a
    return Formula("X", (a,))


def _is_gf(a: Formula) -> bool:
    return a.op == "G" and a.args[0].op == "F"


def _is_fg(a: Formula) -> bool:
    return a.op == "F" and a.args[0].op == "G"


def mk_eventually(a: Formula) -> Formula:
    if a is TRUE or a is FALSE or a.op == "F" or _is_gf(a):
        return a
    if a.op == "X":
        return mk_next(mk_eventually(a.args[0]))
    if a.op == "U":
        return mk_eventually(a.args[1])
    return Formula("F", (a,))


def mk_always(a: Formula) -> Formula:
    if a is TRUE or a is FALSE or a.op == "G" or _is_fg(a):
        return a
    if a.op == "X":
        return mk_next(mk_always(a.args[0]))
    if a.op == "R":
        return mk_always(a.args[1])
    if a.op == "F" and a.args[0].op == "X":  # G F X a = G F a
        return mk_always(mk_eventually(a.args[0].args[0]))
    return Formula("G", (a,))


def mk_until(a: Formula, b: Formula) -> Formula:
    if b is TRUE or b is FALSE or a is FALSE:
        return b
    if a is TRUE:
        return mk_eventually(b)
    if a is b or implies(a, b) or b.op == "F" or _is_gf(b):
        return b
    return Formula("U", (a, b))


def mk_release(a: Formula, b: Formula) -> Formula:
    if b is TRUE or b is FALSE or a is TRUE:
        return b
    if a is FALSE:
        return mk_always(b)
    if a is b or implies(b, a) or b.op == "G" or _is_fg(b):
        return b
    return Formula("R", (a, b))


@lru_cache(maxsize=MEMO_SIZE)
def _nnf(f: Formula, neg: bool) -> Formula:
    op = f.op
    if op == "true":
        return FALSE if neg else TRUE
    if op == "false":
        return TRUE if neg else FALSE
    if op == "ap":
        return Formula("!", (f,)) if neg else f
    if op == "!":
        return _nnf(f.args[0], not neg)
    if op == "X":
        return mk_next(_nnf(f.args[0], neg))
    if op == "F":
        a = _nnf(f.args[0], neg)
        return mk_always(a) if neg else mk_eventually(a)
    if op == "G":
        a = _nnf(f.args[0], neg)
        return mk_eventually(a) if neg else mk_always(a)
    if op in ("&", "|"):
        parts = [_nnf(a, neg) for a in f.args]
        return mk_or(*parts) if (op == "&") == neg else mk_and(*parts)
    a, b = f.args
    if op == "->":
        return mk_and(_nnf(a, False), _nnf(b, True)) if neg else mk_or(_nnf(a, True), _nnf(b, False))
    if op == "<->":
        if neg:
            return mk_or(mk_and(_nnf(a, False), _nnf(b, True)), mk_and(_nnf(a, True), _nnf(b, False)))
        return mk_or(mk_and(_nnf(a, False), _nnf(b, False)), mk_and(_nnf(a, True), _nnf(b, True)))
    if op == "U":  # !(a U b) = !a R !b
        return mk_release(_nnf(a, True), _nnf(b, True)) if neg else mk_until(_nnf(a, False), _nnf(b, False))
    if op == "R":
        return mk_until(_nnf(a, True), _nnf(b, True)) if neg else mk_release(_nnf(a, False), _nnf(b, False))
    if op == "W":  # a W b = b R (a | b);  !(a W b) = !b U (!a & !b)
        if neg:
            nb = _nnf(b, True)
            return mk_until(nb, mk_and(_nnf(a, True), nb))
        pb = _nnf(b, False)
        return mk_release(pb, mk_or(_nnf(a, False), pb))
    if op == "M":  # a M b = b U (a & b);  !(a M b) = !b R (!a | !b)
        if neg:
            nb = _nnf(b, True)
            return mk_release(nb, mk_or(_nnf(a, True), nb))
        pb = _nnf(b, False)
        return mk_until(pb, mk_and(_nnf(a, False), pb))
    raise ValueError(f"unknown operator {op!r}")  # pragma: no cover


def negate(f: Formula) -> Formula:
    """NNF of ``!f`` (simplified)."""
    return _nnf(f, True)


def nnf(f: Formula) -> Formula:
    """Equivalent formula in negation normal form, simplified (see the module docstring)."""
    return _nnf(f, False)


simplify = nnf


@lru_cache(maxsize=MEMO_SIZE)
def is_cosafe(f: Formula) -> bool:
    """Syntactically co-safe NNF: only literals, constants, ``& | X F U`` (a guarantee
    property: every satisfying word has a finite good prefix)."""
    if f.op in ("G", "R", "W", "M", "->", "<->"):
        return False
    if f.op == "!":
        return f.args[0].op == "ap"
    return all(is_cosafe(a) for a in f.args)


@lru_cache(maxsize=MEMO_SIZE)
def is_safe(f: Formula) -> bool:
    """Syntactically safe NNF: only literals, constants, ``& | X G R`` (every violating word
    has a finite bad prefix)."""
    if f.op in ("F", "U", "W", "M", "->", "<->"):
        return False
    if f.op == "!":
        return f.args[0].op == "ap"
    return all(is_safe(a) for a in f.args)
