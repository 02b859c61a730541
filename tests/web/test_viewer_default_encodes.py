"""The browser viewer opens what `csgs encode` writes with default settings (issue #28): the
sample in the repository always, every shared scene when ../shared is present, the sample at
qualities 1 and 9 and in tiles, and a file with a semantic layer. The page reaches "done" and
the arrays its decode worker decoded hash-equal the Python decoder's (the page hashes them
when asked with ``?hashes=1``).

A file the encoder writes and the page cannot open fails here: nothing is skipped except a
shared scene that is absent (skipped, saying so).
"""

from __future__ import annotations

import os

import pytest

from benchmarks._js_receiver import scene_hashes
from csgs_codec import Decoder, write_ply
from csgs_codec.semantic.synthetic import labelled_blob_scene
from csgs_codec.web.server import ViewerServer
from tests.conftest import SAMPLE, shared_path
from tests.web.browser import wait_for_state
from tests.web.test_viewer_browser import SCREENSHOT, SCREENSHOT_ENV, save_page_screenshot

SHARED_SCENES = ("donut", "biker", "guitar", "plant", "playbot")
SIZE = "400x300"


def _open_and_compare(browser, path) -> dict:
    """Open ``path`` in the page with hashes on; assert it reaches "done" with the Python
    decoder's arrays; return the page state."""
    expected = Decoder().decode(path.read_bytes(), layers="color,semantic")
    with ViewerServer(path) as server:
        browser.get(f"{server.url}?size={SIZE}&hashes=1")
        state = wait_for_state(browser, lambda s: (s["phase"] == "done" and s["colorShown"]
                                                   and s["hashes"] is not None) or s["error"])
    assert state["error"] is None, f"{path.name}: the page could not open it: {state['error']}"
    assert state["count"] == len(expected)
    assert state["hashes"] == scene_hashes(expected), f"{path.name}: decoded arrays differ"
    assert state["firstFrameMs"] is not None and state["colorFrameMs"] >= state["firstFrameMs"]
    return state


def test_the_default_encode_of_the_sample_opens_as_python_decodes_it(browser, default_encode):
    path = default_encode(SAMPLE)
    _open_and_compare(browser, path)
    if os.environ.get(SCREENSHOT_ENV):
        save_page_screenshot(browser, SCREENSHOT)


@pytest.mark.parametrize("flags", [("--quality", "1"), ("--quality", "9"),
                                   ("--tile-size", "24000")],
                         ids=["quality-1", "quality-9", "tiles"])
def test_the_sample_encoded_with_other_settings_opens(browser, default_encode, flags):
    _open_and_compare(browser, default_encode(SAMPLE, *flags))


def test_a_default_encode_with_a_semantic_layer_opens(browser, default_encode, tmp_path):
    ply = tmp_path / "objects.ply"
    write_ply(labelled_blob_scene(5, 2000, sh_degree=1, seed=4), ply)  # 10k: every tool on
    state = _open_and_compare(browser, default_encode(ply))
    assert state["semanticReady"] and state["hashes"]["semantic"]["shape"][1] == 6


@pytest.mark.parametrize("name", SHARED_SCENES)
def test_the_default_encode_of_every_shared_scene_opens(browser, default_encode, name):
    _open_and_compare(browser, default_encode(shared_path("scenes", f"{name}.ply")))
