"""Reproducible mutants of the seed captures of :mod:`tests.fuzz.loader_seeds`.

:func:`mutant_at` draws a layout, its seed, then one file of the capture to edit:

* camera files: byte operators (:func:`tests.fuzz.reader_mutators.mutate_bytes`); JSON
  edits (:func:`~tests.fuzz.reader_mutators.mutate_json`) and value swaps of a camera field
  (huge, negative, NaN, inf numbers, wrong types, long strings, absolute and ``../`` paths);
  COLMAP text token swaps and image-name swaps in the text and binary models;
* ``poses_bounds.npy``: edits of its header (dtype, shape, order, header length, version);
* images and masks: truncation, a PNG header whose size lies, the picture re-saved in
  another mode (grey 16-bit, palette, RGBA, 1-bit, 32-bit int, float) or as a JPEG.
"""

from __future__ import annotations

import io
import json
import random
import re
import struct
import zlib
from dataclasses import dataclass

from tests.fuzz.loader_seeds import FORMATS, LoaderSeed
from tests.fuzz.reader_mutators import ASCII_TOKENS, dumps, mutate_bytes, mutate_json

PATHS = ("/etc/hostname", "/nonexistent/x.png", "../outside.png", "../../images/view_000.png",
         "images/../../x.png", "a" * 5000, "images/" + "b" * 300 + ".png", "x\0y.png", "",
         ".", "images", "images/", "masks/view_000.png", "~/x.png", "C:\\x.png", "\u00e9.png")
NUMBERS = (1e308, -1e308, float("nan"), float("inf"), -float("inf"), -1, 0, 2 ** 64, 10 ** 400,
           1e-320, 0.5, 3, -3.5)
TYPES = (None, True, [], {}, [[1, 2]], "7", {"a": 1}, [1.0] * 4)
CAMERA_KEYS = ("w", "h", "fl_x", "fl_y", "cx", "cy", "camera_angle_x", "camera_angle_y",
               "transform_matrix", "file_path", "width", "height", "fx", "fy", "position",
               "rotation", "img_name", "id", "frames", "k1")
NPY_DESCR = ("'<f4'", "'>f8'", "'|O'", "'<c16'", "'|S8'", "'<i8'", "'|b1'", "'<f16'", "'x'",
             "'<V8'", "[('a', '<f8')]")
NPY_SHAPES = ("()", "(3,)", "(0, 17)", "(3, 16)", "(2, 17)", "(4, 17)", "(3, 17, 1)",
              "(-1, 17)", "(99999999999, 17)", "(3, 18446744073709551616)", "(3,17,)", "x")
MODES = ("I;16", "P", "RGBA", "1", "I", "F", "LA", "L", "CMYK", "jpeg")


@dataclass(frozen=True)
class LoaderMutant:
    """A mutated capture: every file (relative path -> bytes) and the operators used."""

    seed: LoaderSeed
    files: dict[str, bytes]
    operators: tuple[str, ...]

    @property
    def size(self) -> int:
        """Bytes in all the mutant's files."""
        return sum(len(data) for data in self.files.values())


def _swap_value(rng: random.Random, document, ops: list[str]):
    """A camera field (top level or in one frame/entry) set to a hostile value."""
    entries = document.get("frames") if isinstance(document, dict) else document
    holder = document
    if isinstance(entries, list) and entries and rng.random() < 0.8:
        holder = rng.choice(entries)
    if not isinstance(holder, dict):
        return document
    key = rng.choice(CAMERA_KEYS)
    kind = rng.choice(("number", "type", "path", "deep"))
    if kind == "number":
        value = rng.choice(NUMBERS)
    elif kind == "type":
        value = rng.choice(TYPES)
    elif kind == "path":
        key = "file_path" if isinstance(document, dict) else "img_name"
        value = rng.choice(PATHS)
    else:
        value = 1
        for _ in range(rng.choice((50, 500, 3000))):
            value = [value]
    holder[key] = value
    ops.append(f"json-swap-{kind}")
    return document


