"""Guarantees of tamp.ltl.to_buchi: the automaton accepts a lasso word exactly when the word
satisfies the formula (randomised against the exact oracle :func:`tamp.ltl.semantics.evaluate`,
and on a hand-checked suite of robot-mission patterns), the automata meet the size targets of
issue 3, and unsatisfiable formulas give automata with no accepting state.

The default run checks :data:`DEFAULT_FORMULAS` random formulas x :data:`WORDS` words; the
``slow`` run (``python -m pytest -m slow``) checks :data:`SLOW_FORMULAS` x :data:`WORDS`.
A failure names the formula's seed and index (replay with ``tests.ltlgen.formula_at``).
"""

from __future__ import annotations

import functools
import json

import pytest

from tamp.ltl import to_buchi
from tamp.ltl.formula import Formula
from tamp.ltl.semantics import accepts, evaluate
from tamp.ltl.syntax import parse

from .conftest import world_file
from .ltlgen import APS, format_word, formula_sample, word_sample

SEED = 2024
WORDS = 50
DEFAULT_FORMULAS = 2000  # the minimum; about 6 s
SLOW_FORMULAS = 20000  # about 1 min
CHUNK = 250
SLOW_CHUNK = 1000


@functools.lru_cache(maxsize=None)
def _buchi(f: Formula):
    return to_buchi(f)


def _check_sample(start: int, count: int) -> None:
    mismatches = []
    checked = 0
    for k, f in formula_sample(SEED, start, count):
        aut = to_buchi(f)
        for u, v in word_sample(SEED, k, WORDS):
            expected = evaluate(f, u, v)
            got = accepts(aut, u, v)
            checked += 1
            if got != expected:
                mismatches.append(
                    f"  formula {k} (seed {SEED}): {f}\n    word: {format_word(u, v)}\n"
                    f"    satisfies: {expected}, automaton accepts: {got} "
                    f"({aut.num_states} states)"
                )
    assert checked == count * WORDS
    assert not mismatches, (
        f"{len(mismatches)} of {checked} (formula, word) pairs disagree; first ones:\n"
        + "\n".join(mismatches[:10])
    )


@pytest.mark.parametrize("start", range(0, DEFAULT_FORMULAS, CHUNK))
def test_random_formulas_agree_with_the_oracle(start):
    _check_sample(start, CHUNK)


@pytest.mark.slow
@pytest.mark.parametrize("start", range(0, SLOW_FORMULAS, SLOW_CHUNK))
def test_random_formulas_agree_with_the_oracle_full(start):
    _check_sample(start, SLOW_CHUNK)


# ------------------------------------------------------------- exclusive propositions
EXCLUSIVE_FORMULAS = 1000


def _exclusive_words(k: int, count: int):
    """Lasso words whose letters hold at most one proposition (one region at a time)."""
    import random

    rng = random.Random(f"exclusive-words-{SEED}-{k}")

    def letter():
        r = rng.randrange(len(APS) + 1)
        return frozenset() if r == len(APS) else frozenset({APS[r]})

    return [([letter() for _ in range(rng.randint(0, 5))], [letter() for _ in range(rng.randint(1, 5))])
            for _ in range(count)]


@pytest.mark.parametrize("start", range(0, EXCLUSIVE_FORMULAS, CHUNK))
def test_exclusive_automata_agree_with_the_oracle_on_one_proposition_at_a_time(start):
    """``to_buchi(f, exclusive=True)`` accepts a word whose letters hold at most one
    proposition exactly when it satisfies ``f``, and has no edge for any other letter."""
    from itertools import combinations

    mismatches = []
    for k, f in formula_sample(SEED, start, CHUNK):
        aut = to_buchi(f, exclusive=True)
        n = len(aut.aps)
        multi = [sum(1 << i for i in c) for r in range(2, n + 1) for c in combinations(range(n), r)]
        assert not any(e.guard.holds(m) for out in aut.edges for e in out for m in multi), (k, str(f))
        for u, v in _exclusive_words(k, WORDS):
            if accepts(aut, u, v) != evaluate(f, u, v):
                mismatches.append(f"  formula {k}: {f}\n    word: {format_word(u, v)}")
    assert not mismatches, f"{len(mismatches)} disagree:\n" + "\n".join(mismatches[:10])


