"""Whatever the encoder writes, the default decoder reads (issue #20, item 2).

Rules: a scene of many identical Gaussians (every channel constant, a few bytes of payload)
is padded with a base-layer ``fill`` chunk to ceil(N / 64) bytes, so the default Decoder's
64-Gaussians-per-byte limit takes it; that limit still refuses a small file declaring many
Gaussians; what the format cannot carry (semantic names over 256 UTF-8 bytes, more than 255
semantic channels, more Gaussians than the decoder takes) is refused before any coding,
naming what is wrong.
"""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.chunks.scene_header import SceneHeader
from csgs_codec.codec import encoder_checks
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import Chunk, read_layers, write_container
from tests.codec.helpers import random_scene


def _identical(n: int, semantic: int = 0):
    return random_scene(1, sh_degree=1, semantic=semantic).subset(np.zeros(n, np.int64))


def test_identical_gaussians_decode_with_the_default_decoder():
    scene = _identical(200_000, semantic=2)
    result = Encoder(quality=5, hyperprior=False,
                     step_allocation=False).encode_with_report(scene)
    assert len(result.data) >= 200_000 // 64
    assert result.stream_bytes.get("fill", 0) > 0
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert len(decoded) == 200_000
    assert decoded.equals(result.reconstruction)


def test_the_padding_sits_in_the_base_layer():
    data = Encoder(quality=5, hyperprior=False, step_allocation=False).encode(_identical(50_000))
    fills = [entry for entry in read_layers(data).toc if entry.type == "fill"]
    assert len(fills) == 1 and fills[0].layer.label == "base"


def test_scenes_that_code_large_enough_are_not_padded():
    result = Encoder(quality=5, hyperprior=False).encode_with_report(random_scene(500))
    assert "fill" not in result.stream_bytes


def test_a_small_file_declaring_many_gaussians_is_still_refused():
    data = Encoder(quality=5, hyperprior=False).encode(random_scene(50))
    header = SceneHeader.from_bytes(read_layers(data).payload("SCNE"))
    forged = SceneHeader(1 << 20, header.sh_degree_stored, header.sh_degree_coded,
                         header.quality, header.grid_origin, header.grid_cell,
                         header.grid_bits, 0)
    chunks = [Chunk(c.type, c.layer, forged.to_bytes() if c.type == "SCNE" else c.payload)
              for c in read_layers(data, layers={"color", "semantic"}).chunks()]
    small = write_container(chunks)
    assert len(small) < 20_000
    with pytest.raises(FormatError, match="above this decoder's limit") as err:
        Decoder().decode(small)
    assert err.value.chunk == "SCNE"


def test_a_semantic_name_of_257_bytes_is_refused_before_coding():
    scene = random_scene(40, semantic=2)
    scene.semantic_names = ("é" * 128 + "x", "b")  # 257 UTF-8 bytes
    with pytest.raises(InputError, match="257 bytes long") as err:
        Encoder(hyperprior=False).encode(scene)
    assert err.value.property.startswith("éé")


def test_a_semantic_name_of_256_bytes_decodes():
    scene = random_scene(40, semantic=2)
    scene.semantic_names = ("ins_feat_" + "a" * 247, "sem_b")  # the longest name allowed
    result = Encoder(hyperprior=False).encode_with_report(scene)
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert decoded.semantic_names == scene.semantic_names
    assert decoded.equals(result.reconstruction)


def test_more_than_255_semantic_channels_are_refused_before_coding():
    scene = random_scene(20, semantic=256)
    with pytest.raises(InputError, match="256 semantic channels; .* at most 255") as err:
        Encoder(hyperprior=False).encode(scene)
    assert err.value.property == "ins_feat_255"


def test_255_semantic_channels_decode():
    scene = random_scene(20, semantic=255)
    result = Encoder(hyperprior=False).encode_with_report(scene)
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert decoded.semantic.shape == (20, 255) and decoded.equals(result.reconstruction)


def test_semantic_none_does_not_check_what_it_does_not_write():
    scene = random_scene(20, semantic=300)
    data = Encoder(hyperprior=False, semantic="none").encode(scene)
    assert Decoder().decode(data, layers="color,semantic").semantic is None


def test_more_gaussians_than_the_decoder_takes_are_refused(monkeypatch):
    monkeypatch.setattr(encoder_checks, "MAX_GAUSSIANS", 10)
    with pytest.raises(InputError, match="11 Gaussians; the format's decoders take at most 10"):
        Encoder(hyperprior=False).encode(random_scene(11))


def test_an_anchor_scene_with_a_257_byte_semantic_name_is_refused_before_the_fit():
    import copy

    from csgs_codec.codec.anchor_encoder import AnchorEncoder
    from tests.anchors.helpers import small_scene

    scene = copy.copy(small_scene())
    scene.semantic_names = ("n" * 257,) + tuple(scene.semantic_names[1:])
    with pytest.raises(InputError, match="257 bytes long"):
        AnchorEncoder(5).encode(scene)
