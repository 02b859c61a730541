"""The built-in classical segmenter: graph-based segmentation (Felzenszwalb & Huttenlocher 2004).

The fallback that makes instance masks when a dataset comes without any. It is far weaker than
a learned segmenter (SAM and the like): it splits textured objects and merges objects of
similar color, and stage-2 semantic quality follows the masks.

Method: the image (scaled to 0..255) is smoothed with a Gaussian (``sigma``), every pixel is
joined to its 8 neighbours by an edge weighted with the RGB distance, and edges are visited in
increasing weight (stable order): two components merge when the edge is no heavier than either
component's internal difference plus ``scale / size``. Components under ``min_size`` pixels are
then merged into a neighbour along the lightest edges. Ids are numbered 0, 1, ... in raster
order of each segment's first pixel. Everything is deterministic. Images above
:data:`MAX_SEGMENT_PIXELS` are segmented at a reduced size and the ids scaled back up.
"""

from __future__ import annotations

import math

import numpy as np

from csgs_codec.errors import InputError

#: Images above this many pixels are segmented at a reduced size (speed), ids upsampled.
MAX_SEGMENT_PIXELS = 1 << 18


def _merge_components(edges_a: np.ndarray, edges_b: np.ndarray, weights: np.ndarray,
                      n_pixels: int, scale: float, min_size: int) -> np.ndarray:
    """Union-find over edges sorted by weight: (n_pixels,) int64 root of each pixel."""
    parent = np.arange(n_pixels)
    size = np.ones(n_pixels, dtype=np.int64)
    threshold = np.full(n_pixels, scale, dtype=np.float64)
    for i in range(edges_a.size):
        a = edges_a[i]
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        b = edges_b[i]
        while parent[b] != b:
            parent[b] = parent[parent[b]]
            b = parent[b]
        if a != b and weights[i] <= threshold[a] and weights[i] <= threshold[b]:
            if size[a] < size[b]:
                a, b = b, a
            parent[b] = a
            size[a] += size[b]
            threshold[a] = weights[i] + scale / size[a]
    for i in range(edges_a.size):  # small components join their lightest neighbour
        a = edges_a[i]
        while parent[a] != a:
            a = parent[a]
        b = edges_b[i]
        while parent[b] != b:
            b = parent[b]
        if a != b and (size[a] < min_size or size[b] < min_size):
            if size[a] < size[b]:
                a, b = b, a
            parent[b] = a
            size[a] += size[b]
    roots = np.empty(n_pixels, dtype=np.int64)
    for p in range(n_pixels):
        r = p
        while parent[r] != r:
            r = parent[r]
        roots[p] = r
    return roots


try:
    from csgs_codec.render.numba_runtime import compile_safely, jit_kernel

    _merge = compile_safely(jit_kernel()(_merge_components))
except ImportError:  # numba is the optional "fast" extra; the plain loop gives the same ids
    _merge = _merge_components


def _gaussian_blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """(H, W, C) float64 separable Gaussian blur with edge-replicating borders."""
    if sigma <= 0:
        return image
    radius = max(1, int(math.ceil(4 * sigma)))
    taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    taps /= taps.sum()
    out = image
    for axis in (0, 1):
        pad = [(0, 0)] * 3
        pad[axis] = (radius, radius)
        padded = np.pad(out, pad, mode="edge")
        length = out.shape[axis]
        out = sum(taps[k] * np.take(padded, np.arange(k, k + length), axis=axis)
                  for k in range(taps.size))
    return out


def _grid_edges(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel index pairs (E,), (E,) of the 8-neighbour grid (each pair once)."""
    index = np.arange(height * width).reshape(height, width)
    pairs = [(index[:, :-1], index[:, 1:]), (index[:-1, :], index[1:, :]),
             (index[:-1, :-1], index[1:, 1:]), (index[:-1, 1:], index[1:, :-1])]
    return (np.concatenate([a.ravel() for a, _ in pairs]),
            np.concatenate([b.ravel() for _, b in pairs]))


def segment_image(image: np.ndarray, *, scale: float = 300.0, sigma: float = 0.8,
                  min_size: int | None = None) -> np.ndarray:
    """Segment an RGB image into regions of similar color (see the module notes).

    Args:
        image: (H, W, 3) float RGB in [0, 1].
        scale: the k of Felzenszwalb & Huttenlocher on 0..255 colors; larger gives fewer,
            larger segments.
        sigma: Gaussian pre-smoothing in pixels (0 for none).
        min_size: smallest segment in pixels; default 0.1% of the image (at least 8).

    Returns:
        (H, W) int32 segment ids 0..S-1, in raster order of first appearance.

    Raises:
        InputError: the image is not (H, W, 3) finite.
    """
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] < 1 or image.shape[1] < 1:
        raise InputError(f"expected an (H, W, 3) image, got shape {image.shape}",
                         property="image")
    if not np.all(np.isfinite(image)):
        raise InputError("image holds non-finite values", property="image")
    height, width = image.shape[:2]
    factor = math.sqrt(height * width / MAX_SEGMENT_PIXELS)
    if factor > 1:
        from csgs_codec.train.image_files import resize_image, resize_mask

        small_w, small_h = max(1, round(width / factor)), max(1, round(height / factor))
        small = resize_image(image.astype(np.float32), small_w, small_h)
        ids = segment_image(small, scale=scale, sigma=sigma,
                            min_size=None if min_size is None
                            else max(1, round(min_size / factor**2)))
        return _renumber(resize_mask(ids, width, height))
    if min_size is None:
        min_size = max(8, height * width // 1000)
    smooth = _gaussian_blur(image.astype(np.float64) * 255.0, sigma)
    a, b = _grid_edges(height, width)
    flat = smooth.reshape(-1, 3)
    weights = np.sqrt(np.sum((flat[a] - flat[b]) ** 2, axis=1))
    order = np.argsort(weights, kind="stable")
    roots = _merge(a[order], b[order], weights[order], height * width, float(scale),
                   int(min_size))
    return _renumber(roots.reshape(height, width))


def _renumber(ids: np.ndarray) -> np.ndarray:
    """(H, W) ids renumbered 0..S-1 in raster order of first appearance, int32."""
    _, first, inverse = np.unique(ids.ravel(), return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[inverse].reshape(ids.shape).astype(np.int32)
