"""Writing and reading containers: round trip, layers, atomic writes, chunk rules."""

from __future__ import annotations

import os

import pytest

from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import (
    CHUNK_TYPES,
    Chunk,
    ChunkType,
    Layer,
    read_layers,
    write_container,
)
from csgs_codec.format.layout import HEADER_SIZE
from tests.format.samples import GuardedFile, sample_chunks

ALL = ("color", "semantic")


def test_round_trip_returns_every_chunk_in_file_order():
    chunks = sample_chunks()
    container = read_layers(write_container(chunks), ALL)
    assert container.chunks() == chunks
    assert container.version == (1, 0)
    assert container.flags == 0
    assert container.complete
    assert [(e.type, e.layer, e.tile, e.length) for e in container.toc] == [
        (c.type, c.layer, c.tile, len(c.payload)) for c in chunks]


def test_round_trip_of_an_empty_scene():
    data = write_container([])
    container = read_layers(data, ALL)
    assert container.toc == ()
    assert container.chunks() == []
    assert container.file_size == len(data) == container.header_and_toc_size


def test_writer_orders_chunks_by_layer_keeping_order_within_a_layer():
    chunks = sample_chunks()
    shuffled = [chunks[4], chunks[2], chunks[0], chunks[5], chunks[3], chunks[1]]
    container = read_layers(write_container(shuffled), ALL)
    assert container.chunks() == [chunks[0], chunks[1], chunks[2], chunks[3], chunks[4],
                                  chunks[5]]


def test_color_read_returns_base_and_color_only():
    container = read_layers(write_container(sample_chunks()), {"color"})
    assert container.layers_read == {Layer.BASE, Layer.COLOR}
    assert {c.layer for c in container.chunks()} == {Layer.BASE, Layer.COLOR}
    assert len(container.toc) == 6  # the TOC still lists the semantic chunks


def test_layers_accept_names_numbers_and_comma_strings():
    data = write_container(sample_chunks())
    by_name = read_layers(data, ["semantic"]).payloads
    assert read_layers(data, [2]).payloads == by_name
    assert read_layers(data, "semantic").payloads == by_name
    assert read_layers(data, [Layer.SEMANTIC]).payloads == by_name


def test_unknown_layer_name_is_an_input_error():
    with pytest.raises(InputError, match="unknown layer"):
        read_layers(write_container([]), {"colour"})


def test_color_only_read_never_touches_semantic_bytes():
    data = write_container(sample_chunks())
    color_end = read_layers(data, ALL).layer_end("color")
    guarded = GuardedFile(data, forbidden=[(color_end, len(data))])
    container = read_layers(guarded, {"color"})
    assert container.chunks() == [c for c in sample_chunks() if c.layer <= Layer.COLOR]
    assert max(offset + n for offset, n in guarded.reads) <= color_end


def test_semantic_only_read_skips_color_bytes():
    data = write_container(sample_chunks())
    full = read_layers(data, ALL)
    guarded = GuardedFile(data, forbidden=[(full.layer_end("base"), full.layer_end("color"))])
    container = read_layers(guarded, {"semantic"})
    assert [c.layer for c in container.chunks()] == [Layer.BASE, Layer.BASE, Layer.SEMANTIC,
                                                     Layer.SEMANTIC]


def test_unknown_optional_chunk_is_skipped_without_reading_it():
    chunks = [Chunk("fill", 0, b"a"), Chunk("zzzz", 1, b"unknown"), Chunk("fill", 1, b"b")]
    data = write_container(chunks)
    unknown = read_layers(data, ALL).toc[1]
    guarded = GuardedFile(data, forbidden=[(unknown.offset, unknown.end)])
    container = read_layers(guarded, ALL)
    assert [c.payload for c in container.chunks()] == [b"a", b"b"]
    assert container.toc[1].type == "zzzz" and not container.toc[1].known


def test_unknown_critical_chunk_is_rejected_in_a_requested_layer():
    data = write_container([Chunk("fill", 0, b"a"), Chunk("ZZZZ", 2, b"x")])
    assert read_layers(data, {"color"}).chunks() == [Chunk("fill", 0, b"a")]
    with pytest.raises(FormatError, match="unknown critical") as info:
        read_layers(data, ALL)
    assert info.value.chunk == "ZZZZ"
    assert info.value.offset == read_layers(data, {"color"}).toc[1].toc_offset


