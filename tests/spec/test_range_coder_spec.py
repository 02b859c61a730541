"""The range coder text of spec/FORMAT.md (§16.2.3, §16.2.4) is complete: a decoder written
from it alone decodes what constriction, the reference encoder, writes."""

from __future__ import annotations

import constriction
import numpy as np
import pytest

from csgs_codec.entropy.tables import gaussian_family
from tests.spec.range_decoder_reference import (
    RangeDecodeError,
    ReferenceRangeDecoder,
    coder_view,
)


def _random_table(rng: np.random.Generator, size: int) -> np.ndarray:
    """Integer frequencies >= 1 summing to 2^16, skewed like real tables."""
    weights = rng.gamma(0.3, size=size)
    freqs = 1 + np.floor(weights / weights.sum() * ((1 << 16) - size)).astype(np.int64)
    freqs[int(np.argmax(freqs))] += (1 << 16) - int(freqs.sum())
    return freqs


def _model(freqs: np.ndarray):
    return constriction.stream.model.Categorical(freqs / float(1 << 16), perfect=False)


def _encode(groups: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    encoder = constriction.stream.queue.RangeEncoder()
    for freqs, symbols in groups:
        encoder.encode(symbols.astype(np.int32), _model(freqs))
    return encoder.get_compressed()


def test_coder_view_example_from_the_spec():
    assert coder_view([16384, 49152]) == [0, 4194304, 16777216]


@pytest.mark.parametrize("size", [2, 3, 255, 1282, 4097])
def test_coder_view_matches_constriction_probabilities(size):
    rng = np.random.default_rng(size)
    freqs = _random_table(rng, size)
    view = coder_view(freqs.tolist())
    symbols = np.arange(size, dtype=np.int32)
    widths = np.diff(np.asarray(view))
    assert widths.min() >= 1 and int(widths.sum()) == 1 << 24
    # Decoding a stream of every symbol once checks the intervals end to end.
    words = _encode([(freqs, symbols)])
    assert ReferenceRangeDecoder(words.tolist()).decode_many(view, size) == symbols.tolist()


@pytest.mark.parametrize("seed", range(12))
def test_reference_decoder_equals_constriction_on_random_streams(seed):
    rng = np.random.default_rng(1000 + seed)
    groups = []
    for _ in range(int(rng.integers(1, 6))):
        size = int(rng.choice([2, 5, 255, 1000, 4097]))
        freqs = _random_table(rng, size)
        p = freqs / freqs.sum()
        count = int(rng.integers(0, 3000))
        groups.append((freqs, rng.choice(size, size=count, p=p)))
    words = _encode(groups)
    decoder = ReferenceRangeDecoder(words.tolist())
    oracle = constriction.stream.queue.RangeDecoder(words)
    for freqs, symbols in groups:
        view = coder_view(freqs.tolist())
        got = decoder.decode_many(view, symbols.size)
        assert got == symbols.tolist()
        assert got == oracle.decode(_model(freqs), symbols.size).tolist()


def test_reference_decoder_equals_constriction_on_frozen_tables():
    family = gaussian_family()
    rng = np.random.default_rng(7)
    groups = []
    for index in (0, 11, 20, 40, 63):
        freqs = family.freqs[index]
        groups.append((freqs, rng.choice(freqs.size, size=500, p=freqs / freqs.sum())))
    words = _encode(groups)
    decoder = ReferenceRangeDecoder(words.tolist())
    for freqs, symbols in groups:
        assert decoder.decode_many(coder_view(freqs.tolist()), symbols.size) == symbols.tolist()


@pytest.mark.parametrize("seed", range(6))
def test_reading_past_the_end_and_garbage_match_constriction(seed):
    """Truncated or random words: same symbols as constriction, or both fail."""
    rng = np.random.default_rng(50 + seed)
    freqs = _random_table(rng, 37)
    view = coder_view(freqs.tolist())
    full = _encode([(freqs, rng.choice(37, size=400, p=freqs / freqs.sum()))])
    cases = [full[: full.size // 2], full[:1], full[:0],
             rng.integers(0, 1 << 32, size=8, dtype=np.uint64).astype(np.uint32)]
    for words in cases:
        decoder = ReferenceRangeDecoder(words.tolist())
        oracle = constriction.stream.queue.RangeDecoder(words)
        for _ in range(400):
            try:
                want = int(oracle.decode(_model(freqs), 1)[0])
            except (AssertionError, ValueError, RuntimeError, OverflowError):
                with pytest.raises(RangeDecodeError):
                    decoder.decode(view)
                break
            assert decoder.decode(view) == want


def test_a_quantile_past_2_to_the_24_fails():
    # point - lower = 2^64 - 1 gives quantile 2^24 with range = 2^64 - 1.
    words = np.array([0xFFFFFFFF, 0xFFFFFFFF], dtype=np.uint32)
    with pytest.raises(RangeDecodeError):
        ReferenceRangeDecoder(words.tolist()).decode(coder_view([1 << 15, 1 << 15]))
    with pytest.raises((AssertionError, ValueError, RuntimeError, OverflowError)):
        constriction.stream.queue.RangeDecoder(words).decode(_model(np.array([1 << 15] * 2)), 1)
