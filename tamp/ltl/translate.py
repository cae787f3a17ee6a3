"""LTL -> state-based Büchi automaton, in pure Python (paper 001 section 4.1.1, step 1).

Pipeline (each step is an established construction):

0. **Alphabet.** By default every letter (set of true propositions) counts. With
   ``exclusive=True`` only the letters in which at most one proposition holds do (a robot is
   in at most one of a world's disjoint region discs): every tableau guard is intersected with
   them, so the terms that need two propositions at once vanish as they are built, and the
   subset construction of step 3 runs over ``n + 1`` letters instead of ``2^n``. The result
   is the automaton of the formula's words over that alphabet (no edge reads another letter),
   all the product of paper 001 section 4.1.1 reads.
1. **Rewrite** the formula to simplified negation normal form (:mod:`tamp.ltl.rewrite`).
2. **Tableau** (Couvreur 1999, "On-the-fly verification of LTL formulae"; the LTL2TGBA
   construction of Spot). A state is a set of NNF obligations (kept as one simplified
   conjunction, so equivalent sets coincide). Expanding a state gives *terms*
   ``(guard, next obligations, promises)`` by the fixpoint laws
   ``a U b = b | (a & X(a U b))`` and ``a R b = b & (a | X(a R b))``; a term that postpones
   an eventuality ``a U b`` (or ``F b``) *promises* it. This is a transition-based
   generalized Büchi automaton (TGBA) with one acceptance set per eventuality ``e``: the
   transitions that do not promise ``e``. Terms dominated by another term (weaker guard,
   more obligations, more promises) are dropped.
3. **Obligation shortcut** (Dax, Eisinger & Klaedtke 2007, minimal weak DBA, specialised to the
   syntactic classes): a *co-safe* formula (only ``X F U & |``) is accepted exactly when a
   finite prefix reaches the empty obligation set, a *safe* one (only ``X G R & |``) exactly
   when its tableau never dies. For both, the tableau is determinised by the subset
   construction over the explicit alphabet and minimised (Moore partition refinement); the
   result is a deterministic Büchi automaton (an accepting ``true`` sink for co-safe
   formulas, all states accepting for safe ones). Mission patterns (visits, sequences,
   transport, avoidance) fall in these classes and get their minimal deterministic automaton.
   Used when the alphabet has at most ``2^``:data:`EXPLICIT_ALPHABET_MAX_APS` letters.
4. Otherwise **SCC-aware degeneralization**: acceptance marks are cleaned per strongly
   connected component of the TGBA (an SCC that misses some set is rejecting, sets present on
   every internal transition are dropped, an SCC whose every transition carries every set is
   accepting); the remaining sets of each SCC are counted by a level that restarts whenever
   the run enters a new SCC. A state ``(q, level)`` is accepting when the level is full.
5. **Reductions** on the Büchi automaton: states that cannot reach an accepting cycle are
   pruned; bisimilar states (same acceptance, same guarded successors up to the partition)
   are merged by partition refinement; edges to the same state are merged (guard OR).

The result accepts exactly the words that satisfy the formula (tested against the exact
lasso-word semantics of :mod:`tamp.ltl.semantics` on thousands of random formulas). An
unsatisfiable formula gives a one-state automaton with no edges and no accepting state.
"""

from __future__ import annotations

from collections import deque
from functools import lru_cache
from collections.abc import Sequence

from ._graph import reachable, strongly_connected_components
from .automaton import Buchi, Edge
from .bdd import Bdd, from_minterms
from .formula import FALSE, TRUE, Formula
from .rewrite import MEMO_SIZE, implies, is_cosafe, is_safe, negate, simplify, sort_key
from .syntax import FormulaLike, parse

__all__ = ["to_buchi", "exclusive_letters", "EXPLICIT_ALPHABET_MAX_APS"]

EXPLICIT_ALPHABET_MAX_APS = 10

_Term = tuple  # (guard: Bdd, next: Formula, promises: frozenset[Formula])


