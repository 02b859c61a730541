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


def _stream(path, layers: str, threads: int) -> dict:
    import subprocess

    runner = REPO / "tests" / "js" / "level_stream_runner.mjs"
    done = subprocess.run([node_executable(), str(runner),
                           str(path), "--layers", layers, "--threads", str(threads)],
                          capture_output=True, text=True, timeout=300, check=True)
    return json.loads(done.stdout)


@pytest.mark.parametrize("path", LEVELED, ids=lambda p: p.stem)
@pytest.mark.parametrize("threads", [1, 2])
def test_levels_streamed_tile_by_tile_decode_as_in_python(path, threads):
    """What the viewer does: each level's tiles from the byte ranges of their frames alone,
    decoded tile by tile (on decode lanes too), equal the Python decoder's level."""
    layers = "color,semantic"
    streamed = _stream(path, layers, threads)
    data = path.read_bytes()
    for level in streamed["levels"]:
        report = Decoder().decode_with_report(data, layers, lod=level["level"])
        assert level["tiles"] == report.tiles
        assert level["arrays"] == scene_hashes(report.scene), f"level {level['level']}"
    # Each level came from its own tiles' frames, one range per layer at the coarsest
    # (coarse tiles lead every layer); the index from the header, the TOC and TIDX.
    from csgs_codec.format.source import open_source
    from csgs_codec.format.toc import read_toc

    toc = read_toc(open_source(data))
    assert streamed["index"] == [[0, 16], [16, toc.header_and_toc_size],
                                 [toc.entries[0].offset, toc.entries[0].end]]
    for level in streamed["levels"]:
        frames = [(e.offset, e.end) for e in toc.entries if e.tile in level["tiles"]
                  and e.type != "TIDX"]
        read = sum(end - start for start, end in level["ranges"])
        assert read == sum(end - start for start, end in frames)
        assert all(any(a <= s and e <= b for a, b in frames) or
                   _joined(frames, s, e) for s, e in level["ranges"])
    coarsest = streamed["levels"][0]
    assert len(coarsest["ranges"]) == len({e.layer for e in toc.entries
                                           if e.tile in coarsest["tiles"]})


def _joined(frames, start, end) -> bool:
    """Whether [start, end) is frames of ``frames`` that follow each other exactly."""
    at = start
    for a, b in sorted(frames):
        if a == at:
            at = b
    return at >= end
