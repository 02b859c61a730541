"""The ``SEMC`` chunk (spec/FORMAT.md §12.23), both directions: semantic features that take few
distinct values, coded exactly as a codebook and one instance id per Gaussian.

What ``csgs segment`` writes is of this kind: every Gaussian carries its instance's prototype
feature, so the features are K distinct rows (K <= 255). The chunk holds the K prototypes as
float16 when every value is one exactly (``csgs segment`` rounds them so: its per-instance
embeddings can be long), else float32, and the ids in the file's Gaussian order as two
categorical streams (§12.18): one flag per Gaussian after the first, 1 when its id equals the
previous Gaussian's, and the ids of the first Gaussian and of every Gaussian whose flag is 0.
Gaussians are in Morton order (§12.4), so neighbours mostly share an instance: on fruit_drops
(4,721 real Gaussians, 9 instances) the ids cost 0.46 bits each against 3.03 for one table over
the ids.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.chunks.semantic_names import names_from_bytes, names_to_bytes
from csgs_codec.entropy.categorical import decode_categorical, encode_categorical
from csgs_codec.errors import InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter
from csgs_codec.scene.instance_table import MAX_EMBEDDING_DIM, MAX_EMBEDDING_VALUE, InstanceTable

#: Payload layout version (the only one).
VERSION = 1
#: Most instances a codebook holds (one categorical symbol each).
MAX_INSTANCES = 255
#: ``prototype_format`` values: how the prototype table is stored.
FLOAT32, FLOAT16 = 0, 1


def codebook_of(features: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """((K, S) float32 distinct rows in increasing order, (N,) int64 row of each Gaussian)
    when the (N, S) features take 1..:data:`MAX_INSTANCES` distinct values, else None."""
    features = np.asarray(features, np.float32)
    if features.ndim != 2 or features.shape[0] == 0 or features.shape[1] == 0:
        return None
    # Distinct bit patterns, so -0.0 and 0.0 stay apart and decode exactly as written.
    bits = np.ascontiguousarray(features).view(np.uint32)
    rows, first, inverse = np.unique(bits, axis=0, return_index=True, return_inverse=True)
    if len(rows) > MAX_INSTANCES:
        return None
    return features[first], inverse.reshape(-1).astype(np.int64)


def instance_embeddings(scene, codebook: tuple[np.ndarray, np.ndarray] | None
                        ) -> np.ndarray | None:
    """(K, E) embeddings of the codebook's prototypes from ``scene.instances``, or None when
    the scene has no instance table.

    Raises:
        InputError: a table whose features are not few distinct rows, or a feature row the
            table has no embedding for.
    """
    table = getattr(scene, "instances", None)
    if table is None:
        return None
    if codebook is None:
        raise InputError(f"instance embeddings need features of at most {MAX_INSTANCES} "
                         "distinct rows (one per instance)", property="instances")
    rows = table.rows_of(codebook[0])
    if (rows < 0).any():
        raise InputError("a semantic feature row has no instance embedding",
                         property="instances")
    return table.embeddings[rows]


def write_codebook(out: ByteWriter, names: tuple[str, ...], prototypes: np.ndarray,
                   ids: np.ndarray, embeddings: np.ndarray | None = None) -> np.ndarray | None:
    """Append the SEMC payload: ``names`` (S), (K, S) float32 ``prototypes``, (N,) ids in
    [0, K) and optionally (K, E) per-instance ``embeddings`` (stored as binary16).

    Returns:
        The (K, E) float32 embeddings as a decoder reads them back (rounded to binary16), or
        None.
    """
    prototypes = np.asarray(prototypes, np.float32)
    ids = np.asarray(ids, np.int64)
    half = prototypes.astype(np.float16)
    exact = np.array_equal(half.astype(np.float32).view(np.uint32), prototypes.view(np.uint32))
    out.fixed("u8", VERSION)
    names_to_bytes(out, names)
    out.varint(len(prototypes))
    out.fixed("u8", FLOAT16 if exact else FLOAT32)
    if exact:
        out.array(half.reshape(-1), "<f2")
    else:
        out.array(prototypes.reshape(-1), "<f4")
    stored = None
    if embeddings is None:
        out.varint(0)
    else:
        embeddings = np.asarray(embeddings, np.float32)
        if not np.isfinite(embeddings).all() or (
                embeddings.size and float(np.abs(embeddings).max()) > MAX_EMBEDDING_VALUE):
            raise InputError(f"embeddings must be finite with magnitudes up to "
                             f"{MAX_EMBEDDING_VALUE:g} (binary16)", chunk="SEMC",
                             property="embeddings")
        half_embeddings = embeddings.astype(np.float16)
        out.varint(half_embeddings.shape[1])
        out.array(half_embeddings.reshape(-1), "<f2")
        stored = half_embeddings.astype(np.float32)
    same = (ids[1:] == ids[:-1]).astype(np.int64)
    starts = ids[np.r_[True, same == 0]] if ids.size else ids
    out.byte_string(encode_categorical(same, 2))
    out.byte_string(encode_categorical(starts, max(len(prototypes), 2)))
    return stored


def read_codebook(r: ByteReader, count: int, max_channels: int
                  ) -> tuple[tuple[str, ...], np.ndarray, InstanceTable | None]:
    """Read a SEMC payload for ``count`` Gaussians: (names, (count, S) float32 features, the
    instance table when the payload carries embeddings).

    Raises:
        FormatError: any field that breaks §12.23, at its offset.
    """
    return read_codebook_with_ids(r, count, max_channels)[:3]


def read_codebook_with_ids(r: ByteReader, count: int, max_channels: int
                           ) -> tuple[tuple[str, ...], np.ndarray, InstanceTable | None,
                                      np.ndarray, int]:
    """:func:`read_codebook` followed by the (count,) int64 instance ids and the instance
    count K (a tile's ``SEMR`` may map them to labels, §12.25).

    Raises:
        FormatError: any field that breaks §12.23, at its offset.
    """
    version = r.fixed("u8", "version")
    if version != VERSION:
        raise r.error(f"SEMC version {version} is not {VERSION}", r.offset - 1)
    names = names_from_bytes(r, max_channels)
    if not names:
        raise r.error("a codebook needs at least one channel")
    at = r.offset
    instances = r.varint("instance_count", maximum=1 << 32)
    if not 1 <= instances <= MAX_INSTANCES:
        raise r.error(f"instance_count {instances} is outside 1..{MAX_INSTANCES}", at)
    at = r.offset
    layout = r.fixed("u8", "prototype_format")
    if layout not in (FLOAT32, FLOAT16):
        raise r.error(f"prototype_format {layout} is not 0 (float32) or 1 (float16)", at)
    at = r.offset
    kind = "<f4" if layout == FLOAT32 else "<f2"
    prototypes = r.array(instances * len(names), kind, "prototypes").astype(np.float32)
    if not np.isfinite(prototypes).all():
        raise r.error("a prototype value is not finite", at)
    prototypes = prototypes.reshape(instances, len(names))
    if len(np.unique(prototypes.view(np.uint32), axis=0)) != instances:
        raise r.error("two prototype rows are equal (each instance has its own)", at)
    at = r.offset
    width = r.varint("embedding_dim", maximum=1 << 32)
    if width > MAX_EMBEDDING_DIM:
        raise r.error(f"embedding_dim {width} is above {MAX_EMBEDDING_DIM}", at)
    table = None
    if width:
        at = r.offset
        embeddings = r.array(instances * width, "<f2", "embeddings").astype(np.float32)
        if not np.isfinite(embeddings).all():
            raise r.error("an embedding value is not finite", at)
        table = InstanceTable(prototypes, embeddings.reshape(instances, width))
    same_bytes = r.byte_string("same_stream")
    same = decode_categorical(same_bytes, max(count - 1, 0), chunk=r.chunk,
                              base_offset=r.offset - len(same_bytes), alphabet=2)
    starts_count = 0 if count == 0 else 1 + int(np.count_nonzero(same == 0))
    at = r.offset
    start_bytes = r.byte_string("id_stream")
    starts = decode_categorical(start_bytes, starts_count, chunk=r.chunk,
                                base_offset=r.offset - len(start_bytes),
                                alphabet=max(instances, 2))
    if starts.size and starts.max() >= instances:
        raise r.error(f"an instance id is not below instance_count {instances}", at)
    r.expect_end("the SEMC payload")
    ids = np.empty(count, np.int64)
    if count:
        # Each run of equal ids starts where a flag is 0 (and at Gaussian 0).
        run = np.cumsum(np.r_[1, (same == 0).astype(np.int64)]) - 1
        ids = starts[run]
    return names, prototypes[ids], table, ids, instances

