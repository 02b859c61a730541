"""The integer grid positions are quantized to, sized from the extent of a scene's dense core.

Positions map to cells of a cube grid: ``i = round((p - origin) / cell)``, and back to
``origin + i * cell`` in float64, rounded once to float32 — two correctly rounded IEEE
operations, so every decoder reconstructs identical positions.

The cell size comes from the robust extent (percentile box) of the scene's *dense core*
(:func:`dense_core`), not of all points: far floaters, whatever their share below one half,
do not coarsen the grid. Gaussians that lie outside what ``max_bits`` can cover at that cell
size are "far points", coded apart (:mod:`csgs_codec.attributes.far_positions`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError

#: Most bits per axis a grid may use (the geometry coder's limit).
MAX_BITS = 21
#: The dense core's radius doubles while the shell it would add holds more than this share
#: of the points it would then contain (see :func:`dense_core`).
CORE_SHELL_SHARE = 1.0 / 256
#: A 2x gap ends the core when at most this share of the points lies beyond it (a 4x gap
#: ends it whatever lies beyond, below one half).
CORE_LEFT_OUT = 0.25


def dense_core(positions: np.ndarray) -> np.ndarray:
    """The (N,) boolean mask of the scene's dense core: the points within Chebyshev distance
    R of the per-axis median.

    R starts at the median Chebyshev distance r50 (the median of the positive distances
    when more than half of the points sit on the median) and doubles until the shell
    (R, 2R] holds at most ``CORE_SHELL_SHARE`` of the points within 2R (a gap of 2x in
    distance) and either the next shell (2R, 4R] does too (a gap of 4x: whatever lies
    beyond is far) or at most ``CORE_LEFT_OUT`` of all points lie beyond R. The median and
    r50 are set by the nearer half of the points, so any share of far points below one half
    leaves the core where the dense points are, and a shell of floaters beyond a 2x gap
    holding under a quarter of the points is left out too; a scene without such gaps (every
    object-centric capture measured: their points lie within 5 r50, without gaps) keeps all
    its points in the core. Points left out of the core stay on the grid when it can hold
    them: the core sets only the cell size.

    Args:
        positions: (N, 3) finite world positions.
    """
    p = np.asarray(positions, dtype=np.float64)
    n = len(p)
    if n == 0:
        return np.zeros(0, dtype=bool)
    centre = np.median(p, axis=0)
    d = np.max(np.abs(p - centre), axis=1)
    ds = np.sort(d)
    radius = float(ds[(n - 1) // 2])
    if radius <= 0:
        positive = ds[ds > 0]
        if not len(positive):
            return np.ones(n, dtype=bool)
        radius = float(positive[(len(positive) - 1) // 2])  # the spread of the others
    count = lambda r: int(np.searchsorted(ds, r, side="right"))  # noqa: E731
    while count(radius) < n:
        within, next1, next2 = count(radius), count(2 * radius), count(4 * radius)
        if next1 - within <= CORE_SHELL_SHARE * next1 and (
                next2 - next1 <= CORE_SHELL_SHARE * next2 or n - within <= n * CORE_LEFT_OUT):
            break
        radius *= 2
    return d <= radius


@dataclass(frozen=True)
class PositionGrid:
    """A cube grid: ``origin`` (3,) float64 world units, ``cell`` (> 0) world units per step,
    ``bits`` per axis (cells 0 .. 2**bits - 1)."""

    origin: tuple[float, float, float]
    cell: float
    bits: int

    @classmethod
    def fit(cls, positions: np.ndarray, resolution_bits: int, *, percentile: float = 1.0,
            max_bits: int = MAX_BITS) -> PositionGrid:
        """The grid for ``positions`` (N, 3): the robust box's largest side spans
        ``2**resolution_bits`` cells; the grid grows (up to ``max_bits``) to cover the rest.

        The robust box is that of the dense core (:func:`dense_core`); it runs per axis from
        ``sorted[k]`` to ``sorted[M - 1 - k]`` (0-based) of the M core points,
        k = ceil(percentile / 100 * (M - 1)), so even among a few dozen points a single
        floater is left out of it. When the grid would need more than ``max_bits``, the
        largest allowed grid is centred on the robust box and the points outside it are far
        points (``quantize`` marks them).

        Raises:
            InputError: ``resolution_bits`` outside 1..max_bits or non-finite positions.
        """
        if not 1 <= resolution_bits <= max_bits:
            raise InputError(f"resolution_bits must be in 1..{max_bits}, got {resolution_bits}")
        p = np.asarray(positions, dtype=np.float64)
        if len(p) == 0:
            return cls((0.0, 0.0, 0.0), 1.0, 1)
        if not np.all(np.isfinite(p)):
            raise InputError("positions must be finite", property="positions")
        # Sample percentiles, not interpolated ones: below ~100 points an interpolated 1%
        # would lie between a floater and its neighbour and stretch the box towards it.
        core = p[dense_core(p)]
        lo_r = np.percentile(core, percentile, axis=0, method="higher")
        hi_r = np.percentile(core, 100 - percentile, axis=0, method="lower")
        extent = float(np.max(hi_r - lo_r))
        full_lo, full_hi = p.min(axis=0), p.max(axis=0)
        if extent <= 0:  # the core's percentile box is flat: its full box, else all points'
            extent = float(np.max(core.max(axis=0) - core.min(axis=0)))
        if extent <= 0:
            extent = float(np.max(full_hi - full_lo))
        if extent <= 0:  # every point identical
            return cls(tuple(float(v) for v in full_lo), 1.0, 1)
        cell = extent / (2**resolution_bits - 1)
        span_cells = float(np.max(full_hi - full_lo)) / cell
        bits = max(resolution_bits, int(np.ceil(np.log2(span_cells + 1.0))))
        if bits <= max_bits:
            return cls(tuple(float(v) for v in full_lo), cell, bits)
        # Centre the largest allowed grid on the robust box; the rest become far outliers.
        centre = (lo_r + hi_r) / 2
        half = (2**max_bits - 1) * cell / 2
        return cls(tuple(float(v) for v in centre - half), cell, max_bits)

    def quantize(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cells (N, 3) int64 and the boolean (N,) mask of points inside the grid.

        Points outside (far outliers) get cell 0 and ``inside`` False.
        """
        p = np.asarray(positions, dtype=np.float64)
        idx = np.rint((p - np.asarray(self.origin)) / self.cell)
        top = 2**self.bits - 1
        inside = np.all((idx >= 0) & (idx <= top), axis=1)
        idx[~inside] = 0
        return idx.astype(np.int64), inside

    def dequantize(self, cells: np.ndarray) -> np.ndarray:
        """World positions (N, 3) float32 of ``cells`` (N, 3) integers."""
        c = np.asarray(cells, dtype=np.float64)
        with np.errstate(over="ignore"):  # callers check finiteness (a damaged header)
            return (np.asarray(self.origin, dtype=np.float64) + c * self.cell).astype(np.float32)

    @property
    def centre(self) -> tuple[float, float, float]:
        """The grid's centre, ``origin + (2**bits - 1) * cell / 2`` per axis (float64 world
        units): the centre of the dense core's box when far points exist."""
        half = (2**self.bits - 1) * self.cell / 2
        return tuple(float(v + half) for v in self.origin)

    @property
    def max_error(self) -> float:
        """Largest per-axis error of a point inside the grid, world units (half a cell, plus
        the float32 rounding of the result)."""
        top = max(abs(v) for v in self.origin) + (2**self.bits) * self.cell
        return self.cell / 2 + float(np.spacing(np.float32(top)))
