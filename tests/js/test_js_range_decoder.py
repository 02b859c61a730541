"""Both loops of the JavaScript receiver's range decoder (WebAssembly and plain JavaScript)
decode constriction's output like constriction, also past the end of the data and on
garbage (where they must fail exactly when it does). Skipped when ``node`` is not on PATH."""

from __future__ import annotations

import json
import subprocess

import constriction
import numpy as np
import pytest

from benchmarks._js_receiver import REPO, node_executable

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

SCRIPT = REPO / "tests" / "js" / "range_cases.mjs"
FAILURES = (AssertionError, ValueError, RuntimeError, OverflowError)


def _table(rng, size):
    weights = rng.gamma(0.3, size=size)
    freqs = 1 + np.floor(weights / weights.sum() * ((1 << 16) - size)).astype(np.int64)
    freqs[int(np.argmax(freqs))] += (1 << 16) - int(freqs.sum())
    return freqs


def _model(freqs):
    return constriction.stream.model.Categorical(freqs / float(1 << 16), perfect=False)


def _expected(words, groups):
    decoder = constriction.stream.queue.RangeDecoder(words)
    out = []
    for freqs, count in groups:
        try:
            out += decoder.decode(_model(freqs), count).tolist()
        except FAILURES:
            return out, True
    return out, False


def test_both_loops_decode_like_constriction():
    rng = np.random.default_rng(5)
    cases, expected = [], []
    for case in range(40):
        groups, symbols = [], []
        for _ in range(int(rng.integers(1, 5))):
            size = int(rng.choice([2, 3, 17, 255, 1282, 4097]))
            freqs = _table(rng, size)
            count = int(rng.integers(0, 2000))
            groups.append((freqs, count))
            symbols.append(rng.choice(size, size=count, p=freqs / freqs.sum()))
        encoder = constriction.stream.queue.RangeEncoder()
        for (freqs, _), s in zip(groups, symbols):
            encoder.encode(s.astype(np.int32), _model(freqs))
        words = encoder.get_compressed()
        if case % 4 == 1:
            words = words[: words.size // 2]  # read past the end
        elif case % 4 == 2:
            words = rng.integers(0, 1 << 32, size=words.size, dtype=np.uint64).astype(np.uint32)
        want, failed = _expected(words, groups)
        expected.append(want + (["error"] if failed else []))
        cases.append({"words": words.tolist(),
                      "groups": [[f.tolist(), c] for f, c in groups]})
    done = subprocess.run([node_executable(), str(SCRIPT)], input=json.dumps(cases),
                          capture_output=True, text=True, timeout=300, check=True)
    results = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(results) == len(cases)
    for want, got in zip(expected, results):
        # constriction's batch decode stops a whole group at a failure; compare up to it.
        for kind in ("wasm", "js"):
            if "error" in want:
                assert got[kind][-1] == "error", kind
                assert got[kind][:len(want) - 1] == want[:-1], kind
            else:
                assert got[kind] == want, kind
    assert any("error" in w for w in expected)
