"""Guarantees of tamp.ltl.syntax: printing round-trips, precedence and associativity follow
FORMATS.md, the aliases parse, and bad formulas are refused with the exact offset."""

from __future__ import annotations

import pytest

from navigation.errors import TampError
from tamp.errors import LtlSyntaxError
from tamp.ltl.formula import (
    FALSE,
    TRUE,
    Always,
    Equiv,
    Eventually,
    Formula,
    Implies,
    Next,
    Not,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    ap,
)
from tamp.ltl.syntax import parse, to_string

from .ltlgen import formula_sample

a, b, c, d = ap("a"), ap("b"), ap("c"), ap("d")


def _and(*fs):
    return Formula("&", fs)


def _or(*fs):
    return Formula("|", fs)


# ---------------------------------------------------------------------- round trip
HAND = [
    "a",
    "true",
    "false",
    "!a",
    "!!a",
    "X a",
    "X X !a",
    "G F a",
    "F G !c",
    "a & b & c",
    "(a & b) & c",
    "a & (b & c)",
    "a | b & c",
    "(a | b) & c",
    "a -> b -> c",
    "(a -> b) -> c",
    "a <-> b <-> c",
    "(a <-> b) <-> c",
    "a U b U c",
    "(a U b) U c",
    "a U (b R c)",
    "(a W b) M c",
    "!(a U b)",
    "X(a U b)",
    "G(a -> F b) & G !c",
    "F((p1 | p2) & F d1) & F((p1 | p2) & F d2) & F((p1 | p2) & F d3)",
    "F(a & F(b & F(c & F(d & F(e & F f)))))",
    "x_1 | region_22",
    "true U false",
    "!true R !false",
]


@pytest.mark.parametrize("text", HAND)
def test_hand_formulas_round_trip(text):
    f = parse(text)
    assert parse(str(f)) is f
    assert to_string(f) == str(f)


@pytest.mark.parametrize("text", HAND)
def test_printing_is_canonical(text):
    """Printing a parsed formula is a fixed point: str(parse(str(f))) == str(f)."""
    s = str(parse(text))
    assert str(parse(s)) == s


def test_random_formulas_round_trip():
    for k, f in formula_sample(7, 0, 2000):
        text = str(f)
        assert parse(text) is f, (
            f"formula {k} of seed 7 printed as {text!r} parses back as {parse(text)!r}")


def test_parse_returns_a_formula_unchanged():
    f = Always(Eventually(a))
    assert parse(f) is f


def test_parse_rejects_non_text():
    with pytest.raises(TypeError, match="int"):
        parse(3)


# ---------------------------------------------------------------------- precedence
PRECEDENCE = [
    # binary temporal operators are right-associative
    ("a U b U c", Until(a, Until(b, c))),
    ("a R b R c", Release(a, Release(b, c))),
    ("a U b R c", Until(a, Release(b, c))),
    ("a W b M c", WeakUntil(a, StrongRelease(b, c))),
    # unary operators bind tighter than binary temporal ones
    ("!a U b", Until(Not(a), b)),
    ("X a U b", Until(Next(a), b)),
    ("F a U G b", Until(Eventually(a), Always(b))),
    ("!a & b", _and(Not(a), b)),
    # U R W M bind tighter than & and |
    ("a & b U c", _and(a, Until(b, c))),
    ("a U b & c", _and(Until(a, b), c)),
    ("a | b W c", _or(a, WeakUntil(b, c))),
    # & tighter than |, | tighter than ->, -> tighter than <->
    ("a | b & c", _or(a, _and(b, c))),
    ("a & b | c", _or(_and(a, b), c)),
    ("a | b -> c", Implies(_or(a, b), c)),
    ("a -> b | c", Implies(a, _or(b, c))),
    ("a -> b <-> c", Equiv(Implies(a, b), c)),
    ("a <-> b -> c", Equiv(a, Implies(b, c))),
    # -> and <-> are right-associative
    ("a -> b -> c", Implies(a, Implies(b, c))),
    ("a <-> b <-> c", Equiv(a, Equiv(b, c))),
    # & and | chains are one n-ary node; parentheses keep their own node
    ("a & b & c", _and(a, b, c)),
    ("a | b | c | d", _or(a, b, c, d)),
    ("(a & b) & c", _and(_and(a, b), c)),
    ("a | (b | c)", _or(a, _or(b, c))),
    # unary chains
    ("G F a", Always(Eventually(a))),
    ("!X a", Not(Next(a))),
    ("X(a & b)", Next(_and(a, b))),
    ("! a", Not(a)),
]


@pytest.mark.parametrize(("text", "expected"), PRECEDENCE, ids=[t for t, _ in PRECEDENCE])
def test_precedence_and_associativity(text, expected):
    assert parse(text) is expected


ALIASES = [
    ("<>a", "F a"),
    ("[]a", "G a"),
    ("[]<>a", "G F a"),
    ("<>[]!a", "F G !a"),
    ("a && b", "a & b"),
    ("a || b", "a | b"),
    ("a && b || c", "a & b | c"),
    ("GFa", "G F a"),
    ("FGa", "F G a"),
    ("Xa", "X a"),
    ("XXa", "X X a"),
    ("aUb", "a U b"),
    ("G(a->Fb)", "G(a -> F b)"),
    ("1", "true"),
    ("0", "false"),
    ("1 U 0", "true U false"),
    ("  a\t&\nb  ", "a & b"),
    ("GFa && []<>(b || c)", "G F a & G F(b | c)"),
]


