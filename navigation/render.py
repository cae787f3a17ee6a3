"""Render a world's navigation function to a PNG: heat map, boundaries, regions, descents.

This is the project's main job until the service exists::

    harmonic-tamp-nav office --out office_nf.png
    python -m navigation.render simple --region b --starts 20 --scale logit

The picture shows ``phi_NF / mu`` over the workspace (viridis: dark near the goal, yellow near
``mu``; ``--scale logit`` shows the harmonic potential ``phi_P`` instead, which the logistic
flattens near the boundaries), contour lines, the workspace and obstacle boundaries (inflated
obstacles in light grey when ``--inflation`` is set), the regions with their names, the goal,
and gradient-descent trajectories from random free starts (green: reached the goal, red: did
not). Points outside free space are dark grey. The whole grid is evaluated in one vectorised
call of ``nf.value`` and one of ``nf.is_free``.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from enum import Enum
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

from ._argtypes import integer, number, seed
from .descent import descend_many
from .errors import HarmonicTampError, OutsideFreeSpaceError, WorldError

__all__ = ["Scale", "Rendering", "render", "main"]

# BGR colours.
_OUTSIDE = (60, 60, 60)
_NONFINITE = (255, 0, 255)
_BOUNDARY = (255, 255, 255)
_GROWN = (170, 170, 170)
_REGION = (255, 255, 255)
_GOAL = (0, 0, 255)
_REACHED = (0, 200, 0)
_FAILED = (0, 0, 255)


class Scale(str, Enum):
    """What the heat map's colour shows.

    ``LINEAR``: ``phi_NF / mu`` on ``[0, 1]``. ``LOGIT``: ``ln(u / (1 - u))`` with ``u = phi_NF /
    mu``, which is the harmonic potential ``phi_P`` of the point world (eq. 9 inverted), stretched
    between its 1st and 99th percentiles over the free grid points; it shows the structure that
    the logistic flattens near ``mu``.
    """

    LINEAR = "linear"
    LOGIT = "logit"


@dataclass(frozen=True, slots=True)
class Rendering:
    """What :func:`render` drew and measured.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), uint8
        BGR picture, ready for ``cv2.imwrite``.
    points : int
        Grid points evaluated (``H * W``).
    free_fraction : float
        Fraction of grid points in free space.
    nonfinite : int
        Free grid points where ``nf.value`` was not finite (drawn magenta; should be 0).
    grid_seconds : float
        Wall time of the grid evaluation (``is_free`` and ``value``).
    reached, trajectories : int
        Descent trajectories that reached the goal, and trajectories drawn.
    descent_seconds : float
        Wall time of all descents.
    """

    image: np.ndarray
    points: int
    free_fraction: float
    nonfinite: int
    grid_seconds: float
    reached: int
    trajectories: int
    descent_seconds: float


def _builtin_names() -> list[str]:
    """Names of the worlds shipped in ``navigation/data/worlds`` (``load_world`` accepts them)."""
    worlds = resources.files(__package__) / "data" / "worlds"
    return sorted(p.name[:-5] for p in worlds.iterdir() if p.name.endswith(".json"))


def _pick_goal(world, goal, region) -> tuple[str, tuple[float, float]]:
    """The goal's label and position: ``--goal``, ``--region``, else the first region's centre."""
    if goal is not None:
        return f"({goal[0]:g}, {goal[1]:g})", (float(goal[0]), float(goal[1]))
    if region is None:
        if not world.regions:
            raise WorldError(f"world {world.name!r} has no regions; pass --goal X Y", "regions")
        region = next(iter(world.regions))
    if region not in world.regions:
        raise WorldError(f"unknown region {region!r} (world {world.name!r} has: "
                         f"{', '.join(world.regions) or 'none'})", "regions")
    cx, cy = world.regions[region].center
    return region, (float(cx), float(cy))


class _Canvas:
    """World-to-pixel mapping of the workspace's bounding box (y up in the world, down in pixels)."""

    def __init__(self, workspace, size: int):
        pts = workspace.boundary_points(512)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        margin = 0.02 * float(np.max(hi - lo))
        self.lo, self.hi = lo - margin, hi + margin
        self.res = float(np.max(self.hi - self.lo)) / size  # metres per pixel
        self.w = max(1, round((self.hi[0] - self.lo[0]) / self.res))
        self.h = max(1, round((self.hi[1] - self.lo[1]) / self.res))
        self.thick = max(1, size // 500)
        self.font = max(0.35, size / 1600)

    def grid(self) -> np.ndarray:
        """World coordinates of every pixel centre, row-major, shape ``(h * w, 2)``."""
        xs = self.lo[0] + (np.arange(self.w) + 0.5) * self.res
        ys = self.hi[1] - (np.arange(self.h) + 0.5) * self.res
        gx, gy = np.meshgrid(xs, ys)
        return np.column_stack((gx.ravel(), gy.ravel()))

    def px(self, points) -> np.ndarray:
        """Pixel coordinates (int32 ``(N, 2)``, columns x, y) of world points ``(N, 2)``."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        u = (p[:, 0] - self.lo[0]) / self.res
        v = (self.hi[1] - p[:, 1]) / self.res
        return np.round(np.column_stack((u, v))).astype(np.int32)

    def length(self, metres: float) -> int:
        return max(1, int(round(metres / self.res)))


def _heat_map(canvas: _Canvas, nf, levels: int, scale: Scale) -> tuple[np.ndarray, float, int, float]:
    """Colour every pixel by ``nf.value``; returns image, free fraction, non-finite count, time."""
    q = canvas.grid()
    t0 = time.perf_counter()
    free = np.asarray(nf.is_free(q), dtype=bool)
    value = np.asarray(nf.value(q), dtype=float)
    seconds = time.perf_counter() - t0
    ok = free & np.isfinite(value)
    u = np.clip(np.where(ok, value, nf.params.mu) / nf.params.mu, 0.0, 1.0)
    if scale is Scale.LOGIT:
        u = np.clip(u, 1e-15, 1.0 - 1e-15)
        z = np.log(u) - np.log1p(-u)
        lo, hi = np.percentile(z[ok], (1, 99)) if ok.any() else (0.0, 1.0)
        u = np.clip((z - lo) / max(hi - lo, 1e-12), 0.0, 1.0)
    u2, free2, ok2 = (a.reshape(canvas.h, canvas.w) for a in (u, free, ok))
    image = cv2.applyColorMap(np.round(255 * u2).astype(np.uint8), cv2.COLORMAP_VIRIDIS)
    if levels > 0:
        band = np.minimum(np.floor(u2 * levels), levels - 1)
        edge = np.zeros_like(free2)
        edge[:, 1:] |= band[:, 1:] != band[:, :-1]
        edge[1:, :] |= band[1:, :] != band[:-1, :]
        image[edge] = (image[edge] * 0.55).astype(np.uint8)
    image[~free2] = _OUTSIDE
    image[free2 & ~ok2] = _NONFINITE
    return image, float(free.mean()), int((free2 & ~ok2).sum()), seconds


def _random_free_starts(nf, canvas: _Canvas, n: int, rng: np.random.Generator) -> np.ndarray:
    """Up to ``n`` uniformly random points of free space (fewer if free space is tiny)."""
    found = np.empty((0, 2))
    for _ in range(20):
        if len(found) >= n:
            break
        cand = rng.uniform(canvas.lo, canvas.hi, size=(max(64, 4 * n), 2))
        found = np.vstack((found, cand[np.asarray(nf.is_free(cand), dtype=bool)]))
    return found[:n]


def render(nf, world, *, size: int = 640, starts: int = 10, seed: int = 0, levels: int = 20,
           scale: Scale = Scale.LINEAR, max_steps: int = 500) -> Rendering:
    """Draw ``nf`` over ``world`` (see the module docstring for what the picture shows).

    Parameters
    ----------
    nf : NavigationFunction
        Built for ``world``; supplies the values, the free space, the goal and the (inflated)
        obstacles of its forest.
    world : World
        Supplies the workspace, the true obstacles and the regions.
    size : int
        Pixels along the longer side of the workspace's bounding box.
    starts : int
        Descent trajectories (:func:`~navigation.descent.descend_many`, all starts advancing
        together) from uniformly random free starts drawn with ``seed``.
    levels : int
        Iso-lines between ``levels`` equal bands of the colour scale; 0 draws none.
    scale : Scale
        What the colour shows.
    max_steps : int
        Step limit of every descent.

    Returns
    -------
    Rendering
    """
    canvas = _Canvas(world.workspace, size)
    image, free_fraction, nonfinite, grid_seconds = _heat_map(canvas, nf, levels, scale)
    aa, t = cv2.LINE_AA, canvas.thick

    def outline(sq, colour, thickness):
        cv2.polylines(image, [canvas.px(sq.boundary_points(256))], True, colour, thickness, aa)

    given = {world.workspace, *world.obstacles}
    for sq in (nf.forest.workspace, *nf.forest.obstacles):
        if sq not in given:  # inflated
            outline(sq, _GROWN, 1)
    for sq in world.obstacles:
        outline(sq, _BOUNDARY, t)
    outline(world.workspace, _BOUNDARY, t)

    for name, region in world.regions.items():
        c = canvas.px(region.center)[0]
        cv2.circle(image, tuple(int(v) for v in c), canvas.length(region.radius), _REGION, t, aa)
        cv2.putText(image, name, (int(c[0]) + canvas.length(region.radius) + 2, int(c[1]) - 2),
                    cv2.FONT_HERSHEY_SIMPLEX, canvas.font, _REGION, 1, aa)

    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    points = _random_free_starts(nf, canvas, starts, rng) if starts > 0 else np.empty((0, 2))
    results = descend_many(nf, points, max_steps=max_steps) if len(points) else []
    for start, result in zip(points, results):
        colour = _REACHED if result.reached else _FAILED
        cv2.polylines(image, [canvas.px(result.path)], False, colour, t, aa)
        cv2.circle(image, tuple(int(v) for v in canvas.px(start)[0]), 2 * t + 1, colour, -1, aa)
    reached = sum(bool(r.reached) for r in results)
    descent_seconds = time.perf_counter() - t0

    cv2.drawMarker(image, tuple(int(v) for v in canvas.px(nf.goal)[0]), _GOAL, cv2.MARKER_TILTED_CROSS,
                   6 * t + 8, 2 * t, aa)
    return Rendering(image, canvas.w * canvas.h, free_fraction, nonfinite, grid_seconds,
                     reached, len(points), descent_seconds)


# ---------------------------------------------------------------------------------------- CLI
def _png(text: str) -> Path:
    if not text.lower().endswith(".png"):
        raise argparse.ArgumentTypeError(f"must name a .png file, got {text!r}")
    return Path(text)


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows defaults, except the ``None`` of options whose help already says what happens."""

    def _get_help_string(self, action):
        return action.help if action.default is None else super()._get_help_string(action)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="harmonic-tamp-nav",
        description="Build the harmonic navigation function of a world for one goal and render it "
                    "to a PNG: heat map of phi_NF/mu, iso-value lines, obstacle and workspace "
                    "boundaries, regions, goal, and gradient-descent trajectories from random "
                    "free starts (green: reached the goal, red: did not).",
        epilog=f"Built-in worlds: {', '.join(_builtin_names())}. Exit status: 0 on success, 2 on "
               "bad arguments, an invalid world, a goal outside free space or an unwritable "
               "output. No environment variables are read.",
        formatter_class=_HelpFormatter,
    )
    parser.add_argument("world", nargs="?", default="office",
                        help="world file (FORMATS.md JSON), or the bare name of a built-in world")
    target = parser.add_mutually_exclusive_group()
    target.add_argument("--goal", nargs=2, type=number(), metavar=("X", "Y"),
                        help="goal position in metres (default: centre of the world's first region)")
    target.add_argument("--region", metavar="NAME",
                        help="use the centre of this region as the goal")
    parser.add_argument("--inflation", type=number(0.0), default=0.0, metavar="R",
                        help="grow every obstacle by R metres (e.g. the robot radius)")
    parser.add_argument("--out", type=_png, default="nf.png", metavar="PATH", help="output PNG file")
    parser.add_argument("--size", type=integer(32, 8000), default=640, metavar="PX",
                        help="image size along the workspace's longer side, in pixels")
    parser.add_argument("--starts", type=integer(0, 10_000), default=10, metavar="N",
                        help="number of descent trajectories from random free starts (at most 10000)")
    parser.add_argument("--seed", type=seed, default=0, metavar="S",
                        help="seed of the random start positions (>= 0)")
    parser.add_argument("--max-steps", type=integer(0, 1_000_000), default=500, metavar="K",
                        help="step limit of each descent (a step is at most 1%% of the workspace's "
                             "larger extent; at most 1000000)")
    parser.add_argument("--scale", default=Scale.LINEAR.value, choices=[m.value for m in Scale],
                        help="colour scale: 'linear' shows phi_NF/mu, 'logit' shows the harmonic "
                             "potential ln(u/(1-u)), u = phi_NF/mu, stretched over its 1st-99th "
                             "percentiles")
    parser.add_argument("--levels", type=integer(0, 1000), default=20, metavar="L",
                        help="number of equal bands of the colour scale separated by contour lines "
                             "(0: none; at most 1000)")
    return parser


