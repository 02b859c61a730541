"""Scene conformance vectors: .csgs files with their expected decodes (spec/FORMAT.md §14).

Valid vectors carry the SHA-256 of the canonical PLY (csgs_codec.interchange.ply_io.ply_bytes) of
each read, plus the decoded arrays for the small ones; invalid vectors carry the error class
and the chunk it names.

While format 1.0 is a draft, vectors are rewritten only where a revision of the format says so
(spec/CHANGES.md): revision 21, the cleanup before the freeze, rewrote them all once without
revision suffixes. The earlier drafts' vectors are never deleted: they stay as they landed
(:data:`tests.conformance.RETIRED_SCENE_VECTORS`), no longer decoded.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from csgs_codec.chunks.color_streams import rotation_class_table, rotation_coding_offset
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import CsgsError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.format.primitives import ByteReader
from csgs_codec.interchange.ply_io import ply_bytes, read_ply
from csgs_codec.scene.gaussian_scene import GaussianScene

REPO = Path(__file__).resolve().parents[2]
DONUT = REPO / "samples" / "donut.ply"
THREE_POINTS = REPO.parent / "shared" / "data" / "fixtures" / "three_points_sh3.ply"
READS = ("color", "color,semantic")
#: The vectors written before render-aware rotation steps were the default keep one step
#: (regenerating them gives the same bytes); the scored-steps vectors show the default.
UNIFORM = {"rotation_steps": "uniform"}


def small_semantic_scene() -> GaussianScene:
    """A 40-Gaussian SH-1 scene with 3 semantic channels and labels, fixed integers only."""
    i = np.arange(40, dtype=np.float32)
    col = lambda k, scale: np.stack([np.sin(i * (k + j + 1)) * scale  # noqa: E731
                                     for j in range(k)], axis=1).astype(np.float32)
    return GaussianScene(
        positions=np.stack([i % 4, (i // 4) % 5, i // 20], axis=1).astype(np.float32) * 0.25,
        sh_dc=col(3, 1.5), sh_rest=col(9, 0.2).reshape(40, 3, 3),
        opacity=(np.cos(i) * 4).astype(np.float32), scales=col(3, 0.5) - 3,
        rotations=col(4, 1.0) + np.float32(0.1), semantic=col(3, 0.8),
        semantic_names=("ins_feat_0", "ins_feat_1", "ins_feat_2"),
        labels=(i // 8).astype(np.int32))


def _reads(data: bytes, levels: int = 0) -> list[dict]:
    """The outcome of decoding ``data`` with each layer choice; with ``levels``, also of
    each level of detail 0..levels-1 (reads with an ``lod`` key)."""
    reads = []
    for lod in [None] + list(range(levels)):
        for layers in READS:
            try:
                scene = Decoder().decode(data, layers=layers, lod=lod)
            except CsgsError as err:
                reads.append({"layers": layers, "outcome": "error",
                              "error": type(err).__name__, "chunk": err.chunk})
                continue
            read = {"layers": layers, "outcome": "ok", "gaussians": len(scene),
                    "ply_sha256": hashlib.sha256(ply_bytes(scene)).hexdigest()}
            if lod is not None:
                read = {"lod": lod, **read}
            reads.append(read)
    return reads


def _write(out_dir: Path, name: str, data: bytes, description: str, reads: list[dict],
           arrays: GaussianScene | None = None) -> None:
    (out_dir / f"{name}.csgs").write_bytes(data)
    doc = {"schema": "csgs-vector/1", "name": name, "description": description,
           "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest(),
           "valid": all(r["outcome"] == "ok" for r in reads), "reads": reads}
    if arrays is not None:
        saved = {k: v for k, v in vars(arrays).items() if isinstance(v, np.ndarray)}
        if getattr(arrays, "instances", None) is not None:
            saved["instance_prototypes"] = arrays.instances.prototypes
            saved["instance_embeddings"] = arrays.instances.embeddings
        np.savez(out_dir / f"{name}.npz", **saved)
        doc["arrays"] = f"{name}.npz"
    (out_dir / f"{name}.json").write_text(json.dumps(doc, indent=2) + "\n")


def _invalid(data: bytes, drop: str | None = None, cut: str | None = None,
             patch: tuple[str, int, int] | None = None) -> bytes:
    """``data`` rewritten without chunk ``drop``, with chunk ``cut``'s payload halved, or
    with byte ``patch[1]`` of chunk ``patch[0]``'s payload set to ``patch[2]``."""
    container = read_layers(data, layers={"color", "semantic"})
    chunks = []
    for e in container.toc:
        payload = bytes(container.payloads[e.index])
        if e.type == drop:
            continue
        if e.type == cut:
            payload = payload[: len(payload) // 2]
        if patch is not None and e.type == patch[0]:
            changed = bytearray(payload)
            changed[patch[1]] = patch[2]
            payload = bytes(changed)
        chunks.append(Chunk(e.type, e.layer, payload, e.tile))
    return write_container(chunks)


def generate(out_dir: Path) -> None:
    """Write the scene vectors into ``out_dir``."""
    donut = read_ply(DONUT)
    for quality in (3, 7):
        # Written without the color hyperprior, as when they landed; the prior has its own
        # vectors (_color_prior_vectors).
        data = Encoder(quality=quality, hyperprior=False, **UNIFORM).encode(donut)
        _write(out_dir, f"donut_q{quality}", data,
               f"samples/donut.ply (45,624 Gaussians, SH 0) at quality {quality}",
               _reads(data))
    three = read_ply(THREE_POINTS)
    data = Encoder(quality=9, **UNIFORM).encode(three)
    _write(out_dir, "three_points_sh3_q9", data,
           "fixtures/three_points_sh3.ply (3 Gaussians, SH 3) at quality 9",
           _reads(data), arrays=Decoder().decode(data))
    small = small_semantic_scene()
    data = Encoder(quality=6, **UNIFORM).encode(small)
    _write(out_dir, "semantic_small", data,
           "40 Gaussians, SH 1, 3 semantic channels and labels, quality 6",
           _reads(data),
           arrays=Decoder().decode(data, layers="color,semantic"))
    halved = "payload cut in half (frame and CRC rewritten)"
    for name, damage, what in (
            ("truncated_opacity_payload", {"cut": "OPAC"}, f"the OPAC {halved}"),
            ("missing_opacity_chunk", {"drop": "OPAC"}, "no OPAC chunk (a critical color chunk)"),
            ("truncated_dc_payload", {"cut": "SHDC"}, f"the SHDC {halved}"),
            ("truncated_label_payload", {"cut": "SEML"},
             f"the SEML {halved}: the color layer still decodes")):
        bad = _invalid(data, **damage)
        _write(out_dir, name, bad, f"semantic_small with {what}", _reads(bad))
    _semantic_name_vectors(out_dir)
    _semantic_codebook_vectors(out_dir)
    _color_prior_vectors(out_dir, donut)
    _far_point_vectors(out_dir, donut)
    _view_pruned_vectors(out_dir, donut)
    _tiled_vectors(out_dir, donut)
    _level_vectors(out_dir, donut)
    _scored_steps_vectors(out_dir, donut)
    sh_colour_transform_vectors(out_dir)


def correlated_sh3_scene(n: int = 400, seed: int = 20) -> GaussianScene:
    """A seeded SH-3 scene whose SH bands are mostly grey (R, G and B of each coefficient
    close together), as in real captures: the encoder codes them in opponent colours."""
    rng = np.random.default_rng(seed)
    grey = rng.normal(0.0, 0.2, size=(n, 15, 1))
    rest = (grey * rng.uniform(0.8, 1.2, size=(n, 15, 3))
            + rng.normal(0.0, 0.01, size=(n, 15, 3))).astype(np.float32)
    quats = rng.normal(size=(n, 4)).astype(np.float32)
    return GaussianScene(
        positions=rng.uniform(-1, 1, size=(n, 3)).astype(np.float32),
        sh_dc=rng.normal(0.0, 0.5, size=(n, 3)).astype(np.float32), sh_rest=rest,
        opacity=rng.normal(1.0, 1.5, size=n).astype(np.float32),
        scales=rng.normal(-3.5, 0.4, size=(n, 3)).astype(np.float32), rotations=quats)


def sh_colour_transform_vectors(out_dir: Path) -> None:
    """A correlated SH-3 scene at quality 5, its bands coded in opponent colours (SHXF,
    §12.24), and damaged records: an unknown transform, a wrong band count, version 2. The
    base layer reads in each; the color layer is refused."""
    data = Encoder(quality=5, hyperprior=False).encode(correlated_sh3_scene())
    record = _chunk_payload(data, "SHXF")
    if record != bytes([1, 3, 1, 1, 1]):
        raise AssertionError(f"expected every band in opponent colours, got {record!r}")
    _write(out_dir, "sh_colour_transform_q5", data,
           "400 Gaussians, SH 3, grey-ish bands coded in opponent colours (SHXF), quality 5",
           _reads(data), arrays=Decoder().decode(data))
    cases = [("sh_colour_transform_unknown_id", bytes([1, 3, 1, 2, 1]),
              "band 2's transform made 2"),
             ("sh_colour_transform_band_count", bytes([1, 2, 1, 1]),
              "two bands listed for a scene that codes three"),
             ("sh_colour_transform_version_2", bytes([2, 3, 1, 1, 1]),
              "its version byte made 2")]
    for name, payload, what in cases:
        bad = _with_payload(data, "SHXF", payload)
        _write(out_dir, name, bad, f"sh_colour_transform_q5 with {what} (frame and CRC "
               "rewritten): the color layer is refused", _reads(bad))


def _semantic_name_vectors(out_dir: Path) -> None:
    """The frozen vector semantic_small with one semantic channel name broken (§12.16's name
    rule): its SEMF payload is the count (1 byte) then names of 1 + 10 bytes
    (``ins_feat_0``..``_2``). The color layer still reads; the semantic layer is refused at
    the broken name."""
    data = (out_dir / "semantic_small.csgs").read_bytes()
    name_at = lambda k, i: 1 + 11 * k + 1 + i  # noqa: E731 - byte i of name k in the payload
    cases = [
        ("semantic_name_duplicate", (1, 9, ord("0")), "its second name made 'ins_feat_0' too"),
        ("semantic_name_newline", (1, 8, ord("\n")),
         "its second name made 'ins_feat\\n1', which would end a PLY header early"),
        ("semantic_name_no_prefix", (2, 0, ord("x")),
         "its third name made 'xns_feat_2', which a PLY reader would not keep"),
    ]
    for name, (k, i, value), what in cases:
        bad = _invalid(data, patch=("SEMF", name_at(k, i), value))
        _write(out_dir, name, bad, f"semantic_small with {what} (frame and CRC rewritten): "
               "the color layer reads, the semantic layer is refused at that name",
               _reads(bad))


def _semantic_codebook_vectors(out_dir: Path) -> None:
    """semantic_small's scene with each Gaussian's features its label's prototype (5
    instances), so the encoder writes SEMC (§12.23), and damaged copies: a NaN prototype,
    version 2, SEMF beside SEMC, and one instance (K = 1) with an id of 1. The color layer
    reads in each; the semantic layer is refused."""
    from dataclasses import replace

    from csgs_codec.chunks.semantic_codebook import write_codebook
    from csgs_codec.format.primitives import ByteWriter

    small = small_semantic_scene()
    prototypes = np.array([[0.5, -1.25, 2.0], [0.0, 0.75, -0.5], [-2.5, 1.0, 0.25],
                           [1.5, 1.5, -1.0], [-0.75, -0.25, 3.0]], np.float32)
    scene = replace(small, semantic=prototypes[small.labels])
    current = Encoder(quality=6, **UNIFORM).encode(scene)
    data = _seml_as_landed(current)
    _write(out_dir, "semantic_codebook", data,
           "semantic_small's scene with every Gaussian's 3 features its label's prototype "
           "(5 instances): coded exactly as a semantic codebook (SEMC), quality 6",
           _reads(data), arrays=Decoder().decode(data, layers="color,semantic"))
    names = small.semantic_names
    nan = prototypes.copy()
    nan[2, 1] = np.nan
    one = ByteWriter()
    write_codebook(one, names, prototypes[:1], np.r_[np.zeros(39, np.int64), 1])
    cases = [
        ("semantic_codebook_nan_prototype", _codebook_payload(names, nan, small.labels),
         "prototype 2's second value made NaN"),
        ("semantic_codebook_version_2", b"\x02" + _chunk_payload(data, "SEMC")[1:],
         "its version byte made 2"),
        ("semantic_codebook_id_out_of_range", one.getvalue(),
         "one instance (K = 1) and the last Gaussian's id 1"),
    ]
    for name, payload, what in cases:
        bad = _with_payload(data, "SEMC", payload)
        _write(out_dir, name, bad, f"semantic_codebook with {what} (frame and CRC "
               "rewritten): the color layer reads, the semantic layer is refused", _reads(bad))
    _codebook_embedding_vectors(out_dir, scene, prototypes)
    from tests.conformance._label_runs import generate_label_runs

    generate_label_runs(out_dir, current)
    features = Encoder(quality=6, **UNIFORM).encode(small)
    both = _with_payload(data, "SEMF", _chunk_payload(features, "SEMF"), before="SEMC")
    _write(out_dir, "semantic_codebook_with_semf", both,
           "semantic_codebook with semantic_small's SEMF chunk added before its SEMC (a tile "
           "holds one or the other): the color layer reads, the semantic layer is refused",
           _reads(both))


def _codebook_embedding_vectors(out_dir: Path, scene: GaussianScene,
                                prototypes: np.ndarray) -> None:
    """semantic_codebook's scene with a 4-value embedding per instance (SEMC embeddings, for
    open-vocabulary queries), and a copy whose first embedding value is a binary16 NaN."""
    from dataclasses import replace

    from csgs_codec.scene.instance_table import InstanceTable

    embeddings = np.array([[1.0, 0.0, 0.0, 0.5], [0.0, 1.0, 0.25, 0.0],
                           [0.0, 0.0, 1.0, -0.5], [0.5, 0.5, 0.0, 0.75],
                           [-1.0, 0.0, 0.0, 0.125]], np.float32)
    data = _seml_as_landed(Encoder(quality=6, **UNIFORM).encode(
        replace(scene, instances=InstanceTable(prototypes, embeddings))))
    arrays = Decoder().decode(data, layers="color,semantic")
    _write(out_dir, "semantic_codebook_embeddings", data,
           "semantic_codebook's scene with a 4-value embedding per instance (SEMC "
           "embedding_dim 4), quality 6", _reads(data), arrays=arrays)
    payload = bytearray(_chunk_payload(data, "SEMC"))
    # version, count, three names of 1 + 10 bytes, K, format, 5 x 3 binary16, E: then values.
    at = 1 + 1 + 3 * 11 + 1 + 1 + 2 * 15 + 1
    payload[at:at + 2] = np.float16(np.nan).tobytes()
    bad = _with_payload(data, "SEMC", bytes(payload))
    _write(out_dir, "semantic_codebook_embedding_nan", bad,
           "semantic_codebook_embeddings with its first embedding value a binary16 NaN "
           "(frame and CRC rewritten): the color layer reads, the semantic layer is refused",
           _reads(bad))


def _seml_as_landed(data: bytes) -> bytes:
    """``data`` (one tile) with its SEMR chunk written back as the SEML of the same labels:
    the semantic_codebook vectors landed before revision 27, when the encoder wrote SEML
    only, and stay byte for byte as they landed."""
    from csgs_codec.chunks.semantic import label_payload

    labels = Decoder().decode(data, layers="color,semantic").labels
    container = read_layers(data, layers={"color", "semantic"})
    chunks = [Chunk("SEML", e.layer, label_payload(labels), e.tile) if e.type == "SEMR"
              else Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
              for e in container.toc]
    return write_container(chunks)


def _codebook_payload(names: tuple[str, ...], prototypes: np.ndarray, ids: np.ndarray
                      ) -> bytes:
    from csgs_codec.chunks.semantic_codebook import write_codebook
    from csgs_codec.format.primitives import ByteWriter

    out = ByteWriter()
    write_codebook(out, names, prototypes, ids)
    return out.getvalue()


def _chunk_payload(data: bytes, code: str) -> bytes:
    container = read_layers(data, layers={"color", "semantic"})
    return bytes(next(container.payloads[e.index] for e in container.toc if e.type == code))


def _with_payload(data: bytes, code: str, payload: bytes, before: str | None = None) -> bytes:
    """``data`` rewritten with chunk ``code``'s payload replaced, or, given ``before``, with a
    ``code`` chunk holding ``payload`` inserted before chunk ``before``."""
    container = read_layers(data, layers={"color", "semantic"})
    chunks = []
    for e in container.toc:
        if before is not None and e.type == before:
            chunks.append(Chunk(code, e.layer, payload, e.tile))
        own = payload if before is None and e.type == code else container.payloads[e.index]
        chunks.append(Chunk(e.type, e.layer, bytes(own), e.tile))
    return write_container(chunks)


def _color_prior_vectors(out_dir: Path, donut: GaussianScene) -> None:
    """A file with the color hyperprior (CHYP, and channels coded with its tables) and the
    same file without its CHYP chunk. A short fit on 4,000 Gaussians, kept even where the
    network costs more than it saves, so the vector stays small."""
    from csgs_codec.decisions.color_prior_choice import PriorFitPolicy
    from csgs_codec.model.color_hyperprior import ColorFitSettings

    head = donut.subset(np.arange(4000))
    policy = PriorFitPolicy(ColorFitSettings(steps=300), min_gaussians=0,
                            keep_when_larger=True)
    data = Encoder(quality=3, prior_fit=policy, **UNIFORM).encode(head)
    _write(out_dir, "color_prior_q3", data,
           "the first 4,000 Gaussians of samples/donut.ply at quality 3 with the color "
           "hyperprior (CHYP; mode-5 channels)", _reads(data))
    bad = _invalid(data, drop="CHYP")
    _write(out_dir, "color_prior_missing_chyp", bad,
           "color_prior_q3 without its CHYP chunk: mode-5 channels have no prior",
           _reads(bad))


def far_floater_scene(donut: GaussianScene) -> GaussianScene:
    """Every 30th Gaussian of samples/donut.ply (1,521), 76 of them (5%) moved far away with
    opacity -8: about 1e4 units out, every third about 1e30, and the last to (3.4e38,
    -3.4e38, 1), which only the exact list can hold."""
    scene = donut.subset(np.arange(0, len(donut), 30))
    moved = np.arange(3, len(scene), 20)
    k = np.arange(len(moved), dtype=np.float64)
    dirs = np.stack([np.cos(k), np.sin(k), np.cos(2.5 * k)], axis=1)
    distance = np.where(k % 3 == 0, 1e30, 1e4)
    scene.positions[moved] = (dirs * distance[:, None]).astype(np.float32)
    scene.positions[moved[-1]] = (3.4e38, -3.4e38, 1.0)
    scene.opacity[moved] = -8.0
    return scene


def _far_point_vectors(out_dir: Path, donut: GaussianScene) -> None:
    """A scene with far floaters (OUTQ relative-precision far points and one exact OUTL
    point), and two damaged copies: without OUTQ, and with its payload cut in half."""
    import warnings

    from csgs_codec.errors import CsgsWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CsgsWarning)  # "coded apart", expected here
        data = Encoder(quality=5, hyperprior=False, **UNIFORM).encode(
            far_floater_scene(donut))
    _write(out_dir, "far_floaters_q5", data,
           "1,521 Gaussians of samples/donut.ply, 5% moved to ~1e4 / ~1e30 (OUTQ, relative "
           "precision) and one to 3.4e38 (OUTL, exact), quality 5", _reads(data),
           arrays=Decoder().decode(data))
    for name, bad, what in (
            ("far_floaters_missing_outq", _invalid(data, drop="OUTQ"), "without its OUTQ chunk"),
            ("far_floaters_truncated_outq", _invalid(data, cut="OUTQ"),
             "with the OUTQ payload cut in half (frame and CRC rewritten)")):
        _write(out_dir, name, bad, f"far_floaters_q5 {what}", _reads(bad))


