"""LTL text <-> :class:`~tamp.ltl.formula.Formula` (FORMATS.md "LTL syntax", Spot-compatible).

Grammar, from the loosest operator to the tightest::

    equiv   := implies ("<->" implies)*          right-associative
    implies := or ("->" implies)?                right-associative
    or      := and (("|" | "||") and)*           n-ary
    and     := binary (("&" | "&&") binary)*     n-ary
    binary  := unary (("U" | "R" | "W" | "M") binary)?   right-associative
    unary   := ("!" | "X" | "F" | "G" | "<>" | "[]") unary | atom
    atom    := "true" | "false" | "1" | "0" | NAME | "(" equiv ")"

``NAME`` is ``[a-z][a-z0-9_]*`` (region names). The temporal operators are single upper-case
letters and may touch their operand (``GFa`` is ``G F a``), as in Spot.

A chain ``a & b & c`` becomes one n-ary node; a parenthesised group stays its own node, so
``parse(to_string(f)) is f`` for every formula (the printer adds exactly the parentheses the
grammar needs). Errors raise :class:`~tamp.errors.LtlSyntaxError` with the 0-based offset of
the culprit and a caret picture.
"""

from __future__ import annotations

import re

from ..errors import LtlSyntaxError
from .formula import FALSE, TRUE, Formula, ap

__all__ = ["parse", "to_string", "FormulaLike", "as_formula"]

FormulaLike = Formula | str

_TOKEN = re.compile(
    r"\s*(?:(?P<name>[a-z][a-z0-9_]*)|(?P<const>[01])(?![0-9a-zA-Z_])|(?P<op><->|->|&&|\|\||<>|\[\]|[!&|()XFGURWM]))"
)
_BIN_TEMPORAL = {"U", "R", "W", "M"}
_UNARY = {"!": "!", "X": "X", "F": "F", "G": "G", "<>": "F", "[]": "G"}
_NAMES_OF = {"&&": "&", "||": "|"}


def _tokenize(text: str) -> list[tuple[str, str, int]]:
    """Tokens ``(kind, value, offset)``; kind is ``name``, ``const``, ``op`` or ``end``."""
    out: list[tuple[str, str, int]] = []
    pos = 0
    n = len(text)
    while True:
        while pos < n and text[pos].isspace():
            pos += 1
        if pos >= n:
            break
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            ch = text[pos]
            if ch.isalpha() or ch == "_":
                word = re.match(r"\w+", text[pos:]).group(0)
                raise LtlSyntaxError(
                    f"invalid name {word!r}: region names are lower-case letters, digits and "
                    "'_' starting with a letter; temporal operators are X F G U R W M",
                    text,
                    pos,
                )
            raise LtlSyntaxError(f"unexpected character {ch!r}", text, pos)
        kind = m.lastgroup
        value = m.group(kind)
        start = m.start(kind)
        if kind == "name" and value in ("true", "false"):
            kind = "const"
            value = "1" if value == "true" else "0"
        out.append((kind, _NAMES_OF.get(value, value), start))
        pos = m.end()
    out.append(("end", "", len(text)))
    return out


#: Deepest nesting ``parse`` accepts: parentheses, prefix operators and right operands of
#: ``->``, ``<->`` and the binary temporal operators, each a level. Missions are far shallower
#: (visiting 12 regions in order nests 24); the bound keeps the recursive parser and the
#: recursive passes after it (rewriting, translation, printing) within Python's stack, where a
#: formula of 5000 ``!`` raised ``RecursionError``.
MAX_NESTING = 100


