"""Small-alphabet symbols (e.g. the dropped quaternion component) with a transmitted table.

Stream layout (spec/FORMAT.md, "Categorical stream"): varint N, u8 alphabet A (2..255), A
little-endian u16 frequencies (each >= 1, summing to 2^16; made from the symbol counts by
:func:`normalized_frequencies`), varint word count W, W little-endian u32 range-coder words.
"""

from __future__ import annotations

import constriction
import numpy as np

from csgs_codec.entropy.coder_model import TOTAL, categorical_model
from csgs_codec.entropy.geometry_models import normalized_frequencies
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter

MAX_COUNT = (1 << 32) - 1


def encode_categorical(symbols: np.ndarray, alphabet: int) -> bytes:
    """Code (N,) integers in [0, alphabet) with one static table built from their counts."""
    s = np.asarray(symbols, dtype=np.int64)
    if not 2 <= alphabet <= 255:
        raise InputError(f"alphabet must be 2..255, got {alphabet}")
    if s.size and (s.min() < 0 or s.max() >= alphabet):
        raise InputError(f"symbols must lie in [0, {alphabet})")
    freqs = normalized_frequencies(np.bincount(s, minlength=alphabet)[None, :])[0]
    encoder = constriction.stream.queue.RangeEncoder()
    if s.size:
        encoder.encode(s.astype(np.int32), categorical_model(freqs))
    words = encoder.get_compressed()
    out = ByteWriter()
    out.varint(int(s.size))
    out.fixed("u8", alphabet)
    out.array(freqs, "<u2")
    out.varint(int(words.size))
    out.array(words, "<u4")
    return out.getvalue()


def decode_categorical(data: bytes, count: int, *, chunk: str | None = None,
                       base_offset: int = 0, alphabet: int | None = None) -> np.ndarray:
    """Decode :func:`encode_categorical`'s stream holding ``count`` symbols: (count,) int64.

    Args:
        alphabet: the alphabet the stream must declare, or None for any (2..255).

    Raises:
        FormatError: wrong count or alphabet, bad table, truncation or trailing bytes (with
            the offset).
    """
    expected_alphabet = alphabet
    reader = ByteReader(data, base_offset=base_offset, chunk=chunk)
    n = reader.varint("count", maximum=MAX_COUNT)
    if n != count:
        raise reader.error(f"categorical stream holds {n} symbols, expected {count}")
    alphabet = int(reader.fixed("u8", "alphabet"))
    if alphabet < 2:
        raise reader.error(f"alphabet {alphabet} is below 2")
    if expected_alphabet is not None and alphabet != expected_alphabet:
        raise reader.error(f"alphabet {alphabet} is not the expected {expected_alphabet}")
    freqs = reader.array(alphabet, "<u2", "frequencies").astype(np.int64)
    if freqs.min() < 1 or int(freqs.sum()) != TOTAL:
        raise reader.error("frequencies must be >= 1 and sum to 65536")
    n_words = reader.varint("word_count", maximum=reader.remaining // 4)
    words = reader.array(n_words, "<u4", "range_data").astype(np.uint32)
    reader.expect_end("the categorical stream")
    if n == 0:
        return np.zeros(0, np.int64)
    try:
        decoded = constriction.stream.queue.RangeDecoder(words).decode(categorical_model(freqs), n)
    except (AssertionError, ValueError, RuntimeError, OverflowError) as exc:
        raise FormatError(f"range decoder failed ({exc})", chunk=chunk,
                          offset=base_offset) from exc
    return decoded.astype(np.int64)


