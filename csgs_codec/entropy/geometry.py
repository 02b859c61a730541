"""Lossless geometry coding: quantized integer positions <-> bytes (spec/FORMAT.md §15).

Positions on a ``2^bits`` grid per axis are coded as an octree, level by level. Every node
that is the only child of its parent (and the root) first says with a flag whether it holds a
single distinct position; if so, the rest of that position is written as raw bits ("direct
mode"). Other nodes code their 8-bit child occupancy, turned into the node's own frame
(mirrored and axis-sorted by its occupied face siblings), with an adaptive integer model
chosen by how many face siblings are occupied and how many siblings there are. Each level's
symbols are coded in blocks of doubling size; within a block, symbols that share a context go
through one range-coder call, and the counts adapt between blocks. Repeated positions are
counted in a sparse list. The decoder returns points sorted by Morton code, the canonical
order.
"""

from __future__ import annotations

import constriction
import numpy as np

from csgs_codec.entropy.geometry_bytes import (
    field_bits,
    read_fields,
    read_varint,
    read_varints,
    write_varint,
    write_varints,
)
from csgs_codec.entropy.geometry_models import AdaptiveCounts, decode_grouped, encode_grouped
from csgs_codec.entropy.geometry_octree import (
    FLAG_CONTEXTS,
    OCCUPANCY_CONTEXTS,
    Nodes,
    direct_eligible,
    flag_contexts,
    occupancy_contexts,
    occupancy_to_symbols,
    symbols_to_occupancy,
)
from csgs_codec.entropy.morton import MAX_BITS, morton_decode, morton_encode
from csgs_codec.errors import FormatError, InputError

#: Version byte at the start of every geometry payload.
GEOMETRY_VERSION = 1
#: Default limit on the number of points a decoder accepts (it may lower it).
MAX_POINTS = 1 << 26


def canonical_order(q: np.ndarray, bits: int) -> np.ndarray:
    """Permutation putting points in the order :func:`decode_positions` returns them.

    Args:
        q: (N, 3) integer positions, each in ``[0, 2^bits)``.
        bits: bits per axis, 0..21.

    Returns:
        (N,) int64 ``perm`` with ``decode_positions(encode_positions(q, bits)) == q[perm]``:
        increasing Morton code, equal positions in their input order.
    """
    codes = morton_encode(_checked_positions(q, bits))
    return np.argsort(codes, kind="stable")


def encode_positions(q: np.ndarray, bits: int) -> bytes:
    """Encode integer positions losslessly (as a multiset, duplicates counted).

    Args:
        q: (N, 3) integers (any integer dtype), each in ``[0, 2^bits)``.
        bits: bits per axis, 0..21.

    Returns:
        The geometry payload (spec/FORMAT.md §15).

    Raises:
        InputError: wrong shape or dtype, ``bits`` out of range, or a coordinate off the grid.
    """
    codes = morton_encode(_checked_positions(q, bits))
    out = bytearray([GEOMETRY_VERSION, bits])
    out += write_varint(codes.shape[0])
    if codes.shape[0] == 0:
        return bytes(out)
    distinct, counts = np.unique(codes, return_counts=True)
    out += write_varint(distinct.shape[0])
    if distinct.shape[0] < codes.shape[0]:
        repeated = np.flatnonzero(counts > 1)
        gaps = np.diff(np.concatenate(([-1], repeated))) - 1
        out += write_varint(repeated.shape[0])
        out += write_varints(gaps)
        out += write_varints(counts[repeated] - 2)
    words, raw_bits = _encode_tree(distinct, bits)
    out += write_varint(words.shape[0])
    out += words.astype("<u4").tobytes()
    out += np.packbits(raw_bits).tobytes()
    return bytes(out)


