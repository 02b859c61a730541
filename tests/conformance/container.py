"""Container-level conformance vectors (spec/vectors/container/) and the spec's worked example.

Each vector is ``NAME.csgs`` plus ``NAME.json``: a description, the file's SHA-256, and one
or more reads (a set of layers) with the expected outcome: the decoded header, TOC and
payload SHA-256s, or the error class, byte offset and chunk type. The expectations are
written down here by hand; :func:`generate` checks the reader agrees before writing anything.
"""

from __future__ import annotations

import hashlib
import json
import struct
from dataclasses import dataclass, field
from pathlib import Path

from csgs_codec.errors import CsgsError
from csgs_codec.format.chunk import Chunk, Container
from csgs_codec.format.layout import HEADER_SIZE, MAX_TOC_SIZE, TOC_CRC_SIZE, Layer
from csgs_codec.format.primitives import ByteWriter, crc32, encode_varint
from csgs_codec.format.reader import read_layers
from csgs_codec.format.writer import (
    container_bytes,
    encode_frame,
    encode_header,
    encode_toc_body,
)

SCHEMA = "csgs-vector/1"
ALL_LAYERS = ("color", "semantic")


def worked_example_chunks() -> list[Chunk]:
    """The tiny file of spec/FORMAT.md's worked example: one ``fill`` chunk per layer."""
    return [Chunk("fill", Layer.BASE, b"csgs"), Chunk("fill", Layer.COLOR, b"rgb"),
            Chunk("fill", Layer.SEMANTIC, b"ids")]


def decode_summary(container: Container) -> dict:
    """JSON-ready summary of a read: header fields, TOC entries, SHA-256 of each payload read."""
    return {
        "major_version": container.major_version,
        "minor_version": container.minor_version,
        "flags": container.flags,
        "layers_read": sorted(layer.label for layer in container.layers_read),
        "complete": container.complete,
        "toc": [{"type": e.type, "layer": e.layer.label, "tile": e.tile, "offset": e.offset,
                 "length": e.length, "critical": e.critical} for e in container.toc],
        "payloads": [{"index": i, "bytes": len(p), "sha256": hashlib.sha256(p).hexdigest()}
                     for i, p in sorted(container.payloads.items())],
    }


def run_read(data: bytes, layers: list[str]) -> dict:
    """The outcome of ``read_layers(data, layers)`` as stored in a vector's JSON."""
    try:
        container = read_layers(data, layers)
    except CsgsError as err:
        return {"layers": layers, "outcome": "error", "error": type(err).__name__,
                "offset": err.offset, "chunk": err.chunk}
    return {"layers": layers, "outcome": "ok", "decode": decode_summary(container)}


# ---------------------------------------------------------------------------- building blocks

def _assemble(rows: list[tuple[bytes, int, int, int, int]], frames: list[bytes], *,
              major: int = 1, minor: int = 0, flags: int = 0,
              toc_body: bytes | None = None) -> bytes:
    """Header + TOC (with a correct TOC CRC) + frames, from explicit TOC rows."""
    body = encode_toc_body(rows) if toc_body is None else toc_body
    head = encode_header(len(body), flags, major, minor) + body
    return head + struct.pack("<I", crc32(head)) + b"".join(frames)


def _rows_and_frames(chunks: list[tuple[str, int, int, bytes]], extra_toc: int = 0):
    """TOC rows with consistent offsets for (type, layer, tile, payload), plus their frames.

    ``extra_toc`` adds bytes the caller will insert into the TOC body (e.g. an overlong
    varint) so the offsets still point at the frames.
    """
    toc_size = 0
    while True:
        offset = HEADER_SIZE + toc_size + extra_toc + TOC_CRC_SIZE
        rows = []
        for code, layer, tile, payload in chunks:
            rows.append((code.encode("ascii"), layer, tile, offset, len(payload)))
            offset += len(payload) + 12
        size = len(encode_toc_body(rows))
        if size == toc_size:
            break
        toc_size = size
    frames = [encode_frame(code.encode("ascii"), payload) for code, _, _, payload in chunks]
    return rows, frames


def _flip(data: bytes, offset: int, mask: int = 0x01) -> bytes:
    out = bytearray(data)
    out[offset] ^= mask
    return bytes(out)


def _with_header(data: bytes, **fields: int) -> bytes:
    """``data`` with header fields replaced and the TOC CRC recomputed."""
    major, minor, flags, toc_size = struct.unpack_from("<BBHI", data, 8)
    values = {"major": major, "minor": minor, "flags": flags, **fields}
    head = encode_header(toc_size, values["flags"], values["major"], values["minor"])
    toc_end = HEADER_SIZE + toc_size
    new_head = head + data[HEADER_SIZE:toc_end]
    return new_head + struct.pack("<I", crc32(new_head)) + data[toc_end + TOC_CRC_SIZE:]


