"""The integer grid positions are quantized to, sized from a scene's robust extent.

Positions map to cells of a cube grid: ``i = round((p - origin) / cell)``, and back to
``origin + i * cell`` in float64, rounded once to float32 — two correctly rounded IEEE
operations, so every decoder reconstructs identical positions. The cell size comes from the
robust extent (percentile box), so a few floaters do not coarsen the grid; Gaussians that lie
outside what ``max_bits`` can cover at that cell size are "far outliers", kept aside with their
exact float32 positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError

#: Most bits per axis a grid may use (the geometry coder's limit).
MAX_BITS = 21


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

        The robust box runs per axis from ``sorted[k]`` to ``sorted[N - 1 - k]`` (0-based),
        k = ceil(percentile / 100 * (N - 1)), so even among a few dozen points a single
        floater is left out of it.

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
        lo_r = np.percentile(p, percentile, axis=0, method="higher")
        hi_r = np.percentile(p, 100 - percentile, axis=0, method="lower")
        extent = float(np.max(hi_r - lo_r))
        full_lo, full_hi = p.min(axis=0), p.max(axis=0)
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
    def max_error(self) -> float:
        """Largest per-axis error of a point inside the grid, world units (half a cell, plus
        the float32 rounding of the result)."""
        top = max(abs(v) for v in self.origin) + (2**self.bits) * self.cell
        return self.cell / 2 + float(np.spacing(np.float32(top)))