def decode_positions(data: bytes, max_points: int = MAX_POINTS) -> np.ndarray:
    """Decode a geometry payload.

    Args:
        data: the payload written by :func:`encode_positions`.
        max_points: refuse payloads that declare more points than this.

    Returns:
        (N, 3) uint32 positions in canonical order (increasing Morton code).

    Raises:
        FormatError: the payload is malformed (with the byte offset where that is meaningful).
    """
    data = bytes(data)
    if len(data) < 2:
        raise FormatError("geometry: payload shorter than its 2-byte header", offset=0)
    if data[0] != GEOMETRY_VERSION:
        raise FormatError(f"geometry: unknown version {data[0]}", offset=0)
    bits = data[1]
    if bits > MAX_BITS:
        raise FormatError(f"geometry: {bits} bits per axis exceeds {MAX_BITS}", offset=1)
    n_points, pos = read_varint(data, 2, "point count")
    if n_points > max_points:
        raise FormatError(f"geometry: {n_points} points exceed the limit {max_points}", offset=2)
    if n_points == 0:
        _expect_end(data, pos)
        return np.zeros((0, 3), np.uint32)
    n_distinct, at = read_varint(data, pos, "distinct count")
    if not 1 <= n_distinct <= min(n_points, 1 << (3 * bits)):
        raise FormatError(f"geometry: distinct count {n_distinct} out of range", offset=pos)
    counts, pos = _read_repeats(data, at, n_points, n_distinct)
    n_words, at = read_varint(data, pos, "range-coder word count")
    if n_words * 4 > len(data) - at:
        raise FormatError("geometry: range-coder data runs past the payload", offset=pos)
    words = np.frombuffer(data, "<u4", count=n_words, offset=at).astype(np.uint32)
    raw_offset = at + 4 * n_words
    raw = np.frombuffer(data, np.uint8, offset=raw_offset)
    distinct = _decode_tree(words, raw, raw_offset, bits, n_distinct)
    codes = distinct if counts is None else np.repeat(distinct, counts)
    return morton_decode(codes)


def _checked_positions(q: np.ndarray, bits: int) -> np.ndarray:
    """Validate encoder input; returns (N, 3) int64."""
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not (
            0 <= bits <= MAX_BITS):
        raise InputError(f"geometry: bits per axis must be an integer in 0..{MAX_BITS}, "
                         f"got {bits!r}")
    arr = np.asarray(q)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"geometry: positions must have shape (N, 3), got {arr.shape}")
    if arr.shape[0] and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"geometry: positions must be integers, got {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.size and (arr.min() < 0 or arr.max() >= 1 << bits):
        bad = int(np.flatnonzero(((arr < 0) | (arr >= 1 << bits)).any(axis=1))[0])
        raise InputError(f"geometry: position {arr[bad].tolist()} is off the {bits}-bit grid",
                         index=bad)
    return arr


def _expect_end(data: bytes, pos: int) -> None:
    if pos != len(data):
        raise FormatError("geometry: trailing bytes after the payload", offset=pos)


def _read_repeats(data: bytes, pos: int, n_points: int, n_distinct: int):
    """Read the repeat list; returns ((D,) counts or None when all are 1, offset after it)."""
    if n_distinct == n_points:
        return None, pos
    n_repeated, at = read_varint(data, pos, "repeat count")
    if not 1 <= n_repeated <= min(n_distinct, n_points - n_distinct):
        raise FormatError(f"geometry: repeat count {n_repeated} out of range", offset=pos)
    gaps, at2 = read_varints(data, at, n_repeated, "repeat gaps")
    extra, end = read_varints(data, at2, n_repeated, "repeat counts")
    if gaps.max() >= n_distinct or extra.max() >= n_points:
        raise FormatError("geometry: repeat entry out of range", offset=at)
    index = np.cumsum(gaps.astype(np.int64) + 1) - 1
    if index[-1] >= n_distinct:
        raise FormatError("geometry: repeat index past the distinct points", offset=at)
    if int(extra.astype(np.int64).sum()) + n_repeated != n_points - n_distinct:
        raise FormatError("geometry: repeat counts do not add up to the point count", offset=at2)
    counts = np.ones(n_distinct, np.int64)
    counts[index] += extra.astype(np.int64) + 1
    return counts, end