class _Tableau:
    """Expansion of NNF obligations into guarded terms (step 2 of the module docstring)."""

    def __init__(self, ap_index: dict[str, int], alphabet: Bdd = Bdd.true):
        self.ap_index = ap_index
        self.alphabet = alphabet  # the letters the automaton must be right on (step 0)
        self._memo: dict[Formula, list[_Term]] = {}

    def expand(self, f: Formula) -> list[_Term]:
        hit = self._memo.get(f)
        if hit is not None:
            return hit
        op = f.op
        if op == "true":
            out = [(Bdd.true, TRUE, frozenset())]
        elif op == "false":
            out = []
        elif op == "ap":
            out = [(Bdd.var(self.ap_index[f.name]), TRUE, frozenset())]
        elif op == "!":
            out = [(~Bdd.var(self.ap_index[f.args[0].name]), TRUE, frozenset())]
        elif op == "X":
            out = [(Bdd.true, f.args[0], frozenset())]
        elif op == "&":
            out = [(Bdd.true, TRUE, frozenset())]
            for a in f.args:
                out = self._product(out, self.expand(a))
                if not out:
                    break
        elif op == "|":
            out = []
            for a in f.args:
                out.extend(self.expand(a))
        elif op == "U":
            a, b = f.args
            out = list(self.expand(b))
            out += self._product(self.expand(a), [(Bdd.true, f, frozenset((f,)))])
        elif op == "F":
            out = list(self.expand(f.args[0]))
            out.append((Bdd.true, f, frozenset((f,))))
        elif op == "R":
            a, b = f.args
            eb = self.expand(b)
            out = self._product(eb, self.expand(a))
            out += self._product(eb, [(Bdd.true, f, frozenset())])
        elif op == "G":
            out = self._product(self.expand(f.args[0]), [(Bdd.true, f, frozenset())])
        else:  # pragma: no cover - NNF has no other operators
            raise ValueError(f"operator {op!r} is not in negation normal form")
        if self.alphabet is not Bdd.true:
            out = [(g & self.alphabet, n, p) for g, n, p in out]
        out = _reduce_terms(out)
        self._memo[f] = out
        return out

    @staticmethod
    def _product(xs: list[_Term], ys: list[_Term]) -> list[_Term]:
        out = []
        for g1, n1, p1 in xs:
            for g2, n2, p2 in ys:
                g = g1 & g2
                if g.is_false:
                    continue
                n = _state_and(n1, n2)
                if n is FALSE:
                    continue
                out.append((g, n, p1 | p2))
        return out


@lru_cache(maxsize=MEMO_SIZE)
def _has_eventuality(f: Formula) -> bool:
    return f.op in ("U", "F") or any(_has_eventuality(a) for a in f.args)


def _state_and(*parts: Formula) -> Formula:
    """Conjunction of obligations for a tableau state.

    Unlike :func:`~tamp.ltl.rewrite.mk_and` it never hides a pending eventuality: an
    obligation implied by another one is dropped only if it contains no ``U``/``F`` or if the
    other one is ``G(...)`` with it as a conjunct (whose expansion expands it, with its
    promise). Dropping e.g. ``F a`` next to ``X F a`` would lose the promise of ``F a`` and
    accept runs that postpone it forever.
    """
    flat: list[Formula] = []
    stack = list(parts)
    while stack:
        x = stack.pop()
        if x.op == "&":
            stack.extend(x.args)
        elif x is FALSE:
            return FALSE
        elif x is not TRUE:
            flat.append(x)
    uniq = list(dict.fromkeys(flat))
    if len(uniq) <= 1:
        return uniq[0] if uniq else TRUE
    present = set(uniq)
    keep = []
    for x in uniq:
        if x.op == "!" and x.args[0] in present:
            return FALSE
        redundant = False
        for y in uniq:
            if y is x:
                continue
            if y.op == "G" and (y.args[0] is x or (y.args[0].op == "&" and x in y.args[0].args)):
                redundant = True
            elif not _has_eventuality(x) and implies(y, x) and not (
                implies(x, y) and not _has_eventuality(y) and sort_key(y) > sort_key(x)
            ):
                redundant = True
            if redundant:
                break
        if not redundant:
            keep.append(x)
    for i, x in enumerate(keep):
        for y in keep[i + 1:]:
            if implies(x, negate(y)):
                return FALSE
    if len(keep) == 1:
        return keep[0]
    keep.sort(key=sort_key)
    return Formula("&", tuple(keep))


