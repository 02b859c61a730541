"""The row-at-a-time compositing kernels (csgs_codec/render/numba_composite.py) give what
the plain per-pixel walk gives, bit for bit: images, transmittance, walked counts and slot
gradients; the row test drops only (Gaussian, pixel) pairs whose alpha is 0."""

from __future__ import annotations

import math

import numpy as np
import pytest

from csgs_codec.render.numba_loader import numba_available
from tests.render.test_tile_culling import _hostile_footprints, _rects

needs_numba = pytest.mark.skipif(not numba_available(), reason="numba not installed")


def _binned(width, height, tile_size, seed, n=3000):
    from csgs_codec.render import numba_kernels as kernels

    means2d, conics, opacities, extents = _hostile_footprints(n, width, height, seed)
    rects = _rects(means2d, extents, width, height, tile_size)
    order = np.argsort(np.random.default_rng(seed).random(len(means2d)), kind="stable")
    tiles_x, tiles_y = math.ceil(width / tile_size), math.ceil(height / tile_size)
    offsets, ids = kernels.bin_tiles(rects, order, tiles_x * tiles_y, tiles_x, tile_size,
                                     width, height, means2d, conics, opacities)
    return offsets, ids, means2d, conics, opacities, tiles_x


def _run(forward, backward, offsets, ids, means2d, conics, opacities, values, width, height,
         tile_size, tiles_x, seed):
    out = np.zeros((height, width, values.shape[1]), np.float32)
    trans = np.ones((height, width), np.float32)
    walked = np.zeros((height, width), np.int32)
    forward(offsets, ids, means2d, conics, opacities, values, width, height, tile_size, tiles_x,
            out, trans, walked)
    rng = np.random.default_rng(seed + 20)
    grads = np.zeros((len(ids), 6 + values.shape[1]), np.float32)
    backward(offsets, ids, means2d, conics, opacities, values, width, height, tile_size,
             tiles_x, out, trans, walked, rng.normal(size=out.shape).astype(np.float32),
             rng.normal(size=trans.shape).astype(np.float32), grads)
    return out, trans, walked, grads


@needs_numba
@pytest.mark.parametrize("tile_size, seed, threads", [(16, 3, 2), (8, 4, 1), (16, 5, 1)])
def test_row_kernels_match_the_plain_walk_bit_for_bit(tile_size, seed, threads):
    import numba

    from csgs_codec.render import numba_kernels as kernels
    from tests.render.plain_walk import plain_backward, plain_composite

    width, height = 93, 71  # not multiples of the tile: the last row and column are short
    offsets, ids, means2d, conics, opacities, tiles_x = _binned(width, height, tile_size, seed)
    values = np.random.default_rng(seed + 10).random((len(means2d), 4)).astype(np.float32)
    args = (offsets, ids, means2d, conics, opacities, values, width, height, tile_size,
            tiles_x, seed)
    plain = _run(plain_composite, plain_backward, *args)
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        rows = _run(kernels.composite_tiles, kernels.composite_tiles_backward, *args)
    finally:
        numba.set_num_threads(before)
    out, trans, walked, _ = plain
    lengths = np.diff(offsets)
    tile_of = ((np.arange(height)[:, None] // tile_size) * tiles_x
               + np.arange(width)[None, :] // tile_size)
    assert trans.min() < 0.5, "the Gaussians should cover the image"
    assert (walked < lengths[tile_of]).any(), "some pixels should stop before their list ends"
    for name, got, expected in zip(("image", "transmittance", "walked", "slot gradients"),
                                   rows, plain):
        np.testing.assert_array_equal(got, expected, err_msg=name)
    assert np.abs(plain[3]).max() > 0


@needs_numba
def test_every_pair_the_row_test_drops_has_alpha_zero():
    """Each (Gaussian, pixel) pair outside its row's column range gets alpha 0 from the
    compositing rule in float32; and the test drops a good share of the pairs a tile holds
    (these footprints are large; on a training view it drops about two pairs in three)."""
    from csgs_codec.render.numba_composite import row_columns
    from csgs_codec.render.numba_pixel import alpha_at, pack_tile

    width, height, tile_size = 64, 48, 16
    offsets, ids, means2d, conics, opacities, tiles_x = _binned(width, height, tile_size, 9,
                                                                n=800)
    dropped = tried = 0
    for t in range(len(offsets) - 1):
        start, count = int(offsets[t]), int(offsets[t + 1] - offsets[t])
        if count == 0:
            continue
        packed = pack_tile(ids, start, count, means2d, conics, opacities)
        x0, y0 = (t % tiles_x) * tile_size, (t // tiles_x) * tile_size
        cols = min(x0 + tile_size, width) - x0
        lows, highs = np.empty(count, np.int64), np.empty(count, np.int64)
        for py in range(y0, min(y0 + tile_size, height)):
            row_columns(packed, count, x0, cols, py, lows, highs)
            assert ((lows >= 0) & (lows <= highs) & (highs <= cols)).all()
            for k in range(count):
                for j in range(cols):
                    if lows[k] <= j < highs[k]:
                        tried += 1
                        continue
                    dropped += 1
                    alpha = alpha_at(packed, k, np.float32(x0 + j) + np.float32(0.5),
                                     np.float32(py) + np.float32(0.5))[0]
                    assert alpha == 0, (t, k, py, j)
    assert dropped > tried / 2


@needs_numba
def test_balanced_tiles_deal_every_full_tile_once():
    from csgs_codec.render.numba_composite import balanced_tiles

    lengths = np.array([0, 5, 0, 9, 1, 1, 7, 0, 3], np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    jobs = balanced_tiles(offsets, 2)
    assert sorted(jobs.tolist()) == [1, 3, 4, 5, 6, 8]
    shares = [lengths[jobs[:3]].sum(), lengths[jobs[3:]].sum()]
    assert shares == [13, 13]  # 9 + 3 + 1 against 7 + 5 + 1
