"""Niantic SPZ (versions 1-4): quantized attribute streams, gzip (v1-v3) or zstd (v4).

Layout (github.com/nianticlabs/spz, README and src/cc/load-spz.cc):

* v1-v3: one gzip stream holding a 16-byte header (magic "NGSP" as u32 0x5053474e,
  version, point count u32; SH degree, fractional bits, flags, reserved u8) and then the
  attribute blocks back to back: positions, alphas, colors, scales, rotations, SH; v3 files
  may carry extension records after them.
* v4: a plain 32-byte header (the 16 above, then stream count u8 at 15, TOC offset u32 at
  16, 12 reserved bytes), optional extension records, a table of contents of (compressed
  size u64, uncompressed size u64) per stream, then one zstd frame per non-empty block.

Blocks: positions as 24-bit signed fixed point with ``fractional bits`` (v1: float16);
alpha u8 = 255 sigmoid(opacity); color u8 = 255 (0.15 f_dc + 0.5); scale u8 = 16 (log
scale + 10); rotation v1-v2 as x, y, z u8 (b / 127.5 - 1, w >= 0 derived), v3+ as a u32 with
the largest component's index in the top 2 bits and the other three as sign + 9-bit
magnitude of |q| / sqrt(1/2); SH u8 = 128 x + 128, coefficient-major with RGB inner.

Coordinates are stored as given, with no axis conversion: what Niantic's ``ply_to_spz`` and
splat-transform do, so a PLY converted by either reads back in its own axes.
"""

from __future__ import annotations

import gzip
import struct
import zlib

import numpy as np

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.interchange.binary import (
    Bytes,
    alpha_to_logit,
    logit_to_alpha,
    normalized_wxyz,
    optional_module,
    round_half_away,
)
from csgs_codec.interchange.source import SceneSource
from csgs_codec.scene.gaussian_scene import GaussianScene

MAGIC = 0x5053474E
GZIP_MAGIC = b"\x1f\x8b"
NGSP_MAGIC = struct.pack("<I", MAGIC)
LEGACY_HEADER = struct.Struct("<IIIBBBB")
HEADER_V4 = struct.Struct("<IIIBBBBI12x")
COLOR_SCALE = 0.15
#: SH coefficients per color channel for SH degree 0..4 (degree 4 is not a csgs scene).
SH_DIMS = (0, 3, 8, 15, 24)
FLAG_ANTIALIASED = 0x1
FLAG_EXTENSIONS = 0x2
LATEST_VERSION = 4
#: Compression ratio no real gzip or zstd stream of packed Gaussians exceeds; declared sizes
#: beyond it are refused before anything is allocated.
MAX_RATIO = 1100
#: Extension records after the blocks of a legacy file: more than this is refused.
MAX_LEGACY_TRAILER = 1 << 20
SQRT1_2 = np.sqrt(0.5)


def _block_sizes(n: int, version: int, sh_degree: int) -> list[tuple[str, int]]:
    return [("positions", n * (6 if version == 1 else 9)), ("alphas", n), ("colors", 3 * n),
            ("scales", 3 * n), ("rotations", n * (4 if version >= 3 else 3)),
            ("sh", n * 3 * SH_DIMS[sh_degree])]


def _check_header(raw: Bytes, version: int, n: int, sh_degree: int, offset: int = 0) -> None:
    if not 1 <= version <= LATEST_VERSION:
        raise raw.error(f"SPZ version {version} is not one of 1-{LATEST_VERSION}",
                        offset=offset + 4)
    if sh_degree > 4:
        raise raw.error(f"SH degree {sh_degree} is not one of 0-4", offset=offset + 12)
    if sh_degree == 4:
        raise UnsupportedError("SH degree 4 (SPZ allows it; 3DGS scenes in csgs stop at 3)",
                               file=raw.source, offset=offset + 12)
    if n == 0 or n > 2**31 - 1:
        raise raw.error(f"point count {n} is not in 1..2^31-1", offset=offset + 8)
    total = sum(size for _, size in _block_sizes(n, version, sh_degree))
    if total > MAX_RATIO * len(raw):
        raise raw.error(f"declares {n:,} Gaussians ({total:,} bytes of attributes), more than "
                        f"{len(raw):,} compressed bytes can hold", offset=offset + 8)


def _gunzip_exactly(raw: Bytes, size: int, decompressor, what: str, consumed: bytes) -> bytes:
    if size == 0:  # zlib reads max_length 0 as "no limit": an empty block takes nothing
        return b""
    out = decompressor.decompress(consumed, size)
    if len(out) < size:
        raise raw.error(f"the gzip stream ends after {len(out)} bytes of {what}, {size} "
                        "declared (truncated file)", offset=len(raw))
    return out