def _reduce_terms(terms: list[_Term]) -> list[_Term]:
    """Merge terms with equal (next, promises); drop terms dominated by another."""
    merged: dict[tuple, Bdd] = {}
    for g, n, p in terms:
        if n is FALSE or g.is_false:
            continue
        key = (n, p)
        merged[key] = merged[key] | g if key in merged else g
    items = [(g, n, p) for (n, p), g in merged.items()]
    keep = []
    for i, (g, n, p) in enumerate(items):
        dominated = False
        for j, (g2, n2, p2) in enumerate(items):
            if i == j:
                continue
            # term j dominates i: covers its letters, fewer obligations, fewer promises
            if p2 <= p and g.implies(g2) and (n2 is TRUE or n2 is n or _conj_subset(n2, n)):
                if (p2 == p and g == g2 and (n2 is n)) and j > i:
                    continue
                dominated = True
                break
        if not dominated:
            keep.append((g, n, p))
    return keep


def _conj_parts(f: Formula) -> tuple[Formula, ...]:
    if f is TRUE:
        return ()
    return f.args if f.op == "&" else (f,)


def _conj_subset(small: Formula, big: Formula) -> bool:
    s = _conj_parts(small)
    b = set(_conj_parts(big))
    return all(x in b for x in s)


def _formula_aps_in_order(f: Formula) -> list[str]:
    seen: dict[str, None] = {}

    def visit(g: Formula):
        if g.op == "ap":
            seen.setdefault(g.name, None)
        for a in g.args:
            visit(a)

    visit(f)
    return list(seen)


# ---- explicit automata (intermediate) ------------------------------------------------------
class _Nba:
    """Mutable state-based NBA used during construction: ``succ[q]`` maps dst -> guard."""

    def __init__(self):
        self.succ: list[dict[int, Bdd]] = []
        self.accepting: set[int] = set()
        self.initial = 0

    def add_state(self, accepting: bool) -> int:
        self.succ.append({})
        q = len(self.succ) - 1
        if accepting:
            self.accepting.add(q)
        return q

    def add_edge(self, src: int, dst: int, guard: Bdd) -> None:
        if guard.is_false:
            return
        out = self.succ[src]
        out[dst] = out[dst] | guard if dst in out else guard


def _sccs(succ: list) -> list[int]:
    """Component id of every node ``0..n-1``; ``succ[q]`` iterable of successors."""
    comp = [-1] * len(succ)
    for c, members in enumerate(strongly_connected_components(range(len(succ)), succ.__getitem__)):
        for q in members:
            comp[q] = c
    return comp


def _prune(nba: _Nba) -> _Nba:
    """Keep states reachable from the initial state that can reach an accepting cycle."""
    good: set[int] = set()
    pred: dict[int, list[int]] = {}
    for qs in strongly_connected_components([nba.initial], nba.succ.__getitem__):
        nontrivial = len(qs) > 1 or qs[0] in nba.succ[qs[0]]
        if nontrivial and any(q in nba.accepting for q in qs):
            good.update(qs)
        for q in qs:
            for d in nba.succ[q]:
                pred.setdefault(d, []).append(q)
    alive = reachable(good, lambda q: pred.get(q, ()))  # backward closure
    out = _Nba()
    if nba.initial not in alive:
        out.add_state(False)
        return out
    order = [nba.initial] + sorted(alive - {nba.initial})
    new = {q: i for i, q in enumerate(order)}
    for q in order:
        out.add_state(q in nba.accepting)
    for q in order:
        for d, g in nba.succ[q].items():
            if d in alive:
                out.add_edge(new[q], new[d], g)
    return out


def _merge_bisimilar(nba: _Nba) -> _Nba:
    """Quotient by the coarsest bisimulation respecting acceptance and guards."""
    n = len(nba.succ)
    block = [1 if q in nba.accepting else 0 for q in range(n)]
    while True:
        sigs: dict[tuple, int] = {}
        new_block = []
        for q in range(n):
            by_block: dict[int, Bdd] = {}
            for d, g in nba.succ[q].items():
                b = block[d]
                by_block[b] = by_block[b] | g if b in by_block else g
            sig = (block[q], frozenset((b, g.node) for b, g in by_block.items()))
            new_block.append(sigs.setdefault(sig, len(sigs)))
        if len(sigs) == len(set(block)):
            block = new_block
            break
        block = new_block
    # rebuild in BFS order from the initial state
    rep: dict[int, int] = {}
    for q in range(n):
        rep.setdefault(block[q], q)
    out = _Nba()
    order: list[int] = []
    index: dict[int, int] = {}
    todo = deque([block[nba.initial]])
    index[block[nba.initial]] = 0
    while todo:
        b = todo.popleft()
        order.append(b)
        for d in nba.succ[rep[b]]:
            bd = block[d]
            if bd not in index:
                index[bd] = len(index)
                todo.append(bd)
    for b in order:
        out.add_state(rep[b] in nba.accepting)
    for b in order:
        for d, g in nba.succ[rep[b]].items():
            out.add_edge(index[b], index[block[d]], g)
    return out


