"""Entropy-layer conformance vectors (spec/vectors/entropy/).

* ``tables.json``: SHA-256 and half-widths of the frozen Gaussian family v1 and sine table v1.
* ``residual_*.bin`` + ``.json``: a residual stream (spec/FORMAT.md §16.3) with its
  inputs (values, means, scale and step indices) and the decoded values, or, for invalid
  streams, the error class and byte offset.
* ``intnet_*.bin`` + ``.json``: a network payload (§16.4.3), input positions and expected outputs,
  or the error of an invalid payload.

Expected reconstructions are computed here in plain Python integers from the spec's formulas
(not with the coder's numpy code), and :func:`generate` checks the decoder agrees.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from csgs_codec.entropy.intnet import IntLayer, IntMLP
from csgs_codec.entropy.intnet_bytes import (
    INTNET_VERSION,
    INTNET_VERSION_RAW,
    intnet_from_bytes,
    intnet_to_bytes,
)
from csgs_codec.entropy.residual import decode_residuals, encode_residuals
from csgs_codec.entropy.tables import (
    DATA_DIR,
    GAUSSIAN_V1_SHA256,
    SINE_V1_SHA256,
    gaussian_family,
)
from csgs_codec.errors import CsgsError

SCHEMA = "csgs-vector/1"


def _step(j: int) -> int:
    m = j + 1
    return m if m < 16 else (8 + m % 8) << (m // 8 - 1)


def _expected_values(values, mean, steps) -> list[int]:
    out = []
    for a, mu, j in zip(values, mean, steps):
        q = _step(j)
        out.append(mu + q * ((2 * (a - mu) + q) // (2 * q)))
    return out


def _residual_cases() -> list[tuple[str, str, list[int], list[int], list[int], list[int]]]:
    rng = np.random.default_rng(51123)
    n = 200
    mean = rng.integers(-5000, 5000, n)
    steps = rng.integers(0, 40, n)
    scales = rng.integers(0, 64, n)
    values = mean + rng.integers(-60, 61, n) * rng.integers(1, 4, n)
    big = 1 << 53
    outliers = [big, -big, 123456789, -987654321, 0, 7, -7, big - 1]
    return [
        ("residual_empty", "No values.", [], [], [], []),
        ("residual_single", "One value, mean 10, step index 3 (q = 4), table 20.",
         [17], [10], [20], [3]),
        ("residual_all_equal", "32 equal values on their mean, table 0 (sigma 0.11), q = 1.",
         [5] * 32, [5] * 32, [0] * 32, [0] * 32),
        ("residual_mixed", "200 random values, all 64 tables possible, steps 0..39.",
         values.tolist(), mean.tolist(), scales.tolist(), steps.tolist()),
        ("residual_escapes", "Huge outliers (up to 2^53) that take the escape path.",
         outliers, [0, 0, 1000, -1000, 0, 0, 0, -big], [0, 63, 10, 30, 0, 0, 0, 5],
         [0, 0, 16, 100, 0, 0, 0, 0]),
    ]


def _network() -> IntMLP:
    rng = np.random.default_rng(7)
    widths = [12, 16, 16, 3]
    layers = tuple(IntLayer(rng.integers(-127, 128, (widths[i + 1], widths[i])),
                            rng.integers(-20000, 20000, widths[i + 1]), shift, 8)
                   for i, shift in enumerate((12, 9, 8)))
    return IntMLP(16, 2, 10, layers, np.array([-4000, 0, 0]), np.array([4000, 63, 175]))


def _positions() -> list[list[int]]:
    rng = np.random.default_rng(11)
    corners = [[0, 0, 0], [65535, 65535, 65535], [32768, 16384, 49152]]
    return corners + rng.integers(0, 1 << 16, (29, 3)).tolist()


def _write(out_dir: Path, name: str, payload: bytes | None, meta: dict) -> None:
    doc = {"schema": SCHEMA, "name": name, **meta}
    if payload is not None:
        (out_dir / f"{name}.bin").write_bytes(payload)
        doc["file"] = f"{name}.bin"
        doc["bytes"] = len(payload)
        doc["sha256"] = hashlib.sha256(payload).hexdigest()
    (out_dir / f"{name}.json").write_text(json.dumps(doc, indent=1) + "\n")


def _error_of(call) -> dict:
    try:
        call()
    except CsgsError as err:
        return {"outcome": "error", "error": type(err).__name__, "offset": err.offset}
    raise AssertionError("an invalid vector decoded without error")


def generate(out_dir: Path) -> None:
    """Write every entropy vector into ``out_dir`` after checking the decoder agrees."""
    out_dir = Path(out_dir)
    family = gaussian_family()
    _write(out_dir, "tables", None, {
        "description": "Frozen tables: Gaussian family v1 and sine table v1.",
        "gaussian_v1": {"sha256": GAUSSIAN_V1_SHA256,
                        "bytes": (DATA_DIR / "gaussian_v1.bin").stat().st_size,
                        "half_widths": family.half_widths.tolist()},
        "sine_v1": {"sha256": SINE_V1_SHA256, "bytes": (DATA_DIR / "sine_v1.bin").stat().st_size},
    })
    for name, text, values, mean, scales, steps in _residual_cases():
        payload = encode_residuals(np.array(values, np.int64), np.array(mean, np.int64),
                                   np.array(scales, np.int64), np.array(steps, np.int64))
        expected = _expected_values(values, mean, steps)
        decoded = decode_residuals(payload, np.array(mean, np.int64),
                                   np.array(scales, np.int64), np.array(steps, np.int64))
        assert decoded.tolist() == expected, name
        _write(out_dir, name, payload, {
            "description": text, "kind": "residual", "outcome": "ok",
            "inputs": {"values": values, "mean": mean, "scale_idx": scales,
                       "step_idx": steps},
            "decoded": expected})
    mixed = _residual_cases()[3]
    good = encode_residuals(*(np.array(v, np.int64) for v in mixed[2:]))
    for name, text, payload in (
            ("residual_truncated", "residual_mixed cut in the range data.", good[:40]),
            ("residual_trailing", "residual_mixed plus one byte.", good + b"\x00"),
            ("residual_wrong_count", "residual_mixed declaring 199 values.",
             bytes([199, 1]) + good[2:])):
        args = [np.array(v, np.int64) for v in mixed[3:]]
        outcome = _error_of(lambda p=payload, a=args: decode_residuals(p, *a))
        _write(out_dir, name, payload, {
            "description": text, "kind": "residual",
            "inputs": {"mean": mixed[3], "scale_idx": mixed[4], "step_idx": mixed[5]},
            **outcome})
    net = _network()
    positions = _positions()
    payload = intnet_to_bytes(net, INTNET_VERSION_RAW)
    outputs = intnet_from_bytes(payload).forward(np.array(positions), path="int64")
    assert (outputs == net.forward(np.array(positions), path="float64")).all()
    _write(out_dir, "intnet_small", payload, {
        "description": "3-layer network, L = 2, widths 12-16-16-3, 8-bit weights, "
                       "act_bits 10; outputs (mean, scale index, step index); payload "
                       "version 1 (fixed-width weights and biases).",
        "kind": "intnet", "outcome": "ok", "positions": positions,
        "embedding_first_row": net.embed(np.array(positions[:1]))[0].tolist(),
        "outputs": outputs.tolist()})
    coded = intnet_to_bytes(net, INTNET_VERSION)
    assert coded[0] == 2 and (intnet_from_bytes(coded).forward(np.array(positions),
                                                               path="int64") == outputs).all()
    _write(out_dir, "intnet_small_v2", coded, {
        "description": "intnet_small in payload version 2 (entropy-coded weights, varint "
                       "biases): the same network, the same outputs.",
        "kind": "intnet", "outcome": "ok", "positions": positions,
        "embedding_first_row": net.embed(np.array(positions[:1]))[0].tolist(),
        "outputs": outputs.tolist()})
    for name, text, blob in (
            ("intnet_bad_version", "intnet_small with version byte 3.",
             b"\x03" + payload[1:]),
            ("intnet_truncated", "intnet_small cut inside the second layer's weights.",
             payload[:400]),
            ("intnet_over_bound",
             "Second layer: worst-case sum 2 (2^23 - 1)(2^30 - 1) exceeds 2^53.",
             _over_bound_payload())):
        outcome = _error_of(lambda b=blob: intnet_from_bytes(b))
        _write(out_dir, name, blob, {"description": text, "kind": "intnet", **outcome})


def _over_bound_payload() -> bytes:
    """Two layers, L = 1, act_bits 30; the second has two 24-bit weights 2^23 - 1 on inputs up
    to 2^30 - 1, so its worst-case sum 2 (2^23 - 1)(2^30 - 1) exceeds 2^53."""
    out = bytearray([1, 16, 1, 30, 2])
    out += bytes([2, 24, 0]) + np.ones(12, "<i4").tobytes() + np.zeros(2, "<i8").tobytes()
    out += bytes([1, 24, 0]) + np.full(2, 2**23 - 1, "<i4").tobytes()
    out += np.zeros(1, "<i8").tobytes()
    out += bytes([0, 2])  # svarint lo = 0, hi = 1
    return bytes(out)