def _view_pruned_vectors(out_dir: Path, donut: GaussianScene) -> None:
    """A view-pruned encode (it carries the optional ``vdis`` record in its base layer) and
    the same file with a ``vdis`` payload of an unknown version, which a decoder that only
    decodes must skip (the chunk is optional) and ``csgs info`` must refuse."""
    head = donut.subset(np.arange(0, len(donut), 12))
    data = Encoder(quality=5, hyperprior=False, view_pruning=True, **UNIFORM).encode(head)
    _write(out_dir, "view_pruned_q5", data,
           "every 12th Gaussian of samples/donut.ply (3,802) at quality 5 with view pruning "
           "on the default sphere of views (a vdis record in the base layer)", _reads(data))
    bad = _invalid(data, patch=("vdis", 0, 9))
    _write(out_dir, "view_pruned_vdis_version_9", bad,
           "view_pruned_q5 with the vdis version byte set to 9 (frame and CRC rewritten): "
           "decoders skip the optional chunk, so the scene still decodes", _reads(bad))


def _tiled_vectors(out_dir: Path, donut: GaussianScene) -> None:
    """Tiled scenes (TIDX, §12.22): every 6th Gaussian of samples/donut.ply in 4 tiles, the
    semantic 40-Gaussian scene in 4 tiles (with arrays), and two damaged copies of the
    first: a tile count one short in the index, and a tile box that misses a Gaussian."""
    from dataclasses import replace

    from csgs_codec.chunks.tile_index import TileIndex

    head = donut.subset(np.arange(0, len(donut), 6))
    data = Encoder(quality=5, hyperprior=False, tile_size=2000, **UNIFORM).encode(head)
    _write(out_dir, "tiled_q5", data,
           "every 6th Gaussian of samples/donut.ply (7,604) at quality 5 in 4 spatial tiles "
           "of at most 2,000 (TIDX first, each tile its own SCNE/GEOM/streams)", _reads(data))
    small = Encoder(quality=6, tile_size=12, **UNIFORM).encode(small_semantic_scene())
    _write(out_dir, "tiled_semantic_small", small,
           "semantic_small's scene (40 Gaussians, SH 1, 3 semantic channels, labels) at "
           "quality 6 in 4 tiles of 10", _reads(small),
           arrays=Decoder().decode(small, layers="color,semantic"))

    def with_index(change) -> bytes:
        container = read_layers(data, layers={"color", "semantic"})
        chunks = [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
                  for e in container.toc]
        tiles = list(TileIndex.from_bytes(chunks[0].payload).tiles)
        chunks[0] = Chunk("TIDX", "base", TileIndex(tuple(change(tiles))).to_bytes())
        return write_container(chunks)

    bad = with_index(lambda t: [replace(t[0], count=t[0].count - 1)] + t[1:])
    _write(out_dir, "tiled_count_mismatch", bad,
           "tiled_q5 with tile 0's gaussian_count one less in TIDX than its SCNE declares",
           _reads(bad))
    bad = with_index(lambda t: t[:1] + [replace(t[1], upper=t[1].lower)] + t[2:])
    _write(out_dir, "tiled_box_misses_a_gaussian", bad,
           "tiled_q5 with tile 1's box in TIDX shrunk to its lower corner", _reads(bad))


