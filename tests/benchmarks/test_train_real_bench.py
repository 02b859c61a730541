"""benchmarks/train_real.py --capture: a photo capture trained as csgs train trains it, per
lambda, with the figures the results file keeps."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from tests.conftest import REPO


@pytest.mark.slow  # two lambdas through all three stages and two encodes: ~25 s of CPU
def test_a_capture_run_writes_its_figures(tmp_path):
    capture = tmp_path / "capture"
    made = subprocess.run([sys.executable, "-m", "csgs_cli.main", "synthetic", str(capture),
                           "--objects", "2", "--gaussians", "150", "--views", "8",
                           "--size", "48x36", "--quiet"],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert made.returncode == 0, made.stderr[-2000:]
    out = tmp_path / "train_real.json"
    done = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "train_real.py"), "--capture",
         str(capture), "--resolution", "40", "--test-every", "4", "--lambdas", "0.004",
         "0.02", "--iterations", "40", "--anchors", "100", "--semantic-iterations", "15",
         "--out", str(out)],
        capture_output=True, text=True, timeout=300, cwd=REPO)
    assert done.returncode == 0, done.stderr[-2000:]
    doc = json.loads(out.read_text())
    assert doc["schema"] == "csgs-bench/1" and doc["benchmark"] == "train_real"
    dataset = doc["dataset"]
    assert (dataset["views"], dataset["train_views"], dataset["test_views"]) == (8, 6, 2)
    assert (dataset["width"], dataset["height"]) == (40, 30)
    assert [row["lambda"] for row in doc["results"]] == [0.004, 0.02]
    for row in doc["results"]:
        assert row["test_views"] == 2 and row["stage1_steps"] == 40
        assert 5.0 < row["test_psnr"] < 60.0 and 0.0 < row["test_ssim"] <= 1.0
        assert 0 < sum(row["layer_bytes"].values()) < row["bytes"]
        assert row["anchors"] > 0 and row["peak_rss_bytes"] > 50e6
        assert math.isfinite(row["wall_s"]) and row["wall_s"] > 0
