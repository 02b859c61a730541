"""The decodes a determinism check repeats: one case per valid read of a conformance vector.

Every case knows its expected digest (from the vector's JSON, without decoding) and how to
compute the actual one (by decoding). Digests are SHA-256 hex strings:

- scenes/: the canonical PLY bytes of the decoded scene (``ply_sha256`` in the JSON), per
  layer choice that the JSON records as "ok";
- container/: the canonical JSON of ``run_read``'s result for each "ok" read;
- entropy/: the canonical JSON of the decoded residuals, or of a network's embedding row and
  its outputs on both inference routes (float64 through BLAS, and int64);
- geometry/: the canonical JSON of the decoded points;
- anchors/: the anchor digest of the decoded anchor scene (its arrays and MLP weights; see
  :func:`anchor_scene_digest`), per "ok" layer choice; this family runs the integer
  hyperprior networks, whose float64 route goes through BLAS.

Canonical JSON is ``json.dumps(value, sort_keys=True, separators=(",", ":"))``.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tests.conformance import current

FAMILIES = ("anchors", "container", "entropy", "geometry", "histogram", "scenes")


@dataclass(frozen=True)
class Case:
    """One decode to repeat: ``id`` like 'scenes/donut_q3[color]', its expected digest and a
    function computing the actual digest."""

    id: str
    expected: str
    compute: Callable[[], str]


def json_digest(value) -> str:
    """SHA-256 hex of the canonical JSON of ``value``."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _scene_cases(folder: Path) -> list[Case]:
    def compute(data_path: Path, layers: str, lod: int | None) -> Callable[[], str]:
        def run() -> str:
            from csgs_codec.codec.decoder import Decoder
            from csgs_codec.interchange.ply_io import ply_bytes

            scene = Decoder().decode(data_path.read_bytes(), layers=layers, lod=lod)
            return hashlib.sha256(ply_bytes(scene)).hexdigest()
        return run

    out = []
    for meta_path in current(sorted(folder.glob("*.json"))):
        doc = json.loads(meta_path.read_text())
        for read in doc["reads"]:
            if read["outcome"] == "ok":
                level = "" if read.get("lod") is None else f", level {read['lod']}"
                out.append(Case(f"scenes/{meta_path.stem}[{read['layers']}{level}]",
                                read["ply_sha256"],
                                compute(meta_path.with_suffix(".csgs"), read["layers"],
                                        read.get("lod"))))
    return out


def _container_cases(folder: Path) -> list[Case]:
    def compute(data_path: Path, layers) -> Callable[[], str]:
        def run() -> str:
            from tests.conformance.container import run_read

            return json_digest(run_read(data_path.read_bytes(), layers))
        return run

    out = []
    for meta_path in sorted(folder.glob("*.json")):
        doc = json.loads(meta_path.read_text())
        for read in doc["reads"]:
            if read["outcome"] == "ok":
                label = ",".join(read["layers"]) or "base"
                out.append(Case(f"container/{meta_path.stem}[{label}]", json_digest(read),
                                compute(folder / doc["file"], read["layers"])))
    return out


def _residual_run(data_path: Path, inputs: dict) -> Callable[[], str]:
    def run() -> str:
        from csgs_codec.entropy.residual import decode_residuals

        args = [np.array(inputs[k], dtype=np.int64) for k in ("mean", "scale_idx", "step_idx")]
        return json_digest(decode_residuals(data_path.read_bytes(), *args).tolist())
    return run


def _network_run(data_path: Path, positions: list) -> Callable[[], str]:
    def run() -> str:
        from csgs_codec.entropy.intnet_bytes import intnet_from_bytes

        net = intnet_from_bytes(data_path.read_bytes())
        x = np.array(positions, dtype=np.int64)
        return json_digest({"embedding_first_row": net.embed(x[:1])[0].tolist(),
                            "float64": net.forward(x, "float64").tolist(),
                            "int64": net.forward(x, "int64").tolist()})
    return run


