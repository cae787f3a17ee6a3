"""The compiled (numba) kernels of the navigation core, and their one-time warm-up.

The forest construction, the exact squircle geometry and the second-order evaluation of the
transformation chain run in numba kernels (``navigation._geom_kernel``, ``_sample_kernel``,
``_pair_kernel``, ``_lp_kernel``, ``_center_kernel``, ``_chain_kernel``). numba compiles a
kernel on its first call and caches the machine code on disk (``cache=True``, in the package's
``__pycache__``), so the first process on a machine pays the compilation (57 s on the 2-core
reference machine on 2026-11-26, about 10 s of it for the chain kernels) and later processes
load the cache (well under a second). :func:`warm_up` makes that cost happen at a chosen moment
(service start-up) instead of at the first map change of a running robot;
:func:`compiled_signatures` lets a test check that nothing compiles after it.
"""

from __future__ import annotations

import time

import numba
import numpy as np

__all__ = ["warm_up", "compiled_signatures"]


def _modules():
    from . import _center_kernel, _chain_kernel, _geom_kernel, _lp_kernel, _pair_kernel, _sample_kernel

    return (_geom_kernel, _sample_kernel, _pair_kernel, _lp_kernel, _center_kernel, _chain_kernel)


def compiled_signatures(modules=()) -> dict[str, int]:
    """Number of compiled type signatures of every kernel (``module.function``) of the navigation
    kernel modules and of ``modules`` (other packages' kernel modules) in this process."""
    out = {}
    for mod in _modules() + tuple(modules):
        for name, obj in vars(mod).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher):
                out[f"{mod.__name__}.{name}"] = len(obj.signatures)
    return out


def warm_up() -> float:
    """Compile (or load from the cache) every navigation kernel with the argument types the
    construction and the simulator use: builds the forest and navigation function of a small
    world with an inner tree, a thin overlap and a wall crossing the workspace boundary, and
    calls the kernels a forest may not reach (refined extreme values, ray entries). Returns the
    seconds it took."""
    from ._geom_kernel import nearest_sample_distance, sample_table
    from ._sample_kernel import extreme_betas_arrays, sample_rows
    from .forest import build_forest
    from .geometry import Squircle, pack, ray_length_packed
    from .oriented import OrientedField
    from .potential import NavigationFunction

    t0 = time.perf_counter()
    ws = Squircle((0.0, 0.0), 10.0, 10.0, 0.0, 0.99)
    obstacles = [Squircle((4.8, 0.0), 1.0, 3.0, 0.0, 0.99),  # crosses the boundary
                 Squircle((-2.0, 0.0), 2.0, 0.5, 0.3, 0.99), Squircle((-1.2, 0.6), 0.5, 2.0, 0.3, 0.9),  # a tree
                 Squircle((1.0, 2.9), 2.0, 0.4, 0.0, 0.99), Squircle((1.0, 3.885), 0.4, 1.6, 0.0, 0.99),  # thin
                 Squircle((1.5, -3.0), 1.0, 1.0, 0.0, 0.5)]
    forest = build_forest(ws, obstacles)
    forest.distances, forest.wall_distance  # noqa: B018 (lazy exact distances)
    nf = NavigationFunction(forest, (-3.0, -3.5))
    nf.evaluate(np.array([[-3.0, 3.0], [3.0, -1.0]]), 2)
    OrientedField(nf, 0.5).evaluate(np.array([[-3.0, 3.0]]))  # the controller's field (oriented kernel)
    P, psi, pts, w0, spacing = sample_rows(pack(obstacles[:2]), 64)
    extreme_betas_arrays(P[::-1].copy(), np.array([1.0, -1.0]), np.zeros((2, 64)), P, psi, pts, spacing, w0)
    ray_length_packed(pack(obstacles[:1]), np.array([[0.0, 0.0]]), np.array([[1.0, 0.0]]), np.ones(1, bool))
    _, pts16, _ = sample_table(pack(obstacles[:1])[0], 16)  # ExactDistance's tables (clearances, the simulator)
    nearest_sample_distance(pts16[None], np.zeros(1, np.intp), np.zeros((1, 2)))  # their sampled distances
    obstacles[-1].distance(np.array([[0.0, 0.0], [3.0, 3.0]]))  # ExactDistance's refinement
    obstacles[-1].offset_points(0.1, 16)  # boundary points and offset curves (Squircle.grow)
    Squircle((0.0, 0.0), 0.2, 0.6, 0.1, 0.99).grow_snug(0.13)  # the roadmaps' inflation (not memoised yet)
    obstacles[-1].gradient(np.array([[0.0, 0.0]]))  # Squircle.gradient
    return time.perf_counter() - t0
