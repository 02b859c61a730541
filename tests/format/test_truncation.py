"""A stream cut anywhere: the color layer decodes iff the cut is at or after its end."""

from __future__ import annotations

import pytest

from csgs_codec.errors import FormatError
from csgs_codec.format import Layer, describe, read_layers, write_container
from tests.format.samples import sample_chunks


def test_every_prefix_decodes_color_exactly_when_cut_at_or_after_the_color_end():
    data = write_container(sample_chunks())
    full = read_layers(data, ("color", "semantic"))
    color_end = full.layer_end("color")
    expected = [c for c in sample_chunks() if c.layer <= Layer.COLOR]
    assert 0 < color_end < len(data)
    for cut in range(len(data) + 1):
        prefix = data[:cut]
        if cut >= color_end:
            container = read_layers(prefix, {"color"})
            assert container.chunks() == expected, cut
            assert container.complete == (cut == len(data))
        else:
            with pytest.raises(FormatError) as info:
                read_layers(prefix, {"color"})
            assert info.value.offset is not None and info.value.offset <= cut, cut


def test_every_prefix_decodes_semantic_only_when_complete():
    data = write_container(sample_chunks())
    for cut in range(len(data)):
        with pytest.raises(FormatError):
            read_layers(data[:cut], ("color", "semantic"))
    assert read_layers(data, ("color", "semantic")).chunks() == sample_chunks()


def test_truncation_error_names_the_chunk_and_first_missing_byte():
    data = write_container(sample_chunks())
    full = read_layers(data, ("color",))
    color = [e for e in full.toc if e.layer == Layer.COLOR][-1]
    cut = color.offset + 10
    with pytest.raises(FormatError, match="truncated") as info:
        read_layers(data[:cut], {"color"})
    assert (info.value.chunk, info.value.offset) == ("fill", cut)


def test_describe_reports_a_cut_stream_as_incomplete():
    data = write_container(sample_chunks())
    color_end = read_layers(data).layer_end("color")
    facts = describe(data[:color_end])
    assert not facts["complete"]
    assert facts["bytes"] == color_end and facts["file_bytes"] == len(data)
    assert facts["layers"]["color"]["present"] and not facts["layers"]["semantic"]["present"]