# ---- construction ---------------------------------------------------------------------------
def _explore(tab: _Tableau, init: Formula):
    """TGBA states (formulas) and transitions ``(src, dst, guard, promises)``."""
    ids = {init: 0}
    states = [init]
    edges: list[list[tuple[int, Bdd, frozenset]]] = []
    i = 0
    while i < len(states):
        f = states[i]
        out = []
        for g, n, p in tab.expand(f):
            j = ids.get(n)
            if j is None:
                j = ids[n] = len(states)
                states.append(n)
            out.append((j, g, p))
        edges.append(out)
        i += 1
    return states, edges


def _obligation_automaton(tab: _Tableau, init: Formula, nvars: int, cosafe: bool,
                          letters: Sequence[int]) -> _Nba:
    """Minimal DBA of a co-safe or safe formula via subset construction over ``letters``
    (step 3)."""
    states, edges = _explore(tab, init)
    # successor sets per tableau state and letter
    step = []
    for out in edges:
        row = []
        for m in letters:
            row.append(frozenset(j for j, g, _ in out if g.holds(m)))
        step.append(row)
    accept_tab = {i for i, f in enumerate(states) if f is TRUE} if cosafe else set()
    SINK = frozenset(("sink",))
    start = frozenset((0,))
    if cosafe and 0 in accept_tab:
        start = SINK
    subsets = {start: 0}
    order = [start]
    trans: list[list[int]] = []
    k = 0
    while k < len(order):
        S = order[k]
        row = []
        for li in range(len(letters)):
            if S is SINK:
                T = SINK
            else:
                T = frozenset().union(*(step[s][li] for s in S)) if S else frozenset()
                if cosafe and T & accept_tab:
                    T = SINK
            if not T:
                row.append(-1)
                continue
            t = subsets.get(T)
            if t is None:
                t = subsets[T] = len(order)
                order.append(T)
            row.append(t)
        trans.append(row)
        k += 1
    n = len(order)
    # Moore partition refinement (dead state = -1 keeps block -1)
    block = [1 if (order[q] is SINK) else 0 for q in range(n)] if cosafe else [0] * n
    nblocks = len(set(block))
    while True:
        sigs: dict[tuple, int] = {}
        new = []
        for q in range(n):
            sig = (block[q], tuple(block[t] if t >= 0 else -1 for t in trans[q]))
            new.append(sigs.setdefault(sig, len(sigs)))
        block = new
        if len(sigs) == nblocks:
            break
        nblocks = len(sigs)
    nba = _Nba()
    index: dict[int, int] = {}
    rep: dict[int, int] = {}
    for q in range(n):
        rep.setdefault(block[q], q)
    todo = deque([block[0]])
    index[block[0]] = nba.add_state(cosafe is False or order[0] is SINK)
    while todo:
        b = todo.popleft()
        q = rep[b]
        by_target: dict[int, list[int]] = {}
        for m, t in zip(letters, trans[q]):
            if t >= 0:
                by_target.setdefault(block[t], []).append(m)
        for bt, ms in by_target.items():
            if bt not in index:
                index[bt] = nba.add_state(cosafe is False or order[rep[bt]] is SINK)
                todo.append(bt)
            nba.add_edge(index[b], index[bt], from_minterms(ms, nvars))
    return nba


