"""Make a peer tool's decoded PLY acceptable to csgs's reader without changing what it means.

PlayCanvas's compressed PLY stores opacity as 8 bits of sigmoid(opacity); codes 0 and 255
decode to logits of -inf and +inf, which ``read_ply`` rejects as non-finite. They are clamped
to +-:data:`OPACITY_LOGIT_LIMIT` (opacity 1e-6 from 0 or 1), the same convention the shared
scenes converted from that format use, so a renderer sees the same picture.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyParseError

from csgs_codec.errors import InputError

#: logit(1 - 1e-6): the largest opacity logit the fix-up writes for +inf (and minus for -inf).
OPACITY_LOGIT_LIMIT = float(np.log((1.0 - 1e-6) / 1e-6))


def clamp_infinite_opacity(path: str | Path) -> int:
    """Clamp +-inf opacity logits in the PLY at ``path`` in place; return how many changed.

    The file is rewritten (same properties, order and binary little-endian format) only when
    some value changed. NaN is left alone: that is a real decode error for the reader to name.

    Raises:
        InputError: the file is not a PLY with a ``vertex`` element holding ``opacity``.
    """
    path = Path(path)
    try:
        ply = PlyData.read(str(path))
        vertex = ply["vertex"]
        opacity = vertex.data["opacity"]
    except (OSError, ValueError, KeyError, PlyParseError) as error:
        raise InputError(f"not a PLY with vertex opacity: {error}", file=path) from error
    infinite = np.isinf(opacity)
    count = int(infinite.sum())
    if count == 0:
        return 0
    data = vertex.data.copy()
    data["opacity"] = np.clip(opacity, -OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT)
    vertex.data = data
    ply.text = False
    ply.byte_order = "<"
    ply.write(str(path))
    return count
