"""The result of rendering one view, as numpy arrays (what :func:`render` returns)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class RenderOutput:
    """One rendered view.

    Attributes:
        image: (H, W, 3) float32 linear RGB, background composited behind; not clipped (values
            may exceed 1 where SH colors do).
        alpha: (H, W) float32 accumulated opacity in [0, 1).
        depth: (H, W) float32 expected camera-space z (world units), 0 where alpha is 0.
        features: (H, W, F) float32 accumulated per-Gaussian features, or None.
        backend: the backend that produced it ("torch", "numba" or "gsplat").
    """

    image: np.ndarray
    alpha: np.ndarray
    depth: np.ndarray
    features: np.ndarray | None
    backend: str
