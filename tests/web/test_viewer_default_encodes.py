"""The browser viewer opens what `csgs encode` writes with default settings (issue #28): the
sample in the repository, the sample at qualities 1 and 9 and in tiles, and files with a
semantic layer (every shared scene: tests/web/test_viewer_shared_scenes.py). The page
reaches "done" and the arrays its decode worker decoded hash-equal the Python decoder's (the
page hashes them when asked with ``?hashes=1``).

A file the encoder writes and the page cannot open fails here: nothing is skipped except a
shared scene that is absent (skipped, saying so).
"""

from __future__ import annotations

import os

import pytest

from benchmarks._js_receiver import REPO, scene_hashes
from csgs_codec import Decoder, write_ply
from csgs_codec.semantic.synthetic import labelled_blob_scene
from csgs_codec.web.server import ViewerServer
from tests.conftest import SAMPLE
from tests.web.browser import wait_for_state
from tests.web.test_viewer_browser import SCREENSHOT, SCREENSHOT_ENV, save_page_screenshot

SIZE = "400x300"


def open_in_page(browser, path) -> tuple[dict, dict]:
    """Open ``path`` in the page with hashes on and wait until it is done or failed; returns
    (the page state, the Python decoder's hashes of the same file's arrays)."""
    expected = Decoder().decode(path.read_bytes(), layers="color,semantic")
    with ViewerServer(path) as server:
        browser.get(f"{server.url}?size={SIZE}&hashes=1")
        state = wait_for_state(browser, lambda s: (s["phase"] == "done" and s["colorShown"]
                                                   and s["hashes"] is not None) or s["error"])
    return state, {"count": len(expected), "hashes": scene_hashes(expected)}


def decoded_as_in_python(state: dict, python: dict) -> bool:
    """Whether the page finished without an error, drew its frames in order, and decoded the
    Python decoder's Gaussians and arrays."""
    return (state["error"] is None and state["count"] == python["count"]
            and state["hashes"] == python["hashes"]
            and state["firstFrameMs"] is not None
            and state["colorFrameMs"] >= state["firstFrameMs"])


def test_the_default_encode_of_the_sample_opens_as_python_decodes_it(browser, default_encode):
    state, python = open_in_page(browser, default_encode(SAMPLE))
    assert decoded_as_in_python(state, python), state["error"]
    if os.environ.get(SCREENSHOT_ENV):
        save_page_screenshot(browser, SCREENSHOT)


@pytest.mark.parametrize("flags", [
    # Qualities 1 and 9 write the sample in the same chunks as the default 5, with other
    # steps: they run under -m slow.
    pytest.param(("--quality", "1"), marks=pytest.mark.slow),
    pytest.param(("--quality", "9"), marks=pytest.mark.slow),
    ("--tile-size", "24000")], ids=["quality-1", "quality-9", "tiles"])
def test_the_sample_encoded_with_other_settings_opens(browser, default_encode, flags):
    state, python = open_in_page(browser, default_encode(SAMPLE, *flags))
    assert decoded_as_in_python(state, python), state["error"]


def test_a_default_encode_with_a_semantic_layer_opens(browser, default_encode, tmp_path):
    ply = tmp_path / "objects.ply"
    # 10k Gaussians: the color hyperprior on (step allocation, on for SH bands, does not
    # change the format and has its own tests; SH 0 keeps it off and saves 20 s).
    write_ply(labelled_blob_scene(5, 2000, sh_degree=0, seed=4), ply)
    state, python = open_in_page(browser, default_encode(ply))
    assert decoded_as_in_python(state, python), state["error"]
    assert state["semanticReady"] and state["hashes"]["semantic"]["shape"][1] == 6