# ---------------------------------------------------------------------------- the vectors

@dataclass
class Vector:
    """One conformance vector: its bytes and the reads with their expected outcome.

    ``reads`` maps a tuple of layer names to "ok" or (offset, chunk type or None) of the
    FormatError expected.
    """

    name: str
    description: str
    data: bytes
    reads: dict[tuple[str, ...], object] = field(default_factory=dict)


def _base_file() -> tuple[bytes, Container]:
    data = container_bytes(worked_example_chunks())
    return data, read_layers(data, ALL_LAYERS)


def _valid_vectors() -> list[Vector]:
    data, full = _base_file()
    color_end = full.layer_end("color")
    unknown_optional = container_bytes([
        Chunk("fill", 0, b"base"), Chunk("zqxj", 1, b"from a newer minor version"),
        Chunk("fill", 1, b"color"), Chunk("fill", 2, b"semantic")])
    tiles = container_bytes([Chunk("fill", 0, b"t0", tile=0), Chunk("fill", 1, b"t0", tile=0),
                             Chunk("fill", 1, b"t1", tile=1), Chunk("fill", 2, b"t1", tile=1)])
    ok_all = {("color",): "ok", ALL_LAYERS: "ok"}
    return [
        Vector("empty_scene", "A container with no chunks: the smallest valid file.",
               container_bytes([]), ok_all),
        Vector("three_layers", "The worked example of spec/FORMAT.md: one fill chunk per layer.",
               data, {(): "ok", **ok_all}),
        Vector("tiles", "Chunks in tiles 0 and 1; tile numbers do not change the framing.",
               tiles, ok_all),
        Vector("unknown_optional_chunk", "An unknown optional chunk 'zqxj' in the color layer "
               "is skipped: listed in the TOC, its payload not read.", unknown_optional, ok_all),
        Vector("truncated_after_color", "The stream ends right after the color layer: the "
               "color layer decodes, the semantic layer is missing.", data[:color_end],
               {("color",): "ok", ALL_LAYERS: (color_end, "fill")}),
        Vector("newer_minor_version", "Minor version 3: read as 1.0 (minor versions only add "
               "optional things).", _with_header(data, minor=3), ok_all),
        Vector("unknown_optional_flag", "Header flag bit 0 (optional, undefined in 1.0) set: "
               "ignored.", _with_header(data, flags=0x0001), ok_all),
    ]