def _parse_legacy(raw: Bytes) -> tuple[dict, dict]:
    d = zlib.decompressobj(16 + zlib.MAX_WBITS)
    try:
        head = _gunzip_exactly(raw, LEGACY_HEADER.size, d, "header", raw.data)
        magic, version, n, sh_degree, fractional, flags, _ = LEGACY_HEADER.unpack(head)
        if magic != MAGIC:
            raise raw.error("the gzip stream does not start with the SPZ magic 'NGSP' "
                            "(not an SPZ file)", offset=0)
        if version == LATEST_VERSION:
            raise raw.error("SPZ v4 is not gzip-compressed (it starts with 'NGSP')", offset=0)
        _check_header(raw, version, n, sh_degree)
        blocks = {}
        for name, size in _block_sizes(n, version, sh_degree):
            blocks[name] = _gunzip_exactly(raw, size, d, f"the {name} block", d.unconsumed_tail)
        trailer = d.decompress(d.unconsumed_tail, MAX_LEGACY_TRAILER + 1)
    except zlib.error as exc:
        raise raw.error(f"corrupt gzip stream ({exc})",
                        offset=len(raw) - len(d.unconsumed_tail)) from None
    if not d.eof:
        raise raw.error("the gzip stream ends before its end marker and checksum (truncated "
                        "file)", offset=len(raw))
    if len(trailer) > MAX_LEGACY_TRAILER or (trailer and not flags & FLAG_EXTENSIONS):
        raise raw.error(f"{len(trailer)} bytes follow the attribute blocks and the header "
                        "declares no extensions", offset=len(raw) - len(d.unconsumed_tail))
    header = {"version": version, "n": n, "sh_degree": sh_degree, "fractional_bits":
              fractional, "flags": flags}
    return header, blocks


def _parse_v4(raw: Bytes) -> tuple[dict, dict]:
    raw.need(0, HEADER_V4.size, "the SPZ v4 header")
    magic, version, n, sh_degree, fractional, flags, streams, toc = HEADER_V4.unpack_from(
        raw.data)
    if version != LATEST_VERSION:
        raise raw.error(f"an 'NGSP' file declares version {version}; only v4 is stored "
                        "without gzip", offset=4)
    _check_header(raw, version, n, sh_degree)
    expected = [(name, size) for name, size in _block_sizes(n, version, sh_degree) if size]
    if streams != len(expected):
        raise raw.error(f"{streams} streams, expected {len(expected)} for SH degree "
                        f"{sh_degree}", offset=15)
    if toc < HEADER_V4.size:
        raise raw.error(f"table of contents at byte {toc}, inside the header", offset=16)
    sizes = raw.array(toc, np.uint64, 2 * streams, "the table of contents").reshape(-1, 2)
    zstd = optional_module("zstandard", "reading SPZ v4 (zstd streams)")
    at = toc + 16 * streams
    blocks = {"sh": b""}
    for i, (name, size) in enumerate(expected):
        packed, unpacked = int(sizes[i, 0]), int(sizes[i, 1])
        if unpacked != size:
            raise raw.error(f"stream {i} ({name}) declares {unpacked} bytes, expected {size}",
                            offset=toc + 16 * i + 8)
        raw.need(at, packed, f"stream {i} ({name})")
        blocks[name] = _unzstd(zstd, raw, at, packed, size, f"stream {i} ({name})")
        at += packed
    if at != len(raw):
        raise raw.error(f"{len(raw) - at} bytes follow the last stream", offset=at)
    header = {"version": version, "n": n, "sh_degree": sh_degree, "fractional_bits":
              fractional, "flags": flags}
    return header, blocks


def _unzstd(zstd, raw: Bytes, at: int, packed: int, size: int, what: str) -> bytes:
    """The ``size`` bytes of the zstd frame at ``at``, never decompressing more (a frame may
    declare any content size)."""
    frame = raw.data[at:at + packed]
    try:
        declared = zstd.frame_content_size(frame)
        if declared not in (-1, size):
            raise raw.error(f"{what}: the zstd frame declares {declared} bytes, {size} "
                            "expected", offset=at)
        with zstd.ZstdDecompressor().stream_reader(frame, read_across_frames=False) as reader:
            out = reader.read(size + 1)
    except zstd.ZstdError as exc:
        raise raw.error(f"corrupt zstd {what}: {exc}", offset=at) from None
    if len(out) != size:
        raise raw.error(f"{what} holds {len(out)} bytes, {size} declared", offset=at)
    return out


