"""Float-stream channels coded with their own frequency table (table source 2, FORMAT
§12.8)."""

from __future__ import annotations

import numpy as np

import csgs_codec.attributes.channel_coders as channel_coders
from csgs_codec.attributes.channel_coders import TABLE_FROZEN, TABLE_HISTOGRAM
from csgs_codec.attributes.float_stream import read_float_stream, write_float_stream
from csgs_codec.codec.decoder import Decoder
from csgs_codec.format.primitives import ByteReader, ByteWriter
from tests.conformance import VECTORS_DIR


def _modes(payload: bytes) -> list[int]:
    """Coding byte of each channel of a stream with a single channel (right after F)."""
    r = ByteReader(payload)
    r.varint("count")
    r.fixed("u8", "channels")
    r.fixed("u8", "frac_bits")
    return [r.fixed("u8", "coding")]


def _round_trip(values: np.ndarray, step: float) -> tuple[bytes, np.ndarray, np.ndarray]:
    out = ByteWriter()
    recon = write_float_stream(out, values, step)
    data = out.getvalue()
    decoded = read_float_stream(ByteReader(data), len(values), values.shape[1])
    return data, recon, decoded


def test_a_bimodal_channel_is_coded_with_its_own_table():
    rng = np.random.default_rng(0)
    values = np.concatenate([rng.normal(-6, 0.3, 4000), rng.normal(4, 0.3, 4000)])
    data, recon, decoded = _round_trip(values.astype(np.float32)[:, None], 0.05)
    assert _modes(data) == [TABLE_HISTOGRAM]
    assert np.array_equal(recon, decoded)
    assert np.abs(decoded[:, 0] - values).max() <= 0.05 * 0.523


def test_a_gaussian_channel_keeps_the_frozen_tables():
    values = np.random.default_rng(1).normal(0, 1, (8000, 1)).astype(np.float32)
    data, recon, decoded = _round_trip(values, 0.05)
    assert _modes(data) == [TABLE_FROZEN]
    assert np.array_equal(recon, decoded)


def test_predicted_histogram_channels_round_trip():
    rng = np.random.default_rng(2)
    base = np.concatenate([rng.normal(-2, 0.2, 3000), rng.normal(2, 0.2, 3000)])
    values = np.stack([base, base * 0.9 + rng.normal(0, 0.01, base.size),
                       -base + rng.normal(0, 0.01, base.size)], axis=1).astype(np.float32)
    _, recon, decoded = _round_trip(values, 0.02)
    assert np.array_equal(recon, decoded)
    assert np.abs(decoded - values).max() <= 0.02 * 0.523


def test_the_current_scene_vectors_use_histogram_channels(monkeypatch):
    calls = []
    real = channel_coders.decode_histogram
    monkeypatch.setattr(channel_coders, "decode_histogram",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    data = (VECTORS_DIR / "scenes" / "donut_q3.csgs").read_bytes()
    assert len(Decoder().decode(data)) == 45624
    assert calls