def _invalid_vectors() -> list[Vector]:
    data, full = _base_file()
    toc_size = full.header_and_toc_size - HEADER_SIZE - TOC_CRC_SIZE
    color = full.toc[1]
    cut_in_color = color.offset + 9
    critical_color = [("fill", 0, 0, b"base"), ("ZQXJ", 1, 0, b"needs a newer decoder"),
                      ("fill", 2, 0, b"semantic")]
    rows, frames = _rows_and_frames(critical_color)
    unknown_critical = _assemble(rows, frames)
    critical_semantic = [("fill", 0, 0, b"base"), ("fill", 1, 0, b"color"),
                         ("ZQXJ", 2, 0, b"needs a newer decoder")]
    rows_s, frames_s = _rows_and_frames(critical_semantic)
    unknown_critical_semantic = _assemble(rows_s, frames_s)
    toc_entry = [HEADER_SIZE + 1 + 8 * i for i in range(3)]  # 1-byte count, 8-byte entries

    swapped = list(full.toc)
    rows_swap = [(e.type.encode(), int(e.layer), e.tile, e.offset, e.length) for e in swapped]
    rows_swap[1], rows_swap[2] = ((b"fill", 2, 0, rows_swap[1][3], rows_swap[1][4]),
                                  (b"fill", 1, 0, rows_swap[2][3], rows_swap[2][4]))
    out_of_order = _assemble(rows_swap, [data[e.offset:e.end] for e in swapped])

    rows_off = [(e.type.encode(), int(e.layer), e.tile, e.offset, e.length) for e in swapped]
    rows_off[1] = rows_off[1][:3] + (rows_off[1][3] + 1, rows_off[1][4])
    offset_mismatch = _assemble(rows_off, [data[e.offset:e.end] for e in swapped])

    rows_l3 = [(e.type.encode(), int(e.layer), e.tile, e.offset, e.length) for e in swapped]
    rows_l3[2] = (b"fill", 3) + rows_l3[2][2:]
    layer_range = _assemble(rows_l3, [data[e.offset:e.end] for e in swapped])

    rows_bad = [(e.type.encode(), int(e.layer), e.tile, e.offset, e.length) for e in swapped]
    rows_bad[1] = (b"fi1l",) + rows_bad[1][1:]
    bad_type = _assemble(rows_bad, [data[e.offset:e.end] for e in swapped])

    # Overlong varint: the color entry's tile written as 0x80 0x00 instead of 0x00.
    rows_v, frames_v = _rows_and_frames([(e.type, int(e.layer), e.tile, full.payloads[e.index])
                                         for e in swapped], extra_toc=1)
    body = bytearray(encode_toc_body(rows_v))
    tile_at = 1 + 8 + 5  # count, entry 0, then type + layer of entry 1
    body[tile_at:tile_at + 1] = b"\x80\x00"
    overlong = _assemble(rows_v, frames_v, toc_body=bytes(body))

    count_over = ByteWriter()
    count_over.varint(65_536)
    count_over.raw(bytes(8))
    too_many = _assemble([], [], toc_body=count_over.getvalue())

    # A 2^32-1 length is a 5-byte varint: lay out with a 0 length, 4 spare TOC bytes.
    huge_rows, huge_frames = _rows_and_frames([("fill", 0, 0, b"base"), ("fill", 1, 0, b"")],
                                              extra_toc=4)
    huge_rows[1] = huge_rows[1][:4] + ((1 << 32) - 1,)
    huge = _assemble(huge_rows, huge_frames[:1])

    frame_len = bytearray(data)
    struct.pack_into("<I", frame_len, color.offset, color.length + 1)
    frame_type = bytearray(data)
    frame_type[color.offset + 4:color.offset + 8] = b"fiLL"
    header_size = bytearray(data)
    struct.pack_into("<I", header_size, 12, MAX_TOC_SIZE + 1)
    return [
        Vector("empty_file", "Zero bytes.", b"", {("color",): (0, None)}),
        Vector("bad_magic_lf", "The CR LF of the magic became LF (text-mode transfer).",
               data[:4] + data[5:], {("color",): (4, None)}),
        Vector("unsupported_major_version", "Major version 2.", _with_header(data, major=2),
               {("color",): (8, None)}),
        Vector("reserved_flag_set", "Header flag bit 8 (reserved, must be zero) set.",
               _with_header(data, flags=0x0100), {("color",): (10, None)}),
        Vector("toc_size_over_limit", "toc_size one past the limit; checked before reading.",
               bytes(header_size), {("color",): (12, None)}),
        Vector("truncated_toc", "The stream ends inside the TOC.", data[:30],
               {("color",): (30, None)}),
        Vector("bad_toc_crc", "One bit of the TOC CRC flipped.",
               _flip(data, HEADER_SIZE + toc_size), {("color",): (HEADER_SIZE + toc_size, None)}),
        Vector("chunk_count_over_limit", "chunk_count 65536, one past the limit.", too_many,
               {("color",): (HEADER_SIZE, None)}),
        Vector("overlong_varint", "A TOC varint in a longer form than needed (0x80 0x00).",
               overlong, {("color",): (HEADER_SIZE + tile_at, "fill")}),
        Vector("bad_type_code", "A TOC type with a digit: 'fi1l'.", bad_type,
               {("color",): (toc_entry[1], None)}),
        Vector("layer_out_of_range", "A TOC entry with layer 3.", layer_range,
               {("color",): (toc_entry[2] + 4, "fill")}),
        Vector("layers_out_of_order", "A semantic chunk before a color chunk.", out_of_order,
               {("color",): (toc_entry[2] + 4, "fill")}),
        Vector("offset_mismatch", "A TOC offset one past the end of the previous chunk.",
               offset_mismatch, {("color",): (toc_entry[1], "fill")}),
        Vector("trailing_bytes", "One byte after the last chunk.", data + b"\x00",
               {("color",): (len(data), None)}),
        Vector("unknown_critical_chunk", "An unknown critical chunk 'ZQXJ' in the color layer: "
               "the color layer cannot be decoded; base alone can.", unknown_critical,
               {(): "ok", ("color",): (toc_entry[1], "ZQXJ")}),
        Vector("unknown_critical_in_semantic", "An unknown critical chunk in the semantic layer: "
               "a color-only read succeeds, a semantic read fails.", unknown_critical_semantic,
               {("color",): "ok", ALL_LAYERS: (toc_entry[2], "ZQXJ")}),
        Vector("bad_chunk_crc", "One bit of the color chunk's CRC flipped.",
               _flip(data, color.end - 4), {(): "ok", ("color",): (color.end - 4, "fill")}),
        Vector("frame_length_mismatch", "The color frame's length differs from its TOC entry.",
               bytes(frame_len), {("color",): (color.offset, "fill")}),
        Vector("frame_type_mismatch", "The color frame's type differs from its TOC entry.",
               bytes(frame_type), {("color",): (color.offset + 4, "fill")}),
        Vector("truncated_in_color", "The stream ends inside the color chunk's payload.",
               data[:cut_in_color], {(): "ok", ("color",): (cut_in_color, "fill")}),
        Vector("huge_length_claim", "A color chunk claiming 2^32-1 bytes in a tiny file: an "
               "error, with nothing allocated.", huge,
               {(): "ok", ("color",): (len(huge), "fill")}),
    ]


