"""The JavaScript receiver's stream decoders (geometry §15, residual §16.3, integer network
§16.4, histogram §16.5) give every bare-stream conformance vector its recorded values, or
reject it at its recorded offset. Skipped when ``node`` is not on PATH."""

from __future__ import annotations

import json
import subprocess

import pytest

from benchmarks._js_receiver import REPO, node_executable

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

VECTORS = REPO / "spec" / "vectors"
SCRIPT = REPO / "tests" / "js" / "stream_vectors.mjs"


def _expected_values(record: dict) -> list[str]:
    """The recorded decode of a vector, in stream_vectors.mjs's text form."""
    if "points" in record:
        return [" ".join(map(str, p)) for p in record["points"]]
    if "outputs" in record:
        return [" ".join(map(str, row)) for row in record["outputs"]]
    values = record["decoded"] if "decoded" in record else record["values"]
    return [str(v) for v in values]


@pytest.mark.parametrize("range_coder", ["wasm", "js"])
def test_stream_vectors_decode_as_recorded(range_coder):
    done = subprocess.run([node_executable(), str(SCRIPT), str(VECTORS), range_coder],
                          capture_output=True, text=True, timeout=300, check=True)
    results = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(results) >= 36
    for result in results:
        family, name = result["name"].split("/")
        record = json.loads((VECTORS / family / name).with_suffix(".json").read_text())
        valid = record.get("valid", record.get("outcome") == "ok")
        assert result["ok"] == valid, f"{result['name']}: {result}"
        if valid:
            assert result["values"] == _expected_values(record), result["name"]
        else:
            assert result["offset"] == record["offset"], f"{result['name']}: {result}"
