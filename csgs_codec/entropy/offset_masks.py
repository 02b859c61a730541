"""Offset masks (M, K) bool with a static context model: bit k of an anchor is coded with
the table of context (k, j), j = how many of the anchor's slots before k are kept.

Stream (spec/FORMAT.md §17.6): varint M | u8 K | K(K+1)/2 u16 frequencies f1 of "kept" (in
[1, 65535], context (k, j) at index k(k+1)/2 + j, made by
:func:`~csgs_codec.entropy.geometry_models.normalized_frequencies` from the counts) | varint
word count W | W u32 range-coder words. Slots are coded k = 0..K-1; within a slot the anchors
go through one constriction call per context, contexts increasing, anchors increasing.
"""

from __future__ import annotations

from functools import lru_cache

import constriction
import numpy as np

from csgs_codec.entropy.coder_model import TOTAL, binary_model
from csgs_codec.entropy.geometry_models import normalized_frequencies
from csgs_codec.entropy.grouping import groups_by_key
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Largest K a mask stream may hold.
MAX_SLOTS = 64


@lru_cache(maxsize=4096)


def _contexts(k: int) -> int:
    return k * (k + 1) // 2


def encode_masks(mask: np.ndarray) -> bytes:
    """Code an (M, K) bool mask; returns the mask stream."""
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.dtype != np.bool_ or not 1 <= mask.shape[1] <= MAX_SLOTS:
        raise InputError(f"offset mask must be (M, 1..{MAX_SLOTS}) bool, got {mask.shape} "
                         f"{mask.dtype}", property="offset_mask")
    m, k = mask.shape
    bits = mask.astype(np.int64)
    before = np.concatenate([np.zeros((m, 1), np.int64), np.cumsum(bits, axis=1)[:, :-1]],
                            axis=1)
    counts = np.zeros((_contexts(k), 2), dtype=np.int64)
    ctx = before + (np.arange(k) * (np.arange(k) + 1) // 2)[None, :]
    np.add.at(counts, (ctx.reshape(-1), bits.reshape(-1)), 1)
    f1 = normalized_frequencies(counts)[:, 1]
    encoder = constriction.stream.queue.RangeEncoder()
    for slot in range(k):
        base = _contexts(slot)
        for j, rows in groups_by_key(before[:, slot]):
            encoder.encode(bits[rows, slot].astype(np.int32), binary_model(int(f1[base + j])))
    words = encoder.get_compressed()
    out = ByteWriter()
    out.varint(m)
    out.fixed("u8", k)
    out.array(f1, "<u2")
    out.varint(int(words.size))
    out.array(words, "<u4")
    return out.getvalue()


def decode_masks(data: bytes, count: int, slots: int, *, chunk: str | None = None,
                 base_offset: int = 0) -> np.ndarray:
    """Decode a mask stream that must hold ``count`` anchors of ``slots`` slots: (M, K) bool."""
    reader = ByteReader(data, base_offset=base_offset, chunk=chunk)
    m = reader.varint("anchor_count")
    start = reader.offset
    k = reader.fixed("u8", "slots")
    if m != count or k != slots:
        raise reader.error(f"mask stream holds {m} x {k}, the header says {count} x {slots}",
                           at=start)
    f1 = reader.array(_contexts(k), "<u2", "frequencies").astype(np.int64)
    if f1.size and (f1.min() < 1 or f1.max() >= TOTAL):
        raise reader.error("a mask frequency is outside [1, 65535]")
    n_words = reader.varint("word_count", maximum=reader.remaining // 4)
    words = reader.array(n_words, "<u4", "range_data").astype(np.uint32)
    reader.expect_end("the mask stream")
    decoder = constriction.stream.queue.RangeDecoder(words)
    mask = np.zeros((m, k), dtype=np.bool_)
    before = np.zeros(m, dtype=np.int64)
    for slot in range(k):
        base = _contexts(slot)
        for j, rows in groups_by_key(before):
            try:
                symbols = decoder.decode(binary_model(int(f1[base + j])), rows.size)
            except (AssertionError, ValueError, RuntimeError, OverflowError) as exc:
                raise FormatError(f"range decoder failed in mask slot {slot} ({exc})",
                                  chunk=chunk, offset=base_offset) from None
            mask[rows, slot] = symbols.astype(bool)
        before += mask[:, slot]
    return mask
