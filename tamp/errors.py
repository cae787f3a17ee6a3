"""Errors of the mission layer (LTL, automata, plans), under the product's one root.

Every class derives from :class:`navigation.errors.TampError` (and so from
:class:`~navigation.errors.HarmonicTampError`) and from the matching builtin, so callers can
catch either. Each error type is distinct so the service can answer with a precise code
(FORMATS.md bus contract: ``parse_error``, ``unknown_region``, ``unsatisfiable``,
``invalid_request``).
"""

from __future__ import annotations

from navigation.errors import TampError

__all__ = [
    "TampError",
    "LtlSyntaxError",
    "UnknownRegionError",
    "UnsatisfiableError",
    "HoaError",
    "NoPlanError",
    "InvalidRequestError",
    "brief",
]


def brief(text: str, limit: int = 120) -> str:
    """``repr(text)``, cut to about ``limit`` characters with ``...`` for error messages that
    quote a mission (a request can carry megabytes of formula; the message goes on the bus)."""
    text = str(text)
    if len(text) <= limit:
        return repr(text)
    return repr(text[:limit]) + f"... ({len(text)} characters)"


class LtlSyntaxError(TampError, SyntaxError):
    """A formula that does not parse.

    Attributes
    ----------
    text : str
        The formula as given.
    position : int
        0-based character offset of the problem in ``text``.
    reason : str
        What is wrong there, without the caret picture.

    ``str(err)`` shows the reason, the formula and a caret under the offending column; of a
    formula longer than ``2 * WINDOW`` characters only ``WINDOW`` either side of the column
    (``...`` marks the cut), and line breaks and tabs as spaces, so the caret stays under it.
    """

    WINDOW = 40

    def __init__(self, reason: str, text: str, position: int):
        self.reason = reason
        self.text = text
        self.position = int(position)
        pos = max(self.position, 0)
        start, end = 0, len(text)
        if len(text) > 2 * self.WINDOW:
            start, end = max(0, pos - self.WINDOW), min(len(text), pos + self.WINDOW)
        shown = text[start:end].translate({ord("\n"): " ", ord("\r"): " ", ord("\t"): " "})
        lead = "..." if start > 0 else ""
        shown = lead + shown + ("..." if end < len(text) else "")
        caret = " " * (len(lead) + pos - start) + "^"
        super().__init__(f"{reason} at column {self.position + 1}\n  {shown}\n  {caret}")

    def __str__(self) -> str:  # SyntaxError.__str__ would print only the first argument
        return self.args[0]


class UnknownRegionError(TampError, ValueError):
    """A formula names atomic propositions that are not regions of the world.

    Attributes
    ----------
    names : tuple of str
        The unknown names, sorted.
    known : tuple of str
        The names that would have been accepted.
    """

    def __init__(self, names, known=()):
        self.names = tuple(sorted(names))
        self.known = tuple(sorted(known))
        def listed(items, show):
            more = len(items) - 20
            return ", ".join(map(show, items[:20])) + (f", ... ({more} more)" if more > 0 else "")

        super().__init__(
            f"unknown region name(s) {listed(self.names, repr)}; "
            f"known regions: {listed(self.known, str) or '(none)'}"
        )


class UnsatisfiableError(TampError, ValueError):
    """The formula's language is empty: no behaviour at all satisfies it.

    Attributes
    ----------
    formula : str
    """

    def __init__(self, formula: str, detail: str = ""):
        self.formula = str(formula)
        msg = f"the mission {brief(self.formula)} is unsatisfiable: no infinite run satisfies it"
        super().__init__(msg + (f" ({detail})" if detail else ""))


class HoaError(TampError, ValueError):
    """HOA text that cannot be read; the message names the line and the problem."""

    def __init__(self, message: str, line: int | None = None):
        self.line = line
        super().__init__(f"line {line}: {message}" if line is not None else message)


class NoPlanError(TampError):
    """The mission has no accepting lasso in the current navigation map.

    Attributes
    ----------
    blocked : tuple
        Transitions of the navigation map that are missing or removed and that the plan would
        need (pairs of region names), as far as they could be identified; may be empty.
    """

    def __init__(self, message: str, blocked=()):
        self.blocked = tuple(blocked)
        super().__init__(message)


class InvalidRequestError(TampError, ValueError):
    """A mission request that is malformed (bad mode, bad fields)."""