def test_visiting_ten_regions_one_at_a_time_is_the_subset_automaton():
    """The mission that made the full alphabet exponential (``2^10`` letters, about a minute):
    its exclusive automaton is the minimal one, a state per set of visited regions."""
    names = [f"r{i}" for i in range(10)]
    aut = to_buchi(" & ".join(f"F {r}" for r in names), exclusive=True)
    assert aut.num_states == 1 << 10
    tour = [frozenset({r}) for r in names]
    assert accepts(aut, tour[::-1], [frozenset()])
    assert not accepts(aut, tour[1:] * 3, [frozenset()] + tour[1:])  # r0 never visited


def test_guards_from_minterms_hold_exactly_at_their_letters():
    import random

    from tamp.ltl.bdd import from_minterms

    rng = random.Random(5)
    for nvars in (0, 1, 3, 6):
        for _ in range(30):
            letters = {m for m in range(1 << nvars) if rng.random() < rng.random()}
            g = from_minterms(letters, nvars)
            assert all(g.holds(m) == (m in letters) for m in range(1 << nvars))
            assert g.is_false == (not letters)
    assert from_minterms(range(1 << 5), 5).is_true
    assert from_minterms([0, 1, 2, 4, 8, 1 << 20], 21).holds(1 << 20)
    with pytest.raises(ValueError):
        from_minterms([8], 3)


# ---------------------------------------------------------------------- mission patterns
E = frozenset()
A, B, C = frozenset({"a"}), frozenset({"b"}), frozenset({"c"})
AB = A | B
P1, P2 = frozenset({"p1"}), frozenset({"p2"})
D1, D2, D3, D4 = (frozenset({f"d{i}"}) for i in range(1, 5))

OFFICE_TRANSPORT = "F((p1 | p2) & F d1) & F((p1 | p2) & F d2) & F((p1 | p2) & F d3)"
SIMPLE = "G F a & G F b & G !c"
CLUTTERED20 = "F d1 & F d2 & F d3 & F d4"

# name -> (formula, accepted words, rejected words); each verdict checked by hand.
MISSIONS = {
    "visit": ("F a", [
        ([], [A]),
        ([E, E, A], [E]),
        ([B], [E, A]),
    ], [
        ([], [E]),
        ([B, C], [B]),
    ]),
    "sequenced visit": ("F(a & F b)", [
        ([A, B], [E]),
        ([A], [E, B]),
        ([AB], [E]),  # F b holds at the position of a itself
    ], [
        ([B, A], [E]),  # b only before a
        ([], [A]),
        ([B], [E, A]),
    ]),
    "ordered visit": ("F b & (!b U a)", [
        ([A], [B]),
        ([E, A, E], [B]),
        ([AB], [E]),
    ], [
        ([B, A], [B]),  # b comes first
        ([A], [E]),  # b never comes
        ([], [E, B]),  # a never comes
    ]),
    "patrolling": ("G F a & G F b", [
        ([], [A, B]),
        ([C], [AB]),
        ([E, E], [A, E, B]),
    ], [
        ([], [A]),
        ([AB, AB], [B]),
        ([], [E]),
    ]),
    "avoidance": ("G !c & F a", [
        ([E], [A]),
        ([], [E, A]),
        ([A], [B]),
    ], [
        ([A], [C]),
        ([C, A], [E]),
        ([], [E]),
    ]),
    "response": ("G(a -> F b)", [
        ([], [E]),  # vacuous
        ([A, B], [E]),
        ([], [A, B]),
        ([], [AB]),
    ], [
        ([B, A], [E]),
        ([], [A]),
        ([A, B], [A, E]),
    ]),
    "until": ("!b U a", [
        ([A], [E]),
        ([E, C], [A]),
        ([AB], [B]),
    ], [
        ([B], [A]),
        ([], [E]),
        ([E, B, A], [A]),
    ]),
    "office transport": (OFFICE_TRANSPORT, [
        ([P1, D1, P2, D2, P1, D3], [E]),
        ([], [P1, D1, D2, D3]),
        ([P2 | D1 | D2 | D3], [E]),  # pick up and drop at once
        ([P1, D3, D2], [D1]),
    ], [
        ([D1, D2, D3], [E]),  # nothing picked up
        ([P1, D1, D2], [E]),  # d3 never served
        ([D3, P2, D1, D2], [E]),  # d3 only before any pickup
        ([], [P1, P2]),
    ]),
    "simple": (SIMPLE, [
        ([], [A, B]),
        ([E], [AB]),
        ([A, A], [E, B, E, A]),
    ], [
        ([], [A, B, C]),
        ([C], [A, B]),
        ([], [A]),
    ]),
    "cluttered20": (CLUTTERED20, [
        ([D1, D2], [D3, D4]),
        ([D4, D3, D2, D1], [E]),
        ([], [D1 | D2 | D3 | D4]),
    ], [
        ([D1, D2, D3], [E]),
        ([], [D1, D2]),
        ([D4], [D3, D2]),
    ]),
    "chain of six": ("F(a & F(b & F(c & F(d & F(e & F f)))))", [
        ([A, B, C, frozenset("d"), frozenset("e"), frozenset("f")], [E]),
        ([frozenset("abcdef")], [E]),
    ], [
        ([A, B, C, frozenset("d"), frozenset("f"), frozenset("e")], [E]),
        ([], [frozenset("abcde")]),
    ]),
    "response and avoidance": ("G(a -> F b) & G !c", [
        ([], [A, B]),
        ([A], [B]),
        ([], [E]),
    ], [
        ([A], [E]),
        ([C], [E]),
        ([], [A, C, B]),
    ]),
}

