"""Decoder fuzzing: mutated real .csgs files decode to finite scenes or raise FormatError,
within the memory bound; and the fuzzer itself reaches the chunk decoders."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from csgs_codec.chunks.tile_index import TileIndex
from csgs_codec.codec.decoder import Decoder
from csgs_codec.errors import InputError
from tests.conformance import VECTORS_DIR
from tests.fuzz.campaign import mutant_at, run_campaign
from tests.fuzz.campaign_process import CampaignProcessError, run_in_child
from tests.fuzz.container_edit import build, layout_of, repair_crcs, split_chunks
from tests.fuzz.mutators import PAYLOAD_EDITS
from tests.fuzz.oracle import error_stage, memory_bound, run_decoder
from tests.fuzz.seeds import build_seeds
from tests.heap_peak import heap_tracing

#: Inputs of the default run; every second one has its heap peak traced.
DEFAULT_INPUTS = 1000
TRACE_EVERY = 2
SLOW_INPUTS = 100_000
OPERATORS = {"payload_bit_flip", "payload_byte_set", "payload_resize", "payload_varint",
             "payload_word", "splice", "chunk_swap", "payload_swap", "chunk_drop",
             "chunk_duplicate", "toc_length_lie", "frame_length_lie", "toc_offset_lie",
             "toc_layer_lie", "toc_tile_lie", "toc_type_lie", "toc_row_count_lie",
             "toc_size_lie", "minor_version", "flag_bit", "major_version", "crc_lie",
             "bit_flip", "byte_set", "truncate", "crc_repaired", "tile_index_edit"}


@pytest.fixture(scope="module")
def seeds():
    return build_seeds()


@pytest.fixture(scope="module")
def campaign(seeds):
    return run_campaign(seeds, 0, DEFAULT_INPUTS, trace_every=TRACE_EVERY)


def _crash_report(summary) -> str:
    return "\n".join(f"input {c.index} ({c.seed}, {' '.join(c.operators)}): {c.detail}"
                     for c in summary.crashes[:20])


def test_no_mutant_crashes_the_decoder(campaign):
    assert campaign.inputs == DEFAULT_INPUTS
    assert not campaign.crashes, _crash_report(campaign)


def test_no_traced_mutant_passes_the_memory_bound(campaign):
    assert campaign.traced == DEFAULT_INPUTS // TRACE_EVERY
    assert campaign.max_bound_use <= 1.0


def test_most_mutants_get_past_the_crc_and_container_checks(campaign):
    reached = campaign.stages["payload"] + campaign.outcomes["ok"]
    assert reached >= 0.4 * campaign.inputs
    assert campaign.stages["crc"] <= 0.1 * campaign.inputs


def test_every_mutation_operator_is_exercised(campaign):
    assert set(campaign.operators) == OPERATORS


def test_seeds_cover_semantics_outliers_two_qualities_and_the_scene_vectors(seeds):
    names = {s.name for s in seeds}
    assert {"donut300_q2", "donut300_q8", "semantic200_q2", "semantic200_q8"} <= names
    assert {"vector:donut_q3", "vector:semantic_small", "vector:three_points_sh3_q9"} <= names
    semantic = next(s for s in seeds if s.name == "semantic200_q8")
    assert {c.type for c in semantic.chunks} >= {b"SEMF", b"SEML"}
    for name, source in (("labelruns200_q8", 0), ("labelmap200_q8", 1)):
        labelled = next(s for s in seeds if s.name == name)
        semr = next(c for c in labelled.chunks if c.type == b"SEMR")
        assert semr.payload[1] == source, name
    outliers = next(s for s in seeds if s.name == "outliers300_q2")
    assert b"OUTL" in {c.type for c in outliers.chunks}
    if (VECTORS_DIR / "anchors").is_dir():
        assert "vector:anchors_semantic_q5" in names


def test_seeds_include_multi_tile_files(seeds):
    for name in ("semantic200_tiled", "outliers300_tiled", "vector:tiled_q5"):
        seed = next(s for s in seeds if s.name == name)
        assert seed.chunks[0].type == b"TIDX", name
        assert sum(c.type == b"SCNE" for c in seed.chunks) == 4, name


def test_seeds_include_a_file_with_three_levels_of_detail(seeds):
    seed = next(s for s in seeds if s.name == "levels3000_l3")
    index = TileIndex.from_bytes(seed.chunks[0].payload)
    assert index.levels == 3 and index.count > 3000
    assert [len(index.level_tiles(k)) for k in range(3)] == [16, 2, 1]


def test_the_oracle_decodes_every_level_of_a_file_with_levels(seeds):
    seed = next(s for s in seeds if s.name == "levels3000_l3")
    layout = layout_of(list(seed.chunks))
    layout.frames[1].crc = 0  # a chunk of the root tile (level 2): level 0 never reads it
    data = layout.to_bytes()
    Decoder().decode(data, layers="color,semantic")
    outcome = run_decoder(data, trace=False)
    assert outcome.kind == "FormatError" and outcome.stage == "crc"
    assert run_decoder(seed.data, trace=False).kind == "ok"


def test_split_and_build_reproduce_a_seed_byte_for_byte(seeds):
    for seed in seeds:
        assert build(split_chunks(seed.data)) == seed.data


def test_repairing_the_crcs_of_a_valid_file_changes_nothing(seeds):
    for seed in seeds:
        assert repair_crcs(seed.data) == seed.data


def test_crc_repair_lets_a_payload_edit_reach_the_chunk_decoder(seeds):
    seed = next(s for s in seeds if s.name == "donut300_q2")
    chunks = split_chunks(seed.data)
    assert chunks[0].type == b"SCNE"
    # A scene header cut after its first byte: only the SCNE parser can notice.
    chunks[0] = dataclasses.replace(chunks[0], payload=chunks[0].payload[:1])
    stale = bytearray(build(chunks))
    stale[-1] ^= 0xFF  # damage the last chunk's CRC; repair must fix it again
    outcomes = {name: run_decoder(data, trace=False)
                for name, data in (("stale", bytes(stale)), ("repaired", repair_crcs(stale)))}
    assert outcomes["stale"].kind == outcomes["repaired"].kind == "FormatError"
    assert outcomes["stale"].stage == "crc"
    assert outcomes["repaired"].stage == "payload"


def test_damage_in_the_semantic_layer_never_changes_a_color_read(seeds):
    import random

    rng = random.Random(5)
    names = ("semantic200_q8", "vector:semantic_small", "labelruns200_q8", "labelmap200_q8")
    for seed in [s for s in seeds if s.name in names]:
        color = Decoder().decode(seed.data, layers="color")
        semantic = [i for i, c in enumerate(seed.chunks)
                    if c.type in (b"SEMF", b"SEML", b"SEMC", b"SEMR")]
        for _ in range(50):
            chunks = list(seed.chunks)
            i = rng.choice(semantic)
            edit = PAYLOAD_EDITS[rng.choice(sorted(PAYLOAD_EDITS))]
            chunks[i] = dataclasses.replace(chunks[i], payload=edit(rng, chunks[i].payload))
            data = repair_crcs(build(chunks))
            assert Decoder().decode(data, layers="color").equals(color)
            assert not run_decoder(data, trace=False).crashed


def test_a_mutant_is_rebuilt_from_its_index_alone(seeds):
    first = [mutant_at(seeds, i, campaign_seed=7) for i in range(20)]
    again = [mutant_at(seeds, i, campaign_seed=7) for i in range(20)]
    assert first == again
    assert len({m.data for m in first}) == 20


def _tiny_input(seeds) -> bytes:
    return next(s for s in seeds if s.name == "vector:three_points_sh3_q9").data


def test_oracle_calls_a_foreign_exception_a_crash(seeds, monkeypatch):
    def broken(self, source, layers="color"):
        raise IndexError("index 9 is out of bounds")

    monkeypatch.setattr(Decoder, "decode", broken)
    outcome = run_decoder(_tiny_input(seeds), trace=False)
    assert outcome.crashed and outcome.detail.startswith("IndexError")


def test_oracle_calls_an_input_error_on_bytes_a_crash(seeds, monkeypatch):
    def wrong_class(self, source, layers="color"):
        raise InputError("not the error for damaged bytes")

    monkeypatch.setattr(Decoder, "decode", wrong_class)
    assert run_decoder(_tiny_input(seeds), trace=False).crashed


def test_oracle_calls_a_non_finite_decoded_value_a_crash(seeds, monkeypatch):
    good = Decoder().decode(_tiny_input(seeds), layers="color")
    good.scales[0, 1] = np.inf
    monkeypatch.setattr(Decoder, "decode", lambda self, source, layers="color": good)
    outcome = run_decoder(_tiny_input(seeds), trace=False)
    assert outcome.crashed and "scales" in outcome.detail


def test_oracle_calls_an_allocation_over_the_bound_a_crash(seeds, monkeypatch):
    data = _tiny_input(seeds)
    good = Decoder().decode(data, layers="color")

    def hungry(self, source, layers="color"):
        block = np.ones(memory_bound(len(data)) // 8 + 1024, np.float64)
        return good if block.sum() else None

    monkeypatch.setattr(Decoder, "decode", hungry)
    with heap_tracing():
        outcome = run_decoder(data)
    assert outcome.crashed and "heap peak" in outcome.detail


def test_a_campaign_in_a_child_process_totals_as_in_this_one(seeds, tmp_path):
    alone = run_in_child(0, 40, campaign_seed=3, trace_every=4, folder=tmp_path, timeout=300)
    here = run_campaign(seeds, 0, 40, campaign_seed=3, trace_every=4)
    assert (alone.inputs, alone.traced) == (here.inputs, here.traced) == (40, 10)
    assert alone.outcomes == here.outcomes and alone.operators == here.operators


def test_a_child_that_outlives_its_time_is_killed_and_fails_saying_so(tmp_path):
    with pytest.raises(CampaignProcessError, match="still running after 0.2 s"):
        run_in_child(0, 10**6, campaign_seed=0, trace_every=1, folder=tmp_path, timeout=0.2)


def test_error_stage_tells_crc_container_and_payload_errors_apart():
    from csgs_codec.errors import FormatError

    assert error_stage(FormatError("chunk CRC mismatch", chunk="GEOM")) == "crc"
    assert error_stage(FormatError("TOC entry 2: bad", chunk="GEOM")) == "container"
    assert error_stage(FormatError("toc_size 0 is outside 1..4")) == "container"
    assert error_stage(FormatError("grid_bits 30 exceeds 21", chunk="SCNE")) == "payload"


@pytest.mark.slow
# 100,000 decodes: 965-986 s on the 2-core project box with the other core busy, 1,169-1,188 s
# in clean-clone runs on slower days (the suite's default timeout is 900 s). In a child
# process of its own (tests/fuzz/campaign_process.py), which a crash fails alone.
@pytest.mark.timeout(2400)
def test_a_long_campaign_finds_no_crash(tmp_path):
    summary = run_in_child(DEFAULT_INPUTS, SLOW_INPUTS, campaign_seed=1, trace_every=4,
                           folder=tmp_path, timeout=2300)
    assert summary.inputs == SLOW_INPUTS
    assert not summary.crashes, _crash_report(summary)
    assert summary.max_bound_use <= 1.0
