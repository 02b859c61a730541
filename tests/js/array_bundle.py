"""Typed arrays between the tests and Node scripts: a little-endian u32 header length, a JSON
header ``{"meta": {...}, "arrays": {name: {"dtype", "shape", "offset"}}}`` and the raw
little-endian bytes of each array (tests/js/array_bundle.mjs reads and writes the same)."""

from __future__ import annotations

import json
import struct

import numpy as np

#: numpy dtype names the bundle carries, as the JavaScript side names them.
DTYPES = {"float32": "<f4", "float64": "<f8", "int32": "<i4", "uint8": "u1"}


def pack(arrays: dict[str, np.ndarray], meta: dict | None = None) -> bytes:
    """One bundle of ``arrays`` (cast to the nearest carried dtype) and ``meta``."""
    header, blobs, offset = {"meta": meta or {}, "arrays": {}}, [], 0
    for name, value in arrays.items():
        value = np.asarray(value)
        kind = {"f": "float32" if value.dtype == np.float32 else "float64", "b": "uint8",
                "u": "uint8" if value.dtype == np.uint8 else "int32", "i": "int32"}[
            value.dtype.kind]
        data = np.ascontiguousarray(value, dtype=DTYPES[kind]).tobytes()
        header["arrays"][name] = {"dtype": kind, "shape": list(value.shape), "offset": offset}
        blobs.append(data)
        offset += len(data)
    text = json.dumps(header).encode()
    return struct.pack("<I", len(text)) + text + b"".join(blobs)


def unpack(data: bytes) -> tuple[dict[str, np.ndarray], dict]:
    """(arrays, meta) of a bundle."""
    (length,) = struct.unpack_from("<I", data)
    header = json.loads(data[4:4 + length])
    body = data[4 + length:]
    arrays = {}
    for name, spec in header["arrays"].items():
        dtype = np.dtype(DTYPES[spec["dtype"]])
        count = int(np.prod(spec["shape"], dtype=np.int64))
        arrays[name] = np.frombuffer(body, dtype, count, spec["offset"]).reshape(spec["shape"])
    return arrays, header["meta"]
