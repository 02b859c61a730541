"""Mutations of interchange seed files (:mod:`tests.fuzz.reader_seeds`).

Byte operators (any file): bit flips, byte sets, large 32-bit values (counts, sizes,
offsets), truncation, splices (a range of the file copied over another, or from another
seed of the same format), aimed at the header half the time. Structured operators reach
past the checksums and framing that catch most byte edits:

* PLY: header-line edits (counts, types, names, format, lines dropped, doubled, swapped,
  elements added); ASCII bodies also get token edits (out-of-range integers, nan, 1e400,
  "1_0", rows dropped, doubled or joined).
* gzip SPZ: the inflated payload is mutated, then deflated again.
* SOG: one member (meta.json or an image) is mutated, then the zip or folder rebuilt.
* GLB and SOG meta.json: JSON edits (a value replaced by another type, a huge or negative
  number, deep nesting, a key dropped), lengths kept consistent.

Everything is drawn from one ``random.Random``, so mutant ``index`` of ``campaign`` is a
pure function of the seeds: :func:`mutant_at` rebuilds it.
"""

from __future__ import annotations

import copy
import gzip
import io
import json
import random
import struct
import zipfile
from dataclasses import dataclass

from tests.fuzz.mutators import byte_position
from tests.fuzz.reader_seeds import FORMATS, ReaderSeed

#: Bytes at the start of a file where most of the fields sit: half the edits land here.
HEAD_BYTES = 4200
LARGE_VALUES = (0, 1, 2, 3, 255, 256, 0x7FFF, 0xFFFF, 1 << 16, 1 << 24, (1 << 31) - 1, 1 << 31,
                (1 << 32) - 1)
INTERESTING_BYTES = (0x00, 0x01, 0x02, 0x03, 0x04, 0x20, 0x0A, 0x7F, 0x80, 0xFE, 0xFF)
ASCII_TOKENS = (b"300", b"-1", b"256", b"-129", b"65536", b"4294967296", b"-2147483649",
                b"1e400", b"-1e400", b"nan", b"-inf", b"1_0", b"0x10", b"1.5", b"+7", b"-0",
                b"1e-400", b"99999999999999999999999", b"", b"0", b"3", b"1e9")
JSON_VALUES = (None, True, False, -1, 0, 1, 3, 2 ** 31, 2 ** 32, 2 ** 63, 10 ** 30, -2 ** 31,
               1e308, -1e308, 0.5, "x", "", "../x.webp", "means_l.webp", [], {}, [0], [[0]],
               {"uri": "x"})


@dataclass(frozen=True)
class Mutant:
    """A mutated seed: the bytes of a file, or of each member of a SOG folder."""

    seed: ReaderSeed
    data: bytes
    members: dict[str, bytes]
    operators: tuple[str, ...]

    @property
    def size(self) -> int:
        """Bytes in the mutant (all members of a folder)."""
        return len(self.data) + sum(len(m) for m in self.members.values())


# ------------------------------------------------------------------- byte operators
def _position(rng: random.Random, size: int) -> int:
    """A byte position in [0, size), the first HEAD_BYTES drawn half the time."""
    return byte_position(rng, size, HEAD_BYTES)


def flip_bits(rng: random.Random, data: bytes) -> bytes:
    """One to four bits flipped."""
    out = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if out:
            out[_position(rng, len(out))] ^= 1 << rng.randrange(8)
    return bytes(out)


def set_bytes(rng: random.Random, data: bytes) -> bytes:
    """One to three bytes set to boundary values (or random ones)."""
    out = bytearray(data)
    for _ in range(rng.randint(1, 3)):
        if out:
            out[_position(rng, len(out))] = (rng.choice(INTERESTING_BYTES) if rng.random() < 0.7
                                             else rng.randrange(256))
    return bytes(out)


def large_value(rng: random.Random, data: bytes) -> bytes:
    """A 32-bit little-endian count, size or offset written over four bytes (4-aligned half
    the time, where most fields sit)."""
    if len(data) < 4:
        return data
    at = _position(rng, len(data) - 3)
    if rng.random() < 0.5:
        at -= at % 4
    value = rng.choice(LARGE_VALUES) if rng.random() < 0.8 else rng.getrandbits(32)
    return data[:at] + struct.pack("<I", value) + data[at + 4:]


def truncate(rng: random.Random, data: bytes) -> bytes:
    """The file cut short: anywhere, or within its header."""
    if not data:
        return data
    limit = len(data) if rng.random() < 0.5 else min(len(data), 256)
    return data[:rng.randrange(limit)]


def splice(rng: random.Random, data: bytes, other: bytes) -> bytes:
    """A range of ``other`` (another seed of the format, or this file) copied over a range
    of ``data``, or inserted, or a range deleted."""
    if not data:
        return data
    at = _position(rng, len(data))
    length = rng.choice((1, 4, 16, 64, 512))
    choice = rng.random()
    if choice < 0.2:
        return data[:at] + data[at + length:]
    source = other if other and rng.random() < 0.5 else data
    start = rng.randrange(len(source))
    piece = source[start:start + length]
    if choice < 0.6:
        return data[:at] + piece + data[at + len(piece):]
    return data[:at] + piece + data[at:]


