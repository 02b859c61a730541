"""The JavaScript receiver decodes anchor scenes (spec/FORMAT.md §17) to the arrays the Python
reference decoder (AnchorDecoder) returns, hash for hash: every anchor conformance vector,
an anchor file with view origins (vorg) and an appearance table, and what ``csgs train``
writes for a tiny synthetic capture; and its result feeds the browser's bake as it is.
Skipped when ``node`` is not on PATH.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from benchmarks._js_receiver import REPO, node_executable, run_js
from csgs_codec.bake.anchor_bake import BakeSettings, bake_anchor_scene
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.format import read_layers
from csgs_codec.format.chunk import Chunk
from csgs_codec.format.writer import write_container
from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.anchors.helpers import FAST_FIT, scene_with_origins_and_appearance
from tests.js.anchor_results import assert_same_anchors, python_anchor_result
from tests.js.array_bundle import unpack
from tests.js.test_js_anchor_bake import assert_same_bake

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

ANCHORS = sorted((REPO / "spec" / "vectors" / "anchors").glob("*.csgs"))
LAYER_READS = ("color", "color,semantic")
#: Networks fitted just enough to be exported (the edge-shape tests need files, not rates).
TINY_FIT = FitSettings(hidden=8, carm_hidden=4, steps=5, batch=64)


def _compare(paths: list[Path], layers: str, **options) -> list[dict]:
    results = run_js(paths, layers=layers, **options)
    for path, js in zip(paths, results):
        assert_same_anchors(js, python_anchor_result(path.read_bytes(), layers),
                            f"{path.name} [{layers}]")
    return results


def test_the_anchor_vectors_are_there():
    names = {p.stem for p in ANCHORS}
    assert {"anchors_color_q8", "anchors_color_q8_mlp_float16", "anchors_semantic_q5",
            "anchors_semantic_q5_acrm_v2", "anchors_missing_features"} <= names


@pytest.mark.parametrize(("threads", "range_coder"), [(1, "js"), (2, "wasm")])
@pytest.mark.parametrize("layers", LAYER_READS)
def test_anchor_vectors_decode_as_in_python(layers, threads, range_coder):
    results = _compare(ANCHORS, layers, threads=threads, range_coder=range_coder)
    decoded = {p.stem: r for p, r in zip(ANCHORS, results) if r["ok"]}
    # Not vacuous: the semantic read yields features and labels, the colour read none.
    semantic = decoded["anchors_semantic_q5"]["arrays"]
    assert ("semantic" in semantic and "labels" in semantic) == (layers == "color,semantic")
    assert "mlp.color.w1" in decoded["anchors_color_q8_mlp_float16"]["arrays"]


def test_anchor_labels_coded_as_runs_decode_as_in_python(tmp_path):
    """The anchor encoder writes SEMR (§12.25) where it is smaller than SEML: the helper
    scene's labels are such a case."""
    from tests.anchors.helpers import encoded

    path = tmp_path / "labels.csgs"
    path.write_bytes(encoded().data)
    assert "SEMR" in {e.type for e in read_layers(path.read_bytes(), "semantic").toc}
    (result,) = _compare([path], "color,semantic")
    assert result["ok"] and "labels" in result["arrays"]


@pytest.fixture(scope="module")
def vorg_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("vorg") / "origins.csgs"
    path.write_bytes(AnchorEncoder(6, fit=FAST_FIT).encode(scene_with_origins_and_appearance()))
    return path


def test_a_file_cut_after_its_color_layer_decodes_that_layer_as_in_python(tmp_path):
    """A colour-only read never needs a semantic byte; asking for the semantic layer of the
    cut file is refused where Python refuses it."""
    data = (REPO / "spec" / "vectors" / "anchors" / "anchors_semantic_q5.csgs").read_bytes()
    toc = read_layers(data, layers="base").toc
    cut = min(e.offset for e in toc if e.layer.label == "semantic")
    prefix = tmp_path / "color_prefix.csgs"
    prefix.write_bytes(data[:cut])
    (js,) = _compare([prefix], "color", threads=1)
    assert js["ok"] and "semantic" not in js["arrays"]
    (js,) = _compare([prefix], "color,semantic", threads=1)
    assert not js["ok"]


def _edge_scene(shape: str):
    """Small scenes at the edges of §17's ranges: every offset masked (AOFF the empty
    stream), no MLPs (has_mlps clear), one CARM group (ACRM empty), one channel per group
    (G = F), K = 64 slots."""
    if shape == "all_masked":
        scene = synthetic_anchor_scene(1, 20, feat_dim=10, n_offsets=4, seed=1)
        scene.offset_mask[:] = False
        scene.offsets[:] = 0
        return scene, {}
    if shape == "no_mlps":
        return synthetic_anchor_scene(1, 20, feat_dim=10, seed=2, with_mlps=False), {}
    if shape == "one_group":
        return synthetic_anchor_scene(1, 20, feat_dim=10, seed=3), {"carm_groups": 1}
    if shape == "group_per_channel":
        return synthetic_anchor_scene(1, 20, feat_dim=6, n_offsets=3, feature_groups=3,
                                      seed=4), {"carm_groups": 6}
    return synthetic_anchor_scene(1, 20, feat_dim=8, n_offsets=64, feature_groups=2,
                                  seed=5), {}


@pytest.mark.parametrize("shape", ["all_masked", "no_mlps", "one_group", "group_per_channel",
                                   "k_64"])
