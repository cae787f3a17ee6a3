"""The numba kernels of navigation._sample_kernel (behind navigation.forest's ``_sample_rows`` and
its relation tests; the samples equal Squircle.boundary_psi's to rounding, the extreme betas were bit-identical to the former numpy code on every captured build input) on
inputs captured from real builds and random ones: samples on the boundary, evenly spaced in arc
length; extreme betas never worse than a dense sampling where they are refined, and of the right
sign elsewhere; rows independent of their batch."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import navigation
import navigation.forest as nf
from navigation._sample_kernel import extreme_betas_arrays, sample_rows
from navigation.geometry import CX, CY, S, beta_gradient_rows, point_at_rows

from .conftest import shared_world
from .worldgen import random_forest_world



def _world(name):
    """A named example world or ``(seed, n_obstacles)`` of :func:`random_forest_world`."""
    if isinstance(name, str):
        return shared_world(name)
    return _random_world(*name)


@functools.lru_cache(maxsize=None)
def _random_world(seed: int, n: int):
    """``random_forest_world(seed, n_obstacles=n, max_depth=4)``, generated once."""
    return random_forest_world(seed, n_obstacles=n, max_depth=4)


def _stack(bodies):
    """The stacked body fields ``(rows, psi, pts, spacing, w0)`` of :func:`extreme_betas_arrays`."""
    return (np.stack([b.row for b in bodies]), np.stack([b.psi for b in bodies]), np.stack([b.pts for b in bodies]),
            np.array([b.spacing for b in bodies]), np.array([b.w0 for b in bodies]))


@functools.lru_cache(maxsize=None)
def _captured(name):
    """Arguments of every ``_sample_rows`` call of a cold ``build_forest`` of world ``name``, and
    the extreme-beta problems of its relation tests: per obstacle the workspace's beta along
    its boundary (max and min), per pair of obstacles whose bounding discs meet the second's
    beta along the first's boundary (min and max), as ``(others, sign, vals, rows, psi, pts,
    spacing, w0)``."""
    world = _world(name)
    samples = []
    orig_s = nf._sample_rows

    def rec_s(P, n):
        samples.append((np.array(P), n))
        return orig_s(P, n)

    nf._sample_rows = rec_s
    try:
        nf.clear_cache()
        navigation.build_forest(world.workspace, world.obstacles)
        bodies = nf._bodies(world.obstacles, nf._SAMPLES)
        ws = nf._bodies([world.workspace], nf._WS_SAMPLES)[0]
    finally:
        nf._sample_rows = orig_s
        nf.clear_cache()
    assert samples
    problems = []
    for b in bodies:
        problems += [(ws.row, -1.0, b), (ws.row, 1.0, b)]
    for i, a in enumerate(bodies):
        for b in bodies[i + 1:]:
            if np.hypot(*(a.row[:2] - b.row[:2])) <= a.radius + b.radius:
                problems += [(b.row, 1.0, a), (b.row, -1.0, a), (a.row, -1.0, b)]
    others = np.array([o for o, _, _ in problems])
    sign = np.array([g for _, g, _ in problems])
    body = [b for _, _, b in problems]
    vals = nf._beta(others, np.stack([b.pts for b in body]))
    return samples, [(others, sign, vals, *_stack(body))]


def _random_rows(rng, K, s_max=0.99, aspect_min=0.2):
    """``K`` random packed squircles (half-extents 0.05 .. 3, aspect >= ``aspect_min``)."""
    P = np.zeros((K, 7))
    P[:, CX:CY + 1] = rng.uniform(-5.0, 5.0, (K, 2))
    th = rng.uniform(0.0, 2 * np.pi, K)
    P[:, 2], P[:, 3] = np.cos(th), np.sin(th)
    P[:, 4] = rng.uniform(0.05, 3.0, K)
    P[:, 5] = P[:, 4] * rng.uniform(aspect_min, 1.0, K)
    P[:, S] = rng.uniform(0.0, s_max, K)
    return P


# ---------------------------------------------------------------------- sample_rows
def test_sample_rows_rows_are_independent():
    P = _random_rows(np.random.default_rng(3), 30)
    P[::3, S] = 0.99
    batch = sample_rows(P, 256)
    for k in range(len(P)):
        for a, b in zip(sample_rows(P[k:k + 1], 256)[1:], batch[1:]):
            np.testing.assert_array_equal(a[0], b[k])


def _check_sample_properties(P, psi, pts, w0, spacing, chord_spread):
    """Samples on the boundary, angles increasing in ``[0, 2 pi)``, chords even to
    ``chord_spread`` (relative), ``spacing`` the largest chord, ``w0`` 1.5 x the largest gap."""
    np.testing.assert_allclose(pts, point_at_rows(P, psi), rtol=0, atol=1e-12)
    beta = nf._beta(P, pts)
    assert np.abs(beta).max() < 1e-12
    assert np.all(psi[:, 0] == 0.0) and np.all(np.diff(psi, axis=1) > 0) and np.all(psi[:, -1] < 2 * np.pi)
    chords = np.linalg.norm(pts - np.roll(pts, 1, axis=1), axis=2)
    assert np.all(chords.max(axis=1) <= (1.0 + chord_spread) * chords.min(axis=1))
    np.testing.assert_array_equal(spacing, chords.max(axis=1))
    gaps = np.diff(np.concatenate((psi, psi[:, :1] + 2 * np.pi), axis=1), axis=1)
    np.testing.assert_array_equal(w0, 1.5 * gaps.max(axis=1))


@pytest.mark.parametrize("n", [256, 1024])
def test_sample_rows_properties_random(n):
    # smooth squircles (aspect >= 1:5), as many samples as forest uses: chords within 1 %
    P = _random_rows(np.random.default_rng(100 + n), 200)
    _check_sample_properties(*sample_rows(P, n), chord_spread=0.01)


@pytest.mark.parametrize("name", ["office", "cluttered20", (0, 20)], ids=str)
def test_sample_rows_properties_real(name):
    # thin walls (aspect down to 1:10) with s = 0.99: chords within 2 %
    for P, n in _captured(name)[0]:
        _check_sample_properties(*sample_rows(P, n), chord_spread=0.02)


@pytest.mark.parametrize("n", [256, 1024, 90, 7])
def test_sample_rows_equal_boundary_psi(n):
    # the angles equal those of Squircle.boundary_psi (8 n chords) to rounding, for any n
    rng = np.random.default_rng(7 + n)
    P = _random_rows(rng, 40)
    P[::4, S] = 0.99
    P[1::4, S] = 0.0
    psi = sample_rows(P, n)[1]
    for k in range(len(P)):
        sq = navigation.Squircle(center=tuple(P[k, :2]), width=2 * P[k, 4], height=2 * P[k, 5],
                                 theta=float(np.arctan2(P[k, 3], P[k, 2])), s=float(P[k, S]))
        np.testing.assert_allclose(psi[k], sq.boundary_psi(n), rtol=0, atol=1e-11)


def test_sample_rows_empty():
    P, psi, pts, w0, spacing = sample_rows(np.zeros((0, 7)), 256)
    assert psi.shape == (0, 256) and pts.shape == (0, 256, 2) and w0.shape == spacing.shape == (0,)


# ---------------------------------------------------------------------- extreme_betas_arrays
def _random_pairs(seed, K=80, n=256):
    """Bodies sampled by :func:`sample_rows` and, per body, another squircle: a slightly moved,
    turned and scaled copy (extremes near zero: refined), or a random one (mostly not)."""
    rng = np.random.default_rng(seed)
    P, psi, pts, w0, spacing = sample_rows(_random_rows(rng, K), n)
    others = P.copy()
    step = 10.0 ** rng.uniform(-7, 0, K)
    others[:, CX:CY + 1] += step[:, None] * rng.standard_normal((K, 2))
    th = np.arctan2(P[:, 3], P[:, 2]) + step * rng.standard_normal(K)
    others[:, 2], others[:, 3] = np.cos(th), np.sin(th)
    others[:, 4:6] *= 1.0 + step[:, None] * rng.standard_normal((K, 2))
    others[K // 2:] = _random_rows(rng, K - K // 2)
    sign = np.where(rng.uniform(size=K) < 0.5, 1.0, -1.0)
    vals = nf._beta(others, pts)
    return others, sign, vals, P, psi, pts, spacing, w0


def _refined(others, sign, vals, pts, spacing):
    """Rows that ``_extreme_betas`` refines (its rule, in numpy)."""
    va = (sign[:, None] * vals).min(axis=1)
    gx, gy = beta_gradient_rows(others[:, None, :], pts[..., 0], pts[..., 1])
    return ~(np.abs(va) > 2.0 * spacing * np.hypot(gx, gy).max(axis=1) + 1e-12)


def test_extreme_betas_centre_on_a_sample():
    # another squircle centred on a sample: grad beta is NaN there (numpy: refine; no error)
    others, sign, vals, P, psi, pts, spacing, w0 = _random_pairs(11, K=10)
    others[:, CX:CY + 1] = pts[:, 7]
    vals = nf._beta(others, pts)
    got = extreme_betas_arrays(others, sign, vals, P, psi, pts, spacing, w0)
    assert np.all(got[sign > 0] == -1.0)  # the centre is the minimum
    assert np.all(np.isfinite(got))


def test_extreme_betas_rows_are_independent():
    args = _random_pairs(21, K=30)
    batch = extreme_betas_arrays(*args)
    for k in range(30):
        assert extreme_betas_arrays(*(a[k:k + 1] for a in args))[0] == batch[k]


def _check_dense(others, sign, vals, P, pts, spacing, got, m=16384):
    """Refined rows: ``sign * got`` at most every dense-sample value of ``sign * beta`` (+1e-12);
    the others: the sampled extreme, with the dense extreme's sign."""
    dense = np.linspace(0.0, 2 * np.pi, m, endpoint=False)
    f = sign[:, None] * nf._beta(others, point_at_rows(P, np.broadcast_to(dense, (len(P), m))))
    fmin = f.min(axis=1)
    g = sign * got
    assert np.all(g <= (sign[:, None] * vals).min(axis=1))
    ref = _refined(others, sign, vals, pts, spacing)
    assert np.all(g[ref] <= fmin[ref] + 1e-12)
    assert np.all(g[~ref] == (sign[:, None] * vals).min(axis=1)[~ref])
    assert np.all(np.sign(g[~ref]) == np.sign(fmin[~ref]))
    return ref.sum()