def parse_spz(data: bytes, source: str = "<bytes>") -> tuple[GaussianScene, SceneSource]:
    """Decode SPZ bytes (any version 1-4).

    Raises:
        InputError: bad magic, version, counts larger than the file, truncated or corrupt
            streams (naming the byte offset in the file, or the block of the gzip stream).
        UnsupportedError: SH degree 4; v4 without the zstandard package.
    """
    raw = Bytes(data, source)
    if data[:2] == GZIP_MAGIC:
        header, blocks = _parse_legacy(raw)
    elif data[:4] == NGSP_MAGIC:
        header, blocks = _parse_v4(raw)
    else:
        raise raw.error("not an SPZ file: neither a gzip stream nor the 'NGSP' magic",
                        offset=0)
    scene = _unpack(header, blocks)
    details = {"fractional_bits": header["fractional_bits"],
               "antialiased": bool(header["flags"] & FLAG_ANTIALIASED)}
    return scene, SceneSource("spz", "Niantic SPZ", str(header["version"]), lossy=True,
                              details=details)


def _unpack(header: dict, blocks: dict) -> GaussianScene:
    n, version, dims = header["n"], header["version"], SH_DIMS[header["sh_degree"]]
    if version == 1:
        positions = np.frombuffer(blocks["positions"], "<f2").reshape(n, 3).astype(np.float32)
    else:
        b = np.frombuffer(blocks["positions"], np.uint8).reshape(n, 3, 3).astype(np.int32)
        fixed = b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16)
        fixed = np.where(fixed & 0x800000, fixed - (1 << 24), fixed)
        positions = (fixed * (1.0 / (1 << header["fractional_bits"]))).astype(np.float32)
    if version >= 3:
        rotations = _unpack_smallest_three(np.frombuffer(blocks["rotations"], "<u4"))
    else:
        xyz = np.frombuffer(blocks["rotations"], np.uint8).reshape(n, 3) / 127.5 - 1.0
        w = np.sqrt(np.maximum(0.0, 1.0 - np.sum(xyz * xyz, axis=1)))
        rotations = np.column_stack([w, xyz])
    colors = np.frombuffer(blocks["colors"], np.uint8).reshape(n, 3)
    sh = np.frombuffer(blocks["sh"], np.uint8).reshape(n, dims, 3)
    return GaussianScene(
        positions=positions,
        sh_dc=((colors / 255.0 - 0.5) / COLOR_SCALE).astype(np.float32),
        sh_rest=((sh.astype(np.float32) - 128.0) / 128.0),
        opacity=alpha_to_logit(np.frombuffer(blocks["alphas"], np.uint8) / 255.0),
        scales=(np.frombuffer(blocks["scales"], np.uint8).reshape(n, 3) / 16.0 - 10.0
                ).astype(np.float32),
        rotations=rotations.astype(np.float32),
    )


def _unpack_smallest_three(packed: np.ndarray) -> np.ndarray:
    """(N,) u32 -> (N, 4) float64 quaternions (w, x, y, z); SPZ orders them x, y, z, w."""
    n = len(packed)
    largest = (packed >> 30).astype(np.int64)
    xyzw = np.zeros((n, 4))
    rest = packed.astype(np.int64)
    rows = np.arange(n)
    # The first component (in x, y, z, w order) other than the largest is in the top bits:
    # walk the slots from w down to x, taking 10 bits from the bottom each time.
    for slot in (3, 2, 1, 0):
        take = largest != slot
        value = SQRT1_2 * (rest & 511) / 511.0
        value = np.where((rest >> 9) & 1, -value, value)
        xyzw[take, slot] = value[take]
        rest = np.where(take, rest >> 10, rest)
    xyzw[rows, largest] = np.sqrt(np.maximum(0.0, 1.0 - np.sum(xyzw * xyzw, axis=1)))
    return xyzw[:, [3, 0, 1, 2]]


