"""Scene vectors of ``SEMR`` (FORMAT §12.25, spec revision 27): labels coded as runs, and as a
map of the tile's ``SEMC`` instances, with damaged copies for each invalid-if rule.

Called by :func:`tests.conformance.scenes.generate`; the leading underscore keeps it out of
the family list (its vectors live in ``spec/vectors/scenes/``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from csgs_codec.chunks.label_runs import mapping_payload
from csgs_codec.chunks.semantic import label_payload
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.entropy.categorical import encode_categorical
from csgs_codec.format.primitives import ByteWriter
from csgs_codec.semantic.synthetic import labelled_blob_scene


def label_runs_scene():
    """400 Gaussians in 4 blobs of 100, labels 0..3, no semantic features (SH 0)."""
    scene = labelled_blob_scene(n_objects=4, per_object=100, seed=26)
    scene.semantic = scene.semantic_names = None
    return scene


def _runs_with_index(labels: np.ndarray, last: int) -> bytes:
    """A source-0 ``SEMR`` payload with one value (0) whose index stream follows the runs of
    ``labels`` and ends in index ``last``."""
    same = (labels[1:] == labels[:-1]).astype(np.int64)
    starts = np.zeros(1 + int(np.sum(same == 0)), np.int64)
    starts[-1] = last
    out = ByteWriter()
    for byte in (1, 0, 1):  # version, source 0 (runs), value_count 1
        out.fixed("u8", byte)
    out.svarint(0)
    out.byte_string(encode_categorical(same, 2))
    out.byte_string(encode_categorical(starts, 2))
    return out.getvalue()


def generate_label_runs(out_dir: Path, instances_data: bytes) -> None:
    """Write the SEMR vectors; ``instances_data`` is an encode whose labels follow its SEMC
    instance ids (semantic_codebook's scene as the current encoder writes it)."""
    from tests.conformance.scenes import (
        UNIFORM,
        _chunk_payload,
        _invalid,
        _reads,
        _with_payload,
        _write,
    )

    data = Encoder(quality=6, **UNIFORM).encode(label_runs_scene())
    arrays = Decoder().decode(data, layers="color,semantic")
    payload = _chunk_payload(data, "SEMR")
    if payload[:4] != bytes([1, 0, 4, 0]):
        raise AssertionError(f"expected SEMR runs of 4 labels, got {payload[:8]!r}")
    _write(out_dir, "label_runs", data,
           "400 Gaussians in 4 labelled blobs, no semantic features, quality 6: labels "
           "coded as runs (SEMR source 0)", _reads(data), arrays=arrays)
    map_payload = _chunk_payload(instances_data, "SEMR")
    if map_payload[:2] != bytes([1, 1]):
        raise AssertionError(f"expected SEMR source 1, got {map_payload!r}")
    _write(out_dir, "label_runs_instances", instances_data,
           "semantic_codebook's scene (40 Gaussians, 5 SEMC instances, each one label), "
           "quality 6: labels coded as a map of the instances (SEMR source 1)",
           _reads(instances_data),
           arrays=Decoder().decode(instances_data, layers="color,semantic"))
    labels = arrays.labels
    rewritten = "(frame and CRC rewritten): the color layer reads, the semantic layer is refused"
    cases = [
        ("label_runs_version_2", _invalid(data, patch=("SEMR", 0, 2)), "its version byte 2"),
        ("label_runs_source_2", _invalid(data, patch=("SEMR", 1, 2)), "its source byte 2"),
        ("label_runs_not_increasing", _invalid(data, patch=("SEMR", 4, 0)),
         "its second value made 0, equal to the first"),
        ("label_runs_index_out_of_range",
         _with_payload(data, "SEMR", _runs_with_index(labels, 1)),
         "one value (K = 1) and the last run's index 1"),
        ("label_runs_with_seml",
         _with_payload(data, "SEML", label_payload(labels), before="SEMR"),
         "a SEML chunk of the same labels added before its SEMR (a tile holds one)"),
        ("label_runs_instances_without_semc",
         _with_payload(data, "SEMR", mapping_payload([0, 1, 2, 3])),
         "a SEMR of source 1 (a map of SEMC instances) in a file without SEMC"),
        ("label_runs_instances_value_count",
         _with_payload(instances_data, "SEMR", map_payload[:2] + bytes([map_payload[2] - 1])
                       + map_payload[3:-1]),
         "label_runs_instances with one value fewer than SEMC's instances"),
    ]
    for name, bad, what in cases:
        base = "label_runs_instances" if "instances_value" in name else "label_runs"
        _write(out_dir, name, bad, f"{base} with {what} {rewritten}", _reads(bad))
