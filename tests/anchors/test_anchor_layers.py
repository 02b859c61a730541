"""A colour-only decode of an anchor file never reads a byte of the semantic layer."""

from __future__ import annotations

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.format import read_layers
from tests.anchors.helpers import encoded
from tests.format.samples import GuardedFile


def test_colour_only_decode_reads_no_semantic_bytes():
    data = encoded().data
    colour_end = read_layers(data, layers="color").layer_end("color")
    assert colour_end < len(data)
    guarded = GuardedFile(data, [(colour_end, len(data))])
    colour = AnchorDecoder().decode(guarded, layers="color")
    assert max(offset + n for offset, n in guarded.reads) <= colour_end
    full = AnchorDecoder().decode(data, layers="color,semantic")
    assert colour.features.tobytes() == full.features.tobytes()


def test_a_stream_cut_after_the_colour_layer_decodes_its_colour():
    data = encoded().data
    colour_end = read_layers(data, layers="color").layer_end("color")
    cut = AnchorDecoder().decode(data[:colour_end], layers="color")
    assert cut.equals(AnchorDecoder().decode(data, layers="color"))
