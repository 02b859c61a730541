"""The JavaScript receiver decodes every level of detail of the level vectors (TIDX version 2,
FORMAT §12.22) to the Python decoder's arrays, and refuses a level the file lacks. Damaged
trees are among the scene vectors that tests/js/test_js_decoder.py compares. Skipped when
``node`` is not on PATH."""

from __future__ import annotations

import json

import pytest

from benchmarks._js_receiver import REPO, node_executable, run_js, scene_hashes
from csgs_codec import Decoder

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

SCENES = REPO / "spec" / "vectors" / "scenes"
LEVELED = [SCENES / "levels_q5.csgs", SCENES / "levels_semantic_small.csgs"]


@pytest.mark.parametrize("path", LEVELED, ids=lambda p: p.stem)
@pytest.mark.parametrize("threads", [1, 2])
def test_every_level_decodes_as_in_python(path, threads):
    record = json.loads(path.with_suffix(".json").read_text())
    reads = [r for r in record["reads"] if "lod" in r]
    assert {r["lod"] for r in reads} == set(range(max(r["lod"] for r in reads) + 1))
    for read in reads:
        (js,) = run_js([path], layers=read["layers"], lod=read["lod"], threads=threads)
        scene = Decoder().decode(path.read_bytes(), layers=read["layers"], lod=read["lod"])
        assert js["ok"], js
        assert js["count"] == len(scene) == read["gaussians"]
        assert js["arrays"] == scene_hashes(scene), f"{path.name} level {read['lod']}"


def test_a_level_the_file_lacks_is_refused_with_exit_2():
    (js,) = run_js([LEVELED[0]], lod=3)
    assert not js["ok"] and js["error"] == "InputError"
    assert "levels 0..2" in js["message"]
    (js,) = run_js([SCENES / "tiled_q5.csgs"], lod=1)
    assert not js["ok"] and "one level" in js["message"]