def test_extreme_betas_dense_random():
    refined = 0
    for seed in range(4):
        others, sign, vals, P, psi, pts, spacing, w0 = _random_pairs(seed)
        got = extreme_betas_arrays(others, sign, vals, P, psi, pts, spacing, w0)
        assert _refined(others, sign, vals, pts, spacing).sum() >= 20  # the pattern search is exercised
        refined += _check_dense(others, sign, vals, P, pts, spacing, got)
    assert refined >= 80


@pytest.mark.parametrize("name", ["office", "cluttered20", (0, 20), (5, 20)], ids=str)
def test_extreme_betas_dense_real(name):
    for others, sign, vals, rows, psi, pts, spacing, w0 in _captured(name)[1]:
        got = extreme_betas_arrays(others, sign, vals, rows, psi, pts, spacing, w0)
        _check_dense(others, sign, vals, rows, pts, spacing, got)


def test_extreme_betas_empty():
    assert extreme_betas_arrays(np.zeros((0, 7)), np.zeros(0), np.zeros((0, 256)), np.zeros((0, 7)),
                                np.zeros((0, 256)), np.zeros((0, 256, 2)), np.zeros(0), np.zeros(0)).shape == (0,)


# ---------------------------------------------------------------------- helpers
def test_inline_hypot_matches_numpy():
    import numba

    from navigation._sample_kernel import _hypot

    @numba.njit
    def run(x, y, out):
        for i in range(x.size):
            v, ok = _hypot(x[i], y[i])
            out[i] = v if ok else np.nan
        return out

    rng = np.random.default_rng(5)
    x = np.concatenate((rng.standard_normal(200_000),
                        rng.standard_normal(50_000) * 10.0 ** rng.integers(-300, 300, 50_000)))
    y = np.concatenate((rng.standard_normal(200_000) * rng.uniform(0, 1, 200_000),
                        rng.standard_normal(50_000) * 10.0 ** rng.integers(-300, 300, 50_000)))
    x[:8], y[:8] = [0.0, 0.0, 3.0, -0.0, 1e-300, 1e300, np.inf, np.nan], [0.0, 5.0, -4.0, 2.0, 1e-301, 1e299, 1.0, 1.0]
    got = run(x, y, np.empty_like(x))
    ok = ~np.isnan(got)
    assert ok[:4].all() and ok[8:200_000].all() and ok.sum() > 200_000 and not ok[4:8].any()
    # bit-identical to glibc's hypot (the same algorithm), within an ulp of any other libm's
    np.testing.assert_allclose(got[ok], np.hypot(x, y)[ok], rtol=2.3e-16, atol=0)


