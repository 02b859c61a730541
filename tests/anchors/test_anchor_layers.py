"""A color-only decode of an anchor file never reads a byte of the semantic layer."""

from __future__ import annotations

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.format import read_layers
from tests.anchors.helpers import encoded
from tests.format.samples import GuardedFile


def test_color_only_decode_reads_no_semantic_bytes():
    data = encoded().data
    color_end = read_layers(data, layers="color").layer_end("color")
    assert color_end < len(data)
    guarded = GuardedFile(data, [(color_end, len(data))])
    color = AnchorDecoder().decode(guarded, layers="color")
    assert max(offset + n for offset, n in guarded.reads) <= color_end
    full = AnchorDecoder().decode(data, layers="color,semantic")
    assert color.features.tobytes() == full.features.tobytes()


def test_a_stream_cut_after_the_color_layer_decodes_its_color():
    data = encoded().data
    color_end = read_layers(data, layers="color").layer_end("color")
    cut = AnchorDecoder().decode(data[:color_end], layers="color")
    assert cut.equals(AnchorDecoder().decode(data, layers="color"))
