"""Seeded random LTL formulas and lasso words for the oracle tests (deterministic per seed).

:func:`random_formula` draws a formula of a given size (number of nodes, at most
:data:`MAX_SIZE`) over up to four propositions ``a b c d`` with every operator of the syntax:
``true false ! X F G & | -> <-> U R W M`` (``&`` and ``|`` sometimes with three operands).
:func:`random_word` draws a lasso word ``u v^omega``: prefix length 0..5, cycle length 1..5,
each letter a random subset of the propositions.

:func:`formula_sample` and :func:`word_sample` fix how the tests index their samples: formula
``k`` of a sample comes from its own generator seeded with ``(seed, k)``, so a failure names
``(seed, k)`` and can be replayed alone with :func:`formula_at`.
"""

from __future__ import annotations

import random

from tamp.ltl.formula import FALSE, TRUE, Formula, ap

__all__ = [
    "APS",
    "MAX_SIZE",
    "UNARY_OPS",
    "BINARY_OPS",
    "random_formula",
    "random_word",
    "formula_at",
    "formula_sample",
    "word_sample",
    "format_word",
]

APS = ("a", "b", "c", "d")
MAX_SIZE = 15
UNARY_OPS = ("!", "X", "F", "G")
BINARY_OPS = ("&", "|", "->", "<->", "U", "R", "W", "M")
MAX_PREFIX = 5
MAX_CYCLE = 5


def _leaf(rng: random.Random, aps) -> Formula:
    r = rng.random()
    if r < 0.06:
        return TRUE
    if r < 0.12:
        return FALSE
    return ap(rng.choice(aps))


def _build(rng: random.Random, size: int, aps) -> Formula:
    """A random formula with exactly ``size`` nodes."""
    if size == 1:
        return _leaf(rng, aps)
    if size == 2 or rng.random() < 0.3:
        return Formula(rng.choice(UNARY_OPS), (_build(rng, size - 1, aps),))
    op = rng.choice(BINARY_OPS)
    rest = size - 1
    if op in ("&", "|") and rest >= 3 and rng.random() < 0.2:
        # three operands of sizes >= 1 summing to ``rest``
        i = rng.randint(1, rest - 2)
        j = rng.randint(1, rest - i - 1)
        parts = (i, j, rest - i - j)
        return Formula(op, tuple(_build(rng, s, aps) for s in parts))
    left = rng.randint(1, rest - 1)
    return Formula(op, (_build(rng, left, aps), _build(rng, rest - left, aps)))


def random_formula(rng: random.Random, max_size: int = MAX_SIZE, aps=APS) -> Formula:
    """A random formula of size uniform in ``1 .. max_size`` over (a subset of) ``aps``.

    The number of propositions the formula may use is uniform in ``1 .. len(aps)``.
    """
    if not 1 <= max_size <= MAX_SIZE:
        raise ValueError(f"max_size must be in 1..{MAX_SIZE}, got {max_size}")
    names = aps[: rng.randint(1, len(aps))]
    return _build(rng, rng.randint(1, max_size), names)


def random_word(rng: random.Random, aps=APS) -> tuple[list[frozenset[str]], list[frozenset[str]]]:
    """A random lasso word ``(prefix, cycle)``; letters are subsets of ``aps``."""

    def letter():
        return frozenset(a for a in aps if rng.random() < 0.5)

    prefix = [letter() for _ in range(rng.randint(0, MAX_PREFIX))]
    cycle = [letter() for _ in range(rng.randint(1, MAX_CYCLE))]
    return prefix, cycle


def formula_at(seed: int, k: int) -> Formula:
    """Formula ``k`` of the sample with ``seed`` (replays one case of :func:`formula_sample`)."""
    return random_formula(random.Random(f"formula-{seed}-{k}"))


def formula_sample(seed: int, start: int, count: int) -> list[tuple[int, Formula]]:
    """Formulas ``start .. start+count-1`` of the sample with ``seed``, as ``(k, formula)``."""
    return [(k, formula_at(seed, k)) for k in range(start, start + count)]


def word_sample(seed: int, k: int, count: int):
    """``count`` lasso words for formula ``k`` of the sample with ``seed``."""
    rng = random.Random(f"words-{seed}-{k}")
    return [random_word(rng) for _ in range(count)]


def format_word(prefix, cycle) -> str:
    """Spot-like text of a lasso word, e.g. ``{a}; {}; cycle{{b,c}}``."""

    def fmt(letter):
        return "{" + ",".join(sorted(letter)) + "}"

    head = "".join(fmt(x) + "; " for x in prefix)
    return head + "cycle{" + "; ".join(fmt(x) for x in cycle) + "}"