def _degeneralized_automaton(tab: _Tableau, init: Formula) -> _Nba:
    """TGBA -> state-based Büchi with SCC-local levels (step 4)."""
    states, edges = _explore(tab, init)
    events = sorted({e for out in edges for _, _, p in out for e in p}, key=str)
    ev_index = {e: i for i, e in enumerate(events)}
    k = len(events)
    full = frozenset(range(k))
    # marks of each transition: the sets it does *not* promise
    marks = [[full - frozenset(ev_index[e] for e in p) for _, _, p in out] for out in edges]
    comp = _sccs([[j for j, _, _ in out] for out in edges])
    # per-SCC cleaning
    internal: dict[int, list[frozenset]] = {}
    for q, out in enumerate(edges):
        for (j, _, _), mk in zip(out, marks[q]):
            if comp[j] == comp[q]:
                internal.setdefault(comp[q], []).append(mk)
    relevant: dict[int, tuple[int, ...]] = {}
    accepting_scc: dict[int, bool] = {}
    for c in set(comp):
        mks = internal.get(c, [])
        if not mks:
            relevant[c], accepting_scc[c] = (), False
            continue
        used = frozenset().union(*mks)
        if used != full:
            relevant[c], accepting_scc[c] = (), False
            continue
        everywhere = frozenset.intersection(*mks)
        relevant[c] = tuple(sorted(full - everywhere))
        accepting_scc[c] = True
    nba = _Nba()
    ids: dict[tuple[int, int], int] = {}

    def state(q: int, level: int) -> int:
        key = (q, level)
        s = ids.get(key)
        if s is None:
            c = comp[q]
            acc = accepting_scc[c] and level == len(relevant[c])
            s = ids[key] = nba.add_state(acc)
            todo.append(key)
        return s

    todo: list[tuple[int, int]] = []
    state(0, 0)
    while todo:
        q, level = todo.pop()
        src = ids[(q, level)]
        c = comp[q]
        rel = relevant[c]
        for (j, g, _), mk in zip(edges[q], marks[q]):
            if comp[j] != c:
                nl = 0
            else:
                nl = 0 if level == len(rel) else level
                while nl < len(rel) and rel[nl] in mk:
                    nl += 1
            nba.add_edge(src, state(j, nl), g)
    return nba


def exclusive_letters(n: int) -> tuple[int, ...]:
    """The letters over ``n`` propositions in which at most one holds: the empty letter, then
    ``{p_0}``, ..., ``{p_{n-1}}`` (as masks)."""
    return (0,) + tuple(1 << i for i in range(n))


def to_buchi(formula: FormulaLike, aps: Sequence[str] | None = None, *, exclusive: bool = False) -> Buchi:
    """Translate an LTL formula into a state-based Büchi automaton.

    Parameters
    ----------
    formula : str or Formula
        The mission, in FORMATS.md syntax.
    aps : sequence of str, optional
        Atomic propositions of the automaton, in order (e.g. every region name of a world).
        Must contain every proposition of the formula. Default: the formula's propositions
        in order of first appearance.
    exclusive : bool
        At most one proposition holds at a time (the regions of a world are disjoint discs):
        the automaton accepts exactly the words over those letters that satisfy ``formula``
        and has no edge for a letter with two or more propositions (step 0 of the module
        docstring). ``n + 1`` letters instead of ``2^n``: visiting 10 regions in any order
        translates in about half a second instead of about a minute.

    Returns
    -------
    Buchi
        Accepts exactly the words satisfying ``formula``. Its ``name`` is the formula as
        printed by :func:`tamp.ltl.to_string`. For an unsatisfiable formula: one state, no
        edges, no accepting state.

    Raises
    ------
    LtlSyntaxError
        If ``formula`` is a string that does not parse.
    ValueError
        If ``aps`` misses a proposition of the formula.

    Examples
    --------
    >>> b = to_buchi("G F a & G F b")
    >>> b.num_states, sorted(b.accepting)
    (3, [1])
    """
    f = parse(formula)
    order = _formula_aps_in_order(f)
    if aps is None:
        aps = order
    else:
        aps = list(aps)
        missing = [a for a in order if a not in aps]
        if missing:
            raise ValueError(f"aps {aps} miss the formula's propositions {missing}")
    ap_index = {a: i for i, a in enumerate(aps)}
    g = simplify(f)
    letters = exclusive_letters(len(aps)) if exclusive else range(1 << len(aps))
    tab = _Tableau(ap_index, from_minterms(letters, len(aps)) if exclusive else Bdd.true)
    if (is_cosafe(g) or is_safe(g)) and len(letters) <= 1 << EXPLICIT_ALPHABET_MAX_APS:
        nba = _obligation_automaton(tab, g, len(aps), cosafe=is_cosafe(g), letters=letters)
    else:
        nba = _degeneralized_automaton(tab, g)
    nba = _prune(nba)
    nba = _merge_bisimilar(nba)
    nba = _prune(nba)
    edges = tuple(
        tuple(Edge(guard, dst) for dst, guard in sorted(out.items())) for out in nba.succ
    )
    return Buchi(tuple(aps), 0, edges, frozenset(nba.accepting), name=str(f))