# --------------------------------------------------------------------------- writing
def spz_bytes(scene: GaussianScene, *, version: int = LATEST_VERSION, sh1_bits: int = 5,
              sh_rest_bits: int = 4) -> bytes:
    """The scene as SPZ ``version`` 3 or 4 (Niantic's quantization, coordinates as given).

    Args:
        version: 4 (zstd streams; needs the zstandard package) or 3 (one gzip stream).
        sh1_bits: bits kept of each degree-1 SH coefficient's 8 (Niantic's default 5).
        sh_rest_bits: bits kept of degree-2 and 3 coefficients (default 4).

    Raises:
        InputError: a position beyond +-8,388,607 world units (no 24-bit fixed point holds
            it); an empty scene.
        UnsupportedError: another version; v4 without zstandard.
    """
    if version not in (3, 4):
        raise UnsupportedError(f"writing SPZ v{version}: csgs writes v3 and v4")
    if not 1 <= sh1_bits <= 8 or not 1 <= sh_rest_bits <= 8:
        raise InputError("SH bits must be 1-8", property="sh_bits")
    scene.validate()
    n = len(scene)
    if n == 0:
        raise InputError("SPZ cannot hold an empty scene (its readers refuse 0 points)")
    fractional = _fractional_bits(scene.positions)
    blocks = _pack(scene, fractional, sh1_bits, sh_rest_bits)
    sh_degree = scene.sh_degree_stored
    if version == 3:
        header = struct.pack("<IIIBBBB", MAGIC, 3, n, sh_degree, fractional, 0, 0)
        return gzip.compress(header + b"".join(blocks), compresslevel=9, mtime=0)
    zstd = optional_module("zstandard", "writing SPZ v4 (zstd streams)")
    streams = [zstd.ZstdCompressor(level=12).compress(b) for b in blocks if b]
    header = HEADER_V4.pack(MAGIC, 4, n, sh_degree, fractional, 0, len(streams),
                            HEADER_V4.size)
    toc = b"".join(struct.pack("<QQ", len(s), len(b))
                   for s, b in zip(streams, [b for b in blocks if b]))
    return header + toc + b"".join(streams)


def _fractional_bits(positions: np.ndarray) -> int:
    """The most fractional bits (at most Niantic's 12) whose 24-bit range holds every
    position."""
    reach = float(np.max(np.abs(positions))) if len(positions) else 0.0
    for bits in range(12, -1, -1):
        if round_half_away(reach * (1 << bits)) <= (1 << 23) - 1:
            return bits
    raise InputError(f"a position {reach:.6g} units from the origin is beyond SPZ's 24-bit "
                     "range (+-8,388,607)", property="positions")


def _pack(scene: GaussianScene, fractional: int, sh1_bits: int, sh_rest_bits: int
          ) -> list[bytes]:
    n = len(scene)
    fixed = round_half_away(scene.positions.astype(np.float64) * (1 << fractional))
    fixed = fixed.astype(np.int64) & 0xFFFFFF
    positions = np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, fixed >> 16], axis=-1)

    def u8(values):
        return np.clip(round_half_away(values), 0, 255).astype(np.uint8)

    alphas = u8(255.0 * logit_to_alpha(scene.opacity))
    colors = u8(scene.sh_dc.astype(np.float64) * (COLOR_SCALE * 255.0) + 127.5)
    scales = u8((scene.scales.astype(np.float64) + 10.0) * 16.0)
    rotations = _pack_smallest_three(normalized_wxyz(scene.rotations))
    sh = round_half_away(scene.sh_rest.astype(np.float64) * 128.0) + 128.0
    bucket = np.full(sh.shape[1], 1 << (8 - sh_rest_bits))
    bucket[:3] = 1 << (8 - sh1_bits)
    bucket = bucket[None, :, None]
    sh = np.clip((sh + bucket // 2) // bucket * bucket, 0, 255).astype(np.uint8)
    return [positions.astype(np.uint8).tobytes(), alphas.tobytes(), colors.tobytes(),
            scales.tobytes(), rotations.astype("<u4").tobytes(), sh.reshape(n, -1).tobytes()]


def _pack_smallest_three(wxyz: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions (w, x, y, z) -> (N,) u32 in SPZ's smallest-three form."""
    xyzw = wxyz[:, [1, 2, 3, 0]]
    largest = np.argmax(np.abs(xyzw), axis=1)
    rows = np.arange(len(xyzw))
    negate = xyzw[rows, largest] < 0
    packed = largest.astype(np.uint64)
    for slot in range(4):
        take = largest != slot
        value = xyzw[:, slot]
        negbit = ((value < 0) ^ negate).astype(np.uint64)
        mag = np.floor(511.0 * np.abs(value) / SQRT1_2 + 0.5).astype(np.uint64)
        mag = np.minimum(mag, 511)
        packed = np.where(take, (packed << np.uint64(10)) | (negbit << np.uint64(9)) | mag,
                          packed)
    return packed.astype(np.uint32)
