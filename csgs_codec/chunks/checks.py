"""A check every chunk reader applies to the values it decodes."""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import FormatError


def check_finite(values: np.ndarray, chunk: str) -> None:
    """FormatError when a decoded stream holds a non-finite value (float32 overflow)."""
    if values.size and not np.all(np.isfinite(values)):
        raise FormatError("decoded values overflow float32", chunk=chunk)