def _entropy_cases(folder: Path) -> list[Case]:
    out = []
    for meta_path in sorted(folder.glob("*.json")):
        doc = json.loads(meta_path.read_text())
        if doc.get("outcome") != "ok" or "file" not in doc:
            continue
        data_path = folder / doc["file"]
        if doc.get("kind") == "residual":
            out.append(Case(f"entropy/{meta_path.stem}", json_digest(doc["decoded"]),
                            _residual_run(data_path, doc["inputs"])))
        elif "outputs" in doc:
            expected = {"embedding_first_row": doc["embedding_first_row"],
                        "float64": doc["outputs"], "int64": doc["outputs"]}
            out.append(Case(f"entropy/{meta_path.stem}", json_digest(expected),
                            _network_run(data_path, doc["positions"])))
    return out


def _histogram_run(data_path: Path, count: int) -> Callable[[], str]:
    def run() -> str:
        from csgs_codec.entropy.histogram import decode_histogram

        return json_digest(decode_histogram(data_path.read_bytes(), count).tolist())
    return run


def _histogram_cases(folder: Path) -> list[Case]:
    out = []
    for meta_path in sorted(folder.glob("*.json")):
        doc = json.loads(meta_path.read_text())
        if doc.get("outcome") == "ok":
            out.append(Case(f"histogram/{meta_path.stem}", json_digest(doc["values"]),
                            _histogram_run(folder / doc["file"], doc["count"])))
    return out


def _geometry_cases(folder: Path) -> list[Case]:
    def compute(data_path: Path) -> Callable[[], str]:
        def run() -> str:
            from csgs_codec.entropy.geometry import decode_positions

            return json_digest(decode_positions(data_path.read_bytes()).astype(int).tolist())
        return run

    out = []
    for meta_path in sorted(folder.glob("*.json")):
        doc = json.loads(meta_path.read_text())
        if doc.get("valid"):
            out.append(Case(f"geometry/{meta_path.stem}", json_digest(doc["points"]),
                            compute(folder / doc["file"])))
    return out


#: Anchor-scene arrays in the order the digest hashes them.
ANCHOR_ARRAYS = ("positions", "features", "offsets", "scaling", "offset_mask", "semantic",
                 "labels")


def anchor_scene_digest(scene) -> str:
    """The digest anchor vectors record (spec/FORMAT.md §17), computed without torch.

    SHA-256 over, for each array of :data:`ANCHOR_ARRAYS` that is present, its name, its shape
    as Python prints it and its bytes; then the semantic names joined by '|' (UTF-8); then the
    bytes of every MLP head's arrays in order. (tests.conformance.anchors holds the same
    definition but imports the encoder, hence torch, which a torch-free run must not load.)
    """
    h = hashlib.sha256()
    for name in ANCHOR_ARRAYS:
        value = getattr(scene, name)
        if value is not None:
            h.update(name.encode() + str(value.shape).encode() + value.tobytes())
    h.update("|".join(scene.semantic_names).encode("utf-8"))
    if scene.mlps is not None:
        for head in scene.mlps.heads().values():
            for array in head.arrays().values():
                h.update(array.tobytes())
    return h.hexdigest()


def _anchor_cases(folder: Path) -> list[Case]:
    def compute(data_path: Path, layers: str) -> Callable[[], str]:
        def run() -> str:
            from csgs_codec.codec.anchor_decoder import AnchorDecoder

            scene = AnchorDecoder().decode(data_path.read_bytes(), layers=layers)
            return anchor_scene_digest(scene)
        return run

    out = []
    for meta_path in sorted(folder.glob("*.json")):
        doc = json.loads(meta_path.read_text())
        for read in doc["reads"]:
            if read["outcome"] == "ok":
                out.append(Case(f"anchors/{meta_path.stem}[{read['layers']}]", read["digest"],
                                compute(meta_path.with_suffix(".csgs"), read["layers"])))
    return out


_BUILDERS = {"anchors": _anchor_cases, "container": _container_cases, "entropy": _entropy_cases,
             "histogram": _histogram_cases,
             "geometry": _geometry_cases, "scenes": _scene_cases}


def vector_cases(vectors_dir: Path, only: list[str] | None = None) -> list[Case]:
    """Every valid read of the vectors under ``vectors_dir`` (families present there).

    Args:
        only: keep cases whose id starts with one of these prefixes (e.g. 'entropy',
            'scenes/semantic_small'); None keeps all.
    """
    cases = []
    for family in FAMILIES:
        folder = vectors_dir / family
        if folder.is_dir():
            cases += _BUILDERS[family](folder)
    if only:
        cases = [c for c in cases if c.id.startswith(tuple(only))]
    return cases
