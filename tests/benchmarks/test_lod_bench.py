"""benchmarks/lod.py on a tiny scene: the document's schema and rows, ratios computed from the
files it encoded, each level's bytes and reads, and the copies laid apart on a grid (not
whether the issue's targets hold: that is what the recorded run says)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks.lod import GAP, grid_copies, main, widths_reaching
from csgs_codec import read_scene
from csgs_codec.scene.orbit import robust_bounds
from tests.conftest import SAMPLE


@pytest.fixture(scope="module")
def lod_document(tmp_path_factory):
    out = tmp_path_factory.mktemp("lod") / "lod.json"
    assert main(["--scene", str(SAMPLE), "--keep", "600", "--copies", "4", "--tile-size",
                 "400", "--levels", "2", "3", "--views", "1", "--widths", "48", "24",
                 "--quiet", "--out", str(out)]) == 0
    return json.loads(out.read_text())


def _rows(doc, kind):
    return [r for r in doc["results"] if r["kind"] == kind]


def test_the_document_is_a_lod_benchmark_of_the_built_scene(lod_document):
    doc = lod_document
    assert doc["schema"] == "csgs-bench/1" and doc["benchmark"] == "lod"
    assert doc["gaussians"] == 2400 and doc["copies"] == 4 and doc["levels"] == [2, 3]
    assert doc["level0_equals_tiles_file"] is True
    assert [r["file"] for r in _rows(doc, "encode")] == ["single", "tiles", "levels2",
                                                         "levels3"]


def test_ratios_are_each_files_bytes_over_the_single_level_and_the_tiles_file(lod_document):
    encodes = {r["file"]: r for r in _rows(lod_document, "encode")}
    single, tiles = encodes["single"]["bytes"], encodes["tiles"]["bytes"]
    assert encodes["tiles"]["tiles"] == 8 and encodes["levels3"]["tiles"] == 10
    for row in encodes.values():
        assert row["ratio_to_single"] == round(row["bytes"] / single, 4)
        assert row["ratio_to_tiles"] == round(row["bytes"] / tiles, 4)
        assert row["encode_s"] > 0
    assert lod_document["worst_ratio_to_single"] == max(
        encodes["levels2"]["ratio_to_single"], encodes["levels3"]["ratio_to_single"])


def test_every_level_reads_its_frames_and_the_index(lod_document):
    encodes = {r["file"]: r for r in _rows(lod_document, "encode")}
    for name in ("levels2", "levels3"):
        levels = [r for r in _rows(lod_document, "level") if r["file"] == name]
        assert [r["level"] for r in levels] == list(range(int(name[-1])))
        assert sum(r["bytes"] for r in levels) < encodes[name]["bytes"]
        assert levels[0]["gaussians"] == 2400 and levels[1]["gaussians"] < 2400 / 4
        for row in levels:  # the header, TOC and TIDX besides the level's frames
            assert row["bytes"] < row["bytes_read"] < encodes[name]["bytes"]
            assert row["read_share"] == round(row["bytes_read"] / encodes[name]["bytes"], 5)
    coarsest = [r for r in _rows(lod_document, "level") if r["file"] == "levels3"][-1]
    assert lod_document["coarsest_read_share"] == coarsest["read_share"]


def test_psnr_rows_cover_every_coarse_level_and_width(lod_document):
    table = _rows(lod_document, "psnr")
    assert sorted((r["level"], r["width"]) for r in table) == [(1, 24), (1, 48), (2, 24),
                                                               (2, 48)]
    for row in table:
        assert np.isfinite(row["psnr"]) and row["views"] == 1
    for row in [r for r in _rows(lod_document, "level") if r["file"] == "levels3"]:
        assert row["widths_at_30db"] == (widths_reaching(table, row["level"], 30.0)
                                         if row["level"] else None)
        assert row["width_at_refine_px"] > 0


def test_the_widths_reaching_a_threshold_are_those_at_or_above_it():
    table = [{"level": 1, "width": 200, "psnr": 36.0}, {"level": 1, "width": 400, "psnr": 31.0},
             {"level": 1, "width": 800, "psnr": 28.0}, {"level": 2, "width": 200, "psnr": 29.0}]
    assert widths_reaching(table, 1, 30.0) == [200, 400]
    assert widths_reaching(table, 1, 35.0) == [200]
    assert widths_reaching(table, 2, 30.0) == []


def test_copies_lie_apart_on_a_square_grid():
    scene = read_scene(SAMPLE)
    scene = scene.subset(np.arange(500))
    grid = grid_copies(scene, 4)
    assert len(grid) == 2000
    offsets = [grid.positions[k * 500] - scene.positions[0] for k in range(4)]
    assert len({tuple(np.round(o, 4)) for o in offsets}) == 4
    moved = [np.flatnonzero(np.abs(o) > 1e-6) for o in offsets]
    assert all(len(axes) <= 2 for axes in moved)  # never along the up axis
    assert np.allclose(np.mean(offsets, axis=0), 0, atol=1e-5)  # centred on the original
    low, high = robust_bounds(scene)
    step = (high - low) * (1 + GAP)  # neighbours a quarter of a copy's width apart
    apart = np.abs(offsets[1] - offsets[0])  # copies 0 and 1: neighbours in a row
    assert np.allclose(apart[apart > 0], step[apart > 0], rtol=1e-4)
