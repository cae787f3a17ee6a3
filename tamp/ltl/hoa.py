"""HOA v1 (Hanoi Omega-Automata format) output and input for :class:`~tamp.ltl.automaton.Buchi`.

Format reference: https://adl.github.io/hoaf/ (version 1).

Output (:func:`to_hoa`) is a state-based Büchi automaton with explicit transition labels
printed as DNF over AP indices, one ``Start:`` state and ``Acceptance: 1 Inf(0)``. The text is a
pure function of the automaton (same automaton, same bytes).

Input (:func:`from_hoa`) reads what LTL tools such as Spot, ltl2ba or Owl print for
(generalized) Büchi automata:

* state-based and/or transition-based acceptance marks (``State: 0 {0}``, ``[0] 1 {0 1}``);
* any positive Boolean combination of ``Inf(i)`` as acceptance condition (generalized Büchi
  ``Inf(0)&Inf(1)&...``, ``Inf(0)|Inf(1)``), ``t`` (every run accepts) and ``f`` (none does);
* several ``Start:`` lines (a fresh initial state is added), ``States:`` omitted;
* explicit labels over AP indices with ``t``, ``f``, ``!``, ``&``, ``|``, parentheses and
  ``@aliases``; state labels ``State: [label] n`` (applied to the unlabelled outgoing edges);
* state names, nested ``/* comments */``, header items in any order, unknown header items whose
  name starts with a lower-case letter (ignored, as the format allows).

The result is the state-based :class:`Buchi` with exactly the same language: generalized and
transition-based acceptance is *degeneralized* with a level counter (states ``(q, level)``,
created only when reachable). An automaton whose acceptance already is state-based with a
single ``Inf`` set, or ``t``/``f``, keeps its states and numbering, so
``from_hoa(to_hoa(b))`` gives back ``b`` (same states, edges, accepting set, APs and name).

Refused with :class:`~tamp.errors.HoaError` naming the line: other acceptance conditions
(``Fin``, ``Inf(!i)``: co-Büchi, Rabin, Streett, parity...), universal branching (``&`` in
``Start:`` or in an edge's destination), implicit labels (an edge without label in a state
without label), unknown header items starting with an upper-case letter, missing
``--BODY--``/``--END--``, ``--ABORT--``, undeclared states, APs, aliases or acceptance sets,
and any syntax error.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from ..errors import HoaError
from .automaton import Buchi, Edge
from .bdd import Bdd

__all__ = ["to_hoa", "from_hoa"]

TOOL = "harmonic-tamp"


# ============================================================================================
# Output
# ============================================================================================
def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _is_deterministic(buchi: Buchi) -> bool:
    for out in buchi.edges:
        seen = Bdd.false
        for e in out:
            if e.guard.intersects(seen):
                return False
            seen = seen | e.guard
    return True


def _is_complete(buchi: Buchi) -> bool:
    for out in buchi.edges:
        covered = Bdd.false
        for e in out:
            covered = covered | e.guard
        if not covered.is_true:
            return False
    return True


def to_hoa(buchi: Buchi) -> str:
    """Print ``buchi`` in HOA v1.

    Parameters
    ----------
    buchi : Buchi

    Returns
    -------
    str
        HOA text ending with ``--END--`` and a newline. Guards are printed as an irredundant
        DNF over AP indices (``t`` for true); edges with a false guard are left out. The
        ``deterministic`` and ``complete`` properties are stated only when they hold.

    Examples
    --------
    >>> from tamp.ltl.automaton import Buchi, Edge
    >>> b = Buchi(("a",), 0, ((Edge(Bdd.var(0), 0), Edge(~Bdd.var(0), 0)),), frozenset({0}), "G F a")
    >>> print(to_hoa(b), end="")
    HOA: v1
    name: "G F a"
    States: 1
    Start: 0
    AP: 1 "a"
    acc-name: Buchi
    Acceptance: 1 Inf(0)
    properties: trans-labels explicit-labels state-acc deterministic complete
    tool: "harmonic-tamp"
    --BODY--
    State: 0 {0}
    [0] 0
    [!0] 0
    --END--
    """
    props = ["trans-labels", "explicit-labels", "state-acc"]
    if _is_deterministic(buchi):
        props.append("deterministic")
    if _is_complete(buchi):
        props.append("complete")
    lines = ["HOA: v1"]
    if buchi.name:
        lines.append(f"name: {_quote(buchi.name)}")
    lines.append(f"States: {buchi.num_states}")
    lines.append(f"Start: {buchi.initial}")
    lines.append(" ".join([f"AP: {len(buchi.aps)}"] + [_quote(a) for a in buchi.aps]))
    lines.append("acc-name: Buchi")
    lines.append("Acceptance: 1 Inf(0)")
    lines.append("properties: " + " ".join(props))
    lines.append(f"tool: {_quote(TOOL)}")
    lines.append("--BODY--")
    for q, out in enumerate(buchi.edges):
        lines.append(f"State: {q} {{0}}" if q in buchi.accepting else f"State: {q}")
        for e in out:
            if e.guard.is_false:
                continue
            lines.append(f"[{e.guard.to_str(true='t', false='f')}] {e.dst}")
    lines.append("--END--")
    return "\n".join(lines) + "\n"


# ============================================================================================
# Input: tokens
# ============================================================================================
_TOKEN = re.compile(
    r"""
    (?P<string>"(?:[^"\\]|\\.)*")
  | (?P<section>--(?:BODY|END|ABORT)--)
  | (?P<header>[A-Za-z_][0-9A-Za-z_-]*:)
  | (?P<ident>[A-Za-z_][0-9A-Za-z_-]*(?:\.[0-9]+)*)
  | (?P<int>[0-9]+)
  | (?P<alias>@[0-9A-Za-z_-]+)
  | (?P<punct>[\[\]{}()!&|])
    """,
    re.VERBOSE | re.DOTALL,
)


class _Tok:
    __slots__ = ("kind", "value", "line")

    def __init__(self, kind: str, value: str, line: int):
        self.kind = kind
        self.value = value
        self.line = line

    def show(self) -> str:
        if self.kind == "eof":
            return "the end of the text"
        return repr(self.value)


def _tokenize(text: str) -> list[_Tok]:
    """HOA tokens with their 1-based line; comments ``/* */`` (nestable) and blanks skipped."""
    out: list[_Tok] = []
    pos, line, n = 0, 1, len(text)
    while pos < n:
        ch = text[pos]
        if ch == "\n":
            line += 1
            pos += 1
            continue
        if ch.isspace():
            pos += 1
            continue
        if text.startswith("/*", pos):
            start_line, depth = line, 0
            while True:
                if pos >= n:
                    raise HoaError("unterminated comment '/*'", start_line)
                if text.startswith("/*", pos):
                    depth += 1
                    pos += 2
                elif text.startswith("*/", pos):
                    depth -= 1
                    pos += 2
                    if depth == 0:
                        break
                else:
                    if text[pos] == "\n":
                        line += 1
                    pos += 1
            continue
        m = _TOKEN.match(text, pos)
        if m is None:
            if ch == '"':
                raise HoaError("unterminated string", line)
            raise HoaError(f"unexpected character {ch!r}", line)
        kind = m.lastgroup
        value = m.group(kind)
        out.append(_Tok(kind, value, line))
        line += value.count("\n")
        pos = m.end()
    out.append(_Tok("eof", "", out[-1].line if out else 1))  # the last line with content
    return out


def _unquote(s: str) -> str:
    return re.sub(r"\\(.)", r"\1", s[1:-1], flags=re.DOTALL)


# ============================================================================================
# Input: parser
# ============================================================================================
_KNOWN_HEADERS = {"HOA", "States", "Start", "AP", "Alias", "Acceptance", "acc-name", "tool",
                  "name", "properties", "controllable-AP"}
_ONCE = {"States", "AP", "Acceptance", "name"}
_UNSUPPORTED_ACC = (
    "only (generalized) Büchi acceptance is supported: a positive combination of Inf(i) "
    "such as 'Inf(0)&Inf(1)', or 't' / 'f'"
)


#: Deepest parenthesis nesting of a label or the acceptance condition (the parser recurses on
#: each; 5000 raised ``RecursionError``). Negations are counted, not recursed.
MAX_NESTING = 100


class _Parser:
    def __init__(self, text: str):
        self.toks = _tokenize(text)
        self.i = 0
        self.depth = 0
        # header
        self.name = ""
        self.num_states: int | None = None
        self.starts: list[tuple[int, int]] = []  # (state, line)
        self.aps: tuple[str, ...] | None = None
        self.aliases: dict[str, Bdd] = {}
        self.acc_sets: int | None = None
        self.acc_cond = None
        self.acc_line = 0
        self.header_ap_uses: list[tuple[int, int]] = []  # (ap index, line) seen before AP:
        # body
        self.state_line: dict[int, int] = {}
        self.state_marks: dict[int, frozenset[int]] = {}
        self.edges: dict[int, list[tuple[Bdd, int, frozenset[int]]]] = {}
        self.dst_refs: list[tuple[int, int]] = []  # (state, line)
        self.mark_refs: list[tuple[int, int]] = []  # (set, line)

    # ---- token helpers ---------------------------------------------------------------------
    def peek(self) -> _Tok:
        return self.toks[self.i]

    def take(self) -> _Tok:
        t = self.toks[self.i]
        if t.kind != "eof":
            self.i += 1
        return t

    def fail(self, message: str, tok: _Tok | None = None):
        raise HoaError(message, (tok or self.peek()).line)

    def nest(self, tok: _Tok) -> None:
        """Enter one parenthesis level (the caller leaves it with ``self.depth -= 1``)."""
        self.depth += 1
        if self.depth > MAX_NESTING:
            self.fail(f"parentheses nested deeper than {MAX_NESTING} levels", tok)

    def expect_int(self, what: str) -> tuple[int, _Tok]:
        t = self.take()
        if t.kind != "int":
            self.fail(f"expected {what} (a non-negative integer), found {t.show()}", t)
        return int(t.value), t

    def expect_punct(self, p: str, context: str) -> _Tok:
        t = self.take()
        if t.kind != "punct" or t.value != p:
            self.fail(f"expected {p!r} {context}, found {t.show()}", t)
        return t

    def at_punct(self, p: str) -> bool:
        t = self.peek()
        return t.kind == "punct" and t.value == p

    # ---- whole automaton -------------------------------------------------------------------
    def parse(self):
        self.header()
        self.body()
        t = self.peek()
        if t.kind != "eof":
            self.fail(f"unexpected {t.show()} after --END-- (one automaton per text)", t)

    # ---- header ----------------------------------------------------------------------------
    def header(self):
        t = self.take()
        if t.kind != "header" or t.value != "HOA:":
            self.fail(f"expected 'HOA: v1' at the start of the automaton, found {t.show()}", t)
        v = self.take()
        if v.kind != "ident" or not re.fullmatch(r"v1(\.[0-9]+)*", v.value):
            self.fail(f"unsupported HOA version {v.show()}; expected v1", v)
        seen: dict[str, int] = {}
        while True:
            t = self.peek()
            if t.kind == "section":
                if t.value == "--BODY--":
                    break
                if t.value == "--ABORT--":
                    self.fail("the automaton was aborted (--ABORT--)", t)
                self.fail(f"missing --BODY-- before {t.value}", t)
            if t.kind == "eof":
                self.fail("missing --BODY-- (the text ends inside the header)", t)
            if t.kind != "header":
                self.fail(f"unexpected {t.show()} in the header; expected a header item such as "
                          "'States:'", t)
            self.take()
            item = t.value[:-1]
            if item in _ONCE and item in seen:
                self.fail(f"header item '{item}:' given twice (first on line {seen[item]})", t)
            seen.setdefault(item, t.line)
            if item == "HOA":
                self.fail("'HOA:' inside the header (several automata are not supported)", t)
            elif item == "States":
                self.num_states, _ = self.expect_int("the number of states after 'States:'")
            elif item == "Start":
                self.starts.append(self.state_conj("Start:", t))
            elif item == "AP":
                self.ap_item(t)
            elif item == "Alias":
                a = self.take()
                if a.kind != "alias":
                    self.fail(f"expected an alias name such as '@a' after 'Alias:', found "
                              f"{a.show()}", a)
                if a.value in self.aliases:
                    self.fail(f"alias {a.value} is defined twice", a)
                self.aliases[a.value] = self.label_expr()
            elif item == "Acceptance":
                self.acc_line = t.line
                self.acc_sets, _ = self.expect_int("the number of acceptance sets after "
                                                   "'Acceptance:'")
                self.acc_cond = self.acc_or()
            elif item == "name":
                s = self.take()
                if s.kind != "string":
                    self.fail(f"expected a quoted string after 'name:', found {s.show()}", s)
                self.name = _unquote(s.value)
            elif item in _KNOWN_HEADERS or item[0].islower() or item[0] == "_":
                self.skip_values()
            else:
                self.fail(f"unsupported header item '{item}:' (items starting with an upper-case "
                          "letter may change the meaning of the automaton)", t)
            nxt = self.peek()
            if nxt.kind not in ("header", "section", "eof"):
                self.fail(f"unexpected {nxt.show()} after the '{item}:' item", nxt)
        if self.acc_cond is None:
            self.fail("missing 'Acceptance:' header item (required by HOA)", self.peek())
        nap = len(self.aps) if self.aps is not None else 0
        for i, line in self.header_ap_uses:
            if i >= nap:
                raise HoaError(f"AP index {i} is not declared (AP: {nap})", line)
        if self.aps is None:
            self.aps = ()

    def skip_values(self):
        while self.peek().kind not in ("header", "section", "eof"):
            self.take()

    def ap_item(self, head: _Tok):
        n, _ = self.expect_int("the number of atomic propositions after 'AP:'")
        names: list[str] = []
        while self.peek().kind == "string":
            names.append(_unquote(self.take().value))
        if len(names) != n:
            self.fail(f"'AP: {n}' announces {n} proposition(s) but lists {len(names)}", head)
        dup = sorted({a for a in names if names.count(a) > 1})
        if dup:
            self.fail(f"duplicate atomic proposition(s) {', '.join(map(repr, dup))}", head)
        self.aps = tuple(names)

    def state_conj(self, context: str, head: _Tok) -> tuple[int, int]:
        q, t = self.expect_int(f"a state number after {context!r}")
        if self.at_punct("&"):
            self.fail(f"universal branching ('&' between states in {context!r}) is not "
                      "supported: only nondeterministic automata can be read", self.peek())
        return q, t.line

    # ---- acceptance condition --------------------------------------------------------------
    def acc_or(self):
        items = [self.acc_and()]
        while self.at_punct("|"):
            self.take()
            items.append(self.acc_and())
        return items[0] if len(items) == 1 else ("|", items)

    def acc_and(self):
        items = [self.acc_atom()]
        while self.at_punct("&"):
            self.take()
            items.append(self.acc_atom())
        return items[0] if len(items) == 1 else ("&", items)

    def acc_atom(self):
        t = self.take()
        if t.kind == "punct" and t.value == "(":
            self.nest(t)
            inner = self.acc_or()
            self.expect_punct(")", "to close '(' in the acceptance condition")
            self.depth -= 1
            return inner
        if t.kind == "ident" and t.value in ("t", "f"):
            return (t.value,)
        if t.kind == "ident" and t.value in ("Inf", "Fin"):
            self.expect_punct("(", f"after {t.value}")
            neg = False
            if self.at_punct("!"):
                self.take()
                neg = True
            i, it = self.expect_int("an acceptance set number")
            self.expect_punct(")", f"to close {t.value}(")
            if t.value == "Fin" or neg:
                txt = f"{t.value}({'!' if neg else ''}{i})"
                self.fail(f"acceptance condition with {txt} is not supported; {_UNSUPPORTED_ACC}",
                          t)
            if self.acc_sets is not None and i >= self.acc_sets:
                self.fail(f"acceptance set {i} is not declared ('Acceptance: {self.acc_sets}' "
                          f"declares sets 0..{self.acc_sets - 1})", it)
            return ("Inf", i)
        self.fail(f"expected Inf(i), Fin(i), t, f or '(' in the acceptance condition, found "
                  f"{t.show()}", t)

    # ---- labels ----------------------------------------------------------------------------
    def label_expr(self) -> Bdd:
        g = self.label_and()
        while self.at_punct("|"):
            self.take()
            g = g | self.label_and()
        return g

    def label_and(self) -> Bdd:
        g = self.label_not()
        while self.at_punct("&"):
            self.take()
            g = g & self.label_not()
        return g

    def label_not(self) -> Bdd:
        negations = 0
        while self.at_punct("!"):
            self.take()
            negations += 1
        g = self.label_atom()
        return ~g if negations % 2 else g

    def label_atom(self) -> Bdd:
        t = self.take()
        if t.kind == "int":
            i = int(t.value)
            if self.aps is None:
                self.header_ap_uses.append((i, t.line))
            elif i >= len(self.aps):
                self.fail(f"AP index {i} is not declared (AP: {len(self.aps)})", t)
            return Bdd.var(i)
        if t.kind == "ident" and t.value == "t":
            return Bdd.true
        if t.kind == "ident" and t.value == "f":
            return Bdd.false
        if t.kind == "alias":
            g = self.aliases.get(t.value)
            if g is None:
                self.fail(f"alias {t.value} is not defined (define it with 'Alias:' in the "
                          "header, before its use)", t)
            return g
        if t.kind == "punct" and t.value == "(":
            self.nest(t)
            g = self.label_expr()
            self.expect_punct(")", "to close '(' in the label")
            self.depth -= 1
            return g
        self.fail(f"expected an AP index, t, f, an @alias, '!' or '(' in the label, found "
                  f"{t.show()}", t)

    def bracket_label(self) -> Bdd:
        self.expect_punct("[", "to open a label")
        g = self.label_expr()
        self.expect_punct("]", "to close the label")
        return g

    def acc_sig(self) -> frozenset[int]:
        if not self.at_punct("{"):
            return frozenset()
        self.take()
        marks = set()
        while self.peek().kind == "int":
            t = self.take()
            marks.add(int(t.value))
            self.mark_refs.append((int(t.value), t.line))
        self.expect_punct("}", "to close the acceptance marks")
        return frozenset(marks)

    # ---- body ------------------------------------------------------------------------------
    def body(self):
        self.take()  # --BODY--
        state: int | None = None
        state_label: Bdd | None = None
        while True:
            t = self.peek()
            if t.kind == "eof":
                self.fail("missing --END-- at the end of the automaton", t)
            if t.kind == "section":
                if t.value == "--END--":
                    self.take()
                    return
                if t.value == "--ABORT--":
                    self.fail("the automaton was aborted (--ABORT--)", t)
                self.fail(f"unexpected {t.value} in the body", t)
            if t.kind == "header":
                if t.value != "State:":
                    self.fail(f"unexpected {t.show()} in the body; expected 'State:' or an edge", t)
                self.take()
                state_label = self.bracket_label() if self.at_punct("[") else None
                state, st = self.expect_int("a state number after 'State:'")
                if state in self.state_line:
                    self.fail(f"state {state} is defined twice (first on line "
                              f"{self.state_line[state]})", st)
                if self.num_states is not None and state >= self.num_states:
                    self.fail(f"state {state} is not declared ('States: {self.num_states}' "
                              f"declares states 0..{self.num_states - 1})", st)
                self.state_line[state] = st.line
                if self.peek().kind == "string":
                    self.take()  # state name: informative only
                self.state_marks[state] = self.acc_sig()
                self.edges[state] = []
                continue
            if state is None:
                self.fail(f"expected 'State:' after --BODY--, found {t.show()}", t)
            # an edge
            if self.at_punct("["):
                if state_label is not None:
                    self.fail(f"edge with a label in state {state}, which already has a state "
                              "label (use one or the other)", t)
                guard = self.bracket_label()
            elif state_label is not None:
                guard = state_label
            else:
                self.fail(f"edge without label in state {state}: implicit labels are not "
                          "supported; write explicit labels such as '[0 & !1] 2'", t)
            dst, line = self.state_conj("the destination of an edge", t)
            self.dst_refs.append((dst, line))
            marks = self.acc_sig()
            self.edges[state].append((guard, dst, marks))


# ============================================================================================
# Input: acceptance condition -> generalized Büchi sets
# ============================================================================================
def _cnf(cond) -> list[frozenset[int]]:
    """Positive condition over Inf atoms as a conjunction of clauses; clause = union of sets.

    ``Inf(A) | Inf(B) == Inf(A u B)``, so every clause is one generalized-Büchi set of marks.
    ``[]`` is true; a clause ``frozenset()`` is false.
    """
    op = cond[0]
    if op == "t":
        return []
    if op == "f":
        return [frozenset()]
    if op == "Inf":
        return [frozenset((cond[1],))]
    if op == "&":
        out: list[frozenset[int]] = []
        for c in cond[1]:
            out.extend(_cnf(c))
        return out
    # "|": distribute
    acc: list[frozenset[int]] = [frozenset()]
    first = True
    for c in cond[1]:
        sub = _cnf(c)
        if not sub:  # ... | t
            return []
        acc = sub if first else [a | b for a in acc for b in sub]
        first = False
    return acc


def _simplify(clauses: list[frozenset[int]]) -> list[frozenset[int]]:
    """Remove duplicate clauses and clauses implied by a smaller one; stable order."""
    uniq = list(dict.fromkeys(clauses))
    return [c for c in uniq if not any(o < c for o in uniq)]


# ============================================================================================
# Input: build the state-based Büchi automaton
# ============================================================================================
def _merge(pairs: Iterable[tuple[Bdd, int]]) -> tuple[Edge, ...]:
    """One edge per destination (guards or-ed), first-seen order, false guards dropped."""
    by_dst: dict[int, Bdd] = {}
    for g, d in pairs:
        if g.is_false:
            continue
        by_dst[d] = by_dst[d] | g if d in by_dst else g
    return tuple(Edge(g, d) for d, g in by_dst.items())


def from_hoa(text: str) -> Buchi:
    """Read one automaton in HOA v1 and return the equivalent state-based Büchi automaton.

    Parameters
    ----------
    text : str
        HOA v1 text of one (generalized) Büchi automaton, state- or transition-based, with
        explicit labels (see the module docstring for what is accepted and refused).

    Returns
    -------
    Buchi
        Same language as the input. Its ``name`` is the ``name:`` header item (or ``""``).
        When the input is already state-based Büchi (one ``Inf`` set, or ``t``/``f``) with
        one initial state, states keep their numbers; otherwise the generalized or
        transition-based acceptance is degeneralized (reachable ``(state, level)`` pairs,
        numbered breadth-first from the initial state), and several initial states get a
        fresh initial state.

    Raises
    ------
    HoaError
        With ``line`` set to the offending line (1-based) and a message saying what is wrong.

    Examples
    --------
    >>> b = from_hoa('''HOA: v1 States: 1 Start: 0 AP: 2 "a" "b"
    ... Acceptance: 2 Inf(0)&Inf(1)
    ... --BODY-- State: 0 [0&!1] 0 {0} [!0&1] 0 {1} [0&1] 0 {0 1} [!0&!1] 0 --END--''')
    >>> b.num_states, sorted(b.accepting)
    (3, [2])
    """
    if not isinstance(text, str):
        raise TypeError(f"from_hoa expects HOA text as str, got {type(text).__name__}")
    p = _Parser(text)
    p.parse()
    aps = p.aps if p.aps is not None else ()

    # states: declared count, or everything the text mentions
    mentioned = set(p.state_line) | {q for q, _ in p.dst_refs} | {q for q, _ in p.starts}
    if p.num_states is not None:
        n = p.num_states
        for q, line in p.dst_refs + p.starts:
            if q >= n:
                raise HoaError(f"state {q} is not declared ('States: {n}' declares states "
                               f"0..{n - 1})" if n else f"state {q} is not declared (States: 0)",
                               line)
    else:
        n = max(mentioned) + 1 if mentioned else 0
    nsets = p.acc_sets or 0
    for m, line in p.mark_refs:
        if m >= nsets:
            raise HoaError(f"acceptance set {m} is not declared ('Acceptance: {nsets}' declares "
                           + (f"sets 0..{nsets - 1})" if nsets else "no set)"), line)

    clauses = _simplify(_cnf(p.acc_cond))
    empty = any(not c for c in clauses)  # condition f: no run accepts
    # out[q] = [(guard, dst, marks)] with state marks folded into the edges
    out = [
        [(g, d, m | p.state_marks.get(q, frozenset())) for g, d, m in p.edges.get(q, [])]
        for q in range(n)
    ]
    starts = list(dict.fromkeys(q for q, _ in p.starts))

    direct_acc: set[int] | None = None
    if empty:
        direct_acc = set()
    elif not clauses:
        direct_acc = set(range(n))
    elif len(clauses) == 1:
        (c,) = clauses
        direct_acc = set()
        for q in range(n):
            hits = {bool(m & c) for _, _, m in out[q]}
            if len(hits) > 1:
                direct_acc = None  # transition-based within a state: degeneralize
                break
            if hits == {True} or p.state_marks.get(q, frozenset()) & c:
                direct_acc.add(q)

    if direct_acc is not None:
        edges = [_merge((g, d) for g, d, _ in out[q]) for q in range(n)]
        if len(starts) == 1:
            initial = starts[0]
        else:  # none or several initial states: a fresh, non-accepting initial state
            initial = len(edges)
            edges.append(_merge((g, d) for s in starts for g, d, _ in out[s]))
        return Buchi(aps, initial, tuple(edges), frozenset(direct_acc), p.name)
    return _degeneralize(aps, out, starts, clauses, p.name)


def _degeneralize(aps, out, starts, clauses, name) -> Buchi:
    """Transition-based generalized Büchi -> state-based Büchi (level counter).

    State ``(q, l)``, ``0 <= l <= k``: the sets ``clauses[0..l-1]`` were seen, in order, since
    the last visit to level ``k``. Taking an edge with marks ``M`` from level ``l`` (restarted
    at 0 when ``l == k``) advances the level over every next set that ``M`` hits. Level ``k``
    states are accepting: reached infinitely often iff every set is hit infinitely often.
    """
    k = len(clauses)

    def advance(level: int, marks: frozenset[int]) -> int:
        lv = 0 if level == k else level
        while lv < k and marks & clauses[lv]:
            lv += 1
        return lv

    index: dict[tuple[int, int], int] = {}
    order: list[tuple[int, int]] = []

    def node(pair: tuple[int, int]) -> int:
        i = index.get(pair)
        if i is None:
            i = index[pair] = len(order)
            order.append(pair)
        return i

    if len(starts) == 1:
        node((starts[0], 0))
    else:  # none or several initial states: a fresh, non-accepting initial state
        order.append((-1, -1))
    edges: list[tuple[Edge, ...]] = []
    i = 0
    while i < len(order):
        q, lv = order[i]
        if q < 0:
            succ = [(g, node((d, advance(0, m)))) for s in starts for g, d, m in out[s]]
        else:
            succ = [(g, node((d, advance(lv, m)))) for g, d, m in out[q]]
        edges.append(_merge(succ))
        i += 1
    accepting = frozenset(j for j, (q, lv) in enumerate(order) if q >= 0 and lv == k)
    return Buchi(aps, 0, tuple(edges), accepting, name)