def test_scenes_at_the_edges_of_the_ranges_decode_as_in_python(shape, tmp_path):
    scene, options = _edge_scene(shape)
    path = tmp_path / f"{shape}.csgs"
    path.write_bytes(AnchorEncoder(7, fit=TINY_FIT, **options).encode(scene))
    (js,) = _compare([path], "color,semantic", threads=1)
    assert js["ok"] and ("mlp.opacity.w1" in js["arrays"]) == (shape != "no_mlps")


def _with_vorg_payload(data: bytes, payload: bytes) -> bytes:
    """``data`` with its vorg chunk's payload replaced."""
    container = read_layers(data, layers="color,semantic")
    return write_container([Chunk(e.type, e.layer.label, payload if e.type == "vorg"
                                  else bytes(container.payloads[e.index]))
                            for e in container.toc])


def test_view_origins_and_the_appearance_table_decode_as_in_python(vorg_file, tmp_path):
    (js,) = _compare([vorg_file], "color,semantic", threads=1)
    assert js["arrays"]["view_origins"]["shape"] == [32, 3]  # an even sample of the 40
    assert js["arrays"]["mlp.appearance"]["shape"] == [5, 4]
    # An invalid vorg payload (NaN origins) is no reason to refuse the file: none reported.
    nan = tmp_path / "nan_origins.csgs"
    nan.write_bytes(_with_vorg_payload(vorg_file.read_bytes(), b"\x01\x02" + b"\xff" * 24))
    (js,) = _compare([nan], "color", threads=1)
    assert js["ok"] and "view_origins" not in js["arrays"]


def test_a_damaged_vorg_frame_is_refused_where_python_refuses_it(vorg_file, tmp_path):
    data = bytearray(vorg_file.read_bytes())
    entry = next(e for e in read_layers(bytes(data), layers="base").toc if e.type == "vorg")
    data[entry.offset + 9] ^= 0x40  # an origin byte: the frame's CRC no longer matches
    bad = tmp_path / "bad_vorg_crc.csgs"
    bad.write_bytes(bytes(data))
    (js,) = _compare([bad], "color")
    assert js["chunk"] == "vorg"


def test_the_decoded_scene_feeds_the_browser_s_bake_as_it_is(vorg_file):
    """decodeAnchorScene then bakeAnchorScene (the page's path) gives the reference bake of
    AnchorDecoder's scene (stored origins, appearance table, semantic layer)."""
    done = subprocess.run([node_executable(), str(REPO / "tests" / "js" / "anchor_decode_bake.mjs"),
                           str(vorg_file), '{"shDegree": 1}'], capture_output=True, timeout=300)
    assert done.returncode == 0, done.stderr.decode()[-3000:]
    ours, _ = unpack(done.stdout)
    scene = AnchorDecoder().decode(vorg_file.read_bytes(), layers="color,semantic")
    assert_same_bake(scene, ours, bake_anchor_scene(scene, settings=BakeSettings(sh_degree=1)))


@pytest.mark.slow  # `csgs train` takes about 45 s here, alone
def test_what_csgs_train_writes_decodes_as_in_python(tmp_path):
    """The default `csgs train` settings (F, K, CARM groups, quality, semantic layer, vorg),
    few iterations, on a tiny synthetic capture."""
    from csgs_cli.main import main

    data, out = tmp_path / "synthetic", tmp_path / "trained.csgs"
    assert main(["synthetic", str(data), "--views", "6", "--size", "48x36", "--gaussians",
                 "100", "-q"]) == 0
    assert main(["train", str(data), "-o", str(out), "--iterations", "3", "--anchors", "20",
                 "--semantic-iterations", "2", "-q"]) == 0
    for layers in LAYER_READS:
        (js,) = _compare([out], layers)
        assert "view_origins" in js["arrays"] and "mlp.opacity.w1" in js["arrays"]
    assert "semantic" in js["arrays"]


def test_anchor_counts_are_bounded_by_the_bytes_present_in_both_decoders(tmp_path):
    """FORMAT §10.1: a file declaring more anchor values than 256 a byte is refused at ANCH
    (by both decoders alike) before anything is allocated for them; the encoder pads a scene
    that codes smaller (32,768 constant anchors on a dense grid) with a `fill` chunk, so
    what it writes decodes, and the same file without the padding is refused."""
    import numpy as np

    from csgs_codec.codec.anchor_decoder import MAX_ANCHOR_VALUES_PER_BYTE
    from csgs_codec.scene.anchor_scene import AnchorScene

    grid = np.stack(np.meshgrid(*[np.arange(32)] * 3, indexing="ij"), -1).reshape(-1, 3)
    m = len(grid)
    scene = AnchorScene(grid.astype(np.float32) * 0.1, np.zeros((m, 4), np.float32),
                        np.zeros((m, 2, 3), np.float32), np.full((m, 6), -2, np.float32),
                        np.ones((m, 2), bool))
    report = AnchorEncoder(fit=FAST_FIT).encode_with_report(scene)
    assert report.chunk_bytes.get("fill", 0) > 0
    assert len(report.data) >= m * (4 + 6 + 6) / MAX_ANCHOR_VALUES_PER_BYTE
    padded, unpadded = tmp_path / "padded.csgs", tmp_path / "unpadded.csgs"
    padded.write_bytes(report.data)
    container = read_layers(report.data, layers="color,semantic")
    unpadded.write_bytes(write_container([
        Chunk(e.type, e.layer, container.payloads[e.index]) for e in container.toc
        if e.type != "fill"]))
    js_padded, js_unpadded = _compare([padded, unpadded], "color", threads=1)
    assert js_padded["ok"] and not js_unpadded["ok"]
    assert js_unpadded["chunk"] == "ANCH"
