"""``python -m tamp.ltl "FORMULA"``: print the Büchi automaton of an LTL formula in HOA v1.

FORMATS.md command-line contract: the automaton goes to stdout (exit 0); a formula that does
not parse gives one line ``error: ...`` on stderr, with the column, and exit 2. Every other
error of the product (:class:`~navigation.errors.HarmonicTampError`) is reported the same way.
"""

from __future__ import annotations

import argparse
import sys
import time

from navigation.errors import HarmonicTampError

from .hoa import to_hoa
from .syntax import parse
from .translate import to_buchi

__all__ = ["main"]

_EPILOG = """\
formula syntax (FORMATS.md): region names [a-z][a-z0-9_]*, true, false, ! X F G (<> []),
& | -> <-> U R W M, parentheses. Precedence from loosest: <->, ->, |, &, U R W M, unary.
examples: python -m tamp.ltl "G F a & G !b"
          python -m tamp.ltl --stats "F(a & F b)" > mission.hoa
          python -m tamp.ltl --exclusive --stats "F a & F b & F c & F d & F e & F f & F g & F h"
No environment variable is read."""


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Show option defaults and keep the epilog's line breaks."""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m tamp.ltl",
        description="Translate an LTL formula into a state-based Büchi automaton and print it "
        "in HOA v1 on stdout.",
        epilog=_EPILOG,
        formatter_class=_HelpFormatter,
    )
    p.add_argument("formula", help="the LTL formula (quote it for the shell)")
    p.add_argument(
        "--stats",
        action="store_true",
        help="also print a one-line summary on stderr: states, edges, accepting states and "
        "translation time in ms",
    )
    p.add_argument(
        "--exclusive",
        action="store_true",
        help="at most one proposition holds at a time (a world's regions are disjoint discs): "
        "the automaton the mission planner uses, with no edge for a letter of two or more "
        "propositions (n + 1 letters instead of 2^n)",
    )
    return p


def _first_line(err: BaseException) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__


def main(argv: list[str] | None = None) -> int:
    """Run the command; returns the exit status (0 success, 2 bad formula or other error)."""
    args = _parser().parse_args(argv)
    try:
        formula = parse(args.formula)
        t0 = time.perf_counter()
        buchi = to_buchi(formula, exclusive=args.exclusive)
        elapsed_ms = (time.perf_counter() - t0) * 1e3
        text = to_hoa(buchi)
    except HarmonicTampError as err:
        print(f"error: {_first_line(err)}", file=sys.stderr)
        return 2
    sys.stdout.write(text)
    sys.stdout.flush()
    if args.stats:
        print(
            f"states: {buchi.num_states}, edges: {buchi.num_edges}, accepting states: "
            f"{len(buchi.accepting)}, translation: {elapsed_ms:.1f} ms",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