def _level_vectors(out_dir: Path, donut: GaussianScene) -> None:
    """Levels of detail (TIDX version 2, §12.22): tiled_q5's scene with 3 levels, the
    semantic 40-Gaussian scene with 2 (with each level's arrays), and damaged trees."""
    from dataclasses import replace

    from csgs_codec.chunks.tile_index import TileIndex

    head = donut.subset(np.arange(0, len(donut), 6))
    data = Encoder(quality=5, hyperprior=False, tile_size=1000, levels=3,
                   **UNIFORM).encode(head)
    _write(out_dir, "levels_q5", data,
           "every 6th Gaussian of samples/donut.ply (7,604) at quality 5 with 3 levels of "
           "detail: 8 level-0 tiles of 950-951, a level-1 tile of 951 merged Gaussians and a "
           "level-2 tile of 119 (tiles 0..9, coarsest first)", _reads(data, levels=3))
    small = Encoder(quality=6, tile_size=12, levels=2, **UNIFORM).encode(
        small_semantic_scene())
    _write(out_dir, "levels_semantic_small", small,
           "semantic_small's scene (40 Gaussians, SH 1, 3 semantic channels, labels) at "
           "quality 6 with 2 levels: 4 level-0 tiles of 10 under one level-1 tile of 5; "
           "arrays: level 0; levels_semantic_small_lod1.npz: level 1", _reads(small, levels=2),
           arrays=Decoder().decode(small, layers="color,semantic"))
    coarse = Decoder().decode(small, layers="color,semantic", lod=1)
    np.savez(out_dir / "levels_semantic_small_lod1.npz",
             **{k: v for k, v in vars(coarse).items() if isinstance(v, np.ndarray)})

    def with_raw_index(change) -> bytes:
        container = read_layers(data, layers={"color", "semantic"})
        chunks = [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
                  for e in container.toc]
        tiles = change(list(TileIndex.from_bytes(chunks[0].payload).tiles))
        out = bytearray([2, len(tiles)])
        for t in tiles:
            out += _entry_bytes(t)
        chunks[0] = Chunk("TIDX", "base", bytes(out))
        return write_container(chunks)

    bad = with_raw_index(lambda t: t[:2] + [replace(t[2], parent=None)] + t[3:])
    _write(out_dir, "levels_leaf_without_parent", bad,
           "levels_q5 with level-0 tile 2's parent cleared in TIDX", _reads(bad))
    bad = with_raw_index(lambda t: t[:2] + [replace(t[2], parent=0)] + t[3:])
    _write(out_dir, "levels_parent_two_levels_up", bad,
           "levels_q5 with level-0 tile 2's parent set to the level-2 tile 0", _reads(bad))
    bad = with_raw_index(lambda t: t[:1] + [replace(t[1], level=0)] + t[2:])
    _write(out_dir, "levels_tile_level_changed", bad,
           "levels_q5 with tile 1 (level 1, the parent of tiles 2-9) marked level 0",
           _reads(bad))


