"""The step-allocation model of benchmarks/precision_bound.py against closed forms, and the
per-variant ratios of benchmarks/rd.py."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from benchmarks.precision_bound import rate_bits, rule_saving, water_fill
from benchmarks.rd import add_ratios, combine, size_at


def test_water_filling_meets_its_target_and_caps_at_the_variances():
    s = np.array([1.0, 4.0, 9.0, 0.25])
    theta, d = water_fill(s, 3.0)
    assert d.sum() == pytest.approx(3.0, rel=1e-9)
    assert np.all(d <= s + 1e-12)
    assert theta == pytest.approx(float(d.max()))
    assert rate_bits(s, d) == pytest.approx(0.5 * np.log2(s / d).sum())


def test_two_sensitivity_levels_save_half_log2_of_their_am_over_gm():
    """At high rate, steps in proportion to J2^-1/2 save 0.5 log2(AM/GM) bits per value."""
    n, a, b = 4000, 1.0, 64.0
    j = np.where(np.arange(n) % 2 == 0, a, b).reshape(-1, 1)
    feature = j.copy()
    saved = rule_saving([(feature, 2)], j, j, 12.0, 1e-4)
    expected = n * 0.5 * math.log2(((a + b) / 2) / math.sqrt(a * b))
    assert saved == pytest.approx(expected, rel=1e-3)


def test_a_feature_blind_to_the_sensitivity_saves_nothing():
    rng = np.random.default_rng(0)
    j = rng.uniform(1, 100, size=(2000, 1))
    feature = rng.uniform(size=(2000, 1))
    saved = rule_saving([(feature, 4)], np.ones_like(j), j, 12.0, 1e-4)
    assert saved == pytest.approx(0.0, abs=1e-6 * j.size)


def _csgs(scene, variant, psnr, size):
    return {"scene": scene, "codec": "csgs", "variant": variant, "setting": "quality 5",
            "bytes": size, "foreground_psnr": psnr}


def test_peer_ratios_are_kept_per_variant():
    rows = [_csgs("s", "plain", 40.0, 1000), _csgs("s", "plain", 50.0, 2000),
            _csgs("s", "stacked", 40.0, 800), _csgs("s", "stacked", 50.0, 1600),
            {"scene": "s", "codec": "peer", "bytes": 4000, "foreground_psnr": 45.0}]
    add_ratios(rows)
    peer = rows[-1]
    plain = size_at(rows[:2], 45.0)
    assert plain == pytest.approx(math.sqrt(1000 * 2000))
    assert peer["csgs_size_ratio"]["plain"] == pytest.approx(plain / 4000)
    assert peer["csgs_size_ratio"]["stacked"] == pytest.approx(0.8 * plain / 4000)
    rows.append({"scene": "s", "codec": "far", "bytes": 10, "foreground_psnr": 70.0})
    add_ratios(rows)
    assert rows[-1]["csgs_size_ratio"] == {"plain": None, "stacked": None}


def test_variants_are_compared_with_the_uniform_curve_at_equal_psnr():
    rows = [_csgs("s", "uniform", 40.0, 1000), _csgs("s", "uniform", 50.0, 2000),
            _csgs("s", "plain", 45.0, 1200), _csgs("s", "plain", 60.0, 3000)]
    add_ratios(rows)
    assert rows[2]["size_vs_uniform_at_same_psnr"] == pytest.approx(
        1200 / math.sqrt(1000 * 2000))
    assert rows[3]["size_vs_uniform_at_same_psnr"] is None  # beyond the uniform curve
    assert "size_vs_uniform_at_same_psnr" not in rows[0]
    assert not any("size_vs_preset_at_same_psnr" in row for row in rows)  # none measured


def test_variants_are_compared_with_the_preset_curve_at_equal_psnr():
    rows = [_csgs("s", "preset", 40.0, 1000), _csgs("s", "preset", 50.0, 2000),
            _csgs("s", "plain", 45.0, 1200)]
    add_ratios(rows)
    assert rows[2]["size_vs_preset_at_same_psnr"] == pytest.approx(
        1200 / math.sqrt(1000 * 2000))
    assert "size_vs_uniform_at_same_psnr" not in rows[2]


def test_combine_refuses_documents_measured_differently(tmp_path):
    one = {"scoring": "held-out", "size": "800x600", "refine_steps": 20,
           "results": [_csgs("a", "plain", 40.0, 1000)]}
    two = dict(one, results=[_csgs("b", "plain", 40.0, 1000)])
    (tmp_path / "1.json").write_text(json.dumps(one))
    (tmp_path / "2.json").write_text(json.dumps(two))
    rows, settings = combine([str(tmp_path / "1.json"), str(tmp_path / "2.json")])
    assert [r["scene"] for r in rows] == ["a", "b"]
    assert settings["combined_from"] == ["1.json", "2.json"]
    (tmp_path / "3.json").write_text(json.dumps(dict(one, size="400x300")))
    with pytest.raises(SystemExit, match="measured differently"):
        combine([str(tmp_path / "1.json"), str(tmp_path / "3.json")])
