"""Frozen tables: checksums, shape rules, reproducibility of the generator."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from csgs_codec.entropy import tablegen, tables
from csgs_codec.errors import FormatError


def test_gaussian_family_has_64_tables_each_summing_to_2_pow_16_with_no_zero():
    family = tables.gaussian_family()
    assert family.count == 64
    for half, freqs in zip(family.half_widths.tolist(), family.freqs):
        assert freqs.shape == (2 * half + 2,)
        assert int(freqs.sum()) == 1 << 16
        assert int(freqs.min()) >= 1


def test_gaussian_tables_are_symmetric_and_peak_at_zero():
    for half, freqs in zip(tables.gaussian_family().half_widths.tolist(),
                           tables.gaussian_family().freqs):
        body = freqs[:2 * half + 1]
        assert np.array_equal(body, body[::-1])
        assert int(np.argmax(body)) == half


def test_half_widths_grow_with_scale():
    half = tables.gaussian_family().half_widths
    assert np.all(np.diff(half) >= 0)
    assert half[0] == 2 and half[-1] == 640


def test_frozen_files_match_the_spec_checksums():
    for name, digest in (("gaussian_v1.bin", tables.GAUSSIAN_V1_SHA256),
                         ("sine_v1.bin", tables.SINE_V1_SHA256)):
        assert hashlib.sha256((tables.DATA_DIR / name).read_bytes()).hexdigest() == digest


def test_table_generator_reproduces_the_frozen_bytes():
    for name, build in tablegen.FILES.items():
        assert build() == (tables.DATA_DIR / name).read_bytes(), name


def test_tampered_table_file_is_rejected(tmp_path, monkeypatch):
    data = bytearray((tables.DATA_DIR / "gaussian_v1.bin").read_bytes())
    data[10] ^= 1
    (tmp_path / "gaussian_v1.bin").write_bytes(bytes(data))
    monkeypatch.setattr(tables, "DATA_DIR", tmp_path)
    with pytest.raises(FormatError, match="SHA-256"):
        tables._read_verified("gaussian_v1.bin", tables.GAUSSIAN_V1_SHA256)


def test_sine_table_has_exact_quarter_wave_symmetry():
    t = tables.sine_table()
    assert t.shape == (1024,)
    assert t[0] == 0 and t[256] == 1 << 14 and t[512] == 0 and t[768] == -(1 << 14)
    i = np.arange(512)
    assert np.array_equal(t[512 + i], -t[i])
    j = np.arange(257)
    assert np.array_equal(t[512 - j], t[j])


def test_scale_index_maps_grid_sigmas_to_their_own_index():
    sigmas = 0.11 * (128 / 0.11) ** (np.arange(64) / 63)
    assert np.array_equal(tables.scale_index(sigmas), np.arange(64))
    assert tables.scale_index(np.array([1e-9, 1e9])).tolist() == [0, 63]


def test_range_coder_sees_the_spec_24_bit_view_of_a_table():
    import constriction

    freqs = tables.gaussian_family().freqs[0]
    n = freqs.size
    starts = np.concatenate(([0], np.cumsum(freqs)))
    view = (starts * ((1 << 24) - n)) // (1 << 16) + np.arange(n + 1)
    view[-1] = 1 << 24
    count = 50000
    for symbol in (n - 1, 0):  # the escape (and a residual) of table 0: 1 / 2^16 each
        encoder = constriction.stream.queue.RangeEncoder()
        encoder.encode(np.full(count, symbol, dtype=np.int32), tables.table_model(0))
        bits = encoder.get_compressed().size * 32
        ideal = -count * np.log2((view[symbol + 1] - view[symbol]) / 2.0**24)
        assert abs(bits - ideal) <= 64
