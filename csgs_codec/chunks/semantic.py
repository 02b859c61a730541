"""The semantic layer's chunks of a standard scene (FORMAT §12.16-12.18), both directions:
SEMF (channel names + a float stream of the features), SEMC (a codebook of distinct feature
rows, :mod:`csgs_codec.chunks.semantic_codebook`) and integer labels: SEML (one residual
stream with step 1, lossless) or SEMR (runs, or a map of the SEMC instances,
:mod:`csgs_codec.chunks.label_runs`), whichever is smaller; anchor scenes use the same
payloads.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.attributes.float_stream import read_float_stream, write_float_stream
from csgs_codec.chunks.checks import check_finite
from csgs_codec.chunks.label_runs import (
    instance_mapping,
    mapping_payload,
    read_runs_payload,
    runs_payload,
)
from csgs_codec.chunks.semantic_codebook import read_codebook_with_ids
from csgs_codec.chunks.semantic_names import MAX_SEMANTIC_CHANNELS, names_from_bytes, names_to_bytes
from csgs_codec.entropy.residual import decode_symbols, encode_symbols
from csgs_codec.entropy.table_choice import best_table
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter
from csgs_codec.scene.gaussian_scene import GaussianScene


def feature_payload(names: tuple[str, ...], features: np.ndarray,
                    step: float) -> tuple[bytes, np.ndarray]:
    """(SEMF payload, the features as decoded (N, S) float32) of ``features`` (N, S) coded
    with quantization step ``step``, their channels named ``names``."""
    out = ByteWriter()
    names_to_bytes(out, names)
    decoded = write_float_stream(out, features, step)
    return out.getvalue(), decoded


def read_feature_payload(data: bytes, offset: int,
                         count: int) -> tuple[tuple[str, ...], np.ndarray]:
    """(channel names, (count, S) float32 features) of a SEMF payload at absolute byte
    ``offset``.

    Raises:
        FormatError: naming SEMF and the byte offset.
    """
    r = ByteReader(data, base_offset=offset, chunk="SEMF")
    names = names_from_bytes(r, MAX_SEMANTIC_CHANNELS)
    values = read_float_stream(r, count, len(names))
    r.expect_end("the semantic feature stream")
    check_finite(values, "SEMF")
    return names, values


def label_payload(labels: np.ndarray) -> bytes:
    """The SEML payload of ``labels`` (N,) int: the median as base, then the residuals
    with the frozen table that codes them smallest."""
    labels = np.asarray(labels, np.int64)
    base = int(np.median(labels)) if labels.size else 0
    residuals = labels - base
    table = best_table(residuals)
    out = ByteWriter()
    out.svarint(base)
    out.fixed("u8", table)
    out.byte_string(encode_symbols(residuals, np.full(labels.size, table, np.int64)))
    return out.getvalue()


def smallest_label_chunk(labels: np.ndarray, instances: tuple[np.ndarray, int] | None = None
                         ) -> tuple[str, bytes]:
    """(chunk type, payload) of the smallest lossless coding of (N,) int ``labels``: SEML,
    SEMR runs, or SEMR as a map of ``instances`` ((N,) ids, instance count K) when the tile
    writes those ids in SEMC and the labels are a function of them. Ties keep SEML."""
    best = ("SEML", label_payload(labels))
    candidates = [runs_payload(labels) if len(labels) else None]
    if instances is not None and len(labels):
        mapping = instance_mapping(labels, *instances)
        if mapping is not None:
            candidates.append(mapping_payload(mapping))
    for payload in candidates:
        if payload is not None and len(payload) < len(best[1]):
            best = ("SEMR", payload)
    return best


def read_label_payload(data: bytes, offset: int, count: int) -> np.ndarray:
    """(count,) int32 labels of a SEML payload at absolute byte ``offset``.

    Raises:
        FormatError: naming SEML and the byte offset (a table index above 63, a stream
            that does not hold ``count`` labels, a label outside int32).
    """
    r = ByteReader(data, base_offset=offset, chunk="SEML")
    base = r.svarint("label_base")
    at = r.offset
    table = r.fixed("u8", "scale_index")
    if table >= 64:
        raise r.error(f"scale index {table} out of range", at=at)
    stream = r.byte_string("label_stream")
    r.expect_end("the label stream")
    labels = decode_symbols(stream, np.full(count, table, np.int64), chunk="SEML",
                            base_offset=r.offset - len(stream)) + base
    if labels.size and (labels.min() < -(1 << 31) or labels.max() >= 1 << 31):
        raise r.error("label outside the int32 range")
    return labels.astype(np.int32)


def read_semantic_layer(container, count: int, scene: GaussianScene) -> None:
    """Set ``scene``'s semantic features, channel names, instances and labels from the
    semantic chunks of ``container`` (a tile's, ``count`` Gaussians); absent chunks leave
    their fields as they are.

    Raises:
        FormatError: naming the chunk and byte offset (also when SEMF and SEMC are both
            there).
    """
    present = {e.type for e in container.toc}
    instances = None
    if "SEMF" in present:
        scene.semantic_names, scene.semantic = read_feature_payload(
            *container.single_payload("SEMF"), count)
    if "SEMC" in present:
        data, offset = container.single_payload("SEMC")
        if "SEMF" in present:
            raise FormatError("a tile holds both SEMF and SEMC", chunk="SEMC", offset=offset)
        r = ByteReader(data, base_offset=offset, chunk="SEMC")
        scene.semantic_names, scene.semantic, scene.instances, ids, k = read_codebook_with_ids(
            r, count, MAX_SEMANTIC_CHANNELS)
        instances = (ids, k)
    labels = read_labels(container, count, instances)
    if labels is not None:
        scene.labels = labels


def read_labels(container, count: int, instances: tuple[np.ndarray, int] | None = None
                ) -> np.ndarray | None:
    """(count,) int32 labels of ``container``'s SEML or SEMR (a tile's, or an anchor
    scene's with ``count`` anchors); None when it holds neither. ``instances`` are the
    tile's SEMC ids (count,) and instance count, None when it has no SEMC.

    Raises:
        FormatError: naming SEML or SEMR and the byte offset (also when a tile holds both).
    """
    present = {e.type for e in container.toc}
    if "SEMR" in present:
        data, offset = container.single_payload("SEMR")
        if "SEML" in present:
            raise FormatError("a tile holds both SEML and SEMR", chunk="SEMR", offset=offset)
        return read_runs_payload(ByteReader(data, base_offset=offset, chunk="SEMR"), count,
                                 instances)
    if "SEML" not in present:
        return None
    return read_label_payload(*container.single_payload("SEML"), count)
