"""The page's choice of tiles for a file with levels of detail (csgs_codec/web/
level_view.mjs), run in Node on a small tile tree: the cut covers every level-0 tile exactly
once, refines what is near and in view first, keeps to the splat budget, leaves tiles out of
view coarse, and draws a decoded ancestor where a wanted tile is missing."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from benchmarks._js_receiver import REPO, node_executable

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

RUNNER = REPO / "tests" / "web" / "level_cut_runner.mjs"


def tree():
    """Root 0 (level 2) over tiles 1 and 2 (level 1: x < 0 and x > 0), each over two level-0
    tiles 3-4 and 5-6 of 100 Gaussians, along x from -4 to 4."""
    def tile(level, parent, x0, x1, count):
        return {"count": count, "lower": [x0, -1, -1], "upper": [x1, 1, 1], "level": level,
                "parent": parent}
    return [tile(2, None, -4, 4, 10), tile(1, 0, -4, 0, 50), tile(1, 0, 0, 4, 50),
            tile(0, 1, -4, -2, 100), tile(0, 1, -2, 0, 100), tile(0, 2, 0, 2, 100),
            tile(0, 2, 2, 4, 100)]


def camera_at(x: float, z: float = -10.0, width: int = 400) -> dict:
    """A camera at (x, 0, z) looking along +z (the project's convention: y down)."""
    world_to_camera = np.eye(4)
    world_to_camera[:3, 3] = [-x, 0, -z]
    return {"width": width, "height": width * 3 // 4, "fx": 400.0, "fy": 400.0,
            "cx": width / 2, "cy": width * 3 / 8,
            "world_to_camera": world_to_camera.reshape(-1).tolist(), "near_plane": 0.01}


def run(camera, sizes, decoded, budget=10_000, pixels=1.5) -> dict:
    payload = {"tiles": tree(), "camera": camera, "sizes": list(sizes.items()),
               "decoded": decoded, "budget": budget, "pixels": pixels}
    done = subprocess.run([node_executable(), str(RUNNER)], input=json.dumps(payload),
                          capture_output=True, text=True, timeout=60, check=True)
    return json.loads(done.stdout)


def covers_each_leaf_once(cut) -> bool:
    parent = {i: t["parent"] for i, t in enumerate(tree())}
    for leaf in (3, 4, 5, 6):
        line, node = [], leaf
        while node is not None:
            line.append(node)
            node = parent[node]
        if sum(n in cut for n in line) != 1:
            return False
    return True


ALL_SIZES = {0: 0.4, 1: 0.2, 2: 0.2, 3: 0.1, 4: 0.1, 5: 0.1, 6: 0.1}
EVERYTHING = list(range(7))


def test_near_and_large_refines_to_level_zero():
    out = run(camera_at(0), ALL_SIZES, EVERYTHING)
    assert out["cut"] == [3, 4, 5, 6] and out["drawn"] == [3, 4, 5, 6] and not out["missing"]


def test_small_on_screen_stays_coarse():
    out = run(camera_at(0, z=-10_000), ALL_SIZES, EVERYTHING)
    assert out["cut"] == [0] and out["drawn"] == [0]


def test_the_budget_refines_the_largest_first():
    # Budget 260: the root (10) splits into 1 and 2 (100); then one of them (+150) fits,
    # the other does not. Moving right makes tile 2's side nearer: it is refined.
    out = run(camera_at(3, z=-3), ALL_SIZES, EVERYTHING, budget=260)
    assert covers_each_leaf_once(out["cut"])
    assert out["cut"] == [1, 5, 6]


def test_tiles_out_of_view_stay_coarse():
    # Looking at x = -3 from close by: the x > 0 side is out of the picture.
    camera = camera_at(-3, z=-1.5, width=400)
    out = run(camera, ALL_SIZES, EVERYTHING)
    assert covers_each_leaf_once(out["cut"])
    assert 2 in out["cut"] and {3, 4} <= set(out["cut"])


def test_a_missing_tile_is_drawn_as_its_decoded_parent():
    sizes = {0: 0.4, 1: 0.2, 2: 0.2}
    out = run(camera_at(0), sizes, [0, 1, 2])
    assert out["cut"] == [3, 4, 5, 6]  # wanted: the sizes of 1 and 2 are known
    assert out["drawn"] == [1, 2] and out["missing"] == [3, 4, 5, 6]
    out = run(camera_at(0), sizes, [0, 1, 2, 3, 4, 5])
    assert out["drawn"] == [2, 3, 4] and out["missing"] == [6]
