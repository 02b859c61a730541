"""The one place a frequency table becomes a range-coder model (spec §16.2.4).

Every coder in csgs draws symbols from integer frequency tables that sum to ``TOTAL`` =
2^16. constriction takes probabilities as floats; ``freqs / TOTAL`` is a dyadic fraction, exact
in float64, and with ``perfect=False`` constriction's quantisation keeps each frequency as
given, so the model the coder uses is exactly the integer table the spec describes.
"""

from __future__ import annotations

import constriction
import numpy as np

#: Bits of every frequency table's total.
PRECISION_BITS = 16
#: What every frequency table sums to.
TOTAL = 1 << PRECISION_BITS


def categorical_model(freqs: np.ndarray):
    """constriction ``Categorical`` model of an integer table ``freqs`` (A,) summing to TOTAL."""
    return constriction.stream.model.Categorical(np.asarray(freqs, dtype=np.float64)
                                                 / float(TOTAL), perfect=False)


def binary_model(f1: int):
    """Model of one binary symbol whose value 1 has frequency ``f1`` of TOTAL (1..TOTAL-1)."""
    return categorical_model(np.array([TOTAL - f1, f1], dtype=np.int64))
