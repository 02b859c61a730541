"""The browser viewer opens the default encode of every shared scene (issue #28): the five
standard scenes and a full-precision SH-3 capture, when ../shared is present (an absent scene
is skipped, saying so; playbot and fruit_drops under -m slow), and of the SH-3 capture the
repository keeps (benchmarks/data), which every run has. Kept apart from the sample's tests
so that test workers share them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import shared_path
from tests.web.test_viewer_default_encodes import decoded_as_in_python, open_in_page

#: Under -m slow, for the time their encodes take (the fast suite opens the repository's SH-3
#: capture below, which has every SH band and per-scene steps too).
SLOW_SCENES = ("scenes/playbot", "real_sh3/fruit_drops")
SHARED_SCENES = ("scenes/donut", "scenes/biker", "scenes/guitar", "scenes/plant",
                 "scenes/playbot",
                 # A full-precision SH-3 capture: every band, steps allocated for the scene.
                 "real_sh3/fruit_drops")


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_SCENES
                                  else n for n in SHARED_SCENES])
def test_the_default_encode_of_every_shared_scene_opens(browser, default_encode, name):
    folder, stem = name.split("/")
    state, python = open_in_page(browser, default_encode(shared_path(folder, f"{stem}.ply")))
    assert decoded_as_in_python(state, python), state["error"]


def test_the_default_encode_of_the_repositorys_sh3_capture_opens(browser, default_encode):
    """Every SH band, per-scene steps and the colour transform, without ../shared."""
    scene = Path(__file__).resolve().parents[2] / "benchmarks" / "data" / "yashica_t4_top8192.ply"
    state, python = open_in_page(browser, default_encode(scene))
    assert decoded_as_in_python(state, python), state["error"]
