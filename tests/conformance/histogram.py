"""Histogram stream conformance vectors (spec/FORMAT.md §16.5): payload + expected values."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from csgs_codec.entropy.histogram import decode_histogram, encode_histogram
from csgs_codec.errors import CsgsError

SCHEMA = "csgs-vector/1"


def _cases() -> list[tuple[str, str, list[int]]]:
    rng = np.random.default_rng(16)
    bimodal = np.concatenate([rng.normal(-6, 1.0, 300), rng.normal(5, 0.7, 200)])
    wide = rng.integers(-5000, 5000, 40).tolist() + [0] * 4000 + [1 << 62, -(1 << 62)]
    return [
        ("histogram_empty", "No values: the single byte 00.", []),
        ("histogram_single", "One value.", [7]),
        ("histogram_bimodal", "Two clusters of values, the case histograms are for.",
         np.rint(bimodal).astype(np.int64).tolist()),
        ("histogram_escapes", "A range wider than 4096 values: the tails (and +-2^62) are "
         "escaped.", wide),
    ]


def _write(out_dir: Path, name: str, payload: bytes, meta: dict) -> None:
    (out_dir / f"{name}.bin").write_bytes(payload)
    doc = {"schema": SCHEMA, "name": name, "kind": "histogram", **meta,
           "file": f"{name}.bin", "bytes": len(payload),
           "sha256": hashlib.sha256(payload).hexdigest()}
    (out_dir / f"{name}.json").write_text(json.dumps(doc, indent=1) + "\n")


def _error_of(payload: bytes, count: int) -> dict:
    try:
        decode_histogram(payload, count)
    except CsgsError as err:
        return {"outcome": "error", "error": type(err).__name__, "offset": err.offset}
    raise AssertionError("an invalid histogram vector decoded without error")


def generate(out_dir: Path) -> None:
    """Write the histogram vectors into ``out_dir``."""
    for name, description, values in _cases():
        payload = encode_histogram(np.array(values, np.int64))
        _write(out_dir, name, payload, {"description": description, "outcome": "ok",
                                        "count": len(values), "values": values})
    good = encode_histogram(np.array([0, 1, 1, 2, 2, 2, 3], np.int64))
    # Bytes: count 07, lo 00, K 04, five one-byte frequencies, then the range data.
    bad_sum = bytearray(good)
    bad_sum[3] += 1
    escape_inside = encode_histogram(np.array([0] * 5000 + [1] * 5000 + [9000], np.int64))
    # The stream ends with the escape of 9000 (zigzag varint d0 8c 01); make it say 1, which
    # lies inside the table's range [0, 2).
    tampered = escape_inside[:-3] + bytes([2])
    invalid = [
        ("histogram_bad_sum", "Frequencies summing to 65537.", bytes(bad_sum), 7),
        ("histogram_trailing", "A valid stream plus one byte.", good + b"\x00", 7),
        ("histogram_truncated", "A valid stream cut before its last byte.", good[:-1], 7),
        ("histogram_wrong_count", "Seven values where eight are expected.", good, 8),
        ("histogram_escape_inside", "An escaped value that lies inside the table's range.",
         tampered, 10001),
    ]
    for name, description, payload, count in invalid:
        _write(out_dir, name, payload, {"description": description, "count": count,
                                        **_error_of(payload, count)})