def test_the_sample_segmented_then_encoded_by_default_opens(browser, default_encode, tmp_path):
    """What a user makes: `csgs segment` on the sample from a capture of it (renders, no
    masks: the built-in segmenter's), then `csgs encode` with no flags (SEMC)."""
    import numpy as np

    from csgs_cli.main import main
    from csgs_codec.interchange.ply_io import read_ply
    from csgs_codec.render.rasterizer import render
    from csgs_codec.scene.orbit import orbit_cameras
    from csgs_codec.train.synthetic import write_transforms_dataset
    from csgs_codec.train.views import TrainingView

    scene = read_ply(SAMPLE)
    views = [TrainingView(np.clip(render(scene, c, backend="numba").image, 0, 1)
                          .astype(np.float32), c, name=f"view_{i}.png")
             for i, c in enumerate(orbit_cameras(scene, 4, width=160, height=120))]
    write_transforms_dataset(views, tmp_path / "capture")
    segmented = tmp_path / "segmented.ply"
    assert main(["segment", "-q", str(SAMPLE), "--images", str(tmp_path / "capture"),
                 "-o", str(segmented), "--iterations", "12"]) == 0
    path = default_encode(segmented)
    assert b"SEMC" in path.read_bytes()
    state, python = open_in_page(browser, path)
    assert decoded_as_in_python(state, python), state["error"]
    assert state["semanticReady"] and state["hashes"]["semantic"] == python["hashes"]["semantic"]


ANCHOR_FIXTURE = REPO / "tests" / "data" / "anchors" / "demo_trained.csgs"


def open_anchors_in_page(browser, path) -> tuple[dict, dict]:
    """Open the anchor file ``path`` in the page (hashes on), wait until it is done or failed;
    returns (the page state, the Python side: the decoded anchors' hashes and its bake)."""
    from benchmarks._js_receiver import anchor_hashes
    from csgs_codec.bake.anchor_bake import bake_anchor_scene
    from csgs_codec.codec.anchor_decoder import AnchorDecoder

    decoded = AnchorDecoder().decode(path, layers="color,semantic")
    with ViewerServer(path) as server:
        browser.get(f"{server.url}?size={SIZE}&hashes=1")
        state = wait_for_state(browser, lambda s: (s["phase"] == "done" and s["colorShown"]
                                                   and s["hashes"] is not None) or s["error"])
    return state, {"hashes": anchor_hashes(decoded), "baked": bake_anchor_scene(decoded),
                   "decoded": decoded}


@pytest.mark.parametrize("name", ["demo_trained.csgs", "anchors_semantic_q5.csgs",
                                  "anchors_color_q8_mlp_float16.csgs"])
def test_anchor_files_open_as_the_reference_bake(browser, name):
    """What `csgs train` writes (the demo's file) and the anchor vectors open: the page
    decodes the anchors hash for hash as Python does, draws a preview first, then the bake
    of as many splats as the reference decoder's, and selects an object by click."""
    path = ANCHOR_FIXTURE if name == ANCHOR_FIXTURE.name else (
        REPO / "spec" / "vectors" / "anchors" / name)
    state, python = open_anchors_in_page(browser, path)
    assert state["error"] is None, state["error"]
    assert state["hashes"] == python["hashes"]
    assert state["count"] == len(python["baked"]) > 0
    assert state["firstFrameMs"] is not None and state["colorFrameMs"] >= state["firstFrameMs"]
    if python["decoded"].labels is not None or python["decoded"].semantic is not None:
        assert state["semanticReady"]
        picked = browser.execute_script(  # the first pixel, centre outwards, with an object
            "const v = window.csgsViewer; let last = 'no pixel tried';"
            "for (let r = 0; r < 150; r += 10) for (const [dx, dy] of "
            "[[0, 0], [r, 0], [-r, 0], [0, r], [0, -r], [r, r], [-r, -r]]) {"
            "  try { const got = v.selectAt(200 + dx, 150 + dy); if (got.count > 0) "
            "    return got.count; } catch (e) { last = String(e); } }"
            "return last;")
        assert isinstance(picked, int) and 0 < picked < state["count"], picked