@pytest.mark.parametrize("name", ["office", (0, 20)], ids=str)
def test_max_grad_norm_matches_numpy(name):
    from navigation._sample_kernel import _max_grad_norm

    cases = [(o, pts) for o, _, _, _, _, pts, *_ in _captured(name)[1]]
    others, _, _, _, _, pts, _, _ = _random_pairs(31, K=40)
    others[:5, CX:CY + 1] = pts[:5, 3]  # centre on a sample: NaN
    cases.append((others, pts))
    for o, p in cases:
        gx, gy = beta_gradient_rows(o[:, None, :], p[..., 0], p[..., 1])
        ref = np.hypot(gx, gy).max(axis=1)
        got = np.array([_max_grad_norm(o[k], p[k], np.empty(p.shape[1])) for k in range(len(o))])
        np.testing.assert_array_equal(got, ref)


# ---------------------------------------------------------------------- relation codes
def _ref_workspace_codes(ws, rows, psi, pts, spacing, w0):
    """The former numpy rules of ``forest._workspace_relations`` on stacked bodies."""
    from navigation._sample_kernel import WS_COVERS, WS_CROSSES, WS_CROSSES_TWICE, WS_INSIDE, WS_OUTSIDE

    K = len(rows)
    W = np.broadcast_to(ws.row, (K, 7)).copy()
    vals = nf._beta(W, pts)
    lo, hi = vals.min(axis=1), vals.max(axis=1)
    out = np.full(K, -1)
    for r in range(K):
        one = (rows[r:r + 1], psi[r:r + 1], pts[r:r + 1], spacing[r:r + 1], w0[r:r + 1])
        if hi[r] < 0 and extreme_betas_arrays(W[r:r + 1], np.array([-1.0]), vals[r:r + 1], *one)[0] <= 0:
            out[r] = WS_INSIDE
        if lo[r] > 0 and extreme_betas_arrays(W[r:r + 1], np.array([1.0]), vals[r:r + 1], *one)[0] > 0:
            covers = np.all(nf._beta(rows[r:r + 1], ws.pts[None])[0] <= 0)
            out[r] = WS_COVERS if covers else WS_OUTSIDE
        if out[r] < 0:
            o = vals[r] > 0
            runs = 1 if o.all() else np.count_nonzero(o & ~np.roll(o, 1))
            out[r] = WS_CROSSES_TWICE if runs > 1 else WS_CROSSES
    return out


