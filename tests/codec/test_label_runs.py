"""SEMR (FORMAT §12.25): labels as runs or as a map of the tile's SEMC instances, chosen only
where smaller than SEML, and every invalid-if rule of its payload."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.chunks.label_runs import (
    instance_mapping,
    mapping_payload,
    read_runs_payload,
    runs_payload,
)
from csgs_codec.chunks.semantic import label_payload, smallest_label_chunk
from csgs_codec.entropy.categorical import encode_categorical
from csgs_codec.errors import FormatError
from csgs_codec.format import read_layers
from csgs_codec.format.primitives import ByteReader, ByteWriter
from csgs_codec.semantic.synthetic import labelled_blob_scene

AT = 1000  # an absolute offset, so errors are seen to carry it


def _reader(data):
    return ByteReader(bytes(data), base_offset=AT, chunk="SEMR")


def _runs(labels, instances=None):
    return read_runs_payload(_reader(runs_payload(labels)), len(labels), instances)


def test_runs_round_trip_keeps_every_label_including_int32_extremes():
    labels = np.array([-(1 << 31), -(1 << 31), 7, 7, 7, (1 << 31) - 1, 7, -3], np.int32)
    decoded = _runs(labels)
    assert decoded.dtype == np.int32 and np.array_equal(decoded, labels)


def test_one_label_and_one_gaussian_round_trip():
    assert np.array_equal(_runs(np.full(500, 4, np.int32)), np.full(500, 4))
    assert np.array_equal(_runs(np.array([-9], np.int32)), [-9])


def test_runs_refuse_more_than_255_distinct_labels():
    assert runs_payload(np.arange(256)) is None and runs_payload(np.arange(255)) is not None
    assert runs_payload(np.empty(0, np.int32)) is None


def test_mapping_round_trip_reads_labels_through_the_instance_ids():
    ids = np.array([0, 0, 2, 2, 1, 0, 3])
    labels = np.array([5, 5, -1, -1, 5, 5, 9], np.int32)
    mapping = instance_mapping(labels, ids, 4)
    assert mapping.tolist() == [5, 5, -1, 9]
    decoded = read_runs_payload(_reader(mapping_payload(mapping)), len(ids), (ids, 4))
    assert np.array_equal(decoded, labels)


def test_labels_that_split_an_instance_have_no_mapping():
    assert instance_mapping(np.array([1, 2, 2]), np.array([0, 0, 1]), 2) is None


def test_blob_labels_choose_semr_and_random_labels_keep_seml():
    labels = labelled_blob_scene(n_objects=4, per_object=400).labels
    code, payload = smallest_label_chunk(labels)
    assert code == "SEMR" and len(payload) < len(label_payload(labels)) / 4
    noisy = np.random.default_rng(3).integers(0, 3, 2000)
    assert smallest_label_chunk(noisy) == ("SEML", label_payload(noisy))


@pytest.mark.parametrize("seed", range(6))
def test_the_chosen_coding_is_never_larger_than_seml(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 3000))
    labels = np.repeat(rng.integers(-5, 5 + 300 * (seed % 2), n), rng.integers(1, 9, n))
    ids = rng.integers(0, 4, labels.size)
    _, payload = smallest_label_chunk(labels, (ids, 4))
    assert len(payload) <= len(label_payload(labels))


def test_labels_that_follow_the_instances_cost_only_the_map():
    ids = np.repeat(np.arange(6), 300)
    labels = np.array([3, 3, 1, 0, 1, 2])[ids]
    code, payload = smallest_label_chunk(labels, (ids, 6))
    assert code == "SEMR" and payload == mapping_payload([3, 3, 1, 0, 1, 2])
    assert len(payload) == 9 and len(payload) < len(runs_payload(labels))


def _payload(source=0, values=(1, 4), same=b"", index=b"", version=1, count=None):
    out = ByteWriter()
    out.fixed("u8", version)
    out.fixed("u8", source)
    out.varint(len(values) if count is None else count)
    for v in values:
        out.svarint(v)
    if source == 0:
        out.raw(same)
        out.raw(index)
    return bytearray(out.getvalue())


def _stream(symbols, alphabet):
    out = ByteWriter()
    out.byte_string(encode_categorical(np.array(symbols), alphabet))
    return out.getvalue()


def assert_refused(data, count=3, instances=None, match="", at=None):
    with pytest.raises(FormatError, match=match) as caught:
        read_runs_payload(_reader(data), count, instances)
    assert caught.value.chunk == "SEMR"
    if at is not None:
        assert caught.value.offset == AT + at
    return caught.value


def test_a_version_other_than_1_is_invalid():
    data = bytearray(runs_payload(np.array([1, 1, 4])))
    data[0] = 2
    assert_refused(data, match="version 2", at=0)


def test_a_source_above_1_is_invalid():
    data = bytearray(runs_payload(np.array([1, 1, 4])))
    data[1] = 2
    assert_refused(data, match="source 2", at=1)


def test_source_1_without_semc_is_invalid():
    assert_refused(mapping_payload([1, 2]), match="without SEMC", at=1)


def test_source_1_with_a_value_count_other_than_the_instance_count_is_invalid():
    assert_refused(mapping_payload([1, 2]), instances=(np.array([0, 1, 2]), 3),
             match="instance_count 3", at=2)


def test_a_value_count_of_0_or_above_255_is_invalid():
    assert_refused(_payload(values=()), match="value_count 0", at=2)
    assert_refused(_payload(values=(), count=256), match="value_count 256", at=2)


def test_values_not_strictly_increasing_are_invalid():
    assert_refused(_payload(values=(4, 4)), match="strictly increasing", at=4)


def test_a_value_outside_int32_is_invalid():
    assert_refused(_payload(values=(1 << 31,)), match="int32", at=3)


def test_an_index_not_below_value_count_is_invalid():
    # One value: the index stream's alphabet is 2, so it can hold an index 1.
    data = _payload(values=(7,), same=_stream([0], 2), index=_stream([0, 1], 2))
    assert_refused(data, count=2, match="not below value_count 1", at=4 + len(_stream([0], 2)))


def test_an_index_stream_with_another_alphabet_is_invalid():
    data = _payload(values=(7, 9), same=_stream([0], 2), index=_stream([0, 1], 3))
    assert_refused(data, count=2, match="alphabet")


def test_trailing_bytes_are_invalid():
    assert_refused(runs_payload(np.array([1, 1, 4])) + b"\0", match="SEMR payload")
    assert_refused(mapping_payload([1, 2]) + b"\0", instances=(np.array([0, 1, 1]), 2),
             match="SEMR payload")


def test_a_truncated_stream_is_invalid():
    assert_refused(runs_payload(np.array([1, 1, 4]))[:-3], match="SEMR|truncat|end")


def _encoded(scene):
    return Encoder(quality=3).encode(scene)


def test_the_encoder_writes_semr_for_blob_labels_and_the_decoder_reads_them():
    scene = labelled_blob_scene(n_objects=4, per_object=400)
    scene.semantic = scene.semantic_names = None
    data = _encoded(scene)
    types = [e.type for e in read_layers(data, "semantic").toc]
    assert "SEMR" in types and "SEML" not in types
    decoded = Decoder().decode(data, layers="color,semantic")
    # Blob k sits at grid cell (k % 2, k // 2), 1 apart: each Gaussian's label is its blob's.
    cell = np.rint(decoded.positions[:, :2]).astype(np.int64)
    assert np.array_equal(decoded.labels, cell[:, 0] + 2 * cell[:, 1])
    assert np.bincount(decoded.labels).tolist() == [400] * 4


def test_a_tile_with_both_seml_and_semr_is_invalid():
    from csgs_codec.chunks.semantic import read_labels

    class Container:
        toc = [type("E", (), {"type": "SEML"})(), type("E", (), {"type": "SEMR"})()]

        def single_payload(self, code):
            return runs_payload(np.array([1, 1])), 77

    with pytest.raises(FormatError, match="both SEML and SEMR"):
        read_labels(Container(), 2)


def test_tiles_of_one_file_may_pick_different_codings():
    """§12.22: each tile keeps its own smaller coding; the file decodes every label."""
    scene = labelled_blob_scene(n_objects=4, per_object=400)
    scene.semantic = scene.semantic_names = None
    east = scene.positions[:, 0] > np.rint(scene.positions[:, 0])
    scene.labels = (2 * scene.labels + east).astype(np.int32)  # two runs-friendly halves
    noisy = scene.labels < 2  # blob 0: labels with no runs, where SEML is smaller
    scene.labels[noisy] = np.random.default_rng(1).integers(0, 7, int(noisy.sum()))
    data = Encoder(quality=3, tile_size=400).encode(scene)
    codes = {e.tile: e.type for e in read_layers(data, "semantic").toc
             if e.type in ("SEML", "SEMR")}
    assert sorted(codes.values()) == ["SEML", "SEMR", "SEMR", "SEMR"]
    decoded = Decoder().decode(data, layers="color,semantic")
    assert np.array_equal(np.bincount(decoded.labels), np.bincount(scene.labels))
    # Every Gaussian keeps its own label: outside blob 0 they follow the decoded positions
    # (away from a blob's centre line, which quantized positions may cross).
    cell = np.rint(decoded.positions[:, :2]).astype(np.int64)
    blob = cell[:, 0] + 2 * cell[:, 1]
    offset = decoded.positions[:, 0] - cell[:, 0]
    clear = (blob > 0) & (np.abs(offset) > 0.02)
    assert clear.sum() > 1000
    assert np.array_equal(decoded.labels[clear], (2 * blob + (offset > 0))[clear])
