"""Geometry payload conformance vectors (spec/vectors/geometry/).

Each vector is ``NAME.bin`` (a geometry payload, spec/FORMAT.md §15) plus ``NAME.json``:
a description, the payload's size and SHA-256, and either the decoded points in canonical
order (valid payloads) or the error class and byte offset (invalid ones). Expected points are
computed here independently of the coder (a plain-Python Morton sort of the input set), and
:func:`generate` checks the decoder agrees before writing anything.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from csgs_codec.entropy.geometry import decode_positions, encode_positions
from csgs_codec.errors import CsgsError

SCHEMA = "csgs-vector/1"


def _morton_key(point: list[int], bits: int) -> int:
    """Morton code by the spec's definition, one bit at a time (no shared code with the coder)."""
    key = 0
    for level in range(bits):
        for axis in range(3):
            key |= ((point[axis] >> level) & 1) << (3 * level + axis)
    return key


def _expected_points(points: list[list[int]], bits: int) -> list[list[int]]:
    return sorted(points, key=lambda p: _morton_key(p, bits))


def _valid_cases() -> list[tuple[str, str, int, list[list[int]]]]:
    rng = np.random.default_rng(20261123)
    cluster = (np.array([300, 700, 512]) + rng.integers(-6, 7, (48, 3))).tolist()
    spread = rng.integers(0, 1 << 16, (40, 3)).tolist()
    top21 = (1 << 21) - 1
    return [
        ("empty", "No points.", 16, []),
        ("single_point", "One point at 16 bits.", 16, [[65535, 0, 4660]]),
        ("all_equal", "Five copies of one point at 8 bits.", 8, [[3, 200, 17]] * 5),
        ("duplicates", "Small 5-bit set where some points repeat two or three times.", 5,
         [[1, 2, 3], [31, 0, 31], [1, 2, 3], [4, 4, 4], [0, 0, 0], [31, 0, 31], [1, 2, 3],
          [4, 5, 4], [17, 9, 30]]),
        ("zero_bits", "A 1x1x1 grid: three points, all at the origin.", 0, [[0, 0, 0]] * 3),
        ("extremes_21bit", "The eight corners of the 21-bit grid, one of them twice.", 21,
         [[x, y, z] for x in (0, top21) for y in (0, top21) for z in (0, top21)] + [[0, 0, 0]]),
        ("cluster_10bit", "48 points in a 13-unit cube at 10 bits (octree occupancy path).", 10,
         cluster),
        ("spread_16bit", "40 points spread over the 16-bit grid (direct-mode path).", 16, spread),
    ]


def _invalid_cases() -> list[tuple[str, str, bytes, int]]:
    good = encode_positions(np.array(_valid_cases()[3][3]), 5)
    return [
        ("bad_version", "Version byte 2.", bytes([2]) + good[1:], 0),
        ("bits_over_21", "22 bits per axis.", bytes([1, 22, 0]), 1),
        ("truncated", "The duplicates payload without its last byte.", good[:-1], None),
        ("trailing_byte", "The duplicates payload with one extra zero byte.", good + b"\x00",
         None),
        ("distinct_over_count", "Distinct count 3 for a 2-point set.", bytes([1, 4, 2, 3]), 3),
        ("empty_with_trailing", "Zero points followed by a byte.", bytes([1, 16, 0, 0]), 3),
    ]


def _outcome(payload: bytes) -> dict:
    try:
        points = decode_positions(payload)
    except CsgsError as err:
        return {"valid": False, "error": type(err).__name__, "offset": err.offset}
    return {"valid": True, "points": points.astype(int).tolist()}


def check_vector(folder: Path, record: dict) -> list[str]:
    """Problems found decoding one vector against its JSON record (empty list: it conforms)."""
    payload = (folder / record["file"]).read_bytes()
    problems = []
    if hashlib.sha256(payload).hexdigest() != record["sha256"]:
        problems.append("payload SHA-256 differs from the record")
    got = _outcome(payload)
    if got["valid"] != record["valid"]:
        problems.append(f"valid is {got['valid']}, record says {record['valid']}")
    elif record["valid"] and got["points"] != record["points"]:
        problems.append("decoded points differ from the record")
    elif not record["valid"] and (got["error"], got["offset"]) != (record["error"],
                                                                   record["offset"]):
        problems.append(f"error {got['error']} at {got['offset']}, record says "
                        f"{record['error']} at {record['offset']}")
    return problems


def generate(out_dir: Path) -> None:
    """Write every geometry vector into ``out_dir`` after checking the decoder agrees."""
    records = []
    for name, description, bits, points in _valid_cases():
        q = np.array(points, np.int64).reshape(-1, 3)
        payload = encode_positions(q, bits)
        record = {"bits": bits, "valid": True, "points": _expected_points(points, bits)}
        records.append((name, description, payload, record))
    for name, description, payload, offset in _invalid_cases():
        got = _outcome(payload)
        if got["valid"]:
            raise AssertionError(f"invalid vector {name} decodes")
        if offset is not None and got["offset"] != offset:
            raise AssertionError(f"vector {name}: error at {got['offset']}, expected {offset}")
        records.append((name, description, payload,
                        {"valid": False, "error": "FormatError", "offset": got["offset"]}))
    for name, description, payload, expected in records:
        record = {"schema": SCHEMA, "file": f"{name}.bin", "description": description,
                  "bytes": len(payload), "sha256": hashlib.sha256(payload).hexdigest(),
                  **expected}
        (out_dir / record["file"]).write_bytes(payload)
        problems = check_vector(out_dir, record)
        if problems:
            raise AssertionError(f"vector {name}: {problems}")
        (out_dir / f"{name}.json").write_text(json.dumps(record, indent=2) + "\n")