class _Parser:
    def __init__(self, text: str):
        self.text = text
        self.toks = _tokenize(text)
        self.i = 0
        self.depth = 0

    def nest(self, tok=None):
        """Enter one level of nesting at ``tok`` (default: the next token); the caller leaves it
        with ``self.depth -= 1``."""
        self.depth += 1
        if self.depth > MAX_NESTING:
            self.error(f"formula nested deeper than {MAX_NESTING} levels", tok)

    def peek(self):
        return self.toks[self.i]

    def take(self):
        t = self.toks[self.i]
        self.i += 1
        return t

    def error(self, reason: str, tok=None):
        tok = tok or self.peek()
        raise LtlSyntaxError(reason, self.text, tok[2])

    def expect_operand(self, after: str | None):
        kind, value, _ = self.peek()
        if kind == "end":
            if after is None:
                self.error("empty formula")
            self.error(f"missing operand after {after!r}")
        if kind == "op" and value in (")", "&", "|", "->", "<->", "U", "R", "W", "M"):
            if after is None:
                self.error(f"expected a formula, found {value!r}")
            self.error(f"missing operand after {after!r} (found {value!r})")

    def parse(self) -> Formula:
        self.expect_operand(None)
        f = self.equiv()
        kind, value, _ = self.peek()
        if kind != "end":
            if value == ")":
                self.error("unmatched ')'")
            self.error(f"unexpected {value!r} after a complete formula (missing operator?)")
        return f

    def equiv(self) -> Formula:
        left = self.implies()
        if self.peek()[:2] == ("op", "<->"):
            self.take()
            self.expect_operand("<->")
            self.nest()
            right = self.equiv()
            self.depth -= 1
            return Formula("<->", (left, right))
        return left

    def implies(self) -> Formula:
        left = self.disj()
        if self.peek()[:2] == ("op", "->"):
            self.take()
            self.expect_operand("->")
            self.nest()
            right = self.implies()
            self.depth -= 1
            return Formula("->", (left, right))
        return left

    def disj(self) -> Formula:
        items = [self.conj()]
        while self.peek()[:2] == ("op", "|"):
            self.take()
            self.expect_operand("|")
            items.append(self.conj())
        return items[0] if len(items) == 1 else Formula("|", tuple(items))

    def conj(self) -> Formula:
        items = [self.binary()]
        while self.peek()[:2] == ("op", "&"):
            self.take()
            self.expect_operand("&")
            items.append(self.binary())
        return items[0] if len(items) == 1 else Formula("&", tuple(items))

    def binary(self) -> Formula:
        left = self.unary()
        kind, value, _ = self.peek()
        if kind == "op" and value in _BIN_TEMPORAL:
            self.take()
            self.expect_operand(value)
            self.nest()
            right = self.binary()
            self.depth -= 1
            return Formula(value, (left, right))
        return left

    def unary(self) -> Formula:
        kind, value, _ = self.peek()
        if kind == "op" and value in _UNARY:
            self.take()
            self.expect_operand(value)
            self.nest()
            operand = self.unary()
            self.depth -= 1
            return Formula(_UNARY[value], (operand,))
        return self.atom()

    def atom(self) -> Formula:
        tok = self.take()
        kind, value, _ = tok
        if kind == "name":
            return ap(value)
        if kind == "const":
            return TRUE if value == "1" else FALSE
        if kind == "op" and value == "(":
            self.expect_operand("(")
            self.nest(tok)
            f = self.equiv()
            self.depth -= 1
            if self.peek()[:2] != ("op", ")"):
                k, v, _ = self.peek()
                if k == "end":
                    raise LtlSyntaxError("missing ')' to close this '('", self.text, tok[2])
                self.error(f"expected ')' or an operator, found {v!r}")
            self.take()
            return f
        self.i -= 1
        self.expect_operand(None)
        self.error(f"unexpected {value!r}")  # pragma: no cover - expect_operand raised


def parse(text: FormulaLike) -> Formula:
    """Parse an LTL formula in FORMATS.md syntax.

    Parameters
    ----------
    text : str or Formula
        The formula; a :class:`Formula` is returned unchanged.

    Returns
    -------
    Formula

    Raises
    ------
    LtlSyntaxError
        With ``position`` (0-based offset) and a caret picture in the message.

    Examples
    --------
    >>> str(parse("GFa && []<>(b || c)"))
    'G F a & G F(b | c)'
    """
    if isinstance(text, Formula):
        return text
    if not isinstance(text, str):
        raise TypeError(f"expected an LTL formula as str, got {type(text).__name__}")
    return _Parser(text).parse()


as_formula = parse

# Printing ------------------------------------------------------------------------------------
_PREC = {"<->": 1, "->": 2, "|": 3, "&": 4, "U": 5, "R": 5, "W": 5, "M": 5}
_ATOM_PREC = 7  # unary operators and atoms


def _prec(f: Formula) -> int:
    return _PREC.get(f.op, _ATOM_PREC)


def to_string(f: Formula) -> str:
    """Print ``f`` in FORMATS.md syntax with the fewest parentheses that parse back to ``f``."""
    op = f.op
    if op == "true":
        return "true"
    if op == "false":
        return "false"
    if op == "ap":
        return f.name
    if op in ("!", "X", "F", "G"):
        (a,) = f.args
        s = to_string(a)
        if _prec(a) < _ATOM_PREC:
            return f"{op}({s})"
        return f"{op}{s}" if op == "!" else f"{op} {s}"
    p = _PREC[op]
    if op in ("&", "|"):
        parts = []
        for a in f.args:
            s = to_string(a)
            parts.append(f"({s})" if _prec(a) <= p else s)
        return f" {op} ".join(parts)
    a, b = f.args
    sa, sb = to_string(a), to_string(b)
    if _prec(a) <= p:
        sa = f"({sa})"
    if _prec(b) < p:
        sb = f"({sb})"
    return f"{sa} {op} {sb}"