def _entry_bytes(tile) -> bytes:
    """One version-2 TIDX entry as written (count, box, level, parent)."""
    from csgs_codec.format.primitives import ByteWriter

    out = ByteWriter()
    out.varint(tile.count)
    out.array(np.asarray(tile.lower + tile.upper, np.float32), "<f4")
    out.fixed("u8", tile.level)
    out.varint(0 if tile.parent is None else tile.parent + 1)
    return out.getvalue()


def _scored_steps_vectors(out_dir: Path, donut: GaussianScene) -> None:
    """An encode whose rotation channels use scored steps (cells of two scores of the
    decoded log-scales and opacity: the default); the same file with its first score weight
    set to NaN, which decoders reject at the first weight's offset; and with a reserved bit
    of its first coded ROTN channel's ``coding`` byte set, rejected at that byte."""
    head = donut.subset(np.arange(0, len(donut), 10))
    data = Encoder(quality=5, hyperprior=False, rotation_steps="footprint").encode(head)
    _write(out_dir, "scored_steps_q5", data,
           "every 10th Gaussian of samples/donut.ply (4,563) at quality 5 with rotation steps "
           "from the decoded area, opacity and anisotropy (ROTN channels with scored steps)",
           _reads(data), arrays=Decoder().decode(data))
    top_byte = _after_rotn_step_index(data) + 3  # f32 little-endian: 0x7fc is a quiet NaN
    bad = _invalid(_invalid(data, patch=("ROTN", top_byte, 0x7F)),
                   patch=("ROTN", top_byte - 1, 0xC0))
    _write(out_dir, "scored_steps_nan_weight", bad,
           "scored_steps_q5 with channel 0's first ROTN score weight set to NaN (frame and "
           "CRC rewritten): invalid, reported at that weight", _reads(bad))
    rotn = read_layers(data, layers={"color"}).single_payload("ROTN")[0]
    at = rotation_coding_offset(rotn)
    coding = rotn[at]
    bad = _invalid(data, patch=("ROTN", at, coding | 0x04))
    _write(out_dir, "coding_reserved_bit", bad,
           "scored_steps_q5 with bit 2 (reserved) of its first coded ROTN channel's coding "
           "byte set (frame and CRC rewritten): invalid, reported at that byte", _reads(bad))


def _after_rotn_step_index(data: bytes) -> int:
    """Offset in the ROTN payload of ``data`` where its first coded channel's score table
    starts (a channel with scored steps)."""
    r = ByteReader(read_layers(data, layers={"color"}).single_payload("ROTN")[0])
    rotation_class_table(r)
    return r.offset
