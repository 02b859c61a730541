"""A range decoder written from spec/FORMAT.md §16.2.3 and §16.2.4 alone, in plain Python.

It exists to prove the spec text is complete: tests/spec/test_range_coder_spec.py checks that
it decodes constriction's output identically. It is deliberately slow and literal; the
codec's decoders use constriction.
"""

from __future__ import annotations

PRECISION = 24
WORD_BITS = 32
MASK64 = (1 << 64) - 1
MASK32 = (1 << 32) - 1


class RangeDecodeError(ValueError):
    """The range decoder failed (§16.2.4 step 3): the stream is invalid."""


def coder_view(freqs: list[int]) -> list[int]:
    """The 24-bit cumulative table L[0..A] of integer frequencies summing to 2^16 (§16.2.3)."""
    a = len(freqs)
    if a < 2 or min(freqs) < 1 or sum(freqs) != 1 << 16:
        raise ValueError("a table needs >= 2 frequencies, each >= 1, summing to 2^16")
    view, cumulative = [], 0
    for s, f in enumerate(freqs):
        view.append(cumulative * ((1 << PRECISION) - a) // (1 << 16) + s)
        cumulative += f
    view.append(1 << PRECISION)
    return view


class ReferenceRangeDecoder:
    """The range decoder of §16.2.4 over a list of 32-bit words."""

    def __init__(self, words: list[int]):
        self._words = [int(w) & MASK32 for w in words]
        self._pos = 0
        self.lower = 0
        self.range = MASK64
        first = self._read_word()
        self.point = (first << WORD_BITS) | self._read_word()

    def _read_word(self) -> int:
        """The next word, or 0 past the end of the data."""
        word = self._words[self._pos] if self._pos < len(self._words) else 0
        self._pos += 1
        return word

    def decode(self, view: list[int]) -> int:
        """Decode one symbol against the coder view ``view`` (L[0..A])."""
        scale = self.range >> PRECISION
        quantile = ((self.point - self.lower) & MASK64) // scale
        if quantile >= 1 << PRECISION:
            raise RangeDecodeError(f"quantile {quantile} >= 2^24")
        lo, hi = 0, len(view) - 1  # largest s with view[s] <= quantile
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if view[mid] <= quantile:
                lo = mid
            else:
                hi = mid
        symbol = lo
        self.lower = (self.lower + scale * view[symbol]) & MASK64
        self.range = scale * (view[symbol + 1] - view[symbol])
        if self.range < 1 << WORD_BITS:
            self.lower = (self.lower << WORD_BITS) & MASK64
            self.range <<= WORD_BITS
            self.point = ((self.point << WORD_BITS) & MASK64) | self._read_word()
        return symbol

    def decode_many(self, view: list[int], count: int) -> list[int]:
        """Decode ``count`` symbols against one table."""
        return [self.decode(view) for _ in range(count)]
