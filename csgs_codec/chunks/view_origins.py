"""The ``vorg`` chunk: where an anchor scene was trained to be seen from (FORMAT §17.12).

Optional, base layer. An anchor's neural Gaussians depend on the view; a receiver that bakes
them into a standard scene (:mod:`csgs_codec.bake.anchor_bake`) fits them over view origins,
and the origins the scene was trained from give a far better bake than a generic sphere (the
heads extrapolate badly to directions no training view saw). Nothing the decoder outputs as
anchors depends on the chunk, so an unreadable one does not make the file invalid: readers
report no origins (:func:`read_view_origins`).
"""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter

VERSION = 1
#: Most origins a payload holds; an encoder keeps an even sample of more.
MAX_ORIGINS = 32


def even_sample(origins: np.ndarray, limit: int = MAX_ORIGINS) -> np.ndarray:
    """At most ``limit`` rows of (V, 3) ``origins``, evenly spaced in their order, float32."""
    origins = np.asarray(origins, np.float32).reshape(-1, 3)
    if len(origins) <= limit:
        return origins.copy()
    picks = np.unique(np.linspace(0, len(origins) - 1, limit).round().astype(np.int64))
    return origins[picks]


def view_origins_payload(origins: np.ndarray) -> bytes:
    """The ``vorg`` payload of (V, 3) finite float32 ``origins``, 1 <= V <= 32, world units.

    Raises:
        ValueError: a count outside 1..32 or a non-finite value (an encoder's own bug).
    """
    origins = np.asarray(origins, np.float32).reshape(-1, 3)
    if not 1 <= len(origins) <= MAX_ORIGINS or not np.all(np.isfinite(origins)):
        raise ValueError("vorg holds 1..32 finite origins")
    out = ByteWriter()
    out.fixed("u8", VERSION)
    out.varint(len(origins))
    out.array(origins, "f4")
    return out.getvalue()


def parse_view_origins(data: bytes, base_offset: int = 0) -> np.ndarray:
    """(V, 3) float32 origins of a ``vorg`` payload.

    Raises:
        FormatError: an unknown version, a count outside 1..32, a truncated array, a
            non-finite value or trailing bytes, naming the byte offset.
    """
    r = ByteReader(data, base_offset=base_offset, chunk="vorg")
    version = r.fixed("u8", "version")
    if version != VERSION:
        raise r.error(f"unknown view-origins version {version}", at=r.offset - 1)
    start = r.offset
    count = r.varint("origin_count", maximum=MAX_ORIGINS)
    if count == 0:
        raise r.error("origin_count is 0", at=start)
    at = r.offset
    origins = r.array(3 * count, "f4", "origins").reshape(count, 3).astype(np.float32)
    if not np.all(np.isfinite(origins)):
        raise r.error("an origin is not finite", at=at)
    r.expect_end("the view-origins record")
    return origins


def read_view_origins(container) -> np.ndarray | None:
    """The origins of the container's ``vorg`` chunk, or None when it has none, holds more
    than one, or its payload is invalid (informative: never a reason to reject the file)."""
    entries = [e for e in container.toc if e.type == "vorg"]
    if len(entries) != 1 or entries[0].index not in container.payloads:
        return None
    entry = entries[0]
    try:
        return parse_view_origins(bytes(container.payloads[entry.index]), entry.offset + 8)
    except FormatError:
        return None
