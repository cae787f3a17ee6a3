"""Bounded ``argparse`` types shared by every command line of the project.

Each factory returns a callable for ``add_argument(type=...)`` that turns the text into a number
or raises :class:`argparse.ArgumentTypeError` with one line naming the bound and the value, so
``argparse`` prints ``error: argument --opt: must be ...`` and exits 2 (no traceback, no silent
NaN or negative count reaching the product code). Used by ``harmonic-tamp-nav``,
``tamp-service``, ``python -m service.sim_node``, ``python -m tamp.run`` and the benchmarks.
It lives in :mod:`navigation`, the lowest layer, so every package can use it.
"""

from __future__ import annotations

import argparse
import math

__all__ = ["integer", "number", "positive", "seed", "world_name"]


def integer(minimum: int | None = None, maximum: int | None = None):
    """An integer in ``[minimum, maximum]`` (either bound may be open)."""
    if minimum is not None and maximum is not None:
        bound = f"between {minimum} and {maximum}"
    elif minimum is not None:
        bound = f">= {minimum}"
    elif maximum is not None:
        bound = f"<= {maximum}"
    else:
        bound = "any integer"

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if (minimum is not None and v < minimum) or (maximum is not None and v > maximum):
            raise argparse.ArgumentTypeError(f"must be an integer {bound}, got {text!r}")
        return v

    parse.__name__ = f"integer {bound}"
    return parse


def number(minimum: float | None = None, maximum: float | None = None, *, above: float | None = None):
    """A finite float in ``[minimum, maximum]``, or ``> above`` (bounds may be open)."""
    parts = [f">= {minimum:g}"] if minimum is not None else []
    parts += [f"> {above:g}"] if above is not None else []
    parts += [f"<= {maximum:g}"] if maximum is not None else []
    bound = " and ".join(parts)
    what = f"a finite number {bound}".rstrip()

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if (not math.isfinite(v) or (minimum is not None and v < minimum)
                or (above is not None and v <= above) or (maximum is not None and v > maximum)):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        return v

    parse.__name__ = what
    return parse


#: A finite number > 0 (rates, durations, speeds, limits).
positive = number(above=0.0)

#: A random seed: numpy refuses negative ones.
seed = integer(0)


def world_name(text: str) -> str:
    """A world file or built-in name that loads (:func:`navigation.load_world`); returns the text.

    For commands that hand the name on (to worker processes, to reports), so that a missing or
    invalid world is one usage error before any work instead of a traceback later."""
    from .errors import WorldError
    from .world import load_world

    try:
        load_world(text)
    except WorldError as err:
        raise argparse.ArgumentTypeError(str(err).replace("\n", " ")) from None
    return text


world_name.__name__ = "world"
