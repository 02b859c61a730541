"""csgs_codec.decode: one call for every .csgs file, handed to the decoder of its kind."""

from __future__ import annotations

import pytest

from csgs_codec import AnchorDecoder, Decoder, decode
from csgs_codec.errors import InputError
from tests.conformance import VECTORS_DIR

STANDARD = VECTORS_DIR / "scenes" / "donut_q3.csgs"
ANCHOR = sorted((VECTORS_DIR / "anchors").glob("*.csgs"))[0]


def test_a_standard_file_decodes_as_the_decoder_decodes_it():
    data = STANDARD.read_bytes()
    assert decode(data, "color,semantic").equals(Decoder().decode(data, "color,semantic"))
    with open(STANDARD, "rb") as handle:  # a file object: read by offset, twice
        assert decode(handle).equals(Decoder(threads=1).decode(STANDARD))


def test_an_anchor_file_decodes_as_the_anchor_decoder_decodes_it():
    from tests.conformance.anchors import anchor_digest

    ours, theirs = decode(ANCHOR, "color,semantic"), AnchorDecoder().decode(ANCHOR,
                                                                           "color,semantic")
    assert type(ours) is type(theirs) and len(ours) == len(theirs) > 0
    assert anchor_digest(ours) == anchor_digest(theirs)


@pytest.mark.parametrize("option", [{"tiles": [0]}, {"region": (0, 0, 0, 1, 1, 1)}])
def test_an_anchor_file_refuses_tiles_and_regions_by_name(option):
    with pytest.raises(InputError, match="no tiles") as err:
        decode(ANCHOR, **option)
    assert err.value.property == next(iter(option))


def test_bad_layers_are_refused_before_reading():
    with pytest.raises(InputError, match="layer"):
        decode(b"not a file", "colour")
