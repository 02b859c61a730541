"""Damaged bitstreams give FormatError naming the chunk; bad arguments give InputError."""

from __future__ import annotations

import contextlib
import random

import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import CsgsError, FormatError, InputError
from csgs_codec.format import Chunk, read_layers, write_container
from tests.codec.helpers import random_scene

DATA = Encoder(quality=4).encode(random_scene(300, sh_degree=1, semantic=2, labels=True))


def chunks_of(data: bytes) -> list[Chunk]:
    container = read_layers(data, layers={"color", "semantic"})
    return [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
            for e in container.toc]


def rebuilt(replace: dict[str, bytes] | None = None, drop: str | None = None) -> bytes:
    chunks = [c if c.type not in (replace or {}) else Chunk(c.type, c.layer, replace[c.type])
              for c in chunks_of(DATA) if c.type != drop]
    return write_container(chunks)


@pytest.mark.parametrize("code", ["SCNE", "GEOM", "SHDC", "SHBA", "OPAC", "SCAL", "ROTN"])
def test_missing_required_chunk_names_it(code):
    with pytest.raises(FormatError, match=f"{code} is missing") as info:
        Decoder().decode(rebuilt(drop=code))
    assert info.value.chunk == code


@pytest.mark.parametrize("code", ["SCNE", "GEOM", "SHDC", "ROTN", "SEMF", "SEML"])
def test_truncated_payload_is_a_format_error_naming_the_chunk(code):
    payload = next(c.payload for c in chunks_of(DATA) if c.type == code)
    with pytest.raises(FormatError) as info:
        Decoder().decode(rebuilt({code: payload[: len(payload) // 2]}), layers="color,semantic")
    assert info.value.chunk == code and info.value.offset is not None


def test_header_count_mismatch_is_caught():
    payload = bytearray(next(c.payload for c in chunks_of(DATA) if c.type == "SCNE"))
    payload[0] ^= 0x01  # the low bit of N: the streams then hold one value more or less
    with pytest.raises(FormatError):
        Decoder().decode(rebuilt({"SCNE": bytes(payload)}))


def test_random_payload_damage_only_raises_format_error():
    rng = random.Random(7)
    chunks = chunks_of(DATA)
    for _ in range(300):
        victim = rng.randrange(len(chunks))
        payload = bytearray(chunks[victim].payload)
        for _ in range(rng.randint(1, 4)):
            if payload:
                payload[rng.randrange(len(payload))] = rng.randrange(256)
        damaged = list(chunks)
        damaged[victim] = Chunk(chunks[victim].type, chunks[victim].layer, bytes(payload))
        with contextlib.suppress(FormatError):
            Decoder().decode(write_container(damaged), layers="color,semantic")


def test_codec_level_errors_name_the_file(tmp_path):
    path = tmp_path / "cut.csgs"
    path.write_bytes(rebuilt(drop="OPAC"))
    with pytest.raises(FormatError) as info:
        Decoder().decode(path)
    assert str(path) in str(info.value) and info.value.chunk == "OPAC"


def test_bad_layers_argument():
    with pytest.raises(CsgsError, match="unknown layer"):
        Decoder().decode(DATA, layers="colour")


@pytest.mark.parametrize("kwargs", [{"quality": 0}, {"quality": 13}, {"semantic": "all"},
                                    {"prune_opacity": 1.5}])
def test_bad_encoder_arguments(kwargs):
    with pytest.raises(InputError):
        Encoder(**kwargs)


def test_invalid_scene_is_refused_before_encoding():
    scene = random_scene(10)
    scene.scales[3, 1] = float("nan")
    with pytest.raises(InputError, match="index 3"):
        Encoder().encode(scene)


def test_out_of_range_prediction_coefficient_is_refused():
    from csgs_codec.attributes.channel_coders import PREDICTED_FLAG, TABLE_FROZEN
    from csgs_codec.attributes.float_stream import read_float_stream
    from csgs_codec.format.primitives import ByteReader, ByteWriter

    out = ByteWriter()
    out.varint(2)
    out.fixed("u8", 2)
    out.fixed("u8", 10)
    out.fixed("u8", 0)
    out.fixed("f32", 1.0)
    out.fixed("u8", TABLE_FROZEN | PREDICTED_FLAG)
    out.svarint(0)
    out.fixed("u8", 10)  # step index
    out.fixed("u8", 3)   # scale index
    out.svarint(1 << 20)  # |A| >= 2^15
    out.svarint(0)
    with pytest.raises(FormatError, match="coefficient out of range"):
        read_float_stream(ByteReader(out.getvalue(), chunk="SCAL"), 2, 2)