_CASES = [
    pytest.param(text, u, v, verdict, id=f"{name}-{'acc' if verdict else 'rej'}{i}")
    for name, (text, good, bad) in MISSIONS.items()
    for verdict, words in ((True, good), (False, bad))
    for i, (u, v) in enumerate(words)
]


@pytest.mark.parametrize(("text", "prefix", "cycle", "expected"), _CASES)
def test_mission_patterns_oracle(text, prefix, cycle, expected):
    assert evaluate(text, prefix, cycle) is expected, f"{text} on {format_word(prefix, cycle)}"


@pytest.mark.parametrize(("text", "prefix", "cycle", "expected"), _CASES)
def test_mission_patterns_automaton(text, prefix, cycle, expected):
    aut = _buchi(parse(text))
    assert accepts(aut, prefix, cycle) is expected, (
        f"{text} on {format_word(prefix, cycle)}: expected "
        f"{'accept' if expected else 'reject'} ({aut.num_states} states)"
    )


def test_paper_missions_match_the_world_files():
    tasks = {name: json.loads(world_file(name).read_text())["task"]
             for name in ("office", "simple", "cluttered20")}
    assert parse(tasks["office"]) is parse(OFFICE_TRANSPORT)
    assert parse(tasks["simple"]) is parse(SIMPLE)
    assert parse(tasks["cluttered20"]) is parse(CLUTTERED20)


# ---------------------------------------------------------------------- size targets
SIZE_TARGETS = [
    (OFFICE_TRANSPORT, 12),
    ("F(a & F(b & F(c & F(d & F(e & F f)))))", 7),
    ("G F a & G F b & G F c & G F d", 5),
    ("G(a -> F b) & G !c", 3),
]


@pytest.mark.parametrize(("text", "limit"), SIZE_TARGETS, ids=[t for t, _ in SIZE_TARGETS])
def test_size_targets(text, limit):
    aut = _buchi(parse(text))
    assert aut.num_states <= limit, f"{text}: {aut.num_states} states, target <= {limit}"


# ---------------------------------------------------------------------- empty languages
UNSATISFIABLE = ["a & !a", "G a & F !a", "false", "G F a & F G !a", "X(b & !b)", "a U false"]


@pytest.mark.parametrize("text", UNSATISFIABLE)
def test_unsatisfiable_formulas_have_no_accepting_state(text):
    aut = _buchi(parse(text))
    assert not aut.accepting, f"{text}: accepting states {sorted(aut.accepting)}"
    for u, v in word_sample(SEED, -1, 20):
        assert not evaluate(text, u, v)


def test_every_memo_of_the_translator_is_bounded():
    """A long-running service translates every mission it is sent; formulas are hash-consed and
    a memo keeps its keys alive, so an unbounded memo grew with the number of distinct missions
    (about 3.5 KB each). Every ``lru_cache`` of the LTL modules has a finite size."""
    import tamp.ltl.rewrite as rewrite
    import tamp.ltl.translate as translate

    memos = [(m.__name__, name, obj) for m in (rewrite, translate) for name, obj in vars(m).items()
             if hasattr(obj, "cache_info")]
    assert len(memos) >= 6
    for mod, name, obj in memos:
        assert obj.cache_info().maxsize == rewrite.MEMO_SIZE, (mod, name)