def _json_file(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    document = json.loads(data)
    for _ in range(rng.randint(1, 2)):
        if rng.random() < 0.6:
            document = _swap_value(rng, document, ops)
        else:
            document = mutate_json(rng, document, ops)
    try:
        return json.dumps(document).encode()  # NaN and Infinity as Python writes them
    except (RecursionError, ValueError):
        return dumps(document)


def _colmap_text(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    lines = data.split(b"\n")
    row = rng.randrange(len(lines))
    tokens = lines[row].split(b" ")
    at = rng.randrange(len(tokens))
    if rng.random() < 0.3 and at == len(tokens) - 1:
        tokens[at] = rng.choice(PATHS).encode("utf-8", "surrogatepass")
        ops.append("colmap-name")
    else:
        tokens[at] = rng.choice(ASCII_TOKENS)
        ops.append("colmap-token")
    lines[row] = b" ".join(tokens)
    return b"\n".join(lines)


def _colmap_binary_name(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    names = list(re.finditer(rb"view_\d{3}\.png\0", data))
    if not names:
        return data
    match = rng.choice(names)
    name = rng.choice(PATHS).replace("\0", "").encode() + b"\0"
    ops.append("colmap-name")
    return data[:match.start()] + name + data[match.end():]


def _npy_header(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    length = struct.unpack_from("<H", data, 8)[0]
    header = data[10:10 + length].decode("latin1")
    body = data[10 + length:]
    edit = rng.choice(("descr", "shape", "order", "length", "version", "text"))
    if edit == "descr":
        header = re.sub(r"'descr': '[^']*'", f"'descr': {rng.choice(NPY_DESCR)}", header)
    elif edit == "shape":
        header = re.sub(r"'shape': \([^)]*\)", f"'shape': {rng.choice(NPY_SHAPES)}", header)
    elif edit == "order":
        header = header.replace("False", rng.choice(("True", "1", "None")))
    elif edit == "text":
        header = rng.choice(("{}", "[]", "{'descr': '<f8'}", "x" * 100, "{" * 300))
    ops.append(f"npy-{edit}")
    encoded = header.encode("latin1")
    size = len(encoded)
    version = b"\x01\x00"
    if edit == "length":
        size = rng.choice((0, 1, size - 7, size + 9, 0xFFFF))
    elif edit == "version":
        version = rng.choice((b"\x02\x00", b"\x03\x00", b"\x09\x00", b"\x00\x00"))
    return b"\x93NUMPY" + version + struct.pack("<H", size) + encoded + body


def _png_size_lie(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    if data[12:16] != b"IHDR":
        return data
    width = rng.choice((0, 1, 7, 9, 16, 65535, 1 << 20, (1 << 31) - 1))
    height = rng.choice((0, 1, 5, 6, 12, 65535, 1 << 20))
    ihdr = bytearray(data[16:29])
    ihdr[0:8] = struct.pack(">II", width, height)
    crc = struct.pack(">I", zlib.crc32(b"IHDR" + bytes(ihdr)))
    ops.append("png-size")
    return data[:16] + bytes(ihdr) + crc + data[33:]


def _picture_mode(rng: random.Random, data: bytes, ops: list[str]) -> bytes:
    from PIL import Image

    mode = rng.choice(MODES)
    with Image.open(io.BytesIO(data)) as picture:
        picture.load()
        out = io.BytesIO()
        if mode == "jpeg":
            picture.convert("RGB").save(out, "JPEG")
        elif mode == "F":
            picture.convert("F").save(out, "TIFF")
        else:
            picture.convert(mode).save(out, "TIFF" if mode in ("CMYK", "I") else "PNG")
    ops.append(f"picture-{mode}")
    return out.getvalue()


def _picture(rng: random.Random, name: str, data: bytes, ops: list[str]) -> bytes:
    choice = rng.random()
    if choice < 0.3:
        ops.append("truncate")
        return data[:rng.randrange(len(data))]
    if choice < 0.55:
        return _png_size_lie(rng, data, ops)
    if choice < 0.8:
        return _picture_mode(rng, data, ops)
    return mutate_bytes(rng, data, b"", ops)


def _camera_edit(rng: random.Random, name: str, data: bytes, ops: list[str]) -> bytes:
    choice = rng.random()
    if name.endswith(".json") and choice < 0.75:
        return _json_file(rng, data, ops)
    if name.endswith(".txt") and choice < 0.6:
        return _colmap_text(rng, data, ops)
    if name.endswith("images.bin") and choice < 0.3:
        return _colmap_binary_name(rng, data, ops)
    if name.endswith(".npy") and choice < 0.6:
        return _npy_header(rng, data, ops)
    return mutate_bytes(rng, data, data, ops)


def mutate(rng: random.Random, seed: LoaderSeed) -> LoaderMutant:
    """One mutant of ``seed``: a camera file edited (60%), else an image or mask."""
    files = dict(seed.files)
    ops: list[str] = []
    cameras = [n for n in files if not n.startswith(("images/", "masks/"))]
    pictures = [n for n in files if n.startswith(("images/", "masks/"))]
    for _ in range(1 if rng.random() < 0.85 else 2):
        edit, names = (_camera_edit, cameras) if rng.random() < 0.6 else (_picture, pictures)
        name = rng.choice(names)
        try:
            files[name] = edit(rng, name, files[name], ops)
        except (ValueError, OSError, struct.error, IndexError, RecursionError):
            # a second edit of a file the first left unparseable: bytes only
            files[name] = mutate_bytes(rng, files[name], b"", ops)
        ops.insert(0, f"file:{name}")
    return LoaderMutant(seed, files, tuple(ops))


def mutant_at(seeds: list[LoaderSeed], index: int, campaign: int = 0) -> LoaderMutant:
    """Mutant ``index`` of campaign ``campaign``: the layout drawn uniformly from
    :data:`FORMATS`, then a seed of it, then the edits."""
    rng = random.Random(f"loaders:{campaign}:{index}")
    present = [f for f in FORMATS if any(s.format == f for s in seeds)]
    fmt = rng.choice(present)
    seed = rng.choice([s for s in seeds if s.format == fmt])
    return mutate(rng, seed)