def _run(args) -> int:
    from . import NavigationFunction, load_world  # noqa: PLC0415  (keeps --help fast)

    out = args.out
    if not out.parent.is_dir() or out.is_dir():  # fail before the expensive part
        raise OSError(f"cannot write {str(out)!r}: " + ("it is a directory" if out.is_dir() else
                                                         f"no directory {str(out.parent)!r}"))
    world = load_world(args.world)
    print(f"world: {world.name} ({len(world.obstacles)} obstacles, {len(world.regions)} regions) "
          f"from {args.world}", flush=True)

    label, goal = _pick_goal(world, args.goal, args.region)
    t0 = time.perf_counter()
    try:
        nf = NavigationFunction(world, goal, inflation=args.inflation)
    except OutsideFreeSpaceError as err:
        if args.goal is None:  # say which region the goal came from
            raise OutsideFreeSpaceError(f"goal = centre of region {label!r}: {err}") from err
        raise
    built = time.perf_counter() - t0
    f = nf.forest
    print(f"navigation function: goal {label} at ({goal[0]:g}, {goal[1]:g}), inflation "
          f"{args.inflation:g} m, {len(f.obstacles)} obstacles ({len(f.dropped)} dropped) in "
          f"{len(f.roots)} interior trees, built in {built:.3f} s", flush=True)

    r = render(nf, world, size=args.size, starts=args.starts, seed=args.seed, levels=args.levels,
               scale=Scale(args.scale), max_steps=args.max_steps)
    h, w = r.image.shape[:2]
    print(f"grid: {w} x {h} px, {100 * r.free_fraction:.1f} % free, evaluated in "
          f"{r.grid_seconds:.3f} s ({1e6 * r.grid_seconds / r.points:.1f} us/point)", flush=True)
    if r.nonfinite:
        print(f"warning: {r.nonfinite} free grid points have a non-finite value (magenta)",
              file=sys.stderr, flush=True)
    if args.starts and r.trajectories < args.starts:
        print(f"warning: found only {r.trajectories} free starts of {args.starts} requested",
              file=sys.stderr, flush=True)
    print(f"trajectories: {r.reached}/{r.trajectories} reached the goal "
          f"({r.descent_seconds:.2f} s)", flush=True)

    try:
        ok = cv2.imwrite(str(out), r.image)
    except cv2.error as err:
        raise OSError(f"cannot write {str(out)!r}: {err}") from err
    if not ok:
        raise OSError(f"cannot write {str(out)!r}")
    print(f"wrote {out}", flush=True)
    return 0


def main(argv=None) -> int:
    """Entry point of ``harmonic-tamp-nav`` / ``python -m navigation.render``; returns the exit status.

    Bad arguments exit with status 2 through argparse. Every product error
    (:class:`~navigation.errors.HarmonicTampError`: invalid world, goal outside free space...)
    and every I/O error is reported as one ``error: ...`` line on stderr, with status 2.
    """
    args = _parser().parse_args(argv)
    try:
        return _run(args)
    except (HarmonicTampError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
