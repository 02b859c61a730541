"""Bytes of per-Gaussian integer labels: SEML (residuals) against SEMR (runs, or a map of the
SEMC instances), as the default encoder writes them.

    .venv/bin/python benchmarks/label_coding.py [--out FILE]

Each case is encoded at quality 5; the labels are taken back from the decoded file (so in the
file's Morton order), and each coding is measured on them: ``seml`` (the old coding),
``semr_runs``, ``semr_map`` (only where the tile writes SEMC and the labels follow its ids)
and ``written`` (the payload the encoder chose; the decoded labels are checked to equal the
input's, Gaussian for Gaussian, under the encoder's order).

Cases: (a) labelled_blob_scene, 4 objects x 400 Gaussians, labels only; (b) fruit_drops
(4,721 real Gaussians) with its 9-class labels from fruit_drops_labels.json, labels only, and
again with a feature prototype per class (as ``csgs segment`` writes them: SEMC); (c) the
default labelled_blob_scene (5 x 400, noisy features: SEMF) and the same with exact
per-object features (SEMC).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402
from selection_real import load_real_scene  # noqa: E402

from csgs_codec.chunks.label_runs import instance_mapping, mapping_payload, runs_payload  # noqa: E402
from csgs_codec.chunks.semantic import label_payload  # noqa: E402
from csgs_codec.chunks.semantic_codebook import codebook_of  # noqa: E402
from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.format import read_layers  # noqa: E402
from csgs_codec.semantic.synthetic import labelled_blob_scene  # noqa: E402


def _prototypes(scene, labels: np.ndarray) -> None:
    """Give ``scene`` one exact 2-channel feature per label (a segmentation's prototypes)."""
    _, index = np.unique(labels, return_inverse=True)
    angle = index.reshape(-1).astype(np.float32)
    scene.semantic = np.stack([np.cos(angle), np.sin(angle)], 1).astype(np.float32)
    scene.semantic_names = ("ins_feat_0", "ins_feat_1")


def cases():
    """(name, scene) pairs of the module notes."""
    a = labelled_blob_scene(n_objects=4, per_object=400)
    a.semantic = a.semantic_names = None
    yield "blobs_4x400_labels_only", a
    real, labels, _ = load_real_scene()
    real.labels = labels
    yield "fruit_drops_labels_only", real
    real, labels, _ = load_real_scene()
    real.labels = labels
    _prototypes(real, labels)
    yield "fruit_drops_with_semc", real
    yield "blobs_5x400_semf", labelled_blob_scene()
    c = labelled_blob_scene()
    _prototypes(c, c.labels)
    yield "blobs_5x400_semc", c


def measure(name: str, scene) -> dict:
    """Bytes of each coding of ``scene``'s labels in the encoded file's order."""
    data = Encoder(quality=5).encode(scene)
    container = read_layers(data, "semantic")
    written = {e.type: len(container.single_payload(e.type)[0]) for e in container.toc
               if e.type in ("SEML", "SEMR")}
    decoded = Decoder().decode(data, layers="color,semantic")
    labels = decoded.labels
    assert np.array_equal(np.sort(labels), np.sort(scene.labels)), name
    row = {"case": name, "gaussians": int(labels.size),
           "distinct_labels": int(np.unique(labels).size),
           "seml": len(label_payload(labels)), "semr_runs": len(runs_payload(labels)),
           "semr_map": None}
    if "SEMC" in {e.type for e in container.toc}:
        prototypes, ids = codebook_of(decoded.semantic)
        mapping = instance_mapping(labels, ids, len(prototypes))
        if mapping is not None:
            row["semr_map"] = len(mapping_payload(mapping))
    (code, size), = written.items()
    row.update(written_chunk=code, written=size,
               bits_per_gaussian_old=round(8 * row["seml"] / labels.size, 3),
               bits_per_gaussian_new=round(8 * size / labels.size, 3))
    return row


def main() -> int:
    """Measure every case and print or write a csgs-bench/1 document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out")
    args = parser.parse_args()
    rows = [measure(name, scene) for name, scene in cases()]
    for row in rows:
        print(f"{row['case']:28s} N={row['gaussians']:5d} K={row['distinct_labels']:2d} "
              f"SEML {row['seml']:5d}  runs {row['semr_runs']:5d}  map {row['semr_map']}  "
              f"-> {row['written_chunk']} {row['written']} B", file=sys.stderr)
    emit(document("label_coding", rows), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