BYTE_OPERATORS = {"flip": flip_bits, "set": set_bytes, "large": large_value,
                  "truncate": truncate}


def mutate_bytes(rng: random.Random, data: bytes, other: bytes, ops: list[str]) -> bytes:
    """One to four byte operators applied to ``data`` (names appended to ``ops``)."""
    for _ in range(rng.choice((1, 1, 2, 3, 4))):
        name = rng.choice((*BYTE_OPERATORS, "splice"))
        data = (splice(rng, data, other) if name == "splice"
                else BYTE_OPERATORS[name](rng, data))
        ops.append(name)
    return data


# ------------------------------------------------------------------- PLY operators
def _split_header(data: bytes) -> tuple[list[bytes], bytes] | None:
    end = data.find(b"end_header\n")
    if end < 0:
        return None
    return data[:end].split(b"\n")[:-1], data[end:]


def _header_line_edit(rng: random.Random, lines: list[bytes]) -> str:
    """One edit of the header ``lines`` (in place); returns its name."""
    i = rng.randrange(1, len(lines)) if len(lines) > 1 else 0
    words = lines[i].split()
    edit = rng.choice(("count", "type", "name", "format", "drop", "double", "swap",
                       "element", "list", "comment"))
    if edit == "count":
        elements = [k for k, line in enumerate(lines) if line.startswith(b"element")]
        if elements:
            k = rng.choice(elements)
            parts = lines[k].split()
            n = int(parts[-1]) if parts[-1].isdigit() else 1
            value = rng.choice((0, 1, n - 1, n + 1, 2 * n, n // 2, 10 ** 9, 2 ** 32, 2 ** 64))
            lines[k] = b" ".join(parts[:-1] + [str(max(value, 0)).encode()])
    elif edit == "type" and words[:1] == [b"property"]:
        words[-2] = rng.choice((b"uchar", b"char", b"short", b"ushort", b"int", b"uint",
                                b"double", b"half", b"float16", b"int64", b"list"))
        lines[i] = b" ".join(words)
    elif edit == "name" and words[:1] == [b"property"]:
        words[-1] = rng.choice((b"x", b"f_rest_0", b"f_rest_44", b"f_dc_0", b"label", b"sem_0",
                                b"opacity", b"nx", b"packed_position", b"min_x", b"q"))
        lines[i] = b" ".join(words)
    elif edit == "format":
        k = next((k for k, line in enumerate(lines) if line.startswith(b"format")), 1)
        lines[k] = rng.choice((b"format ascii 1.0", b"format binary_little_endian 1.0",
                               b"format binary_big_endian 1.0", b"format binary 1.0",
                               b"format ascii 2.0"))
    elif edit == "drop":
        del lines[i]
    elif edit == "double":
        lines.insert(i, lines[i])
    elif edit == "swap" and len(lines) > 2:
        j = rng.randrange(1, len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    elif edit == "element":
        lines.insert(i, rng.choice((b"element face 1", b"element chunk 2", b"element sh 0",
                                    b"element vertex 3")))
    elif edit == "list":
        lines.insert(i, b"property list uchar int vertex_indices")
    else:
        lines.insert(i, rng.choice((b"comment end_header", b"obj_info x", b"bogus line")))
    return f"ply-{edit}"


def mutate_ply_header(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    """One to three header-line edits, the body kept."""
    parts = _split_header(data)
    if parts is None:
        return data
    lines, rest = parts
    for _ in range(rng.randint(1, 3)):
        ops.append(_header_line_edit(rng, lines))
    return b"\n".join(lines) + b"\n" + rest


def mutate_ascii_body(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    """One to three edits of an ASCII body: a token replaced, a row dropped, doubled or
    joined with the next."""
    end = data.find(b"end_header\n")
    if end < 0:
        return data
    body_start = end + len(b"end_header\n")
    rows = data[body_start:].split(b"\n")
    for _ in range(rng.randint(1, 3)):
        r = rng.randrange(len(rows))
        edit = rng.choice(("token", "token", "drop", "double", "join"))
        if edit == "token":
            tokens = rows[r].split(b" ")
            tokens[rng.randrange(len(tokens))] = rng.choice(ASCII_TOKENS)
            rows[r] = b" ".join(tokens)
        elif edit == "drop":
            del rows[r]
        elif edit == "double":
            rows.insert(r, rows[r])
        elif r + 1 < len(rows):
            rows[r:r + 2] = [rows[r] + b" " + rows[r + 1]]
        ops.append(f"ascii-{edit}")
        if not rows:
            rows = [b""]
    return data[:body_start] + b"\n".join(rows)


# ------------------------------------------------------------------- JSON operators
def _containers(node) -> list:
    """Every list and dict in ``node`` (pre-order, at most 2000)."""
    out, stack = [], [node]
    while stack and len(out) < 2000:
        item = stack.pop()
        if isinstance(item, dict | list):
            out.append(item)
            stack.extend(item.values() if isinstance(item, dict) else item)
    return out


def _json_value(rng: random.Random):
    """A fresh copy of one of :data:`JSON_VALUES` (never the shared object itself)."""
    return copy.deepcopy(rng.choice(JSON_VALUES))


def mutate_json(rng: random.Random, document, ops: list[str]):
    """One to three edits of a parsed JSON ``document`` (in place where it can be)."""
    for _ in range(rng.randint(1, 3)):
        containers = _containers(document)
        node = rng.choice(containers)
        keys = list(node) if isinstance(node, dict) else list(range(len(node)))
        edit = rng.choice(("value", "value", "value", "drop", "deep", "copy"))
        if not keys:
            edit = "add"
        key = rng.choice(keys) if keys else None
        if edit == "value":
            node[key] = _json_value(rng)
        elif edit == "drop":
            del node[key]
        elif edit == "deep":
            deep = 0
            for _ in range(rng.choice((3, 70, 200))):
                deep = [deep]
            node[key] = deep
        elif edit == "copy":
            other = rng.choice(containers)
            try:
                node[key] = copy.deepcopy(other) if other is not node else None
            except RecursionError:
                node[key] = None
        elif isinstance(node, dict):
            node["extra"] = _json_value(rng)
        else:
            node.append(_json_value(rng))
        ops.append(f"json-{edit}")
    return document


def dumps(document) -> bytes:
    """``document`` as JSON text; nested too deep for the encoder, 5000 open brackets."""
    try:
        return json.dumps(document).encode()
    except RecursionError:
        return b"[" * 5000


def _glb_json(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    """The GLB with its JSON chunk edited (chunk and file lengths kept consistent)."""
    json_length = struct.unpack_from("<I", data, 12)[0]
    document = json.loads(data[20:20 + json_length])
    text = dumps(mutate_json(rng, document, ops))
    text += b" " * (-len(text) % 4)
    rest = data[20 + json_length:]
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + rest
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _member_edit(rng: random.Random, name: str, data: bytes, other: bytes,
                 ops: list[str]) -> bytes:
    if name == "meta.json" and rng.random() < 0.7:
        return dumps(mutate_json(rng, json.loads(data), ops))
    return mutate_bytes(rng, data, other, ops)


def _zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def _unzip(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


# ------------------------------------------------------------------- mutants
def mutate(rng: random.Random, seed: ReaderSeed, others: list[ReaderSeed]) -> Mutant:
    """One mutant of ``seed``; ``others`` are seeds of the same format (for splices)."""
    ops: list[str] = []
    other = rng.choice(others).data if others else b""
    fmt, data = seed.format, seed.data
    choice = rng.random()
    if seed.members or (fmt == "sog" and choice < 0.7):
        members = dict(seed.members) if seed.members else _unzip(data)
        name = "meta.json" if rng.random() < 0.4 else rng.choice(sorted(members))
        members[name] = _member_edit(rng, name, members[name], other, ops)
        ops.insert(0, f"member:{name}")
        if seed.members:
            return Mutant(seed, b"", members, tuple(ops))
        return Mutant(seed, _zip(members), {}, tuple(ops))
    if fmt in ("ply", "ply-ascii", "compressed-ply") and choice < 0.4:
        data = mutate_ply_header(rng, data, ops)
    elif fmt == "ply-ascii" and choice < 0.8:
        data = mutate_ascii_body(rng, data, ops)
    elif fmt == "glb" and choice < 0.5:
        data = _glb_json(rng, data, ops)
    elif fmt == "spz" and data[:2] == b"\x1f\x8b" and choice < 0.6:
        payload = mutate_bytes(rng, gzip.decompress(data), b"", ops)
        data = gzip.compress(payload, compresslevel=1, mtime=0)
        ops.insert(0, "gzip-payload")
    else:
        data = mutate_bytes(rng, data, other, ops)
    if rng.random() < 0.15:
        data = mutate_bytes(rng, data, other, ops)
    if fmt == "glb" and len(data) >= 12 and rng.random() < 0.5:
        data = data[:8] + struct.pack("<I", len(data)) + data[12:]  # the length kept true
        ops.append("glb-length")
    return Mutant(seed, data, {}, tuple(ops))


def mutant_at(seeds: list[ReaderSeed], index: int, campaign: int = 0) -> Mutant:
    """Mutant ``index`` of campaign ``campaign``: the format drawn uniformly from
    :data:`FORMATS`, then a seed of it, then the operators."""
    rng = random.Random(f"readers:{campaign}:{index}")
    present = [f for f in FORMATS if any(s.format == f for s in seeds)]
    fmt = rng.choice(present)
    group = [s for s in seeds if s.format == fmt]
    seed = rng.choice(group)
    return mutate(rng, seed, group)