def vectors() -> list[Vector]:
    """Every container vector, valid ones first."""
    return _valid_vectors() + _invalid_vectors()


def _check(vector: Vector, layers: tuple[str, ...], expected: object, got: dict) -> None:
    if expected == "ok":
        ok = got["outcome"] == "ok"
    else:
        offset, chunk = expected
        ok = (got["outcome"] == "error" and got["error"] == "FormatError"
              and got["offset"] == offset and got["chunk"] == chunk)
    if not ok:
        raise AssertionError(f"vector {vector.name}, layers {layers}: expected {expected}, "
                             f"the reader gave {got}")


def generate(out_dir: Path) -> None:
    """Write every container vector (``NAME.csgs`` + ``NAME.json``) into ``out_dir``.

    Raises AssertionError, writing nothing, when the reader disagrees with an expectation.
    """
    records = []
    for vector in vectors():
        reads = []
        for layers, expected in vector.reads.items():
            got = run_read(vector.data, list(layers))
            _check(vector, layers, expected, got)
            reads.append(got)
        records.append((vector, reads))
    for vector, reads in records:
        (out_dir / f"{vector.name}.csgs").write_bytes(vector.data)
        doc = {"schema": SCHEMA, "file": f"{vector.name}.csgs", "description": vector.description,
               "bytes": len(vector.data), "sha256": hashlib.sha256(vector.data).hexdigest(),
               "valid": all(r["outcome"] == "ok" for r in reads), "reads": reads}
        (out_dir / f"{vector.name}.json").write_text(json.dumps(doc, indent=2) + "\n")


# ---------------------------------------------------------------------------- worked example

def _rows(offset: int, data: bytes, label: str) -> list[str]:
    lines = []
    for i in range(0, max(len(data), 1), 16):
        part = data[i:i + 16]
        text = " ".join(f"{b:02x}" for b in part)
        lines.append(f"{offset + i:08x}  {text:<47} | {label if i == 0 else '...'}")
    return lines


def annotated_hex(data: bytes) -> str:
    """A hex dump of a valid container, one line per field: ``OFFSET  HEX | field = value``."""
    full = read_layers(data, ALL_LAYERS)
    major, minor, flags, toc_size = struct.unpack_from("<BBHI", data, 8)
    lines = _rows(0, data[0:8], "magic: 0x89 'C' 'S' 'G' CR LF ^Z LF")
    lines += _rows(8, data[8:9], f"major_version = {major}")
    lines += _rows(9, data[9:10], f"minor_version = {minor}")
    lines += _rows(10, data[10:12], f"flags = 0x{flags:04x}")
    lines += _rows(12, data[12:16], f"toc_size = {toc_size}")
    count = encode_varint(len(full.toc))
    lines += _rows(16, count, f"chunk_count = {len(full.toc)} (varint)")
    for e in full.toc:
        at = e.toc_offset
        lines += _rows(at, data[at:at + 4], f"entry {e.index}: type = '{e.type}'")
        lines += _rows(at + 4, data[at + 4:at + 5], f"entry {e.index}: layer = {int(e.layer)} "
                       f"({e.layer.label})")
        at += 5
        for name, value in (("tile", e.tile), ("offset", e.offset), ("length", e.length)):
            size = len(encode_varint(value))
            lines += _rows(at, data[at:at + size], f"entry {e.index}: {name} = {value} (varint)")
            at += size
    crc_at = HEADER_SIZE + toc_size
    lines += _rows(crc_at, data[crc_at:crc_at + 4],
                   f"toc_crc = 0x{struct.unpack_from('<I', data, crc_at)[0]:08x}")
    for e in full.toc:
        at = e.offset
        lines += _rows(at, data[at:at + 4], f"chunk {e.index}: frame_length = {e.length}")
        lines += _rows(at + 4, data[at + 4:at + 8], f"chunk {e.index}: frame_type = '{e.type}'")
        payload = data[at + 8:at + 8 + e.length]
        lines += _rows(at + 8, payload, f"chunk {e.index}: payload {payload!r}")
        crc_value = struct.unpack_from("<I", data, e.end - 4)[0]
        lines += _rows(e.end - 4, data[e.end - 4:e.end],
                       f"chunk {e.index}: crc = 0x{crc_value:08x}")
    return "\n".join(lines)
