"""The JavaScript receiver on mutated files: it never throws anything but FormatError or
UnsupportedError, never dies or hangs, and agrees with the Python decoder on every mutant
(both decode it to the same arrays, or both refuse it with the same kind of error, naming the
same chunk and byte offset).

The receiver's known fault on files with levels of detail (it reads every tile's frames
before a level decode: tests/fuzz/js_differential.py) is counted apart and pinned by a
strict expected failure, which passes (and so fails strict) once the receiver is fixed.

The default run fuzzes the decoder campaign's seeds (tests/fuzz/seeds.py, standard scenes)
and the anchor-scene seeds (build_anchor_seeds); the slow run many more of both, and mutants
of what users make: the default encodes of the sample and of the repository's SH-3 capture.
Skipped when ``node`` is not on PATH.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from benchmarks._js_receiver import node_executable
from csgs_codec.codec.decoder import Decoder
from tests.conftest import SAMPLE
from tests.fuzz.container_edit import layout_of, split_chunks
from tests.fuzz.js_differential import (
    LAYERS,
    DifferentialSummary,
    anchor_seeds,
    compare,
    python_outcome,
    receiver_outcomes,
    run_differential,
    standard_seeds,
)
from tests.fuzz.seeds import Seed, build_anchor_seeds, build_seeds

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

REPO_SH3 = Path(__file__).resolve().parents[2] / "benchmarks" / "data" / "yashica_t4_top8192.ply"
DEFAULT_INPUTS = 300
SLOW_INPUTS = 5000
SLOW_USER_INPUTS = 600
ANCHOR_INPUTS = 200
SLOW_ANCHOR_INPUTS = 3000


@pytest.fixture(scope="module")
def seeds() -> list[Seed]:
    return standard_seeds(build_seeds())


@pytest.fixture(scope="module")
def anchor_seed_files() -> list[Seed]:
    return build_anchor_seeds()


def _report(summary: DifferentialSummary) -> str:
    return "\n".join(f"input {d.index} ({d.seed}, {' '.join(d.operators)}): {d.kind}: "
                     f"{d.detail}" for d in summary.disagreements[:20])


def _assert_agrees(summary: DifferentialSummary, inputs: int) -> None:
    assert summary.inputs == inputs
    assert not summary.disagreements, _report(summary)
    # Not a trivial campaign: some mutants decode, most reach a named rejection.
    assert summary.outcomes["ok"] > 0 and summary.outcomes["FormatError"] > inputs // 2


def test_the_receiver_agrees_with_python_on_mutants_of_the_campaign_seeds(seeds):
    summary = run_differential(seeds, 0, DEFAULT_INPUTS, campaign_seed=11)
    _assert_agrees(summary, DEFAULT_INPUTS)


def test_the_receiver_agrees_with_python_on_mutants_of_anchor_scenes(anchor_seed_files):
    summary = run_differential(anchor_seed_files, 0, ANCHOR_INPUTS, campaign_seed=21)
    assert summary.inputs == ANCHOR_INPUTS
    assert not summary.disagreements, _report(summary)
    # Some mutants decode as anchor scenes; most reach a named rejection.
    assert summary.outcomes["anchors-ok"] > 0
    assert summary.outcomes["FormatError"] > ANCHOR_INPUTS // 2


def test_the_anchor_seeds_are_anchor_scenes_with_every_optional_part(anchor_seed_files):
    assert anchor_seeds(anchor_seed_files) == anchor_seed_files
    names = {s.name for s in anchor_seed_files}
    assert {"vector:anchors_semantic_q5", "anchors_vorg_q6", "anchors_default_q4"} <= names
    vorg = next(s for s in anchor_seed_files if s.name == "anchors_vorg_q6")
    assert any(c.type == b"vorg" for c in vorg.chunks)


def test_the_seeds_are_standard_scenes_of_every_kind(seeds):
    names = {s.name for s in seeds}
    assert {"donut300_q8", "semantic200_q8", "instances200_tiled", "outliers300_q2",
            "vector:color_prior_q3", "vector:scored_steps_q5"} <= names
    assert not any(c.type == b"ANCH" for s in seeds for c in s.chunks)


def test_a_receiver_process_that_dies_is_pinned_on_its_input(seeds, tmp_path):
    good = tmp_path / "good.csgs"
    good.write_bytes(next(s for s in seeds if s.name == "donut300_q2").data)
    missing = tmp_path / "missing.csgs"  # the oracle's read throws outside the decode
    results, _ = receiver_outcomes([good, missing, good])
    assert [r["ok"] for r in results] == [True, False, True]
    assert results[1]["error"] == "died"
    assert compare(python_outcome(good.read_bytes()), results[1])[0] == "died"


def test_the_comparison_flags_each_kind_of_disagreement(seeds):
    data = next(s for s in seeds if s.name == "semantic200_q8").data
    python = python_outcome(data)
    assert python["ok"]
    refused = {"ok": False, "error": "FormatError", "chunk": "SEML", "offset": 9,
               "message": "x"}
    crashed = {"ok": False, "error": "crash", "type": "TypeError", "message": "x"}
    other = {**python, "arrays": {**python["arrays"], "semantic": {"shape": [], "sha256": ""}}}
    assert compare(python, python) is None
    assert compare(python, refused)[0] == "accept"
    assert compare(python, crashed)[0] == "crash"
    assert compare(python, other) == ("arrays", "decoded arrays differ: ['semantic']")
    assert compare(refused, refused) is None
    unsupported = {**refused, "error": "UnsupportedError"}
    assert compare(refused, unsupported)[0] == "error-kind"
    assert compare(refused, {**refused, "offset": 10})[0] == "place"
    assert compare(refused, {**refused, "message": "y"}) is None


def _coarse_crc_broken(seeds) -> bytes:
    """The levels seed with the CRC of its root tile's first chunk (a level-2 frame, which a
    decode of level 0 does not read) made wrong."""
    seed = next(s for s in seeds if s.name == "levels3000_l3")
    layout = layout_of(list(seed.chunks))
    assert seed.chunks[1].tile == 0 and seed.chunks[0].type == b"TIDX"
    layout.frames[1].crc = 0xDEADBEEF
    return layout.to_bytes()


def _receiver_level0(data: bytes, folder: Path) -> dict:
    path = folder / "level0.csgs"
    path.write_bytes(data)
    done = subprocess.run([node_executable(), "csgs_codec/js/decode_cli.mjs", str(path),
                           "--layers", LAYERS, "--lod", "0"], capture_output=True, text=True,
                          check=False, timeout=120, cwd=Path(__file__).resolve().parents[2])
    return json.loads(done.stdout.splitlines()[0])


def test_a_level_decode_reads_only_its_tiles_frames(seeds, tmp_path):
    """FORMAT §12.22: a damaged frame of another level's tile refuses no level-0 decode
    (the receiver read every frame once; the level fuzzing found it)."""
    data = _coarse_crc_broken(seeds)
    python = Decoder().decode(data, LAYERS)
    receiver = _receiver_level0(data, tmp_path)
    assert receiver["ok"] and receiver["count"] == len(python)


@pytest.mark.slow
def test_the_receiver_agrees_with_python_on_many_mutants(seeds):
    summary = run_differential(seeds, 0, SLOW_INPUTS, campaign_seed=12)
    _assert_agrees(summary, SLOW_INPUTS)


@pytest.mark.slow
def test_the_receiver_agrees_with_python_on_mutants_of_default_encodes(default_encode):
    user_made = [Seed(path.stem, path.read_bytes(), tuple(split_chunks(path.read_bytes())), 1.0)
                 for path in (default_encode(SAMPLE), default_encode(REPO_SH3))]
    summary = run_differential(user_made, 0, SLOW_USER_INPUTS, campaign_seed=13, batch=25)
    _assert_agrees(summary, SLOW_USER_INPUTS)


@pytest.mark.slow
def test_the_receiver_agrees_with_python_on_many_mutants_of_anchor_scenes(anchor_seed_files):
    summary = run_differential(anchor_seed_files, 0, SLOW_ANCHOR_INPUTS, campaign_seed=22)
    assert not summary.disagreements, _report(summary)
    assert summary.outcomes["anchors-ok"] > 0
