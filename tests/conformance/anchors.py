"""Anchor-scene conformance vectors (spec/FORMAT.md §17): .csgs files with expected decodes.

Valid vectors record, per layer choice, the anchor count and :func:`anchor_digest` of the
decoded scene, plus the decoded arrays; invalid vectors record the error class and chunk.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from csgs_codec.chunks.anchor_payloads import MLP_VERSION_F16, mlps_to_bytes
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.entropy.intnet_dense import DENSE_VERSION_RAW, IntDenseMLP
from csgs_codec.errors import CsgsError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.format.primitives import ByteReader, ByteWriter
from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene

READS = ("color", "color,semantic")
ARRAYS = ("positions", "features", "offsets", "scaling", "offset_mask", "semantic", "labels")


def anchor_digest(scene: AnchorScene) -> str:
    """SHA-256 over the decoded arrays (``ARRAYS`` order, absent ones skipped), the semantic
    names and the MLP weights: equal digests mean bit-identical decodes."""
    h = hashlib.sha256()
    for name in ARRAYS:
        value = getattr(scene, name)
        if value is not None:
            h.update(name.encode() + str(value.shape).encode() + value.tobytes())
    h.update("|".join(scene.semantic_names).encode("utf-8"))
    if scene.mlps is not None:
        for head in scene.mlps.heads().values():
            for arr in head.arrays().values():
                h.update(arr.tobytes())
    return h.hexdigest()


def vector_scene() -> AnchorScene:
    """Three labelled objects of 20 anchors (F = 20, K = 4, S = 3), with MLPs."""
    return synthetic_anchor_scene(3, 20, feat_dim=20, n_offsets=4, semantic_dim=3, seed=3)


def _reads(data: bytes) -> list[dict]:
    reads = []
    for layers in READS:
        try:
            scene = AnchorDecoder().decode(data, layers=layers)
        except CsgsError as err:
            reads.append({"layers": layers, "outcome": "error", "error": type(err).__name__,
                          "chunk": err.chunk})
            continue
        reads.append({"layers": layers, "outcome": "ok", "anchors": len(scene),
                      "digest": anchor_digest(scene)})
    return reads


def _write(out_dir: Path, name: str, data: bytes, description: str,
           arrays: AnchorScene | None = None) -> None:
    (out_dir / f"{name}.csgs").write_bytes(data)
    reads = _reads(data)
    doc = {"schema": "csgs-vector/1", "name": name, "description": description,
           "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest(),
           "valid": all(r["outcome"] == "ok" for r in reads), "reads": reads}
    if arrays is not None:
        np.savez(out_dir / f"{name}.npz", **{k: getattr(arrays, k) for k in ARRAYS
                                             if getattr(arrays, k) is not None})
        doc["arrays"] = f"{name}.npz"
    (out_dir / f"{name}.json").write_text(json.dumps(doc, indent=2) + "\n")


def _without(data: bytes, code: str) -> bytes:
    container = read_layers(data, layers="color,semantic")
    return write_container([Chunk(e.type, e.layer, bytes(container.payloads[e.index]),
                                  e.tile) for e in container.toc if e.type != code])


def _acrm_version_1(data: bytes) -> bytes:
    """The ACRM payload of ``data`` with every network rewritten in dense version 1."""
    container = read_layers(data, layers="color")
    entry = next(e for e in container.toc if e.type == "ACRM")
    r = ByteReader(bytes(container.payloads[entry.index]), chunk="ACRM")
    out = ByteWriter()
    count = r.varint("network_count")
    out.varint(count)
    for _ in range(count):
        net = IntDenseMLP.from_bytes(r.byte_string("network"))
        out.byte_string(net.to_bytes(DENSE_VERSION_RAW))
    return out.getvalue()


def _replaced(data: bytes, code: str, payload: bytes) -> bytes:
    """``data`` with chunk ``code``'s payload replaced by ``payload``."""
    container = read_layers(data, layers="color,semantic")
    return write_container([Chunk(e.type, e.layer, payload if e.type == code
                                  else bytes(container.payloads[e.index]), e.tile)
                            for e in container.toc])


def generate(out_dir: Path) -> None:
    """Write the anchor vectors into ``out_dir``."""
    scene = vector_scene()
    fit = FitSettings(steps=60, batch=256)
    current = AnchorEncoder(quality=5, fit=fit).encode(scene)
    # As landed, with its CARM networks in dense network version 1; the encoder now writes
    # version 2, kept as its own vector. Vectors derived from this one use the landed bytes.
    full = _replaced(current, "ACRM", _acrm_version_1(current))
    _write(out_dir, "anchors_semantic_q5", full,
           "60 synthetic anchors (F 20, K 4, S 3, labels, MLPs), quality 5, 5 CARM groups",
           AnchorDecoder().decode(full, layers="color,semantic"))
    _write(out_dir, "anchors_semantic_q5_acrm_v2", current,
           "anchors_semantic_q5 as the encoder writes it now: CARM networks in dense network "
           "version 2 (coded weights)", AnchorDecoder().decode(current, layers="color,semantic"))
    color = AnchorEncoder(quality=8, carm_groups=1, semantic="none", fit=fit).encode(scene)
    _write(out_dir, "anchors_color_q8", color,
           "the same anchors at quality 8 without CARM and without a semantic layer",
           AnchorDecoder().decode(color))
    legacy = _replaced(color, "AMLP",
                       mlps_to_bytes(scene.mlps, version=MLP_VERSION_F16)[0])
    _write(out_dir, "anchors_color_q8_mlp_float16", legacy,
           "anchors_color_q8 with its MLP weights in AMLP version 1 (float16)",
           AnchorDecoder().decode(legacy))
    _write(out_dir, "anchors_missing_features", _without(full, "AFEA"),
           "anchors_semantic_q5 without its AFEA chunk: every read fails naming AFEA")
    _write(out_dir, "anchors_missing_semantic_features", _without(full, "ASEM"),
           "anchors_semantic_q5 without ASEM: color decodes, semantic fails naming ASEM")
