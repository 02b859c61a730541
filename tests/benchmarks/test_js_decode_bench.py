"""benchmarks/js_decode.py on a tiny scene: the document it writes, with both decoders'
arrays equal. Skipped when ``node`` is not on PATH."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from benchmarks._js_receiver import node_executable
from benchmarks._scaling import subset_of_size
from csgs_codec import read_ply, write_ply
from tests.conftest import REPO, SAMPLE

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")


def test_js_decode_document(tmp_path):
    scene = tmp_path / "tiny.ply"
    write_ply(subset_of_size(read_ply(SAMPLE), 2000, seed=0), scene)
    out = tmp_path / "js.json"
    subprocess.run([sys.executable, str(REPO / "benchmarks" / "js_decode.py"), "--scene-path",
                    str(scene), "--quality", "3", "--rounds", "1", "--repeat", "2", "--out",
                    str(out)], check=True, capture_output=True, text=True, timeout=300)
    doc = json.loads(out.read_text())
    assert doc["schema"] == "csgs-bench/1" and doc["benchmark"] == "js_decode"
    (row,) = doc["results"]
    assert row["scene"] == "tiny" and row["gaussians"] == 2000 and row["arrays_equal"]
    assert row["quality"] == 3 and row["layers"] == "color"
    for key in ("js_decode_s", "js_1thread_decode_s", "js_first_decode_s", "python_decode_s"):
        assert row[key] > 0, key
    assert row["ratio_js_to_python"] == pytest.approx(row["js_decode_s"]
                                                      / row["python_decode_s"])
    assert len(row["rounds"]) == 1
