"""The ``SEMR`` chunk (spec/FORMAT.md §12.25), both directions: integer labels coded as runs.

Gaussians are in Morton order (§12.4), so neighbours mostly share a label, and the instance
ids of ``SEMC`` (§12.23) are coded as runs for that reason. ``SEMR`` codes labels the same way:
a table of the K distinct labels and, per Gaussian, the index of its label in two categorical
streams (same-as-previous flags, and the indices where they change). When every instance of
the tile's ``SEMC`` has one label, ``SEMR`` instead holds just that mapping (one label per
instance) and no stream at all.

``SEML`` (§12.17) stays: :func:`csgs_codec.chunks.semantic.smallest_label_chunk` measures
every coding and keeps the smallest, so no file grows.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.entropy.categorical import decode_categorical, encode_categorical
from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Payload layout version (the only one).
VERSION = 1
#: ``source`` values: labels from their own runs, or from the tile's SEMC instance ids.
RUNS, INSTANCES = 0, 1
#: Most distinct labels the runs coding holds (one categorical symbol each).
MAX_VALUES = 255
_INT32 = (-(1 << 31), (1 << 31) - 1)


def instance_mapping(labels: np.ndarray, ids: np.ndarray, instance_count: int
                     ) -> np.ndarray | None:
    """(K,) int64 label of each of ``instance_count`` instances when (N,) ``labels`` are a
    function of the (N,) instance ``ids`` in [0, K), else None (an instance no Gaussian has
    gets label 0)."""
    labels = np.asarray(labels, np.int64)
    ids = np.asarray(ids, np.int64)
    mapping = np.zeros(instance_count, np.int64)
    mapping[ids] = labels  # any one Gaussian's label per instance; checked below
    return mapping if np.array_equal(mapping[ids], labels) else None


def runs_payload(labels: np.ndarray) -> bytes | None:
    """The ``SEMR`` payload coding (N,) int ``labels`` (N >= 1) as runs, or None when they
    take more than :data:`MAX_VALUES` distinct values (or none: N = 0)."""
    labels = np.asarray(labels, np.int64)
    values, index = np.unique(labels, return_inverse=True)
    if not 1 <= len(values) <= MAX_VALUES:
        return None
    index = index.reshape(-1)
    out = _header(RUNS, values)
    same = (index[1:] == index[:-1]).astype(np.int64)
    out.byte_string(encode_categorical(same, 2))
    out.byte_string(encode_categorical(index[np.r_[True, same == 0]], max(len(values), 2)))
    return out.getvalue()


def mapping_payload(mapping: np.ndarray) -> bytes:
    """The ``SEMR`` payload whose labels are ``mapping`` (K,) int indexed by the tile's
    ``SEMC`` instance ids."""
    return _header(INSTANCES, np.asarray(mapping, np.int64)).getvalue()


def _header(source: int, values: np.ndarray) -> ByteWriter:
    out = ByteWriter()
    out.fixed("u8", VERSION)
    out.fixed("u8", source)
    out.varint(len(values))
    for value in values.tolist():
        out.svarint(value)
    return out


def read_runs_payload(r: ByteReader, count: int,
                      instances: tuple[np.ndarray, int] | None) -> np.ndarray:
    """(count,) int32 labels of the ``SEMR`` payload ``r`` reads (to its end);
    ``instances`` are the tile's ``SEMC`` ids (count,) and instance count K, None when the
    tile has no ``SEMC``.

    Raises:
        FormatError: naming ``r``'s chunk and the byte offset of the field that breaks
            §12.25.
    """
    version = r.fixed("u8", "version")
    if version != VERSION:
        raise r.error(f"SEMR version {version} is not {VERSION}", r.offset - 1)
    at = r.offset
    source = r.fixed("u8", "source")
    if source not in (RUNS, INSTANCES):
        raise r.error(f"source {source} is not 0 (runs) or 1 (instances)", at)
    if source == INSTANCES and instances is None:
        raise r.error("source 1 (instances) in a tile without SEMC", at)
    at = r.offset
    value_count = r.varint("value_count", maximum=1 << 32)
    if source == RUNS and not 1 <= value_count <= MAX_VALUES:
        raise r.error(f"value_count {value_count} is outside 1..{MAX_VALUES}", at)
    if source == INSTANCES and value_count != instances[1]:
        raise r.error(f"value_count {value_count} is not the SEMC instance_count "
                      f"{instances[1]}", at)
    values = np.empty(value_count, np.int64)
    for k in range(value_count):
        at = r.offset
        values[k] = r.svarint("value")
        if not _INT32[0] <= values[k] <= _INT32[1]:
            raise r.error("label outside the int32 range", at)
        if source == RUNS and k and values[k] <= values[k - 1]:
            raise r.error("values are not strictly increasing", at)
    if source == INSTANCES:
        r.expect_end("the SEMR payload")
        return values[instances[0]].astype(np.int32)
    same_bytes = r.byte_string("same_stream")
    same = decode_categorical(same_bytes, max(count - 1, 0), chunk=r.chunk,
                              base_offset=r.offset - len(same_bytes), alphabet=2)
    at = r.offset
    index_bytes = r.byte_string("index_stream")
    starts = decode_categorical(index_bytes, 0 if count == 0 else 1 + int(np.sum(same == 0)),
                                chunk=r.chunk, base_offset=r.offset - len(index_bytes),
                                alphabet=max(value_count, 2))
    if starts.size and starts.max() >= value_count:
        raise r.error(f"an index is not below value_count {value_count}", at)
    r.expect_end("the SEMR payload")
    if count == 0:
        return np.empty(0, np.int32)
    run = np.cumsum(np.r_[1, (same == 0).astype(np.int64)]) - 1
    return values[starts[run]].astype(np.int32)
