"""The tile index operator (tests/fuzz/tile_index_edit.py): it reads and writes TIDX payloads
byte for byte, each edit changes only levels, parents or the version, and the decoder's tree
checks (FORMAT §12.22) refuse what it makes, naming TIDX."""

from __future__ import annotations

import contextlib
import random
from collections import Counter

import pytest

from csgs_codec.chunks.tile_index import TileIndex
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import FormatError
from tests.fuzz.container_edit import build, split_chunks
from tests.fuzz.oracle import decode_levels
from tests.fuzz.seeds import level_seed_scene
from tests.fuzz.tile_index_edit import edit_tile_index, parse_entries, write_entries


@pytest.fixture(scope="module")
def leveled() -> bytes:
    """600 Gaussians in 3 levels: 8 leaves of 75, one level-1 tile, a root."""
    return Encoder(quality=2, levels=3, tile_size=75).encode(level_seed_scene(600))


def test_a_payload_is_read_and_written_back_byte_for_byte(leveled):
    payload = split_chunks(leveled)[0].payload
    version, entries = parse_entries(payload)
    assert version == 2 and [e.level for e in entries] == [2, 1] + [0] * 8
    assert [e.link for e in entries] == [0, 1] + [2] * 8
    assert write_entries(version, entries) == payload


def test_a_payload_that_is_not_an_index_is_left_alone(leveled):
    payload = split_chunks(leveled)[0].payload
    for broken in (b"", b"\x03" + payload[1:], payload[:-1], payload + b"\x00"):
        assert parse_entries(broken) is None
    chunks = split_chunks(leveled)[1:]  # no TIDX
    assert edit_tile_index(random.Random(0), chunks, []) is None


def test_every_edit_changes_levels_parents_or_the_version_and_the_decoder_says_tidx(leveled):
    original = split_chunks(leveled)
    counts, entries_before = Counter(), parse_entries(original[0].payload)[1]
    rng = random.Random(3)
    for _ in range(60):
        chunks = list(original)
        name = edit_tile_index(rng, chunks, [])
        counts[name] += 1
        version, entries = parse_entries(chunks[0].payload)
        assert [(e.count, e.box) for e in entries] == [(e.count, e.box) for e in entries_before]
        if name.endswith("to_version_1"):
            assert version == 1
            continue
        try:
            TileIndex.from_bytes(chunks[0].payload)
        except FormatError as err:
            assert err.chunk == "TIDX"
            continue
        # a tree the checks accept (two tiles traded places): the decode of every level
        # still ends in a FormatError or a scene, never anything else
        with contextlib.suppress(FormatError):
            decode_levels(build(chunks))
    assert {name.split(":")[1] for name in counts} == {
        "level", "parent", "swap_parents", "swap_links", "to_version_1"}