def _ref_pair_codes(I, J, rows, psi, pts, spacing, w0, contained=1e-12):
    """The former numpy rules of ``forest._pair_relations`` on stacked bodies."""
    from navigation._sample_kernel import PAIR_APART, PAIR_FIRST_INSIDE, PAIR_OVERLAP, PAIR_SECOND_INSIDE

    def ext(body, other, sign, vals):
        return extreme_betas_arrays(rows[other][None], np.array([sign]), vals[None], rows[body][None],
                                    psi[body][None], pts[body][None], spacing[body:body + 1], w0[body:body + 1])[0]

    out = []
    for a, b in zip(I, J):
        va = nf._beta(rows[b][None], pts[a][None])[0]
        vb = nf._beta(rows[a][None], pts[b][None])[0]
        over = va.min() < 0 or vb.min() < 0 or ext(a, b, 1.0, va) < 0
        if not over:
            out.append(PAIR_APART)
        elif vb.max() <= contained and ext(b, a, -1.0, vb) <= contained:
            out.append(PAIR_SECOND_INSIDE)
        elif va.max() <= contained and ext(a, b, -1.0, va) <= contained:
            out.append(PAIR_FIRST_INSIDE)
        else:
            out.append(PAIR_OVERLAP)
    return np.array(out)


@pytest.mark.parametrize("name", ["office", "cluttered20", (0, 20), (5, 20), (3, 50)], ids=str)
def test_relation_codes_equal_the_numpy_rules_real(name):
    from navigation._sample_kernel import pair_relation_codes, workspace_relation_codes

    world = _world(name)
    nf.clear_cache()
    bodies = nf._bodies(world.obstacles, nf._SAMPLES)
    ws = nf._bodies([world.workspace], nf._WS_SAMPLES)[0]
    fields = nf._stacked(bodies)
    got = workspace_relation_codes(ws.row, ws.pts, np.arange(len(bodies)), *fields)
    np.testing.assert_array_equal(got, _ref_workspace_codes(ws, *fields))
    I, J = np.triu_indices(len(bodies), 1)
    near = np.hypot(*(fields[0][I, :2] - fields[0][J, :2]).T) <= np.array([b.radius for b in bodies])[I] + \
        np.array([b.radius for b in bodies])[J] + 1e-3
    I, J = I[near], J[near]
    got = pair_relation_codes(I, J, *fields, 1e-12)
    np.testing.assert_array_equal(got, _ref_pair_codes(I, J, *fields))
    assert len(set(got.tolist())) >= 2


