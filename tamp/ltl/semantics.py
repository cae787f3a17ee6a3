"""Exact LTL semantics on ultimately periodic words ``u v^omega`` (the test oracle).

An ultimately periodic (lasso) word is a finite *prefix* ``u`` followed by a non-empty *cycle*
``v`` repeated forever. Its suffixes are finitely many, so the truth of every subformula can be
tabulated on the ``len(u) + len(v)`` *positions* of the lasso: position ``i`` stands for the
suffix starting at letter ``i``, and the successor of the last position is ``len(u)``, the
start of the cycle.

:func:`evaluate` decides ``u v^omega |= phi`` by computing, bottom-up over the subformulas, the
set of positions where each subformula holds (a bit set stored in a Python ``int``: bit ``i``
is position ``i``). Boolean operators are bitwise operations, ``X`` shifts by one along the
lasso, and the binary temporal operators are the fixpoints of their expansion laws [1]_:

==========  ======================================  ==========
operator    expansion                               fixpoint
==========  ======================================  ==========
``a U b``   ``b | (a & X(a U b))``                  least
``a W b``   ``b | (a & X(a W b))``                  greatest
``a R b``   ``b & (a | X(a R b))``                  greatest
``a M b``   ``b & (a | X(a M b))``                  least
``F b``     ``true U b``                            least
``G b``     ``false R b``                           greatest
==========  ======================================  ==========

On a lasso of ``n`` positions each fixpoint iteration converges after at most ``n + 1``
steps, so the result is exact (no bound on the unrolling is guessed).

:func:`accepts` decides whether a state-based Büchi automaton
(:class:`~tamp.ltl.automaton.Buchi`) accepts ``u v^omega``: it explores the product of the
automaton with the lasso positions from ``(initial, 0)`` and looks for a reachable strongly
connected component that contains an accepting state and a cycle (iterative Tarjan).

Letters are iterables of the names of the propositions that hold (``{"a", "c"}``); names a
formula or automaton does not mention are ignored.

References
----------
.. [1] C. Baier and J.-P. Katoen, *Principles of Model Checking*, MIT Press, 2008,
   sections 5.1 (LTL semantics, expansion laws) and 4.3-4.4 (Büchi acceptance, nested search).
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable, Sequence

from ._graph import strongly_connected_components
from .automaton import Buchi
from .formula import Formula
from .syntax import FormulaLike, parse

__all__ = ["evaluate", "accepts", "Letter", "Word"]

Letter = Iterable[str]
"""One letter: the names of the atomic propositions that hold."""
Word = Sequence[Letter]
"""A finite sequence of letters (a prefix or a cycle)."""

# Compiled formulas: formula -> (ap names, program). A program is a list of
# (op, operand slots) in bottom-up order; slot k holds the result of instruction k.
_compiled: "weakref.WeakKeyDictionary[Formula, tuple]" = weakref.WeakKeyDictionary()


def _compile(f: Formula) -> tuple[tuple[str, ...], list[tuple[str, tuple[int, ...], str]]]:
    hit = _compiled.get(f)
    if hit is not None:
        return hit
    subs = f.subformulas()
    slot = {g: k for k, g in enumerate(subs)}
    program = [(g.op, tuple(slot[a] for a in g.args), g.name) for g in subs]
    aps = tuple(sorted(f.aps))
    hit = (aps, program)
    _compiled[f] = hit
    return hit


def _letters(word: Word, what: str) -> list[frozenset[str]]:
    """Validate and normalise ``word`` (``what`` names it in error messages)."""
    if isinstance(word, (str, bytes)):
        raise TypeError(
            f"{what} must be a sequence of letters (each a set of proposition names), "
            f"got the string {word!r}"
        )
    out = []
    for i, letter in enumerate(word):
        if isinstance(letter, (str, bytes)):
            raise TypeError(
                f"letter {i} of the {what} is the string {letter!r}; give a set of proposition "
                f"names such as {{{letter!r}}} (or set() for the empty letter)"
            )
        try:
            out.append(frozenset(letter))
        except TypeError as err:
            raise TypeError(
                f"letter {i} of the {what} must be an iterable of proposition names, "
                f"got {letter!r}"
            ) from err
    return out


def _lasso(prefix: Word, cycle: Word) -> tuple[list[frozenset[str]], int]:
    """Letters of ``prefix + cycle`` and the loop position ``len(prefix)``."""
    u = _letters(prefix, "prefix")
    v = _letters(cycle, "cycle")
    if not v:
        raise ValueError(
            f"the cycle of a lasso word u v^omega must be non-empty, got cycle={cycle!r}"
        )
    return u + v, len(u)


def _fixpoint(a: int, b: int, disjunctive: bool, least: bool, n: int, loop: int) -> int:
    """Solve ``y = b | (a & X y)`` (``disjunctive``) or ``y = b & (a | X y)`` on the lasso."""
    full = (1 << n) - 1
    last = n - 1
    low = full >> 1  # positions 0 .. n-2
    y = 0 if least else full
    while True:
        nxt = (y >> 1) & low | ((y >> loop) & 1) << last
        new = (b | (a & nxt)) if disjunctive else (b & (a | nxt))
        if new == y:
            return y
        y = new


def _evaluate_bits(program, aps_bits: dict[str, int], n: int, loop: int) -> int:
    full = (1 << n) - 1
    last = n - 1
    low = full >> 1
    val: list[int] = []
    push = val.append
    for op, args, name in program:
        if op == "ap":
            push(aps_bits.get(name, 0))
        elif op == "!":
            push(full & ~val[args[0]])
        elif op == "&":
            r = full
            for k in args:
                r &= val[k]
            push(r)
        elif op == "|":
            r = 0
            for k in args:
                r |= val[k]
            push(r)
        elif op == "X":
            y = val[args[0]]
            push((y >> 1) & low | ((y >> loop) & 1) << last)
        elif op == "F":
            push(_fixpoint(full, val[args[0]], True, True, n, loop))
        elif op == "G":
            push(_fixpoint(0, val[args[0]], False, False, n, loop))
        elif op == "U":
            push(_fixpoint(val[args[0]], val[args[1]], True, True, n, loop))
        elif op == "W":
            push(_fixpoint(val[args[0]], val[args[1]], True, False, n, loop))
        elif op == "R":
            push(_fixpoint(val[args[0]], val[args[1]], False, False, n, loop))
        elif op == "M":
            push(_fixpoint(val[args[0]], val[args[1]], False, True, n, loop))
        elif op == "->":
            push(full & (~val[args[0]] | val[args[1]]))
        elif op == "<->":
            push(full & ~(val[args[0]] ^ val[args[1]]))
        elif op == "true":
            push(full)
        elif op == "false":
            push(0)
        else:  # pragma: no cover - Formula rejects unknown operators
            raise ValueError(f"unknown LTL operator {op!r}")
    return val[-1]


def evaluate(formula: FormulaLike, prefix: Word, cycle: Word) -> bool:
    """Whether the lasso word ``prefix cycle^omega`` satisfies ``formula``.

    Exact for every operator (``true false ! X F G & | -> <-> U R W M``): the truth of each
    subformula is tabulated on the ``len(prefix) + len(cycle)`` positions of the lasso, with
    the temporal operators computed as fixpoints of their expansion laws (see the module
    docstring).

    Parameters
    ----------
    formula : Formula or str
        The formula; a string is parsed with :func:`tamp.ltl.syntax.parse`.
    prefix : sequence of letters
        The finite prefix ``u`` (may be empty). A letter is an iterable of the names of the
        propositions that hold, e.g. ``{"a", "b"}`` or ``()``.
    cycle : sequence of letters
        The non-empty period ``v``, repeated forever.

    Returns
    -------
    bool
        ``u v^omega |= formula``.

    Raises
    ------
    ValueError
        If ``cycle`` is empty.
    TypeError
        If a letter is not an iterable of names (a bare string is refused as ambiguous).
    LtlSyntaxError
        If ``formula`` is a string that does not parse.

    Examples
    --------
    >>> evaluate("G F a", [], [{"a"}, set()])
    True
    >>> evaluate("F G a", [], [{"a"}, set()])
    False
    >>> evaluate("!b U a", [set(), {"b"}], [{"a"}])
    False
    >>> evaluate("a W b", [], [{"a"}])  # weak until: b may never come
    True
    >>> evaluate("a U b", [], [{"a"}])  # strong until: b must come
    False
    >>> evaluate("X X c", [{"a"}], [{"b"}, {"c"}])
    True
    """
    f = parse(formula)
    letters, loop = _lasso(prefix, cycle)
    n = len(letters)
    aps, program = _compile(f)
    bits = dict.fromkeys(aps, 0)
    for i, letter in enumerate(letters):
        for name in letter:
            if name in bits:
                bits[name] |= 1 << i
    return bool(_evaluate_bits(program, bits, n, loop) & 1)


def accepts(buchi: Buchi, prefix: Word, cycle: Word) -> bool:
    """Whether the state-based Büchi automaton ``buchi`` accepts ``prefix cycle^omega``.

    The product of the automaton with the lasso positions has the nodes ``(q, i)`` ("in state
    ``q``, about to read letter ``i``") and the edges ``(q, i) -> (q', succ(i))`` for each
    ``q'`` in ``buchi.successors(q, letter_i)``. The word is accepted exactly when some node
    reachable from ``(initial, 0)`` has an accepting ``q`` and lies on a cycle of the product
    (a non-trivial strongly connected component, found with an iterative Tarjan search).

    Parameters
    ----------
    buchi : Buchi
        The automaton. Letters are converted to masks over ``buchi.aps``; names that are not
        propositions of the automaton are ignored.
    prefix : sequence of letters
        The finite prefix ``u`` (may be empty); each letter an iterable of proposition names.
    cycle : sequence of letters
        The non-empty period ``v``.

    Returns
    -------
    bool
        ``u v^omega`` is in the language of ``buchi``.

    Raises
    ------
    ValueError
        If ``cycle`` is empty.
    TypeError
        If a letter is not an iterable of names.

    Examples
    --------
    The two-state automaton of ``G F a``: state 1 is entered on ``a`` and is accepting.

    >>> from tamp.ltl.automaton import Buchi, Edge
    >>> from tamp.ltl.bdd import Bdd
    >>> a = Bdd.var(0)
    >>> out = (Edge(a, 1), Edge(~a, 0))
    >>> gfa = Buchi(("a",), 0, (out, out), frozenset({1}))
    >>> accepts(gfa, [], [{"a"}, set()])
    True
    >>> accepts(gfa, [{"a"}, {"a"}], [set()])
    False
    >>> accepts(gfa, [], [{"a", "zzz"}])  # "zzz" is not a proposition of the automaton
    True
    """
    letters, loop = _lasso(prefix, cycle)
    n = len(letters)
    index = {a: k for k, a in enumerate(buchi.aps)}
    masks = []
    for letter in letters:
        m = 0
        for name in letter:
            k = index.get(name)
            if k is not None:
                m |= 1 << k
        masks.append(m)
    succ_state = buchi.successors
    accepting = buchi.accepting
    if not accepting:
        return False

    # Product node (q, i) is encoded as q * n + i.
    def successors(node: int) -> list[int]:
        q, i = divmod(node, n)
        j = i + 1 if i + 1 < n else loop
        return [r * n + j for r in succ_state(q, masks[i])]

    # Strongly connected components of the reachable product (lazily; stop at the first
    # non-trivial one that holds an accepting state).
    for component in strongly_connected_components([buchi.initial * n], successors):
        if any(w // n in accepting for w in component):
            if len(component) > 1 or component[0] in successors(component[0]):
                return True
    return False
