"""The JavaScript anchor decoder's exact integer arithmetic against the Python reference on
inputs no conformance vector reaches: grid values beyond 2^53 (kept exactly, rounded to
float32 as numpy rounds int64), the 2^62 range limit, hyperprior parameters outside the
coder's ranges (spec/FORMAT.md §17.2), and CARM networks (§17.5) on inputs beyond 2^53 with
large input shifts. Skipped when ``node`` is not on PATH."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from benchmarks._js_receiver import REPO, node_executable
from csgs_codec.chunks.anchor_streams import grid_floats
from csgs_codec.entropy.anchor_attributes import EntropyParams, decode_block
from csgs_codec.entropy.intnet import IntLayer
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.entropy.residual import encode_symbols
from csgs_codec.errors import FormatError

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

SCRIPT = REPO / "tests" / "js" / "anchor_streams.mjs"
AT = 500


def _run(cases: list[dict]) -> list[dict]:
    done = subprocess.run([node_executable(), str(SCRIPT)], input=json.dumps(cases),
                          capture_output=True, text=True, timeout=120, check=True)
    results = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(results) == len(cases)
    return results


def _values_case(residuals, mean, scale, step) -> tuple[dict, dict]:
    """(the receiver's case, Python's result) of one stream of ``residuals`` decoded with
    per-value mean indices, scale and step indices."""
    stream = encode_symbols(np.array(residuals, np.int64), np.clip(scale, 0, 63))
    case = {"kind": "values", "hex": stream.hex(), "offset": AT, "mean": list(mean),
            "scale": list(scale), "step": list(step)}
    params = EntropyParams(np.array([mean], np.int64), np.array([scale], np.int64),
                           np.array([step[0]], np.int64))
    try:
        values = decode_block(stream, params, chunk="AFEA", base_offset=AT)[0]
    except FormatError as err:
        return case, {"ok": False, "chunk": err.chunk, "offset": err.offset}
    return case, {"ok": True, "values": [str(int(v)) for v in values],
                  "float32": grid_floats(values).astype("<f4").tobytes().hex()}


def test_grid_values_beyond_2_53_decode_exactly_and_round_as_python():
    r = [(1 << 52) + 1, -(1 << 53) - 3, (1 << 37) + 12345, 7, -(1 << 38) + 1, 3]
    cases = [
        _values_case(r, [0] * 6, [20] * 6, [0] * 6),                    # q = 1
        _values_case(r[2:], [(1 << 47) - 1, -(1 << 47), 5, 9], [3, 40, 63, 0], [175] * 4),
        _values_case([1 << 30, -(1 << 29) - 1], [1 << 40, -(1 << 41)], [10, 10], [160] * 2),
        _values_case([1 << 38, -(1 << 38)], [0, 0], [5, 5], [175, 175]),  # exactly +-2^62
    ]
    for (_, py), js in zip(cases, _run([c for c, _ in cases])):
        assert py["ok"] and js == py, (js, py)


@pytest.mark.parametrize(("residuals", "mean", "scale", "step", "place"), [
    ([(1 << 38) + 1, 1], [0, 0], [5, 5], [175, 175], ("AFEA", None)),  # |q r| > 2^62
    ([1, 2], [(1 << 47) + 1, 0], [5, 5], [3, 3], ("AFEA", None)),   # |mu| > 2^53
    ([1, 2], [0, 0], [5, 5], [176, 176], (None, None)),             # step index 176
    ([1, 2], [0, 0], [64, 5], [3, 3], (None, None)),                # scale index 64
    ([1, 2], [0, 0], [-1, 5], [3, 3], (None, None)),                # scale index -1
])
def test_parameters_outside_the_coder_s_ranges_are_refused_as_python(residuals, mean, scale,
                                                                     step, place):
    case, py = _values_case(residuals, mean, scale, step)
    (js,) = _run([case])
    assert not py["ok"] and (py["chunk"], py["offset"]) == place
    assert js == py


def _dense(seed: int, in_width: int, input_shift: int, input_bits: int) -> IntDenseMLP:
    rng = np.random.default_rng(seed)
    layers = (IntLayer(rng.integers(-2048, 2048, (12, in_width)), rng.integers(-999, 999, 12),
                       9, 12),
              IntLayer(rng.integers(-2048, 2048, (4, 12)), rng.integers(-999, 999, 4), 12, 12))
    return IntDenseMLP(in_width, input_shift, input_bits, 14, layers, np.full(4, -300),
                       np.full(4, 300))


@pytest.mark.parametrize("kernel", ["js", "wasm"])
@pytest.mark.parametrize(("input_shift", "input_bits"), [(6, 12), (40, 14), (0, 8)])
def test_carm_networks_on_inputs_beyond_2_53_give_python_s_outputs(kernel, input_shift,
                                                                   input_bits):
    net = _dense(input_shift, 5, input_shift, input_bits)
    rng = np.random.default_rng(1)
    x = rng.integers(-(1 << 62), 1 << 62, (40, 5))
    x[:10] = rng.integers(-(1 << 20), 1 << 20, (10, 5))
    x[10, :] = [(1 << 53) + 1, -(1 << 53) - 1, (1 << 62) - 1, -(1 << 62), 0]
    case = {"kind": "dense", "kernel": kernel, "hex": net.to_bytes().hex(), "offset": AT,
            "inputs": [[str(int(v)) for v in row] for row in x]}
    (js,) = _run([case])
    assert js["ok"] and js["outputs"] == net.forward(x).tolist()
