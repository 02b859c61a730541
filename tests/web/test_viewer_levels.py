"""The browser page streams a file with levels of detail (issue #53): it reads the tile
index, draws its first frame from the coarsest level's byte ranges alone (the server's log
says which ranges were read), refines tile by tile, and its final frame at full detail equals
the page's frame of the same tiles written without levels. The sample in the repository,
encoded as `csgs encode --levels 3 --tile-size 8000` writes it."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.format.source import open_source
from csgs_codec.format.toc import read_toc
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.scene.orbit import orbit_cameras
from csgs_codec.web.server import ViewerServer
from tests.conftest import SAMPLE
from tests.web.browser import psnr, show_camera, wait_for_state

SIZE = "400x300"
TILE = "8000"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("levels")
    leveled, flat = folder / "levels.csgs", folder / "flat.csgs"
    assert main(["encode", str(SAMPLE), "-o", str(leveled), "--levels", "3", "--tile-size",
                 TILE, "--quiet"]) == 0
    assert main(["encode", str(SAMPLE), "-o", str(flat), "--tile-size", TILE,
                 "--quiet"]) == 0
    return leveled, flat


def _coarse_frames(data: bytes) -> list[tuple[int, int]]:
    """Byte ranges a first frame may come from: header and TOC, TIDX, the top level's
    tiles' frames."""
    from csgs_codec.chunks.tile_index import TileIndex
    from csgs_codec.format import read_layers

    toc = read_toc(open_source(data))
    container = read_layers(data, layers=set())
    index = TileIndex.from_bytes(bytes(container.payloads[0]), toc.entries[0].offset + 8)
    top = set(index.level_tiles(index.levels - 1))
    return [(0, toc.header_and_toc_size), (toc.entries[0].offset, toc.entries[0].end)] + [
        (e.offset, e.end) for e in toc.entries[1:] if e.tile in top]


def test_first_frame_from_the_coarse_ranges_and_final_frame_as_without_levels(browser,
                                                                              files):
    leveled, flat = files
    data = leveled.read_bytes()
    camera = orbit_cameras(read_ply(SAMPLE), 1, width=400, height=300)[0]
    # lodpx tiny: the view wants every tile of level 0, so the final frame is full detail.
    with ViewerServer(leveled) as server:
        browser.get(f"{server.url}?size={SIZE}&lodpx=0.001")
        state = wait_for_state(browser, lambda s: s["error"] or (
            s["lod"] and s["lod"]["firstFrameBytes"] is not None))
        assert state["error"] is None, state["error"]
        first_bytes = state["lod"]["firstFrameBytes"]
        ranges = server.scene_ranges
        show_camera(browser, camera)
        state = wait_for_state(browser, lambda s: s["error"] or s["lod"]["joined"])
        final = show_camera(browser, camera)
        state = wait_for_state(browser, lambda s: s["lod"]["joined"])
    # The first frame: the header, TOC, index and the coarsest level's frames, nothing else.
    allowed = _coarse_frames(data)
    counted, read_first = 0, []
    for _, start, end in ranges:
        if counted >= first_bytes:
            break
        read_first.append((start, end))
        counted += end - start
    assert counted == first_bytes
    for start, end in read_first:
        assert any(a <= start and end <= b for a, b in allowed) or _adjacent(allowed, start,
                                                                             end), (start, end)
    assert first_bytes <= 0.05 * len(data)
    # Then every level-0 tile (and nothing else) drawn; the frame equals the flat file's.
    assert state["lod"]["drawnLevels"] == [8, 0, 0] and state["count"] == 45_624
    with ViewerServer(flat) as server:
        browser.get(f"{server.url}?size={SIZE}")
        flat_state = wait_for_state(browser, lambda s: s["phase"] == "done" or s["error"])
        assert flat_state["error"] is None and flat_state["count"] == 45_624
        reference = show_camera(browser, camera)
    assert reference.max() > 0.1
    assert np.array_equal(final, reference), psnr(final, reference)


def _adjacent(frames, start, end) -> bool:
    """Whether [start, end) is frames of ``frames`` that follow each other exactly."""
    at = start
    for a, b in sorted(frames):
        if a == at:
            at = b
    return at >= end


def test_the_view_picks_coarse_levels_for_a_distant_camera(browser, files):
    """Far away, the page draws the coarsest level alone and reads no finer tile."""
    leveled, _ = files
    with ViewerServer(leveled) as server:
        browser.get(f"{server.url}?size={SIZE}&lodpx=50")
        state = wait_for_state(browser, lambda s: s["error"] or (s["lod"]
                                                                and s["lod"]["complete"]))
    assert state["error"] is None
    assert state["lod"]["drawnLevels"] == [0, 0, 1]
    assert state["lod"]["decoded"] == 1 and state["count"] < 1000


def test_click_selects_the_labelled_object_in_a_streamed_file(browser, tmp_path):
    """Selection works on the tiles drawn: at full detail, as in the whole file."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    from csgs_codec import Decoder, Encoder
    from csgs_codec.semantic.evaluation import mask_iou, object_click_points
    from csgs_codec.semantic.selection import select_at_click
    from csgs_codec.semantic.synthetic import labelled_blob_scene, overview_camera
    from tests.web.browser import viewer_state

    path = tmp_path / "objects.csgs"
    path.write_bytes(Encoder(levels=2, tile_size=500).encode(labelled_blob_scene(5, 400, seed=3)))
    scene = Decoder().decode(path.read_bytes(), "color,semantic")  # level 0, tile order
    width, height = 480, 360
    camera = overview_camera(scene.positions, width=width, height=height)
    with ViewerServer(path) as server:
        browser.get(f"{server.url}?size={width}x{height}&lodpx=0.001")
        wait_for_state(browser, lambda s: s["error"] or (s["lod"] and s["lod"]["complete"]))
        show_camera(browser, camera)
        state = wait_for_state(browser, lambda s: s["error"] or s["lod"]["joined"])
        assert state["error"] is None and state["semanticReady"]
        assert state["count"] == len(scene) and state["lod"]["drawnLevels"] == [4, 0]
        canvas = browser.find_element(By.ID, "canvas")
        for label, (x, y) in sorted(object_click_points(scene.positions, scene.labels,
                                                        camera).items()):
            ActionChains(browser).move_to_element_with_offset(
                canvas, int(x) - width // 2, int(y) - height // 2).click().perform()
            selected = np.zeros(len(scene), bool)
            selected[browser.execute_script("return window.csgsViewer.selectionIndices()")] = True
            assert viewer_state(browser)["selection"]["count"] == selected.sum()
            assert mask_iou(selected, scene.labels == label) >= 0.9, label
            assert mask_iou(selected, select_at_click(scene, camera, x, y)) >= 0.99, label
