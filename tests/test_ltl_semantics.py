"""Guarantees of tamp.ltl.semantics: ``evaluate`` is the exact LTL semantics on lasso words
(hand-checked cases, an independent naive evaluator, expansion laws and dualities on random
formulas, invariance under re-presenting the same word), and ``accepts`` is Büchi acceptance
(hand-built automata)."""

from __future__ import annotations

import doctest
import functools
import random

import pytest

import tamp.ltl.semantics as semantics
from tamp.errors import LtlSyntaxError
from tamp.ltl.automaton import Buchi, Edge
from tamp.ltl.bdd import Bdd
from tamp.ltl.formula import (
    FALSE,
    TRUE,
    Always,
    And,
    Eventually,
    Formula,
    Next,
    Not,
    Or,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
)
from tamp.ltl.semantics import accepts, evaluate
from tamp.ltl.syntax import parse

from .ltlgen import format_word, formula_sample, random_formula, random_word, word_sample

E = frozenset()
A, B, C = frozenset("a"), frozenset("b"), frozenset("c")
AB = frozenset("ab")


def test_doctests():
    result = doctest.testmod(semantics, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0


# ---------------------------------------------------------------------- hand-checked evaluate
# (formula, prefix, cycle, expected), each checked by hand on the infinite word.
HAND = [
    ("true", [], [E], True),
    ("false", [], [AB], False),
    ("a", [A], [E], True),
    ("a", [], [E, A], False),
    ("!a", [], [E], True),
    ("X a", [E], [A], True),
    ("X a", [], [A, E], False),
    ("X a", [], [E, A], True),
    ("X X X a", [], [A, E], False),  # a at 0, 2, 4, ...; position 3 is empty
    ("X X X a", [], [E, A], True),
    ("X X a", [E], [A, E], False),  # word: E A E A ...; position 2 is E
    ("X X X a", [E], [A, E], True),
    ("F a", [E, E, E], [E, A], True),
    ("F a", [A, A], [E], True),
    ("F a", [], [E, B], False),
    ("G a", [A], [A, A], True),
    ("G a", [A], [A, E], False),
    ("G a", [E], [A], False),
    ("G F a", [], [E, E, A], True),
    ("G F a", [A, A, A], [E], False),
    ("F G a", [E, E], [A], True),
    ("F G a", [], [A, A, E], False),
    ("F G !a", [A, A], [E], True),
    ("a U b", [A, A], [B], True),
    ("a U b", [B], [E], True),  # b at once
    ("a U b", [A, E], [B], False),  # a fails before b
    ("a U b", [], [A], False),  # b never comes
    ("a W b", [], [A], True),  # ... but weak until is fine with a forever
    ("a W b", [A, E], [B], False),
    ("a W b", [A, AB], [E], True),
    ("a R b", [], [B], True),  # b forever
    ("a R b", [B, AB], [E], True),  # a & b releases
    ("a R b", [B, A], [B], False),  # b fails at 1 before a release
    ("a R b", [B, B], [E], False),
    ("a M b", [], [B], False),  # strong release needs the release
    ("a M b", [B, AB], [E], True),
    ("a M b", [B, B], [AB], True),
    ("a M b", [B, A], [AB], False),
    ("a -> b", [E], [E], True),
    ("a -> b", [A], [E], False),
    ("a -> b", [AB], [E], True),
    ("a <-> b", [E], [A], True),
    ("a <-> b", [A], [A], False),
    ("a <-> b", [AB], [E], True),
    ("G(a -> F b)", [A, E, B], [E], True),
    ("G(a -> F b)", [A, B], [A, E], False),  # the a's in the cycle are never answered
    ("G(a -> F b)", [A], [B, A], True),
    ("G(a -> X b)", [], [A, B], True),
    ("G(a -> X b)", [], [A, E, B], False),
    ("!b U a", [E, E], [A, B], True),
    ("!b U a", [E, B], [A], False),
    ("!b U a", [AB], [E], True),
    ("F(a & F b)", [B, A], [E, E, B], True),
    ("F(a & F b)", [B, A], [E], False),
    ("F(a & X b)", [A, E, A], [B, E], True),
    ("G F a & G F b", [], [A, E, B], True),
    ("G F a & G F b", [AB], [A], False),
    ("G F a & G F b & G !c", [], [A, B], True),
    ("G F a & G F b & G !c", [C], [A, B], False),
    ("(a U b) U c", [A, B, A, B], [C], True),
    ("(a U b) U c", [A, E], [C], False),
    ("a U (b U c)", [A, A, B, B], [C], True),
    ("a U (b U c)", [A, B, A], [C], False),
    ("G(a U b)", [], [A, B], True),
    ("G(a U b)", [], [A, A, E, B], False),
    ("X G a", [E], [A], True),
    ("G X a", [E], [A], True),
    ("X F G a", [], [A, E], False),
]


@pytest.mark.parametrize(("text", "prefix", "cycle", "expected"), HAND,
                         ids=[f"{t}|{format_word(u, v)}" for t, u, v, _ in HAND])
def test_hand_checked(text, prefix, cycle, expected):
    assert evaluate(text, prefix, cycle) is expected
    assert evaluate(parse(text), prefix, cycle) is expected


def test_letter_forms():
    """Letters may be sets, frozensets, lists or tuples; unknown names are ignored."""
    assert evaluate("a & !b", [["a"]], [()])
    assert evaluate("a & !b", [("a", "zzz")], [set()])
    assert evaluate("G a", (), ({"a", "b"},))
    assert not evaluate("F c", [{"a"}], [["b"], ("a", "b")])


def test_empty_cycle_is_refused():
    with pytest.raises(ValueError, match="cycle .* must be non-empty"):
        evaluate("a", [{"a"}], [])
    with pytest.raises(ValueError, match="non-empty"):
        accepts(_gfa(), [{"a"}], [])


def test_string_letters_are_refused():
    with pytest.raises(TypeError, match="letter 1 of the prefix is the string 'ab'"):
        evaluate("a", [{"a"}, "ab"], [set()])
    with pytest.raises(TypeError, match="cycle must be a sequence"):
        evaluate("a", [], "a")
    with pytest.raises(TypeError, match="letter 0 of the cycle"):
        evaluate("a", [], [3])


def test_bad_formula_text():
    with pytest.raises(LtlSyntaxError):
        evaluate("a &", [], [set()])


# ---------------------------------------------------------------------- naive reference
def _reference(f: Formula, letters, loop: int) -> bool:
    """Direct recursive semantics: walk the infinite word, stopping after n+1 steps."""
    n = len(letters)

    def nxt(i):
        return i + 1 if i + 1 < n else loop

    @functools.lru_cache(maxsize=None)
    def sat(g: Formula, i: int) -> bool:
        op, args = g.op, g.args
        if op == "true":
            return True
        if op == "false":
            return False
        if op == "ap":
            return g.name in letters[i]
        if op == "!":
            return not sat(args[0], i)
        if op == "&":
            return all(sat(x, i) for x in args)
        if op == "|":
            return any(sat(x, i) for x in args)
        if op == "->":
            return not sat(args[0], i) or sat(args[1], i)
        if op == "<->":
            return sat(args[0], i) == sat(args[1], i)
        if op == "X":
            return sat(args[0], nxt(i))
        if op in ("F", "G"):
            j = i
            for _ in range(n + 1):
                if sat(args[0], j) != (op == "G"):
                    return op == "F"
                j = nxt(j)
            return op == "G"
        x, y = args
        j = i
        for _ in range(n + 1):  # n + 1 steps revisit a position: the rest repeats
            if op in ("U", "W"):
                if sat(y, j):
                    return True
                if not sat(x, j):
                    return False
            else:  # R, M
                if not sat(y, j):
                    return False
                if sat(x, j):
                    return True
            j = nxt(j)
        return op in ("W", "R")

    return sat(f, 0)


def test_matches_naive_reference():
    for k, f in formula_sample(11, 0, 400):
        for u, v in word_sample(11, k, 25):
            expected = _reference(f, [frozenset(x) for x in u + v], len(u))
            assert evaluate(f, u, v) == expected, (
                f"formula {k} of seed 11: {f}  word: {format_word(u, v)}  naive: {expected}"
            )


# ---------------------------------------------------------------------- laws on random formulas
def _pairs(seed, count):
    """Random pairs of subformula-sized formulas (sizes up to 7 so laws stay size <= 15)."""
    rng = random.Random(f"pairs-{seed}")
    return [(random_formula(rng, 7), random_formula(rng, 7)) for _ in range(count)]


def _words(seed, count):
    rng = random.Random(f"law-words-{seed}")
    return [random_word(rng) for _ in range(count)]


LAWS = {
    "negation": lambda f, g: (Not(f), None),
    "until expansion": lambda f, g: (Until(f, g), Or(g, And(f, Next(Until(f, g))))),
    "release expansion": lambda f, g: (Release(f, g), And(g, Or(f, Next(Release(f, g))))),
    "release is dual of until": lambda f, g: (Release(f, g), Not(Until(Not(f), Not(g)))),
    "weak until": lambda f, g: (WeakUntil(f, g), Or(Until(f, g), Always(f))),
    "weak until as release": lambda f, g: (WeakUntil(f, g), Release(g, Or(f, g))),
    "strong release": lambda f, g: (StrongRelease(f, g), Until(g, And(f, g))),
    "strong release is dual of weak until": lambda f, g: (
        StrongRelease(f, g), Not(WeakUntil(Not(f), Not(g)))),
    "eventually": lambda f, g: (Eventually(f), Until(TRUE, f)),
    "always": lambda f, g: (Always(f), Release(FALSE, f)),
    "always is dual of eventually": lambda f, g: (Always(f), Not(Eventually(Not(f)))),
    "next is self-dual": lambda f, g: (Next(Not(f)), Not(Next(f))),
    "implication": lambda f, g: (Formula("->", (f, g)), Or(Not(f), g)),
    "equivalence": lambda f, g: (Formula("<->", (f, g)), Or(And(f, g), And(Not(f), Not(g)))),
    "de morgan": lambda f, g: (Not(And(f, g)), Or(Not(f), Not(g))),
    "until absorbs eventually": lambda f, g: (Eventually(Until(f, g)), Eventually(g)),
    "idempotent GF": lambda f, g: (
        Always(Eventually(Always(Eventually(f)))), Always(Eventually(f))),
}


@pytest.mark.parametrize("law", list(LAWS))
def test_laws_on_random_formulas(law):
    build = LAWS[law]
    words = _words(law, 20)
    for f, g in _pairs(law, 150):
        left, right = build(f, g)
        for u, v in words:
            lhs = evaluate(left, u, v)
            rhs = (not evaluate(f, u, v)) if right is None else evaluate(right, u, v)
            assert lhs == rhs, f"{law}: {left} vs {right or f'!({f})'} on {format_word(u, v)}"


def test_same_word_different_lasso():
    """u v^omega = (u v) v^omega = u (v v)^omega = (u v0) (v1..vk v0)^omega."""
    for k, f in formula_sample(13, 0, 300):
        for u, v in word_sample(13, k, 10):
            value = evaluate(f, u, v)
            assert evaluate(f, u + v, v) == value, f"{f} on {format_word(u, v)}"
            assert evaluate(f, u, v + v) == value, f"{f} on {format_word(u, v)}"
            assert evaluate(f, u + v[:1], v[1:] + v[:1]) == value, f"{f} on {format_word(u, v)}"


def test_next_shifts_the_word():
    for k, f in formula_sample(17, 0, 300):
        for u, v in word_sample(17, k, 10):
            shifted = (u[1:], v) if u else ([], v[1:] + v[:1])
            assert evaluate(Next(f), u, v) == evaluate(f, *shifted), (
                f"X({f}) on {format_word(u, v)}")


# ---------------------------------------------------------------------- accepts
TT = Bdd.true
_a, _b = Bdd.var(0), Bdd.var(1)


def _gfa() -> Buchi:
    """G F a, deterministic: state 1 means "just read a" and is accepting."""
    out = (Edge(_a, 1), Edge(~_a, 0))
    return Buchi(("a",), 0, (out, out), frozenset({1}), "G F a")


def _fga() -> Buchi:
    """F G a, nondeterministic: guess in state 0 when a holds forever, then stay in 1 on a."""
    return Buchi(("a",), 0, ((Edge(TT, 0), Edge(_a, 1)), (Edge(_a, 1),)), frozenset({1}), "F G a")


def _a_until_b() -> Buchi:
    """a U b over aps (a, b): 0 --a & !b--> 0, 0 --b--> 1, 1 --true--> 1 (accepting)."""
    return Buchi(("a", "b"), 0, ((Edge(_a & ~_b, 0), Edge(_b, 1)), (Edge(TT, 1),)),
                 frozenset({1}), "a U b")


def _gfa_and_gfb() -> Buchi:
    """G F a & G F b, degeneralised: 0 waits for a, 1 waits for b, 2 (accepting) completes."""
    aut_edges = (
        (Edge(_a & _b, 2), Edge(_a & ~_b, 1), Edge(~_a, 0)),
        (Edge(_b, 2), Edge(~_b, 1)),
        (Edge(_a & _b, 2), Edge(_a & ~_b, 1), Edge(~_a, 0)),
    )
    return Buchi(("a", "b"), 0, aut_edges, frozenset({2}), "G F a & G F b")


HAND_AUTOMATA = {"G F a": _gfa, "F G a": _fga, "a U b": _a_until_b, "G F a & G F b": _gfa_and_gfb}


@pytest.mark.parametrize(("prefix", "cycle", "expected"), [
    ([], [A], True),
    ([], [E, A], True),
    ([A, A, A], [E], False),
    ([E], [E, E, AB], True),
    ([], [B], False),
    ([{"a", "zzz"}], [{"zzz"}, {"a"}], True),
])
def test_accepts_gfa(prefix, cycle, expected):
    assert accepts(_gfa(), prefix, cycle) is expected


@pytest.mark.parametrize(("prefix", "cycle", "expected"), [
    ([], [A], True),
    ([E, E, B], [A], True),
    ([], [A, E], False),
    ([A, A], [A, A, E], False),
    ([], [E], False),
])
def test_accepts_fga(prefix, cycle, expected):
    assert accepts(_fga(), prefix, cycle) is expected


@pytest.mark.parametrize(("name", "make"), list(HAND_AUTOMATA.items()))
def test_accepts_agrees_with_evaluate_on_hand_automata(name, make):
    aut = make()
    rng = random.Random(f"hand-automaton-{name}")
    for _ in range(500):
        u, v = random_word(rng, ("a", "b", "c"))
        assert accepts(aut, u, v) == evaluate(name, u, v), f"{name} on {format_word(u, v)}"


def test_accepting_state_off_every_cycle_does_not_accept():
    """The accepting state 0 is visited once, never again: rejected."""
    aut = Buchi(("a",), 0, ((Edge(TT, 1),), (Edge(TT, 1),)), frozenset({0}))
    assert not accepts(aut, [], [A])
    assert not accepts(aut, [A, A], [E, A])


def test_accepting_cycle_not_reachable_with_this_word():
    """The accepting loop exists but the word leaves it: 0 --a--> 0 only."""
    aut = Buchi(("a",), 0, ((Edge(_a, 0),),), frozenset({0}))
    assert accepts(aut, [A], [A])
    assert not accepts(aut, [A], [A, E])  # the run dies at the empty letter
    assert not accepts(aut, [E], [A])


def test_cycle_through_accepting_state_in_a_larger_component():
    """The accepting state sits on a three-state cycle that the word follows."""
    aut = Buchi(("a", "b"), 0, (
        (Edge(_a, 1),),
        (Edge(_b, 2),),
        (Edge(~_a & ~_b, 0),),
    ), frozenset({1}))
    assert accepts(aut, [], [A, B, E])
    assert not accepts(aut, [], [A, B, A])
    assert accepts(aut, [A, B, E, A, B, E], [A, B, E])  # prefix + rotated cycle
    assert accepts(aut, [A], [B, E, A])


def test_no_accepting_state_accepts_nothing():
    aut = Buchi(("a",), 0, ((Edge(TT, 0),),), frozenset())
    assert not accepts(aut, [], [A])


def test_accepts_letters_without_propositions():
    """An automaton over no propositions reads every letter as the empty valuation."""
    aut = Buchi((), 0, ((Edge(TT, 0),),), frozenset({0}), "true")
    assert accepts(aut, [{"x"}], [{"y"}, set()])


def test_public_names():
    import tamp.ltl

    assert tamp.ltl.evaluate is evaluate and tamp.ltl.accepts is accepts
    assert set(semantics.__all__) >= {"evaluate", "accepts"}
