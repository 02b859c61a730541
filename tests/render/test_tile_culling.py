"""Binning drops a Gaussian from the tiles its footprint box covers but its ellipse misses,
and that changes no pixel: compositing with the culled lists gives the same float32 image,
transmittance and gradients, bit for bit, as with every tile of each box."""

from __future__ import annotations

import math

import numpy as np
import pytest

from csgs_codec.render.numba_loader import numba_available

needs_numba = pytest.mark.skipif(not numba_available(), reason="numba not installed")


def _box_binning(rects: np.ndarray, order: np.ndarray, n_tiles: int,
                 tiles_x: int) -> tuple[np.ndarray, np.ndarray]:
    """Every tile of every box, near to far: the binning without culling."""
    lists: list[list[int]] = [[] for _ in range(n_tiles)]
    for g in order:
        tx0, tx1, ty0, ty1 = rects[g]
        for ty in range(ty0, ty1):
            for tx in range(tx0, tx1):
                lists[ty * tiles_x + tx].append(int(g))
    offsets = np.concatenate([[0], np.cumsum([len(x) for x in lists])]).astype(np.int64)
    ids = np.array([g for x in lists for g in x], np.int64)
    return offsets, ids


def _hostile_footprints(n: int, width: int, height: int, seed: int):
    """float32 screen-space Gaussians of every shape: needles at every angle, discs, huge
    ones, ones centred far outside the image, opacities from the threshold up."""
    rng = np.random.default_rng(seed)
    means2d = np.column_stack([rng.uniform(-0.5 * width, 1.5 * width, n),
                               rng.uniform(-0.5 * height, 1.5 * height, n)])
    long_axis = np.exp(rng.uniform(np.log(0.3), np.log(3.0 * width), n))
    short_axis = long_axis * np.exp(rng.uniform(np.log(1e-3), 0.0, n))
    angle = rng.uniform(0.0, np.pi, n)
    cos, sin = np.cos(angle), np.sin(angle)
    # Covariance R diag(l^2, s^2) R^T + the 0.3 px^2 low-pass, then its inverse (the conic).
    sxx = (cos * long_axis) ** 2 + (sin * short_axis) ** 2 + 0.3
    syy = (sin * long_axis) ** 2 + (cos * short_axis) ** 2 + 0.3
    sxy = cos * sin * (long_axis ** 2 - short_axis ** 2)
    det = sxx * syy - sxy ** 2
    conics = np.column_stack([syy / det, -sxy / det, sxx / det])
    opacities = np.where(rng.random(n) < 0.2, rng.uniform(1.0 / 255.0, 0.02, n),
                         rng.uniform(0.02, 1.0, n))
    k = 2.0 * np.log(np.maximum(opacities * 255.0, 1.0))
    extents = np.sqrt(k[:, None] * np.column_stack([sxx, syy])) * (1.0 + 1e-4) + 1e-3
    return (means2d.astype(np.float32), conics.astype(np.float32),
            opacities.astype(np.float32), extents)


def _rects(means2d, extents, width, height, tile_size):
    tiles_x, tiles_y = math.ceil(width / tile_size), math.ceil(height / tile_size)
    lo = np.floor((means2d - extents) / tile_size)
    hi = np.floor((means2d + extents) / tile_size) + 1
    rects = np.column_stack([np.clip(lo[:, 0], 0, tiles_x), np.clip(hi[:, 0], 0, tiles_x),
                             np.clip(lo[:, 1], 0, tiles_y), np.clip(hi[:, 1], 0, tiles_y)])
    rects = rects.astype(np.int64)
    rects[:, 1] = np.maximum(rects[:, 1], rects[:, 0])
    rects[:, 3] = np.maximum(rects[:, 3], rects[:, 2])
    return rects


@needs_numba
@pytest.mark.parametrize("tile_size, seed", [(8, 0), (16, 1), (8, 2)])
def test_culled_tiles_composite_exactly_as_whole_boxes(tile_size, seed):
    from csgs_codec.render import numba_kernels as kernels

    width, height = 93, 71  # not multiples of the tile: the last row and column are short
    means2d, conics, opacities, extents = _hostile_footprints(3000, width, height, seed)
    rects = _rects(means2d, extents, width, height, tile_size)
    order = np.argsort(np.random.default_rng(seed).random(len(means2d)), kind="stable")
    tiles_x, tiles_y = math.ceil(width / tile_size), math.ceil(height / tile_size)
    values = np.random.default_rng(seed + 10).random((len(means2d), 4)).astype(np.float32)

    culled = kernels.bin_tiles(rects, order, tiles_x * tiles_y, tiles_x, tile_size, width,
                               height, means2d, conics, opacities)
    whole = _box_binning(rects, order, tiles_x * tiles_y, tiles_x)
    assert len(culled[1]) < 0.85 * len(whole[1]), "the test's ellipses should leave tiles out"

    results = []
    for offsets, ids in (culled, whole):
        out = np.zeros((height, width, 4), np.float32)
        trans = np.ones((height, width), np.float32)
        walked = np.zeros((height, width), np.int32)
        kernels.composite_tiles(offsets, ids, means2d, conics, opacities, values, width,
                                height, tile_size, tiles_x, out, trans, walked)
        grads = np.zeros((len(ids), 10), np.float32)
        rng = np.random.default_rng(seed + 20)
        kernels.composite_tiles_backward(
            offsets, ids, means2d, conics, opacities, values, width, height, tile_size,
            tiles_x, out, trans, walked, rng.normal(size=out.shape).astype(np.float32),
            rng.normal(size=trans.shape).astype(np.float32), grads)
        per_gaussian = kernels.sum_slots(ids, grads, len(means2d))
        results.append((out, trans, per_gaussian))
    assert results[0][1].min() < 0.5, "the Gaussians should cover the image"
    for got, expected in zip(results[0], results[1]):
        np.testing.assert_array_equal(got, expected)


@needs_numba
def test_every_dropped_tile_is_one_the_gaussian_never_reaches():
    """A direct check of the rule: each (Gaussian, tile) pair culled has alpha 0 at every
    pixel of the tile as the compositing loop computes it in float32."""
    from csgs_codec.render import numba_kernels as kernels

    width, height, tile_size = 64, 48, 8
    means2d, conics, opacities, extents = _hostile_footprints(800, width, height, 7)
    rects = _rects(means2d, extents, width, height, tile_size)
    order = np.arange(len(means2d))
    tiles_x = math.ceil(width / tile_size)
    offsets, ids = kernels.bin_tiles(rects, order, tiles_x * math.ceil(height / tile_size),
                                     tiles_x, tile_size, width, height, means2d, conics,
                                     opacities)
    kept = {(int(g), t) for t in range(len(offsets) - 1) for g in ids[offsets[t]:offsets[t + 1]]}
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32) + np.float32(0.5)
    dropped = 0
    for g in order:
        dx, dy = xs - means2d[g, 0], ys - means2d[g, 1]
        a, b, c = conics[g]
        power = np.float32(-0.5) * (a * dx * dx + c * dy * dy) - b * dx * dy
        reached = np.minimum(np.float32(0.99), opacities[g] * np.exp(power)) >= 1.0 / 255.0
        tx0, tx1, ty0, ty1 = rects[g]
        for ty in range(ty0, ty1):
            for tx in range(tx0, tx1):
                if (int(g), ty * tiles_x + tx) not in kept:
                    dropped += 1
                    window = reached[ty * tile_size:(ty + 1) * tile_size,
                                     tx * tile_size:(tx + 1) * tile_size]
                    assert not window.any(), (g, tx, ty)
    assert dropped > 100
