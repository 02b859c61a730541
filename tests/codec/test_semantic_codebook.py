"""SEMC (FORMAT §12.23): features with few distinct rows coded exactly as a codebook."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from csgs_codec.chunks.semantic_codebook import codebook_of, read_codebook, write_codebook
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter
from csgs_codec.semantic.synthetic import labelled_blob_scene

NAMES = ("ins_feat_0", "ins_feat_1")


def _round_trip(prototypes, ids):
    out = ByteWriter()
    write_codebook(out, NAMES, np.asarray(prototypes, np.float32), np.asarray(ids))
    reader = ByteReader(out.getvalue(), base_offset=100, chunk="SEMC")
    return read_codebook(reader, len(ids), 256)


@pytest.mark.parametrize("ids", [[], [0], [0, 0, 0], [1, 0, 2, 2, 2, 1, 1, 0]])
def test_codebook_round_trips_exactly(ids):
    prototypes = np.array([[0.5, -0.0], [0.0, 1e-30], [-3.25, 7.0]], np.float32)
    names, features, table = _round_trip(prototypes, ids)
    assert table is None
    assert names == NAMES
    assert features.shape == (len(ids), 2) and features.dtype == np.float32
    expected = prototypes[np.asarray(ids, np.int64)] if ids else np.zeros((0, 2), np.float32)
    assert np.array_equal(features.view(np.uint32), expected.view(np.uint32))


def test_codebook_of_keeps_bit_patterns_and_refuses_many_rows():
    rows = np.array([[0.0, 1.0], [-0.0, 1.0], [0.0, 1.0]], np.float32)
    prototypes, ids = codebook_of(rows)
    assert len(prototypes) == 2 and np.array_equal(prototypes[ids].view(np.uint32),
                                                   rows.view(np.uint32))
    many = np.arange(512, dtype=np.float32).reshape(256, 2)
    assert codebook_of(many) is None
    assert codebook_of(np.zeros((0, 2), np.float32)) is None


def test_encoder_writes_semc_for_instance_features_and_semf_for_continuous_ones():
    scene = labelled_blob_scene(4, 200, seed=2)
    prototypes = np.random.default_rng(0).normal(size=(int(scene.labels.max()) + 1, 6))
    snapped = dataclasses.replace(scene, labels=None,
                                  semantic=prototypes[scene.labels].astype(np.float32))
    report = Encoder(quality=5).encode_with_report(snapped)
    assert b"SEMC" in report.data and b"SEMF" not in report.data
    decoded = Decoder().decode(report.data, layers="color,semantic")
    assert np.array_equal(decoded.semantic, snapped.semantic[report.order])
    assert decoded.semantic_names == snapped.semantic_names
    continuous = Encoder(quality=5).encode(dataclasses.replace(scene, labels=None))
    assert b"SEMF" in continuous and b"SEMC" not in continuous


def test_a_damaged_codebook_is_a_format_error_at_its_offset():
    out = ByteWriter()
    write_codebook(out, NAMES, np.array([[1.0, 2.0]], np.float32), np.zeros(5, np.int64))
    data = bytearray(out.getvalue())
    data[0] = 2
    with pytest.raises(FormatError, match="version 2") as err:
        read_codebook(ByteReader(bytes(data), base_offset=100, chunk="SEMC"), 5, 256)
    assert err.value.offset == 100 and err.value.chunk == "SEMC"
    with pytest.raises(FormatError, match="symbols"):
        read_codebook(ByteReader(out.getvalue(), base_offset=100, chunk="SEMC"), 6, 256)


def test_prototypes_exact_in_binary16_are_stored_in_two_bytes():
    ids = np.array([0, 1, 1, 0])
    exact, inexact = ByteWriter(), ByteWriter()
    write_codebook(exact, NAMES, np.array([[0.5, -2.0], [1.25, 3.0]], np.float32), ids)
    write_codebook(inexact, NAMES, np.array([[0.1, -2.0], [1.25, 3.0]], np.float32), ids)
    assert len(inexact) - len(exact) == 4 * 2
    _, features, _ = read_codebook(ByteReader(exact.getvalue(), chunk="SEMC"), 4, 256)
    assert np.array_equal(features, np.array([[0.5, -2.0], [1.25, 3.0]], np.float32)[ids])
    damaged = bytearray(exact.getvalue())
    damaged[1 + 1 + 2 * 11 + 1] = 2  # version, count, two names, K: then the format byte
    with pytest.raises(FormatError, match="prototype_format 2"):
        read_codebook(ByteReader(bytes(damaged), chunk="SEMC"), 4, 256)


def _segmented_blobs(count=1200):
    from csgs_codec.scene.instance_table import InstanceTable

    scene = labelled_blob_scene(4, count // 4, seed=5)
    prototypes = np.random.default_rng(2).normal(size=(int(scene.labels.max()) + 1, 3))
    prototypes = prototypes.astype(np.float16).astype(np.float32)
    embeddings = np.random.default_rng(3).normal(size=(len(prototypes), 8)).astype(np.float32)
    table = InstanceTable(prototypes, embeddings)
    names = ("ins_feat_0", "ins_feat_1", "ins_feat_2")
    return dataclasses.replace(scene, semantic=prototypes[scene.labels], semantic_names=names,
                               instances=table), table


@pytest.mark.parametrize("tile_size", [None, 1000])
def test_instance_embeddings_round_trip_in_binary16(tile_size):
    scene, table = _segmented_blobs(2400)
    report = Encoder(quality=5, tile_size=tile_size).encode_with_report(scene)
    decoded = Decoder().decode(report.data, layers="color,semantic")
    assert decoded.instances is not None
    rows = decoded.instances.rows_of(table.prototypes)
    assert (rows >= 0).all() and len(decoded.instances.prototypes) == len(table.prototypes)
    expected = table.embeddings.astype(np.float16).astype(np.float32)
    assert np.array_equal(decoded.instances.embeddings[rows], expected)
    assert np.array_equal(report.reconstruction.instances.embeddings[
        report.reconstruction.instances.rows_of(table.prototypes)], expected)


def test_an_instance_table_must_cover_every_feature_row():
    from csgs_codec.errors import InputError
    from csgs_codec.scene.instance_table import InstanceTable

    scene, table = _segmented_blobs()
    short = InstanceTable(table.prototypes[:-1], table.embeddings[:-1])
    with pytest.raises(InputError, match="no instance embedding"):
        Encoder(quality=5).encode(dataclasses.replace(scene, instances=short))
    repeated = InstanceTable(table.prototypes[[0, 0]], table.embeddings[:2])
    with pytest.raises(InputError, match="repeat"):
        Encoder(quality=5).encode(dataclasses.replace(scene, instances=repeated))
