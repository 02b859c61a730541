"""mkkellogg GaussianSplats3D ``.ksplat`` (compression levels 0, 1 and 2; SH degree 0-2).

Layout (GaussianSplats3D ``src/loaders/SplatBuffer.js``), all little-endian:

* a 4096-byte main header: version major u8 (0) and minor u8 (>= 1) at 0-1; max section
  count u32 at 4, section count at 8, max splat count at 12, splat count at 16;
  compression level u16 at 20; scene centre float32 x3 at 24; SH range min/max float32 at
  36/40 (level 2; +-1.5 when zero);
* max-section-count 1024-byte section headers: splat count u32 at 0, max splat count at 4,
  bucket size at 8, bucket count at 12, bucket block size float32 at 16, bucket storage
  bytes u16 at 20, quantization range u32 at 24 (0: the level's default), full bucket count
  at 32, partial bucket count at 36, SH degree u16 at 40;
* per section: partial bucket lengths u32, bucket centres float32 x3 (levels 1-2), then
  max-splat-count records of centre, scale, rotation, color RGBA u8 and SH.

Level 0 stores floats; levels 1-2 store centres as u16 offsets from their bucket's centre
((u - range) x block size / 2 / range), scales and rotations (w, x, y, z) as float16; level 2
stores SH as u8 spanning the header's SH range. Color is 8-bit (0.5 + SH_C0 f_dc), alpha
8-bit, scale linear. SH is channel-major within each degree: R, G, B of degree 1, then R, G,
B of degree 2.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import UnsupportedError
from csgs_codec.interchange.binary import (
    Bytes,
    alpha_to_logit,
    color_to_dc,
    linear_to_log_scale,
    normalized_wxyz,
)
from csgs_codec.interchange.source import SceneSource
from csgs_codec.scene.gaussian_scene import GaussianScene

MAIN_HEADER = 4096
SECTION_HEADER = 1024
#: level -> (centre, scale, rotation bytes, SH component bytes, default quantization range)
LEVELS = {0: (12, 12, 16, 4, 1), 1: (6, 6, 8, 2, 32767), 2: (6, 6, 8, 1, 32767)}
SH_COMPONENTS = (0, 9, 24)
DEFAULT_SH_RANGE = 1.5


def looks_like_ksplat(head: bytes) -> bool:
    """True when ``head`` (the first bytes) could start a .ksplat: version 0.x with x >= 1,
    a compression level 0-2 and a non-zero section count (checked against the file when
    read)."""
    if len(head) < 24:
        return False
    major, minor = head[0], head[1]
    sections = int.from_bytes(head[4:8], "little")
    level = int.from_bytes(head[20:22], "little")
    return major == 0 and minor >= 1 and level <= 2 and sections > 0


def parse_ksplat(data: bytes, source: str = "<bytes>") -> tuple[GaussianScene, SceneSource]:
    """Decode ``.ksplat`` bytes; the scene keeps the file's order (bucket order).

    Raises:
        InputError: bad version or level, sections or counts larger than the file, bucket
            tables that do not add up (naming the byte offset).
        UnsupportedError: an SH degree above 2 in a section (the format stops at 2).
    """
    raw = Bytes(data, source)
    raw.need(0, MAIN_HEADER, "the .ksplat main header")
    if data[0] != 0 or data[1] < 1:
        raise raw.error(f"version {data[0]}.{data[1]} is not a .ksplat version (0.1 or "
                        "later)", offset=0)
    u32 = raw.array(0, np.uint32, 6, "main header")
    max_sections, total = int(u32[1]), int(u32[4])
    level = int(raw.array(20, np.uint16, 1, "main header")[0])
    if level not in LEVELS:
        raise raw.error(f"compression level {level} is not 0, 1 or 2", offset=20)
    sh_min, sh_max = (float(v) for v in raw.array(36, np.float32, 2, "main header"))
    sh_min, sh_max = sh_min or -DEFAULT_SH_RANGE, sh_max or DEFAULT_SH_RANGE
    raw.need(MAIN_HEADER, max_sections * SECTION_HEADER, f"{max_sections} section headers")
    centre_b, scale_b, rot_b, sh_b, default_range = LEVELS[level]
    parts = []
    offset = MAIN_HEADER + max_sections * SECTION_HEADER
    degree = 0
    for s in range(max_sections):
        at = MAIN_HEADER + s * SECTION_HEADER
        h = raw.array(at, np.uint32, 11, f"section header {s}")
        count, capacity, bucket_size, buckets = (int(v) for v in h[:4])
        block = float(raw.array(at + 16, np.float32, 1, "section header")[0])
        bucket_bytes = int(raw.array(at + 20, np.uint16, 1, "section header")[0])
        qrange = int(h[6]) or default_range
        full, partial = int(h[8]), int(h[9])
        sec_degree = int(raw.array(at + 40, np.uint16, 1, "section header")[0])
        if sec_degree > 2:
            raise UnsupportedError(f"section {s} declares SH degree {sec_degree}; .ksplat "
                                   "stores 0-2", file=source, offset=at + 40)
        if count > capacity:
            raise raw.error(f"section {s} holds {count} splats but has room for {capacity}",
                            offset=at)
        components = SH_COMPONENTS[sec_degree]
        record = centre_b + scale_b + rot_b + 4 + components * sh_b
        storage = bucket_bytes * buckets + 4 * partial if level else 0
        if level and bucket_bytes != 12:
            raise raw.error(f"section {s}: buckets of {bucket_bytes} bytes, expected 12 "
                            "(three float32)", offset=at + 20)
        raw.need(offset, storage + record * capacity, f"section {s}'s data")
        if count:
            parts.append(_section(raw, offset, count, level, record, components, sh_min,
                                  sh_max, bucket_size, buckets, block, qrange, full,
                                  partial, s))
            degree = max(degree, sec_degree)
        offset += storage + record * capacity
    if sum(len(p[0]) for p in parts) != total:
        raise raw.error(f"the sections hold {sum(len(p[0]) for p in parts)} splats, the "
                        f"header declares {total}", offset=16)
    if not parts:
        raise raw.error("the file holds no splats", offset=16)
    scene = _assemble(parts, degree)
    details = {"compression_level": level, "sections": len(parts)}
    return scene, SceneSource("ksplat", "GaussianSplats3D .ksplat", f"{data[0]}.{data[1]}",
                              lossy=True, details=details)


def _section(raw, offset, count, level, record, components, sh_min, sh_max, bucket_size,
             buckets, block, qrange, full, partial, s):
    centre_b, scale_b, rot_b, sh_b, _ = LEVELS[level]
    storage = 0
    if level:
        if full + partial != buckets or full * bucket_size > count:
            raise raw.error(f"section {s}: {full} full and {partial} partial buckets, "
                            f"{buckets} in all", offset=offset)
        lengths = raw.array(offset, np.uint32, partial, f"section {s} bucket lengths")
        centres = raw.array(offset + 4 * partial, np.float32, 3 * buckets,
                            f"section {s} bucket centres").reshape(buckets, 3)
        storage = 12 * buckets + 4 * partial
        if partial and int(lengths.max()) > bucket_size:
            raise raw.error(f"section {s}: a partial bucket of {int(lengths.max())} splats "
                            f"in buckets of {bucket_size}", offset=offset)
        ends = np.cumsum(np.concatenate([np.full(full, bucket_size, np.int64),
                                         lengths.astype(np.int64)]))
        if not buckets or int(ends[-1]) < count:
            raise raw.error(f"section {s}: buckets hold {int(ends[-1]) if buckets else 0} "
                            f"splats, {count} declared", offset=offset)
        bucket_of = np.searchsorted(ends, np.arange(count), side="right")
    rows = raw.array(offset + storage, np.uint8, record * count,
                     f"section {s} splats").reshape(count, record)
    at = 0

    def field(size, dtype, k):
        nonlocal at
        out = rows[:, at:at + size].copy().view(np.dtype(dtype).newbyteorder("<"))
        at += size
        return out.reshape(count, k)

    if level == 0:
        centres_out = field(12, np.float32, 3).astype(np.float64)
        scale = field(12, np.float32, 3).astype(np.float64)
        rot = field(16, np.float32, 4).astype(np.float64)
    else:
        offsets = field(6, np.uint16, 3).astype(np.float64)
        centres_out = (offsets - qrange) * (block / 2.0 / qrange) + centres[bucket_of]
        scale = field(6, np.float16, 3).astype(np.float64)
        rot = field(8, np.float16, 4).astype(np.float64)
    rgba = field(4, np.uint8, 4)
    if components:
        if level == 2:
            sh = field(components, np.uint8, components) / 255.0 * (sh_max - sh_min) + sh_min
        else:
            sh = field(components * sh_b, np.float32 if level == 0 else np.float16,
                       components).astype(np.float64)
    else:
        sh = np.zeros((count, 0))
    return centres_out, scale, rot, rgba, sh


def _assemble(parts, degree: int) -> GaussianScene:
    centres = np.concatenate([p[0] for p in parts])
    scale = np.concatenate([p[1] for p in parts])
    rot = np.concatenate([p[2] for p in parts])
    rgba = np.concatenate([p[3] for p in parts])
    n = len(centres)
    coeffs = (0, 3, 8)[degree]
    sh_rest = np.zeros((n, coeffs, 3), np.float32)
    row = 0
    for *_, sh in parts:
        m = len(sh)
        if sh.shape[1]:
            # Degree 1: R, G, B x 3 coefficients; degree 2: R, G, B x 5 coefficients.
            sh_rest[row:row + m, :3, :] = sh[:, :9].reshape(m, 3, 3).transpose(0, 2, 1)
            if sh.shape[1] > 9:
                sh_rest[row:row + m, 3:8, :] = sh[:, 9:24].reshape(m, 3, 5).transpose(0, 2, 1)
        row += m
    return GaussianScene(
        positions=centres.astype(np.float32),
        sh_dc=color_to_dc(rgba[:, :3] / 255.0),
        sh_rest=sh_rest,
        opacity=alpha_to_logit(rgba[:, 3] / 255.0),
        scales=linear_to_log_scale(scale),
        # Stored unit quaternions; float16 ones are left as stored, not renormalised.
        rotations=np.where(np.any(rot != 0, axis=1, keepdims=True), rot,
                           normalized_wxyz(rot)).astype(np.float32),
    )
