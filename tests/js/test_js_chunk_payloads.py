"""The JavaScript receiver's readers of single payloads: OUTQ (far points with relative
precision, spec/FORMAT.md §12.20) decodes to the Python decoder's float32 bits, or is
rejected at the same offset, on hand-made, random and edge-case payloads; vdis (§12.21) reads
as Python reads it and is refused where the spec says it is invalid. Skipped when ``node``
is not on PATH."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from benchmarks._js_receiver import REPO, node_executable
from csgs_codec.chunks.far_points import read_relative_far_payload
from csgs_codec.chunks.far_points import relative_far_payload as outq
from csgs_codec.chunks.view_record import ViewRecord
from csgs_codec.codec.describe import describe_bitstream
from csgs_codec.errors import FormatError

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

SCRIPT = REPO / "tests" / "js" / "payloads.mjs"
SCENES = REPO / "spec" / "vectors" / "scenes"
#: Absolute offset the payloads are read at, so that offsets are checked as file offsets.
AT = 1000


def _run(cases: list[dict]) -> list[dict]:
    done = subprocess.run([node_executable(), str(SCRIPT)], input=json.dumps(cases),
                          capture_output=True, text=True, timeout=120, check=True)
    results = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(results) == len(cases)
    return results


def _outq(payload: bytes, far_count: int) -> dict:
    return {"kind": "OUTQ", "hex": payload.hex(), "offset": AT, "max": far_count}


def _python_outq(payload: bytes, far_count: int) -> dict:
    try:
        positions = read_relative_far_payload(payload, AT, far_count)
    except FormatError as err:
        return {"ok": False, "chunk": err.chunk, "offset": err.offset}
    return {"ok": True, "float32": positions.astype("<f4").tobytes().hex()}


def test_outq_hand_example():
    # b = 2, e = 3 (byte 131): a scale of 2^(3 - 2) = 2; mantissas (-4, 3, 0) are the 3-bit
    # fields u = m + 4 = (0, 7, 4), LSB first: bits 000 111 001 -> bytes 0x38 0x01.
    payload = outq((1.0, -2.0, 0.5), 2, np.array([3]), np.array([[-4, 3, 0]]))
    assert payload[-3:] == bytes([131, 0x38, 0x01])
    (js,) = _run([_outq(payload, 1)])
    assert js["ok"]
    assert np.frombuffer(bytes.fromhex(js["float32"]), "<f4").tolist() == [-7.0, 4.0, 0.5]


def _random_payloads(rng) -> list[tuple[bytes, int]]:
    cases = []
    for bits in (1, 2, 7, 15, 23, 29, 30):
        count = int(rng.integers(1, 40))
        top = 1 << bits
        mantissas = rng.integers(-top, top, size=(count, 3))
        mantissas[0] = (-top, top - 1, 0)  # the extremes of the field
        exponents = rng.integers(-128, 100, size=count)
        exponents[0] = -128  # the smallest scale, 2^(-128 - b)
        centre = rng.normal(0, 1e3, 3) * 10.0 ** rng.integers(-6, 8)
        cases.append((outq(centre, bits, exponents, mantissas), count + 3))
    return cases


def _edge_payloads() -> list[tuple[bytes, int]]:
    top = 1 << 30
    one = np.array([[0, 0, 0]])
    return [
        # Float32 range limits: 2^127 (1 - 2^-30) is finite, 2^127 + 2^127 is not.
        (outq((0.0, 0.0, 0.0), 30, np.array([127]), np.array([[top - 1, -top, 1]])), 1),
        (outq((2.0 ** 127, 0.0, 0.0), 30, np.array([127]), np.array([[top - 1, 0, 0]])), 1),
        # Sums that round: a large centre and offsets below its float64 ulp / float32 ulp.
        (outq((1e8, -3e7, 16777217.0), 12, np.array([-5, 3]),
                     np.array([[1, -1, 1], [4095, -4096, 3]])), 2),
        (outq((0.1, 0.2, 0.3), 20, np.array([0]), one), 1),
    ]


def _invalid_payloads() -> list[tuple[bytes, int]]:
    good = outq((1.0, 2.0, 3.0), 5, np.array([1, 2]), np.array([[1, 2, 3], [-32, 31, 0]]))
    body = good[1:]  # after the one-byte count
    padded = bytearray(good)
    padded[-1] |= 0x80  # 6 fields of 6 bits: bits 36..39 of the last byte are padding
    centre_nan = bytearray(good)
    centre_nan[2 + 8:2 + 16] = np.float64(np.nan).tobytes()
    return [
        (b"\x00" + body, 2),  # count 0
        (good, 1),  # count above far_count
        (b"\x82\x00" + body, 2),  # count not in shortest form
        (good[:1] + b"\x00" + good[2:], 2),  # mantissa_bits 0
        (good[:1] + b"\x1f" + good[2:], 2),  # mantissa_bits 31
        (bytes(centre_nan), 2),
        (bytes(padded), 2),
        (good + b"\x00", 2),  # a byte after the mantissas
        (good[:-1], 2),  # mantissas cut short
        (good[:27], 2),  # exponents cut short
        (b"", 2),
    ]


def test_outq_decodes_as_in_python():
    random, edge = _random_payloads(np.random.default_rng(12)), _edge_payloads()
    cases = random + edge + _invalid_payloads()
    results = _run([_outq(p, n) for p, n in cases])
    rejected = 0
    for i, ((payload, far_count), js) in enumerate(zip(cases, results)):
        assert js == _python_outq(payload, far_count), f"case {i}"
        rejected += not js["ok"]
    assert rejected == 12  # the second edge case and every invalid payload
    first_edge = np.frombuffer(bytes.fromhex(results[len(random)]["float32"]), "<f4")
    largest = float(np.float32(2.0 ** 127 * (1 - 2.0 ** -30)))  # rounds to float32
    assert first_edge.tolist() == [largest, -(2.0 ** 127), 2.0 ** 97]


def _vdis(payload: bytes) -> dict:
    return {"kind": "vdis", "hex": payload.hex(), "offset": AT}


def test_vdis_reads_as_in_python():
    record = ViewRecord("cameras", 301, 12345678, "301 training cameras, ünïcode")
    payload = record.to_bytes()
    assert ViewRecord.from_bytes(payload) == record
    text = 2 + 2 + 4  # version, source, view_count (2 varint bytes), left_out (4)
    invalid = {
        "version 9": (b"\x09" + payload[1:], AT),
        "source 2": (payload[:1] + b"\x02" + payload[2:], AT + 1),
        "view_count 2^32 + 1": (payload[:2] + b"\x81\x80\x80\x80\x10" + payload[4:], AT + 2),
        "description of 257 bytes": (payload[:text] + b"\x81\x02" + b"a" * 257, AT + text),
        "description not UTF-8": (payload[:text] + b"\x02\xc3\x28", AT + text),
        "a trailing byte": (payload + b"\x00", AT + len(payload)),
    }
    results = _run([_vdis(payload)] + [_vdis(p) for p, _ in invalid.values()])
    assert results[0] == {"ok": True, "record": {
        "source": "cameras", "count": 301, "leftOut": 12345678,
        "description": "301 training cameras, ünïcode"}}
    # Offsets are the field's first byte (§11); the reference reader names the byte after a
    # bad version or source, which is informative only: a decoder skips the chunk.
    for (what, (bad, offset)), js in zip(invalid.items(), results[1:]):
        with pytest.raises(FormatError):
            ViewRecord.from_bytes(bad, AT)
        assert js == {"ok": False, "chunk": "vdis", "offset": offset}, what


def test_scene_vectors_report_their_view_record():
    from benchmarks._js_receiver import run_js

    paths = sorted(SCENES.glob("view_pruned_*.csgs")) + [SCENES / "far_floaters_q5.csgs"]
    assert [p.stem for p in paths] == ["view_pruned_q5", "view_pruned_vdis_version_9",
                                       "far_floaters_q5"]
    results = run_js(paths, threads=1)
    assert all(js["ok"] for js in results)
    assert results[0]["views"] == describe_bitstream(paths[0])["views"] == {
        "source": "default-sphere", "count": 48, "left_out": 134,
        "description": "48 views on a sphere at 3 distances"}
    # An unknown version is skipped, not a reason to reject the scene; no vdis, no views.
    assert results[1]["views"] is None and results[2]["views"] is None
    assert results[1]["arrays"] == results[0]["arrays"]