def test_registered_type_in_the_wrong_layer_is_rejected(monkeypatch):
    data = write_container([Chunk("Tcol", 2, b"x")])
    monkeypatch.setitem(CHUNK_TYPES, "Tcol", ChunkType("Tcol", Layer.COLOR, "test type"))
    with pytest.raises(FormatError, match="belongs to the color layer") as info:
        read_layers(data, ALL)
    assert (info.value.chunk, info.value.offset) == ("Tcol", HEADER_SIZE + 1 + 4)
    with pytest.raises(FormatError, match="belongs to the color layer"):
        Chunk("Tcol", Layer.SEMANTIC, b"")


def test_registered_critical_type_is_read(monkeypatch):
    monkeypatch.setitem(CHUNK_TYPES, "Tcol", ChunkType("Tcol", Layer.COLOR, "test type"))
    data = write_container([Chunk("Tcol", 1, b"payload")])
    assert read_layers(data).payload("Tcol") == b"payload"


@pytest.mark.parametrize("code", ["fil", "fills", "fi1l", "fil ", "f\u00e9ll"])
def test_chunk_type_must_be_four_ascii_letters(code):
    with pytest.raises(FormatError, match="four ASCII letters"):
        Chunk(code, Layer.BASE, b"")


def test_critical_bit_is_the_case_of_the_first_letter():
    assert Chunk("Abcd", 0, b"").critical
    assert not Chunk("aBCD", 0, b"").critical


def test_tile_out_of_range_is_rejected():
    with pytest.raises(FormatError, match="tile"):
        Chunk("fill", 0, b"", tile=1 << 32)


def test_writer_refuses_flags_version_1_0_does_not_define():
    for flags in (1, 0x100, 1 << 16, -1):
        with pytest.raises(FormatError, match="flags"):
            write_container([], flags=flags)


def test_payload_lookup_finds_one_chunk_per_type_and_tile():
    container = read_layers(write_container(sample_chunks()), ALL)
    with pytest.raises(FormatError, match="present 4 times"):
        container.payload("fill", tile=0)
    with pytest.raises(FormatError, match="missing"):
        container.payload("none", tile=0)
    single = read_layers(write_container([Chunk("fill", 1, b"one", tile=7)]))
    assert single.payload("fill", tile=7) == b"one"


def test_layer_end_is_where_the_color_layer_stops():
    data = write_container(sample_chunks())
    container = read_layers(data, ALL)
    color = [e for e in container.toc if e.layer == Layer.COLOR]
    assert container.layer_end("color") == color[-1].end
    assert container.layer_end("semantic") == len(data)


def test_write_to_path_writes_the_same_bytes_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "scene.csgs"
    data = write_container(sample_chunks(), path=target)
    assert target.read_bytes() == data
    assert os.listdir(tmp_path) == ["scene.csgs"]
    assert read_layers(target, ALL).chunks() == sample_chunks()


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "scene.csgs"
    target.write_bytes(b"old contents")

    def failing_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(InputError, match="cannot write"):
        write_container(sample_chunks(), path=target)
    assert target.read_bytes() == b"old contents"
    assert os.listdir(tmp_path) == ["scene.csgs"]


def test_write_into_a_missing_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError):
        write_container([], path=tmp_path / "missing" / "scene.csgs")


def test_read_from_a_path_names_the_file_in_errors(tmp_path):
    target = tmp_path / "bad.csgs"
    target.write_bytes(b"\x89CSG\r\n\x1a\n")
    with pytest.raises(FormatError) as info:
        read_layers(target)
    assert info.value.file == str(target)
    assert str(target) in str(info.value)


def test_read_from_a_file_starts_at_its_current_position(tmp_path):
    data = write_container(sample_chunks())
    target = tmp_path / "embedded.bin"
    target.write_bytes(b"prefix" + data)
    with open(target, "rb") as handle:
        handle.seek(6)
        assert read_layers(handle, ALL).chunks() == sample_chunks()


def test_missing_path_and_directories_are_input_errors(tmp_path):
    with pytest.raises(InputError):
        read_layers(tmp_path / "absent.csgs")
    with pytest.raises(InputError, match="directory"):
        read_layers(tmp_path)
