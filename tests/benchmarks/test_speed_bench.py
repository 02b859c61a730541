"""benchmarks/speed.py: its --quick smoke run, the scene sizes it builds and its fits."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from benchmarks._fit import growth_exponent
from benchmarks._scaling import scene_of_size, subset_of_size, upsampled_to
from csgs_codec import read_ply
from tests.conftest import REPO, SAMPLE

SIZES = (1500, 3000)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """The JSON document and PNG of one --quick run on two tiny subsets of the sample."""
    out = tmp_path_factory.mktemp("speed")
    done = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "speed.py"), "--quick",
         "--scenes", SAMPLE.stem, "--scenes-dir", str(SAMPLE.parent),
         "--sizes", *map(str, SIZES), "--out", str(out / "speed.json"),
         "--plot", str(out / "speed.png")],
        capture_output=True, text=True, timeout=120, cwd=REPO)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads((out / "speed.json").read_text()), out / "speed.png"


@pytest.fixture(scope="module")
def sample():
    return read_ply(SAMPLE)


def test_quick_run_writes_the_bench_schema(quick_run):
    doc, _ = quick_run
    assert doc["schema"] == "csgs-bench/1"
    assert doc["benchmark"] == "speed"
    assert {"cpus", "platform"} <= set(doc["machine"])
    assert doc["quick"] is True
    assert doc["complete"] is True
    assert isinstance(doc["results"], list) and doc["results"]


def test_quick_run_measures_every_requested_size(quick_run):
    doc, _ = quick_run
    assert sorted(r["gaussians"] for r in doc["results"]) == list(SIZES)
    assert all(r["construction"] == "subset" and r["roundtrip_ok"] for r in doc["results"])


def test_quick_run_figures_are_finite_and_positive(quick_run):
    doc, _ = quick_run
    keys = ("bytes", "bits_per_gaussian", "encode_s", "decode_s", "encode_cpu_s",
            "decode_cpu_s", "encode_gaussians_per_s", "decode_gaussians_per_s",
            "encode_numpy_peak_mb", "decode_numpy_peak_mb")
    for row in doc["results"]:
        for key in keys:
            assert math.isfinite(row[key]) and row[key] > 0, (key, row[key])
        for key in ("encode_peak_rss_delta_mb", "decode_peak_rss_delta_mb"):
            assert math.isfinite(row[key]) and row[key] >= 0, (key, row[key])


def test_quick_run_time_exponents_are_finite(quick_run):
    doc, _ = quick_run
    times = [g for g in doc["growth"]
             if g["metric"] in ("seconds", "cpu_seconds") and g["sizes"] == "all"]
    assert {(g["phase"], g["metric"]) for g in times} == {
        (p, m) for p in ("encode", "decode") for m in ("seconds", "cpu_seconds")}
    assert all(math.isfinite(g["exponent"]) and g["points"] == len(SIZES) for g in times)
    for row in doc["summary"]:
        assert math.isfinite(row["encode_time_exponent"])
        assert math.isfinite(row["decode_time_exponent"])
        assert math.isfinite(row["encode_cpu_time_exponent"])
        assert isinstance(row["meets_decode_rate_target"], bool)


def test_quick_run_writes_a_png(quick_run):
    _, png = quick_run
    with Image.open(png) as image:
        assert image.format == "PNG" and image.width > 400 and image.height > 300


def test_subset_is_deterministic_and_drawn_from_the_scene(sample):
    a = subset_of_size(sample, 500, seed=3)
    b = subset_of_size(sample, 500, seed=3)
    assert len(a) == 500 and a.equals(b)
    source_rows = {row.tobytes() for row in sample.positions}
    assert all(row.tobytes() in source_rows for row in a.positions)
    assert not subset_of_size(sample, 500, seed=4).equals(a)


def test_upsampled_scene_keeps_the_originals_then_adds_jittered_copies(sample):
    small = subset_of_size(sample, 300, seed=0)
    big = upsampled_to(small, 1000, seed=1)
    assert len(big) == 1000
    assert big.subset(np.arange(300)).equals(small)
    assert big.equals(upsampled_to(small, 1000, seed=1))
    copies = big.subset(np.arange(300, 1000))
    assert not np.any(np.all(copies.positions[:, None] == small.positions[None], axis=2))


def test_upsampled_copies_move_by_a_fraction_of_their_scale(sample):
    small = subset_of_size(sample, 300, seed=0)
    big = upsampled_to(small, 900, seed=2, jitter_fraction=0.5)
    copies = big.subset(np.arange(300, 900))
    # Each copy keeps its source's scales and color, so find its source by those.
    keys = {np.concatenate([s, c]).tobytes(): p for s, c, p in
            zip(small.scales, small.sh_dc, small.positions.astype(np.float64))}
    moves, spreads = [], []
    for s, c, p in zip(copies.scales, copies.sh_dc, copies.positions.astype(np.float64)):
        moves.append(np.linalg.norm(p - keys[np.concatenate([s, c]).tobytes()]))
        spreads.append(0.5 * np.exp(s.astype(np.float64).mean()))
    ratio = np.array(moves) / np.array(spreads)
    # |N(0, I3)| has mean ~1.6 and is below 5 with probability ~1 - 1e-5.
    assert 1.2 < ratio.mean() < 2.0 and ratio.max() < 6


def test_scene_of_size_names_its_construction(sample):
    assert scene_of_size(sample, len(sample), 0)[1] == "full"
    assert scene_of_size(sample, 100, 0)[1] == "subset"
    scene, how = scene_of_size(sample, len(sample) + 10, 0)
    assert how == "upsampled" and len(scene) == len(sample) + 10


def test_growth_exponent_recovers_a_power_law():
    sizes = [1e4, 1e5, 1e6]
    assert growth_exponent(sizes, [3e-6 * n ** 1.25 for n in sizes]) == pytest.approx(1.25)


def test_growth_exponent_leaves_out_non_positive_values():
    assert growth_exponent([1, 10, 100], [0.0, 5.0, 50.0]) == pytest.approx(1.0)
    assert growth_exponent([1, 10], [0.0, 5.0]) is None