def test_relation_codes_equal_the_numpy_rules_random():
    # pairs of a squircle and a moved, turned, scaled copy (from 1e-7 to 1: touching, nearly
    # identical, contained, apart), in both orders, and against a random workspace
    from navigation._sample_kernel import pair_relation_codes, workspace_relation_codes

    rng = np.random.default_rng(5)
    K = 120
    base = _random_rows(rng, K)
    other = base.copy()
    step = 10.0 ** rng.uniform(-7, 0, K)
    other[:, CX:CY + 1] += step[:, None] * rng.standard_normal((K, 2))
    other[:, 4:6] *= 1.0 + step[:, None] * rng.uniform(-1, 1, (K, 2))
    other[K // 3:2 * K // 3, 4:6] = base[K // 3:2 * K // 3, 4:6] * 0.5  # contained halves
    other[K // 3:2 * K // 3, CX:CY + 1] = base[K // 3:2 * K // 3, CX:CY + 1]
    rows, psi, pts, w0, spacing = sample_rows(np.concatenate((base, other)), 256)
    fields = (rows, psi, pts, spacing, w0)
    I = np.concatenate((np.arange(K), np.arange(K, 2 * K)))
    J = np.concatenate((np.arange(K, 2 * K), np.arange(K)))
    got = pair_relation_codes(I, J, *fields, 1e-12)
    np.testing.assert_array_equal(got, _ref_pair_codes(I, J, *fields))
    assert len(set(got.tolist())) == 4
    ws = nf._bodies([navigation.Squircle((0.0, 0.0), 9.0, 7.0, 0.3, 0.9)], 1024)[0]
    got = workspace_relation_codes(ws.row, ws.pts, np.arange(2 * K), *fields)
    np.testing.assert_array_equal(got, _ref_workspace_codes(ws, *fields))
    assert len(set(got.tolist())) >= 3
