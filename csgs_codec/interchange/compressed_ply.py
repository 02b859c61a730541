"""PlayCanvas compressed PLY: 256-Gaussian chunks of quantized, bit-packed attributes.

A binary little-endian PLY with three elements (github.com/playcanvas/splat-transform,
``writers/write-compressed-ply.ts`` and ``readers/read-ply.ts``):

* ``chunk``: per 256 Gaussians, float bounds ``min_x``..``max_z``, ``min_scale_x``..
  ``max_scale_z`` (log scales) and, in newer files, ``min_r``..``max_b`` (color);
* ``vertex``: uint ``packed_position`` (11/10/11 bits of the chunk's box),
  ``packed_rotation`` (2 bits: index of the largest quaternion component, then three 10-bit
  others as (v / sqrt 2 + 1/2)), ``packed_scale`` (11/10/11 bits of the chunk's scale box),
  ``packed_color`` (RGBA 8 bits each: color within the chunk's color box, or 0..1 without
  one, and alpha);
* optional ``sh``: uchar ``f_rest_*`` (channel-major) as 8 (v - 1/2) over (b + 1/2) / 256,
  with 0 and 255 meaning the ends of [-4, 4].
"""

from __future__ import annotations

import numpy as np

from csgs_codec.interchange.binary import (
    Bytes,
    alpha_to_logit,
    color_to_dc,
    from_smallest_three,
    sh_rest_from_channel_major,
)
from csgs_codec.interchange.ply_header import MAX_HEADER_BYTES, PlyHeader, parse_header
from csgs_codec.interchange.source import SceneSource
from csgs_codec.scene.gaussian_scene import SH_DEGREE_OF_REST, GaussianScene

CHUNK = 256
BOUNDS = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x",
          "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z")
COLOR_BOUNDS = ("min_r", "min_g", "min_b", "max_r", "max_g", "max_b")
PACKED = ("packed_position", "packed_rotation", "packed_scale", "packed_color")


def is_compressed_ply(header: PlyHeader) -> bool:
    """True when a parsed PLY header has the compressed layout (a ``chunk`` element and a
    ``packed_position`` vertex property)."""
    vertex = header.element("vertex")
    return (header.element("chunk") is not None and vertex is not None
            and any(p.name == "packed_position" for p in vertex.properties))


def parse_compressed_ply(data: bytes, source: str = "<bytes>"
                         ) -> tuple[GaussianScene, SceneSource]:
    """Decode a PlayCanvas compressed PLY.

    Raises:
        InputError: not binary little-endian, a missing element or property, fewer chunks
            than the vertex count needs, or elements larger than the file (byte offset).
    """
    raw = Bytes(data, source)
    header = parse_header(data[:MAX_HEADER_BYTES], source)
    if header.byte_order != "<":
        raise raw.error(f"compressed PLY is binary little-endian, this is {header.format}",
                        offset=0)
    columns, offset = {}, header.header_bytes
    for el in header.elements:
        if el.has_list:
            raise raw.error(f"element '{el.name}' has list properties", offset=offset)
        if not el.properties:
            raise raw.error(f"element '{el.name}' has no properties", offset=offset)
        raw.need(offset, el.count * el.row_bytes, f"element '{el.name}' ({el.count} rows)")
        rows = np.frombuffer(data, el.dtype("<"), count=el.count, offset=offset)
        columns[el.name] = rows
        offset += el.count * el.row_bytes
    if offset != len(data):
        raise raw.error(f"{len(data) - offset} bytes follow the last element", offset=offset)
    for name in ("chunk", "vertex"):
        if name not in columns:
            raise raw.error(f"no '{name}' element (not a compressed PLY)", offset=0)
    chunk, vertex = columns["chunk"], columns["vertex"]
    for name in BOUNDS:
        if name not in chunk.dtype.names:
            raise raw.error("missing chunk property", property=name)
    for name in PACKED:
        if name not in vertex.dtype.names:
            raise raw.error("missing vertex property", property=name)
    n = len(vertex)
    if len(chunk) < -(-n // CHUNK):
        raise raw.error(f"{n} Gaussians need {-(-n // CHUNK)} chunks, the file has "
                        f"{len(chunk)}", offset=header.header_bytes)
    which = np.arange(n) // CHUNK
    bound = {name: chunk[name].astype(np.float64)[which] for name in chunk.dtype.names}
    scene = GaussianScene(
        positions=_lerp_11_10_11(vertex["packed_position"], bound, ""),
        sh_dc=_colors(vertex["packed_color"], bound),
        sh_rest=_sh(columns.get("sh"), n, raw),
        opacity=alpha_to_logit((vertex["packed_color"] & 0xFF) / 255.0),
        scales=_lerp_11_10_11(vertex["packed_scale"], bound, "scale_"),
        rotations=_rotations(vertex["packed_rotation"]),
    )
    details = {"chunks": len(chunk), "color_bounds": all(c in chunk.dtype.names
                                                          for c in COLOR_BOUNDS)}
    return scene, SceneSource("compressed-ply", "PlayCanvas compressed PLY", lossy=True,
                              details=details)


def _unorm(values: np.ndarray, shift: int, bits: int) -> np.ndarray:
    return ((values.astype(np.int64) >> shift) & ((1 << bits) - 1)) / float((1 << bits) - 1)


def _lerp_11_10_11(packed, bound, prefix: str) -> np.ndarray:
    """(N, 3) float32 of 11/10/11-bit fields spread over the chunks' ``min_<prefix>x`` ..
    ``max_<prefix>z`` boxes."""
    out = []
    for axis, (shift, bits) in zip("xyz", ((21, 11), (11, 10), (0, 11))):
        lo, hi = bound[f"min_{prefix}{axis}"], bound[f"max_{prefix}{axis}"]
        t = _unorm(packed, shift, bits)
        out.append(lo * (1 - t) + hi * t)
    return np.stack(out, axis=1).astype(np.float32)


def _colors(packed, bound) -> np.ndarray:
    out = []
    for shift, c in ((24, "r"), (16, "g"), (8, "b")):
        t = _unorm(packed, shift, 8)
        if f"min_{c}" in bound and f"max_{c}" in bound:
            t = bound[f"min_{c}"] * (1 - t) + bound[f"max_{c}"] * t
        out.append(t)
    return color_to_dc(np.stack(out, axis=1))


def _rotations(packed) -> np.ndarray:
    others = np.stack([(_unorm(packed, shift, 10) - 0.5) * np.sqrt(2.0)
                       for shift in (20, 10, 0)], axis=1)
    largest = (packed.astype(np.int64) >> 30) & 3
    return from_smallest_three(largest, others).astype(np.float32)


def _sh(rows, n: int, raw: Bytes) -> np.ndarray:
    if rows is None:
        return np.zeros((n, 0, 3), np.float32)
    names = rows.dtype.names
    count = len(names)
    if count % 3 or count // 3 not in SH_DEGREE_OF_REST or len(rows) != n:
        raise raw.error(f"the 'sh' element has {count} properties and {len(rows)} rows; "
                        f"expected 9, 24 or 45 and {n}", property="f_rest_*")
    order = [f"f_rest_{i}" for i in range(count)]
    if sorted(order) != sorted(names):
        raise raw.error("the 'sh' properties are not f_rest_0..", property="f_rest_*")
    b = np.stack([rows[name].astype(np.float64) for name in order], axis=1)
    unit = np.where(b == 0, 0.0, np.where(b == 255, 1.0, (b + 0.5) / 256.0))
    return sh_rest_from_channel_major((unit - 0.5) * 8.0, n, count // 3)