@pytest.mark.parametrize(("text", "canonical"), ALIASES)
def test_aliases(text, canonical):
    assert parse(text) is parse(canonical)
    assert str(parse(text)) == canonical


def test_constants_and_names():
    assert parse("true") is TRUE and parse("false") is FALSE
    assert parse("true1") is ap("true1")  # a longer name is a name, not the constant
    assert parse("x1 & y_2").args == (ap("x1"), ap("y_2"))


# ---------------------------------------------------------------------- errors
ERRORS = [
    # (text, position, fragment of the reason)
    ("", 0, "empty formula"),
    ("   ", 3, "empty formula"),
    ("a &", 3, "missing operand after '&'"),
    ("a & ", 4, "missing operand after '&'"),
    ("a U", 3, "missing operand after 'U'"),
    ("F", 1, "missing operand after 'F'"),
    ("!", 1, "missing operand after '!'"),
    ("a ->", 4, "missing operand after '->'"),
    ("& a", 0, "expected a formula, found '&'"),
    ("U a", 0, "expected a formula, found 'U'"),
    ("a -> -> b", 5, "missing operand after '->'"),
    ("a & | b", 4, "missing operand after '&'"),
    ("a & (b | )", 9, "missing operand after '|'"),
    ("()", 1, "missing operand after '('"),
    ("(a", 0, "missing ')'"),
    ("((a & b)", 0, "missing ')'"),
    ("G(a", 1, "missing ')'"),
    ("a)", 1, "unmatched ')'"),
    ("(a))", 3, "unmatched ')'"),
    ("a & b)", 5, "unmatched ')'"),
    ("a b", 2, "after a complete formula"),
    ("(a b)", 3, "expected ')'"),
    ("a # b", 2, "unexpected character '#'"),
    ("a <- b", 2, "unexpected character '<'"),
    ("a=b", 1, "unexpected character '='"),
    ("a & 1x", 4, "unexpected character '1'"),
    ("A", 0, "invalid name 'A'"),
    ("a & B", 4, "invalid name 'B'"),
    ("F Office", 2, "invalid name 'Office'"),
    ("_a", 0, "invalid name '_a'"),
]


@pytest.mark.parametrize(("text", "position", "reason"), ERRORS,
                         ids=[repr(t) for t, _, _ in ERRORS])
def test_syntax_errors_point_at_the_culprit(text, position, reason):
    with pytest.raises(LtlSyntaxError) as info:
        parse(text)
    err = info.value
    assert err.position == position, f"{text!r}: position {err.position}, expected {position}"
    assert reason in err.reason
    assert err.text == text
    # the message shows the formula with a caret under the culprit
    lines = str(err).split("\n")
    assert f"column {position + 1}" in lines[0]
    assert lines[1] == "  " + text
    assert lines[2] == "  " + " " * position + "^"


def test_syntax_error_types():
    with pytest.raises(LtlSyntaxError) as info:
        parse("a &")
    assert isinstance(info.value, SyntaxError)
    assert isinstance(info.value, TampError)


def test_non_ascii_letter_is_a_syntax_error():
    with pytest.raises(LtlSyntaxError) as info:
        parse("a & \u00e9t\u00e9")
    assert info.value.position == 4


@pytest.mark.parametrize("make", [
    lambda k: "(" * k + "a" + ")" * k, lambda k: "!" * k + "a", lambda k: "X " * k + "a",
    lambda k: " U ".join(["a"] * (k + 1)), lambda k: " -> ".join(["a"] * (k + 1)),
    lambda k: "F (a & " * k + "b" + ")" * k,
])
def test_nesting_is_bounded_with_a_syntax_error_not_a_recursion_error(make):
    """5000 levels raised RecursionError from the parser (a traceback in every command); up to
    MAX_NESTING levels parse and translate, beyond it one LtlSyntaxError says why."""
    from tamp.ltl import to_buchi
    from tamp.ltl.syntax import MAX_NESTING

    deepest = make(MAX_NESTING // 2 if make(1).startswith("F (") else MAX_NESTING)
    to_buchi(parse(deepest))
    for k in (MAX_NESTING + 1, 5000):
        with pytest.raises(LtlSyntaxError) as info:
            parse(make(k))
        assert f"nested deeper than {MAX_NESTING} levels" in str(info.value)


def test_error_pictures_of_long_formulas_show_a_window_round_the_column():
    text = "F a & " * 100 + "& b\nc"
    with pytest.raises(LtlSyntaxError) as info:
        parse(text)
    _, shown, caret = str(info.value).split("\n")
    assert info.value.position == text.index("& b")
    assert len(shown) < 100 and shown.startswith("  ...") and "\n" not in shown
    assert shown[len(caret) - 1] == "&" and caret.strip() == "^"
    with pytest.raises(LtlSyntaxError) as info:  # a short one is shown whole, line break as a space
        parse("F (a &\n b")
    assert str(info.value).split("\n")[1:] == ["  F (a &  b", "    ^"]