def _encode_tree(distinct: np.ndarray, bits: int) -> tuple[np.ndarray, np.ndarray]:
    """Code sorted distinct Morton codes; returns (range-coder words uint32, raw bits uint8)."""
    encoder = constriction.stream.queue.RangeEncoder()
    flag_stats = AdaptiveCounts(FLAG_CONTEXTS, 2)
    occ_stats = AdaptiveCounts(OCCUPANCY_CONTEXTS, 255)
    raw_parts = []
    nodes = Nodes.root()
    points = distinct
    for level in range(bits):
        remaining = bits - level
        prefixes = points >> np.uint64(3 * remaining)
        starts = np.flatnonzero(np.concatenate(([True], prefixes[1:] != prefixes[:-1])))
        sizes = np.diff(np.concatenate((starts, [points.shape[0]])))
        eligible = direct_eligible(nodes, level)
        flags = (sizes[eligible] == 1).astype(np.int64)
        contexts = flag_contexts(nodes, level)[eligible]
        flag_stats.age()
        encode_grouped(encoder, flags, contexts, flag_stats)
        direct = np.zeros(len(nodes), bool)
        direct[eligible] = flags == 1
        if direct.any():
            low = np.uint64((1 << (3 * remaining)) - 1)
            raw_parts.append(field_bits(points[starts[direct]] & low, 3 * remaining))
            points = points[np.repeat(~direct, sizes)]
            nodes = nodes.subset(~direct)
            sizes = sizes[~direct]
        if len(nodes) == 0:
            break
        child = ((points >> np.uint64(3 * remaining - 3)) & np.uint64(7)).astype(np.uint8)
        node_starts = np.cumsum(sizes) - sizes
        occupancy = np.bitwise_or.reduceat(np.left_shift(1, child, dtype=np.uint8), node_starts)
        symbols = occupancy_to_symbols(nodes, occupancy)
        contexts = occupancy_contexts(nodes, level)
        occ_stats.age()
        encode_grouped(encoder, symbols, contexts, occ_stats)
        nodes = nodes.children(occupancy)
    raw = np.concatenate(raw_parts) if raw_parts else np.zeros(0, np.uint8)
    return encoder.get_compressed(), raw


def _decode_tree(words: np.ndarray, raw: np.ndarray, raw_offset: int, bits: int,
                 n_distinct: int) -> np.ndarray:
    """Decode the octree; returns (D,) sorted uint64 distinct Morton codes."""
    decoder = constriction.stream.queue.RangeDecoder(words)
    flag_stats = AdaptiveCounts(FLAG_CONTEXTS, 2)
    occ_stats = AdaptiveCounts(OCCUPANCY_CONTEXTS, 255)
    found = []
    n_found = 0
    raw_bit = 0
    nodes = Nodes.root()
    for level in range(bits):
        remaining = bits - level
        eligible = direct_eligible(nodes, level)
        contexts = flag_contexts(nodes, level)[eligible]
        flag_stats.age()
        flags = decode_grouped(decoder, contexts, flag_stats)
        direct = np.zeros(len(nodes), bool)
        direct[eligible] = flags == 1
        n_direct = int(direct.sum())
        if n_direct:
            width = 3 * remaining
            if raw_bit + n_direct * width > 8 * raw.shape[0]:
                raise FormatError("geometry: raw position bits run past the payload",
                                  offset=raw_offset + raw_bit // 8)
            low = read_fields(raw, raw_bit, n_direct, width)
            raw_bit += n_direct * width
            found.append((nodes.codes[direct] << np.uint64(width)) | low)
            n_found += n_direct
            nodes = nodes.subset(~direct)
        if len(nodes) == 0:
            break
        contexts = occupancy_contexts(nodes, level)
        occ_stats.age()
        symbols = decode_grouped(decoder, contexts, occ_stats)
        nodes = nodes.children(symbols_to_occupancy(nodes, symbols))
        if n_found + len(nodes) > n_distinct:
            raise FormatError("geometry: octree holds more points than the distinct count",
                              offset=raw_offset)
    if len(nodes):
        found.append(nodes.codes)
        n_found += len(nodes)
    if n_found != n_distinct:
        raise FormatError(f"geometry: octree holds {n_found} points, header says {n_distinct}",
                          offset=raw_offset)
    if (raw_bit + 7) // 8 != raw.shape[0]:
        raise FormatError("geometry: raw section length does not match its bits",
                          offset=raw_offset)
    if raw_bit % 8 and raw[-1] & ((1 << (8 - raw_bit % 8)) - 1):
        raise FormatError("geometry: nonzero padding bits", offset=raw_offset + raw.shape[0] - 1)
    return np.sort(np.concatenate(found), kind="stable")  # merges sorted runs
