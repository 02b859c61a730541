"""The JavaScript receiver's two integer-network kernels (spec/FORMAT.md §16.4.2): the
WebAssembly SIMD layers and the scalar JavaScript loop give the Python reference's outputs,
bit for bit, on random networks up to the exactness bound (largest weights, biases near
2^52, large shifts, tight output clamps) and on position counts that are and are not a
multiple of the SIMD kernel's block of four. Skipped when ``node`` is not on PATH."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from benchmarks._js_receiver import REPO, node_executable
from csgs_codec.entropy.intnet import EMBED_LIMIT, EXACT_LIMIT, IntLayer, IntMLP
from csgs_codec.entropy.intnet_bytes import intnet_to_bytes

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

SCRIPT = REPO / "tests" / "js" / "intnet_kernels.mjs"


def _layer(rng, n_in: int, n_out: int, bound: int, extreme: bool) -> IntLayer:
    """A random layer whose worst-case sum stays within 2^53 for inputs up to ``bound``."""
    bits = int(rng.integers(18, 25)) if extreme else int(rng.integers(4, 12))
    shift = int(rng.integers(20, 45)) if extreme else int(rng.integers(0, 12))
    weights = rng.integers(-(1 << (bits - 1)), 1 << (bits - 1), size=(n_out, n_in))
    room = EXACT_LIMIT - (1 << max(shift - 1, 0))
    worst = np.abs(weights).sum(axis=1).max() * bound
    if worst > room // 2:  # scale the weights down into the bound, keeping their spread
        weights = weights * (room // 2) // max(int(worst), 1)
        worst = np.abs(weights).sum(axis=1).max() * bound
    bias_room = min((1 << 52) - 1, room - int(worst))
    biases = rng.integers(-bias_room, bias_room + 1, size=n_out) if extreme \
        else rng.integers(-(1 << 20), 1 << 20, size=n_out)
    return IntLayer(weights.astype(np.int64), biases.astype(np.int64), shift, bits)


def _network(rng, extreme: bool) -> IntMLP:
    num_freqs = int(rng.integers(1, 17))
    act_bits = int(rng.integers(8, 31))
    widths = [6 * num_freqs] + [int(rng.integers(1, 40)) for _ in range(int(rng.integers(1, 4)))]
    bounds = [EMBED_LIMIT] + [(1 << act_bits) - 1] * (len(widths) - 2)
    layers = tuple(_layer(rng, a, b, bound, extreme)
                   for a, b, bound in zip(widths, widths[1:], bounds))
    out = widths[-1]
    lo = rng.integers(-(1 << 30), 0, size=out)
    hi = lo + rng.integers(0, 1 << 31, size=out)
    return IntMLP(int(rng.integers(1, 33)), num_freqs, act_bits, layers, lo, hi)


def test_both_kernels_give_the_python_reference_outputs():
    rng = np.random.default_rng(28)
    cases, expected = [], []
    for k in range(40):
        net = _network(rng, extreme=k % 2 == 1)
        count = [1, 3, 15, 16, 17, 63, 257, 1030][k % 8]
        positions = rng.integers(0, 1 << net.pos_bits, size=(count, 3), dtype=np.uint64)
        cases.append({"payload": intnet_to_bytes(net).hex(), "positions": positions.tolist()})
        expected.append(net.forward(positions.astype(np.int64), path="int64"))
    done = subprocess.run([node_executable(), str(SCRIPT)], input=json.dumps(cases),
                          capture_output=True, text=True, timeout=300, check=True)
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(lines) == len(cases)
    assert all(line["simd"] for line in lines), "WebAssembly SIMD is missing in this node"
    for k, (line, reference) in enumerate(zip(lines, expected)):
        assert line["wasm"] == line["js"], f"case {k}: the two kernels differ"
        got = np.array([[int(float(v)) for v in row] for row in line["js"]], dtype=np.int64)
        assert np.array_equal(got, reference), f"case {k}: the kernels differ from Python"
