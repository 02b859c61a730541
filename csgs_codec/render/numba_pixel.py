"""The per-pixel rule the numba compositing kernels share: a tile's Gaussians packed for
the pixel loop and the alpha of one (Gaussian, pixel) pair in float32; importing this module
needs numba.

The rule is the one in :mod:`csgs_codec.render.composite_torch`.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.render.composite_torch import MAX_ALPHA, TRANSMITTANCE_STOP
from csgs_codec.render.numba_runtime import jit_kernel
from csgs_codec.render.projection import ALPHA_THRESHOLD

#: Typed constants keep the kernel arithmetic in float32, like the torch reference.
HALF = np.float32(0.5)
ONE = np.float32(1.0)
MAX_ALPHA32 = np.float32(MAX_ALPHA)
ALPHA_THRESHOLD32 = np.float32(ALPHA_THRESHOLD)
T_STOP = np.float32(TRANSMITTANCE_STOP)
#: A pair whose exponent is this far below log(threshold / opacity) is skipped without exp();
#: the margin dwarfs float32 rounding, so the exact alpha test still decides every close case.
POWER_MARGIN = np.float32(1e-3)


@jit_kernel()
def pack_tile(ids: np.ndarray, start: int, count: int, means2d: np.ndarray,
              conics: np.ndarray, opacities: np.ndarray) -> np.ndarray:
    """[count, 7] float32 rows (mean x, mean y, conic a, b, c, opacity, the exponent below
    which alpha misses the threshold) of a tile's Gaussians ``ids[start:start + count]``,
    packed contiguously so the per-pixel loop stays in cache."""
    packed = np.empty((count, 7), np.float32)
    for k in range(count):
        g = ids[start + k]
        packed[k, 0] = means2d[g, 0]
        packed[k, 1] = means2d[g, 1]
        packed[k, 2] = conics[g, 0]
        packed[k, 3] = conics[g, 1]
        packed[k, 4] = conics[g, 2]
        packed[k, 5] = opacities[g]
        packed[k, 6] = np.log(ALPHA_THRESHOLD32 / opacities[g]) - POWER_MARGIN
    return packed


@jit_kernel(inline="always")
def alpha_at(packed: np.ndarray, k: int, pxc: np.float32,
             pyc: np.float32) -> tuple[np.float32, np.float32, np.float32, np.float32]:
    """(alpha, exp(power), dx, dy) of packed Gaussian ``k`` at the pixel centre (pxc, pyc),
    in float32 by the compositing rule; alpha is 0 where it misses the 1/255 threshold."""
    dx = pxc - packed[k, 0]
    dy = pyc - packed[k, 1]
    power = (-HALF * (packed[k, 2] * dx * dx + packed[k, 4] * dy * dy)
             - packed[k, 3] * dx * dy)
    zero = np.float32(0.0)
    if power < packed[k, 6]:
        return zero, zero, dx, dy
    falloff = np.exp(power)
    alpha = min(MAX_ALPHA32, packed[k, 5] * falloff)
    if alpha < ALPHA_THRESHOLD32:
        return zero, falloff, dx, dy
    return alpha, falloff, dx, dy
