"""SH bands in opponent colours (FORMAT §12.24, chunk SHXF): the exact inverse, the record,
the encoder's choice and round trips."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes import sh_colour_transform as xf
from csgs_codec.chunks import sh_colour_transform as shxf
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import FormatError
from csgs_codec.format import read_layers
from tests.codec.helpers import random_scene
from tests.conformance.scenes import correlated_sh3_scene


def chunk_types(data: bytes) -> list[str]:
    return [e.type for e in read_layers(data, layers={"color", "semantic"}).toc]


def test_the_inverse_is_the_spec_expression_and_undoes_the_forward_transform():
    rng = np.random.default_rng(0)
    colours = rng.normal(0, 0.3, size=(500, 9)).astype(np.float32)
    turned = xf.forward(colours)
    back = xf.inverse(turned)
    assert np.max(np.abs(back - colours)) < 1e-6
    y = turned.astype(np.float64).reshape(500, 3, 3)
    a, b, c, d = xf.INVERSE_A, xf.INVERSE_B, xf.INVERSE_C, xf.INVERSE_D
    for i in (0, 17, 499):
        for m in range(3):
            y0, y1, y2 = y[i, m]
            expected = [np.float32((a * y0 + b * y1) + c * y2), np.float32(a * y0 - d * y2),
                        np.float32((a * y0 - b * y1) + c * y2)]
            assert back.reshape(500, 3, 3)[i, m].tolist() == expected
    assert xf.INVERSE_D == 2 * xf.INVERSE_C


def test_the_record_round_trips_and_bad_records_name_the_byte():
    payload = shxf.colour_transform_payload((1, 0, 1))
    assert payload == bytes([1, 3, 1, 0, 1])
    assert shxf.parse_colour_transform(payload, 100, 3) == (1, 0, 1)
    cases = [(bytes([2, 3, 1, 0, 1]), 100, "version"), (bytes([1, 2, 1, 0]), 101, "lists 2"),
             (bytes([1, 3, 1, 3, 1]), 103, "unknown"),
             (bytes([1, 3, 1, 0, 1, 0]), 105, "SH colour transform record")]
    for bad, offset, words in cases:
        with pytest.raises(FormatError, match=words) as err:
            shxf.parse_colour_transform(bad, 100, 3)
        assert err.value.chunk == "SHXF" and err.value.offset == offset


def test_colours_that_overflow_float32_are_refused():
    decoded = {"rest1": np.full((2, 9), 3e38, np.float32)}
    with pytest.raises(FormatError, match="overflow") as err:
        xf.apply_inverse(decoded, (1,), offset=42)
    assert err.value.chunk == "SHXF" and err.value.offset == 42


def test_grey_bands_are_coded_in_opponent_colours_smaller_and_decode_exactly(monkeypatch):
    scene = correlated_sh3_scene()
    transformed = Encoder(quality=5, hyperprior=False).encode_with_report(scene)
    assert "SHXF" in chunk_types(transformed.data)
    decoded = Decoder().decode(transformed.data)
    assert decoded.equals(transformed.reconstruction)
    # The same encode with the bands kept as colours is larger.
    from csgs_codec.codec import encoder as encoder_module

    monkeypatch.setattr(encoder_module, "choose_transforms",
                        lambda plans, values, steps: ((), {}))
    plain = Encoder(quality=5, hyperprior=False).encode_with_report(scene)
    assert "SHXF" not in chunk_types(plain.data)
    sh = ("SHBA", "SHBB", "SHBC")
    assert (sum(transformed.stream_bytes[c] for c in sh)
            < sum(plain.stream_bytes[c] for c in sh))
    # Each opponent value is within half a step; a colour mixes three of them.
    error = np.abs(decoded.sh_rest - scene.subset(transformed.order).sh_rest).max()
    bound = 0.5 * (xf.INVERSE_A + xf.INVERSE_B + xf.INVERSE_C) * Encoder(
        quality=5).preset.rest_step
    assert 0 < error <= bound * 1.001


def test_a_scene_without_sh_bands_has_no_record():
    data = Encoder(quality=5, hyperprior=False).encode(random_scene(300, sh_degree=0, seed=9))
    assert "SHXF" not in chunk_types(data)


def test_tiles_carry_their_own_record_and_decode_exactly():
    scene = correlated_sh3_scene(n=1200, seed=3)
    result = Encoder(quality=5, hyperprior=False, tile_size=400).encode_with_report(scene)
    assert chunk_types(result.data).count("SHXF") >= 2
    assert Decoder().decode(result.data).equals(result.reconstruction)
