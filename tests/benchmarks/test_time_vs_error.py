"""benchmarks/time_vs_error.py on a tiny scene, and the Pareto front it marks."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from benchmarks._fit import pareto_optimal
from benchmarks._scaling import subset_of_size
from csgs_codec import read_ply, write_ply
from tests.conftest import REPO, SAMPLE

QUALITIES = (1, 9)
#: Two made-up peer rows: one smaller and faster than anything (so on every front), one
#: bigger, slower and worse than the near-lossless preset (so on none).
CHEAP_PEER = {"scene": "tiny", "codec": "cheap", "setting": "1.0", "bytes": 10,
              "bits_per_gaussian": 0.04, "encode_s": 1e-6, "decode_s": 1e-6, "psnr": 5.0,
              "ssim": 0.1, "foreground_psnr": 1.0}
POOR_PEER = {"scene": "tiny", "codec": "poor", "setting": "1.0", "bytes": 10**9,
             "bits_per_gaussian": 4e6, "encode_s": 1e6, "decode_s": 1e6, "psnr": 2.0,
             "ssim": 0.0, "foreground_psnr": 0.5}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """JSON, PNG and table of one run: 2000 Gaussians of the sample, 1 view at 64x48."""
    tmp = tmp_path_factory.mktemp("tve")
    (tmp / "scenes").mkdir()
    write_ply(subset_of_size(read_ply(SAMPLE), 2000, seed=0), tmp / "scenes" / "tiny.ply")
    rd = {"schema": "csgs-bench/1", "benchmark": "rd", "machine": {"cpus": 2}, "views": 1,
          "size": "64x48",
          "results": [CHEAP_PEER, POOR_PEER, {**POOR_PEER, "scene": "elsewhere"},
                      {**CHEAP_PEER, "codec": "csgs", "setting": "quality 5"}]}
    (tmp / "rd.json").write_text(json.dumps(rd))
    done = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "time_vs_error.py"),
         "--rd", str(tmp / "rd.json"), "--scenes-dir", str(tmp / "scenes"),
         "--qualities", *map(str, QUALITIES), "--out", str(tmp / "tve.json"),
         "--plot", str(tmp / "tve.png"), "--table", str(tmp / "tve.md")],
        capture_output=True, text=True, timeout=180, cwd=REPO)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads((tmp / "tve.json").read_text()), tmp


def by_codec(doc, codec):
    return [r for r in doc["results"] if r["codec"] == codec]


def test_document_has_the_bench_schema_and_the_rd_views(run):
    doc, _ = run
    assert doc["schema"] == "csgs-bench/1" and doc["benchmark"] == "time_vs_error"
    assert {"cpus", "platform"} <= set(doc["machine"])
    assert (doc["views"], doc["size"]) == (1, "64x48")
    assert doc["peer_source"]["scores_comparable"] is True


def test_every_preset_has_times_size_and_scores(run):
    doc, _ = run
    rows = by_codec(doc, "csgs")
    assert [r["quality"] for r in rows] == list(QUALITIES)
    for r in rows:
        assert r["scene"] == "tiny" and r["measured_in"] == "this run"
        assert r["bytes"] > 0 and r["encode_s"] > 0 and r["decode_s"] > 0
        assert math.isfinite(r["psnr"]) and math.isfinite(r["foreground_psnr"])
    low, high = rows
    assert high["bytes"] > low["bytes"] and high["foreground_psnr"] > low["foreground_psnr"]


def test_peers_come_from_the_rd_document_for_the_scenes_run(run):
    doc, tmp = run
    peers = [r for r in doc["results"] if r["codec"] != "csgs"]
    assert sorted(r["codec"] for r in peers) == ["cheap", "poor"]
    assert all(r["scene"] == "tiny" and r["measured_in"] == str(tmp / "rd.json")
               for r in peers)
    assert by_codec(doc, "cheap")[0]["bytes"] == CHEAP_PEER["bytes"]


def test_fronts_mark_the_undominated_rows(run):
    doc, _ = run
    fronts = ("pareto_size", "pareto_encode", "pareto_decode", "pareto")
    assert all(by_codec(doc, "cheap")[0][f] is True for f in fronts)
    assert all(by_codec(doc, "poor")[0][f] is False for f in fronts)
    best = max(by_codec(doc, "csgs"), key=lambda r: r["foreground_psnr"])
    assert best["pareto"] is True and best["pareto_size"] is True


def test_table_and_plot_are_written(run):
    _, tmp = run
    lines = (tmp / "tve.md").read_text().splitlines()
    assert lines[0].startswith("| scene | codec |") and len(lines) == 2 + 4
    with Image.open(tmp / "tve.png") as image:
        assert image.format == "PNG" and image.height > 3 * 300


def test_pareto_optimal_drops_dominated_rows_and_keeps_ties():
    costs = np.array([[1.0, 5.0], [2.0, 4.0], [2.0, 6.0], [1.0, 5.0], [3.0, 3.0]])
    assert pareto_optimal(costs).tolist() == [True, True, False, True, True]


def test_pareto_optimal_counts_nan_as_worst():
    costs = np.array([[1.0, float("nan")], [2.0, 1.0]])
    assert pareto_optimal(costs).tolist() == [True, True]
    assert pareto_optimal(np.array([[1.0, float("nan")], [1.0, 1.0]])).tolist() == [False, True]
