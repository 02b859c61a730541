"""The JavaScript receiver reads SEMR (FORMAT §12.25) as the Python decoder does, also when its
payload is damaged: seeded payload edits of the two valid label_runs vectors are decoded to the
same arrays, or refused naming the same chunk and byte offset. Skipped without ``node``."""

from __future__ import annotations

import dataclasses
import random

import pytest

from benchmarks._js_receiver import REPO, node_executable, run_js
from tests.fuzz.container_edit import build, repair_crcs, split_chunks
from tests.fuzz.mutators import PAYLOAD_EDITS
from tests.js.test_js_decoder import _assert_same, _python

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

VECTORS = REPO / "spec" / "vectors" / "scenes"
MUTANTS = 120


def test_damaged_semr_payloads_are_read_as_in_python(tmp_path):
    seeds = [(VECTORS / f"{name}.csgs").read_bytes()
             for name in ("label_runs", "label_runs_instances")]
    rng = random.Random(27)
    paths = []
    for i in range(MUTANTS):
        chunks = split_chunks(seeds[i % 2])
        k = next(j for j, c in enumerate(chunks) if c.type == b"SEMR")
        edit = PAYLOAD_EDITS[rng.choice(sorted(PAYLOAD_EDITS))]
        chunks[k] = dataclasses.replace(chunks[k], payload=edit(rng, chunks[k].payload))
        path = tmp_path / f"mutant{i}.csgs"
        path.write_bytes(repair_crcs(build(chunks)))
        paths.append(path)
    outcomes = []
    for path, js in zip(paths, run_js(paths, layers="color,semantic")):
        python = _python(path, "color,semantic")
        _assert_same(js, python, path.name)
        outcomes.append(python["ok"])
    # Not vacuous: most edits are refused, and some still decode.
    assert MUTANTS // 2 < outcomes.count(False) < MUTANTS
