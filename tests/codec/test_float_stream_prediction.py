"""Channel prediction of float streams: the row-wise predictor and the subsampled fit."""

import numpy as np

from csgs_codec.attributes import float_stream
from csgs_codec.format.primitives import ByteReader, ByteWriter


def _encode(values: np.ndarray, step: float) -> tuple[bytes, np.ndarray]:
    out = ByteWriter()
    recon = float_stream.write_float_stream(out, values, step)
    return out.getvalue(), recon


def _correlated(n: int) -> np.ndarray:
    rng = np.random.default_rng(3)
    base = rng.normal(0, 1, n)
    return np.column_stack([base, 0.9 * base + rng.normal(0, 0.05, n)]).astype(np.float32)


def test_fit_rows_covers_small_streams_and_strides_large_ones():
    assert float_stream._fit_rows(10) == slice(None, None, 1)
    big = float_stream.FIT_ROWS * 3 + 1
    rows = np.arange(big)[float_stream._fit_rows(big)]
    assert len(rows) <= float_stream.FIT_ROWS
    assert rows[-1] >= big - 4 * 4  # the stride spans the whole stream


def test_subsampled_fit_round_trips_and_costs_little(monkeypatch):
    values = _correlated(20_000)
    full, _ = _encode(values, 0.01)
    monkeypatch.setattr(float_stream, "FIT_ROWS", 500)
    data, recon = _encode(values, 0.01)
    decoded = float_stream.read_float_stream(ByteReader(data), len(values), 2)
    assert np.array_equal(recon, decoded)
    assert np.abs(decoded - values).max() <= 0.01
    assert len(data) <= len(full) * 1.01


def test_prediction_equals_the_exact_formula():
    rng = np.random.default_rng(5)
    previous = rng.integers(-(2**30), 2**30, size=(1000, 7), dtype=np.int64)
    coefs = rng.integers(-(2**14), 2**14, size=7, dtype=np.int64)
    coefs[2] = 0
    bias = -12345
    exact = [(int(row @ coefs) + bias) // (1 << float_stream.COEF_FRAC_BITS)
             for row in previous]
    got = float_stream.predict(np.ascontiguousarray(previous.T), coefs, bias)
    assert got.tolist() == [int(v) for v in exact]
