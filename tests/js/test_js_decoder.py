"""The JavaScript receiver (csgs_codec/js/) decodes every standard-scene conformance vector
to the same arrays as the Python decoder, reads every container vector as recorded, and
rejects every invalid vector (those cut from anchor scenes too) with an error naming the
chunk and offset the Python decoder names. Anchor scenes' own vectors:
tests/js/test_js_anchor_decoder.py. Skipped when ``node`` is not on PATH.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks._js_receiver import REPO, node_executable, run_js, scene_hashes
from csgs_codec import Decoder
from csgs_codec.errors import FormatError
from csgs_codec.format.source import open_source
from csgs_codec.format.toc import read_toc
from tests.conformance import current
from tests.js.anchor_results import assert_same_anchors, python_anchor_result

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

VECTORS = REPO / "spec" / "vectors"
SCENES = current(sorted((VECTORS / "scenes").glob("*.csgs")))
CONTAINER = sorted((VECTORS / "container").glob("*.csgs"))
ANCHORS = sorted((VECTORS / "anchors").glob("*.csgs"))
MANIFEST = json.loads((VECTORS / "invalid" / "manifest.json").read_text())
INVALID = [VECTORS / "invalid" / v["file"] for v in MANIFEST["vectors"]]
#: Invalid vectors cut from anchor scenes (the reference decoder is AnchorDecoder).
ANCHOR_INVALID = [p for p in INVALID if p.name.startswith("fuzz_anchor_")]
LAYER_READS = ("color", "color,semantic")


def _python(path: Path, layers: str) -> dict:
    """The Python decoder's result in the CLI's terms."""
    try:
        scene = Decoder().decode(path.read_bytes(), layers=layers)
    except FormatError as err:
        return {"ok": False, "chunk": err.chunk, "offset": err.offset}
    return {"ok": True, "count": len(scene), "arrays": scene_hashes(scene),
            "semantic_names": list(scene.semantic_names)}


def _assert_same(js: dict, py: dict, what: str) -> None:
    if py["ok"]:
        assert js["ok"], f"{what}: JavaScript rejected a file Python decodes: {js}"
        assert js["count"] == py["count"], what
        assert js["arrays"] == py["arrays"], f"{what}: decoded arrays differ"
        assert js["semantic_names"] == py["semantic_names"], what
    else:
        assert not js["ok"], f"{what}: JavaScript decoded a file Python rejects ({py})"
        assert js["error"] == "FormatError", f"{what}: {js}"
        assert js["chunk"] == py["chunk"], f"{what}: JavaScript names {js}, Python {py}"
        assert js["offset"] == py["offset"], f"{what}: JavaScript names {js}, Python {py}"
        assert (js["chunk"] or "container") in js["message"], what


def _has_anchor_chunk(path: Path) -> bool | None:
    """Whether the TOC of ``path`` lists an ANCH chunk (None when its TOC is unreadable)."""
    try:
        toc = read_toc(open_source(path.read_bytes()))
    except FormatError:
        return None
    return any(e.type == "ANCH" for e in toc.entries)


def test_the_vector_sets_are_the_expected_ones():
    assert len(SCENES) >= 19 and len(CONTAINER) >= 28 and len(INVALID) >= 30
    assert len(ANCHOR_INVALID) == 7
    names = {p.stem for p in SCENES}
    assert {"far_floaters_q5", "far_floaters_missing_outq", "far_floaters_truncated_outq",
            "view_pruned_q5", "view_pruned_vdis_version_9"} <= names


def test_the_anchor_invalid_vectors_are_anchor_scenes_and_no_other_is():
    """The invalid vectors compared with AnchorDecoder are anchor scenes, and every other
    vector with a readable TOC is a standard one."""
    assert all(_has_anchor_chunk(p) for p in ANCHORS + ANCHOR_INVALID)
    others = SCENES + [p for p in INVALID if p not in ANCHOR_INVALID]
    assert [p.name for p in others if _has_anchor_chunk(p)] == []


@pytest.mark.parametrize(("threads", "range_coder"), [(1, "js"), (2, "wasm")])
@pytest.mark.parametrize("layers", LAYER_READS)
def test_scene_vectors_decode_as_in_python(layers, threads, range_coder):
    results = run_js(SCENES, layers=layers, threads=threads, range_coder=range_coder)
    for path, js in zip(SCENES, results):
        _assert_same(js, _python(path, layers), f"{path.name} [{layers}]")
    # The set holds both kinds, and the color hyperprior decodes.
    assert any(r["ok"] for r in results) and not all(r["ok"] for r in results)
    assert next(r for p, r in zip(SCENES, results) if p.stem == "color_prior_q3")["ok"]


def test_scene_vectors_match_the_recorded_outcomes():
    for layers in LAYER_READS:
        for path, js in zip(SCENES, run_js(SCENES, layers=layers)):
            record = json.loads(path.with_suffix(".json").read_text())
            read = next(r for r in record["reads"] if r["layers"] == layers)
            assert js["ok"] == (read["outcome"] == "ok"), f"{path.name} [{layers}]"
            if read["outcome"] == "ok":
                assert js["count"] == read["gaussians"], path.name
            else:
                assert js["chunk"] == read["chunk"], path.name


def _recorded_layers(read: dict) -> list[str]:
    layers = read["layers"]
    return layers.split(",") if isinstance(layers, str) else list(layers)


def test_container_vectors_read_as_recorded():
    checked = 0
    for path in CONTAINER:
        record = json.loads(path.with_suffix(".json").read_text())
        for read in record["reads"]:
            layers = ",".join(_recorded_layers(read))
            (js,) = run_js([path], layers=layers, container=True)
            what = f"{path.name} [{layers}]"
            if read["outcome"] == "ok":
                assert js["ok"], f"{what}: {js}"
                want = read["decode"]
                for key in ("major_version", "minor_version", "flags", "toc", "payloads",
                            "complete"):
                    assert js[key] == want[key], f"{what}: {key}"
            else:
                assert not js["ok"] and js["error"] == "FormatError", f"{what}: {js}"
                assert js["chunk"] == read.get("chunk"), f"{what}: {js}"
                assert js["offset"] == read.get("offset"), f"{what}: {js}"
            checked += 1
    assert checked >= 28


@pytest.mark.parametrize(("threads", "range_coder"), [(1, "js"), (2, "wasm")])
def test_invalid_vectors_are_rejected_naming_chunk_and_offset(threads, range_coder):
    """Also on two threads: the error raised is the first in the Python decoder's order,
    whichever thread found it."""
    results = run_js(INVALID, layers="color,semantic", threads=threads,
                     range_coder=range_coder)
    for path, js in zip(INVALID, results):
        if path in ANCHOR_INVALID:
            py = python_anchor_result(path.read_bytes(), "color,semantic")
            assert not py["ok"], f"{path.name} decodes in Python"
            assert_same_anchors(js, py, path.name)
            continue
        py = _python(path, "color,semantic")
        assert not py["ok"], f"{path.name} decodes in Python"
        _assert_same(js, py, path.name)
