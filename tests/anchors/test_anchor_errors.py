"""Malformed anchor files and bad inputs give typed errors naming the chunk."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.chunks.anchor_payloads import AnchorHeader
from csgs_codec.chunks.stream_list import read_stream_list, stream_list_payload
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import Chunk, read_layers, write_container
from tests.anchors.helpers import encoded, small_scene

CODES = ("ANCH", "GEOM", "AHYP", "ACRM", "AMSK", "AMLP", "AFEA", "AOFF", "ASCL", "SHYP",
         "ASEM", "SEMR")


def rebuilt(changes: dict[str, bytes | None]) -> bytes:
    container = read_layers(encoded().data, layers="color,semantic")
    chunks = []
    for e in container.toc:
        payload = changes.get(e.type, bytes(container.payloads[e.index]))
        if payload is not None:
            chunks.append(Chunk(e.type, e.layer, payload, e.tile))
    return write_container(chunks)


def payload(code: str) -> bytes:
    container = read_layers(encoded().data, layers="color,semantic")
    return container.payload(code)


@pytest.mark.parametrize("code", [c for c in CODES if c != "SEMR"])
def test_a_missing_chunk_is_a_format_error_naming_it(code):
    with pytest.raises(FormatError) as err:
        AnchorDecoder().decode(rebuilt({code: None}), layers="color,semantic")
    assert err.value.chunk == code


def test_labels_are_optional():
    decoded = AnchorDecoder().decode(rebuilt({"SEMR": None}), layers="color,semantic")
    assert decoded.labels is None and decoded.semantic is not None


@pytest.mark.parametrize("code", CODES)
def test_a_truncated_payload_is_a_format_error(code):
    data = payload(code)
    with pytest.raises(FormatError):
        AnchorDecoder().decode(rebuilt({code: data[: len(data) // 2]}),
                               layers="color,semantic")


def test_header_with_reserved_flags_is_rejected():
    data = bytearray(payload("ANCH"))
    data[-1] = 0x80
    with pytest.raises(FormatError) as err:
        AnchorHeader.from_bytes(bytes(data))
    assert err.value.chunk == "ANCH"


def test_header_declaring_too_many_values_is_rejected():
    header = AnchorHeader.from_bytes(payload("ANCH"))
    big = AnchorHeader(1 << 26, 4096, 64, header.grid_bits, 1.0, (0.0, 0.0, 0.0), 1, 5,
                       False)
    with pytest.raises(FormatError):
        AnchorHeader.from_bytes(big.to_bytes())


@pytest.mark.parametrize("kwargs", [{"quality": 0}, {"carm_groups": 0}, {"semantic": "x"}])
def test_bad_encoder_settings_are_input_errors(kwargs):
    with pytest.raises(InputError):
        AnchorEncoder(**kwargs)


def test_non_finite_features_are_an_input_error():
    scene = small_scene()
    bad = scene.subset(np.arange(len(scene)))
    bad.features = bad.features.copy()
    bad.features[3, 4] = np.nan
    with pytest.raises(InputError):
        AnchorEncoder().encode(bad)


def test_a_carm_network_that_does_not_fit_its_group_names_acrm():
    networks = [data for data, _ in read_stream_list(payload("ACRM"), 0, "ACRM", 4)]
    swapped = stream_list_payload([networks[1], networks[0]] + networks[2:])
    with pytest.raises(FormatError, match="does not fit") as err:
        AnchorDecoder().decode(rebuilt({"ACRM": swapped}))
    assert err.value.chunk == "ACRM" and err.value.offset is not None


def test_a_hyperprior_of_another_layout_names_its_chunk_and_offset():
    with pytest.raises(FormatError, match="outputs") as err:
        AnchorDecoder().decode(rebuilt({"AHYP": payload("SHYP")}))
    assert err.value.chunk == "AHYP" and err.value.offset is not None
    with pytest.raises(FormatError, match="outputs") as err:
        AnchorDecoder().decode(rebuilt({"SHYP": payload("AHYP")}), layers="color,semantic")
    assert err.value.chunk == "SHYP" and err.value.offset is not None
