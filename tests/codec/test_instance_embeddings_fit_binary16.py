"""Instance embeddings the format cannot hold are refused at encode (issue #52, item 10):
values above binary16's 65504 became infinity with only a numpy warning, and the decoder
then refused the file the encoder had written."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from csgs_codec.chunks.semantic_codebook import write_codebook
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import InputError
from csgs_codec.format.primitives import ByteWriter
from csgs_codec.scene.instance_table import MAX_EMBEDDING_VALUE, InstanceTable
from csgs_codec.semantic.synthetic import labelled_blob_scene


def _segmented(largest: float):
    scene = labelled_blob_scene(3, 100, seed=7)
    count = int(scene.labels.max()) + 1
    prototypes = np.arange(count * 3, dtype=np.float32).reshape(count, 3)
    embeddings = np.ones((count, 4), np.float32)
    embeddings[-1, 2] = largest
    return dataclasses.replace(scene, semantic=prototypes[scene.labels],
                               semantic_names=("ins_feat_0", "ins_feat_1", "ins_feat_2"),
                               instances=InstanceTable(prototypes, embeddings))


@pytest.mark.parametrize("largest", [65520.0, -1e6])
def test_an_embedding_over_binary16_is_refused_naming_the_property(largest):
    scene = _segmented(largest)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow warning on the way
        with pytest.raises(InputError, match="exceeds binary16's 65504") as err:
            Encoder(quality=5).encode(scene)
    assert err.value.property == "embeddings"


def test_the_largest_binary16_value_round_trips():
    scene = _segmented(-MAX_EMBEDDING_VALUE)
    decoded = Decoder().decode(Encoder(quality=5).encode(scene), layers="color,semantic")
    assert decoded.instances.embeddings.min() == -MAX_EMBEDDING_VALUE


def test_the_codebook_writer_refuses_them_too():
    with pytest.raises(InputError, match="binary16") as err:
        write_codebook(ByteWriter(), ("ins_feat_0",), np.zeros((2, 1), np.float32),
                       np.array([0, 1]), np.array([[1.0], [1e5]], np.float32))
    assert err.value.chunk == "SEMC"
