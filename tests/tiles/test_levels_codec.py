"""Levels of detail (FORMAT §12.22, tile index version 2): encode, decode per level, the
tree in the tile index, the CLI."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec import Decoder, Encoder
from csgs_codec.chunks.tile_index import TileIndex, TileInfo
from csgs_codec.codec.level_tree import LevelTree, leaf_depth
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import read_layers
from csgs_codec.interchange.ply_io import write_ply
from tests.codec.helpers import random_scene

TILE = 800


@pytest.fixture(scope="module")
def scene():
    """A segmented scene: labels, and features one prototype per label (as csgs segment
    writes them, coded exactly as an instance codebook)."""
    scene = random_scene(3000, sh_degree=2, seed=3, semantic=2, labels=True)
    labels = np.unique(scene.labels, return_inverse=True)[1].reshape(-1)
    prototypes = np.stack([np.arange(labels.max() + 1), -np.arange(labels.max() + 1)], 1)
    scene.semantic = (prototypes[labels] * 0.5).astype(np.float32)
    return scene


@pytest.fixture(scope="module")
def leveled(scene):
    return Encoder(quality=5, hyperprior=False, tile_size=TILE, levels=3).encode_with_report(
        scene)


@pytest.fixture(scope="module")
def flat(scene):
    return Encoder(quality=5, hyperprior=False, tile_size=TILE).encode_with_report(scene)


def tile_index(data: bytes) -> TileIndex:
    container = read_layers(data, layers=set())
    entry = container.toc[0]
    return TileIndex.from_bytes(bytes(container.payloads[entry.index]), entry.offset + 8)


def test_level_zero_is_the_file_without_levels(scene, leveled, flat):
    decoded = Decoder().decode(leveled.data, "color,semantic")
    assert decoded.equals(Decoder().decode(flat.data, "color,semantic"))
    assert decoded.equals(leveled.reconstruction)
    assert np.array_equal(leveled.order, flat.order)
    assert leveled.levels == 3 and leveled.tiles == 4 + 1 + 1


def test_the_tree_in_the_tile_index(leveled):
    index = tile_index(leveled.data)
    assert index.levels == 3
    assert [t.level for t in index.tiles] == [2, 1, 0, 0, 0, 0]
    assert [t.parent for t in index.tiles] == [None, 0, 1, 1, 1, 1]
    assert index.children(1) == [2, 3, 4, 5]
    counts = [sum(index.tiles[i].count for i in index.level_tiles(k)) for k in range(3)]
    assert counts[0] == 3000
    # every tile of level l merges its children's Gaussians 8 to 1
    for level in (1, 2):
        for number in index.level_tiles(level):
            below = sum(index.tiles[c].count for c in index.children(number))
            assert index.tiles[number].count == -(-below // 8)


def test_each_level_decodes_alone_reading_its_tiles_only(leveled):
    sizes = []
    for level in range(3):
        report = Decoder().decode_with_report(leveled.data, "color,semantic", lod=level)
        assert report.level == level and report.levels == 3
        assert report.tiles == tile_index(leveled.data).level_tiles(level)
        sizes.append(report.bytes_read)
        scene = report.scene
        assert np.all(np.isfinite(scene.positions)) and np.all(np.isfinite(scene.opacity))
    assert sizes[2] < sizes[1] < sizes[0]
    assert sizes[2] < 0.05 * len(leveled.data)


def test_coarse_levels_keep_the_scene_and_its_instances(scene, leveled):
    fine = leveled.reconstruction
    coarse = Decoder().decode(leveled.data, "color,semantic", lod=1)
    # every merged Gaussian sits among the Gaussians it came from
    lo, hi = fine.positions.min(axis=0), fine.positions.max(axis=0)
    assert np.all(coarse.positions >= lo - 1e-3) and np.all(coarse.positions <= hi + 1e-3)
    assert set(coarse.labels.tolist()) <= set(fine.labels.tolist())
    fine_rows = {tuple(r) for r in fine.semantic.tolist()}
    assert {tuple(r) for r in coarse.semantic.tolist()} <= fine_rows
    # a coarse Gaussian is larger than the fine ones on average
    assert np.mean(coarse.scales.max(axis=1)) > np.mean(fine.scales.max(axis=1))


def test_region_picks_tiles_of_the_level(leveled):
    index = tile_index(leveled.data)
    box = index.tiles[index.level_tiles(0)[0]]
    report = Decoder().decode_with_report(leveled.data, lod=0, region=box.lower + box.upper)
    assert index.level_tiles(0)[0] in report.tiles
    assert set(report.tiles) <= set(index.level_tiles(0))
    report = Decoder().decode_with_report(leveled.data, lod=2, region=box.lower + box.upper)
    assert report.tiles == [0]


def test_tiles_of_any_level_and_bad_levels(leveled, flat):
    report = Decoder().decode_with_report(leveled.data, tiles=[0, 5])
    assert report.tiles == [0, 5] and report.level is None
    with pytest.raises(InputError, match="levels 0..2"):
        Decoder().decode(leveled.data, lod=3)
    with pytest.raises(InputError, match="not both"):
        Decoder().decode(leveled.data, lod=0, tiles=[1])
    with pytest.raises(InputError, match="lod"):
        Decoder().decode(leveled.data, lod=-1)
    assert len(Decoder().decode(flat.data, lod=0)) == 3000
    with pytest.raises(InputError, match="one level"):
        Decoder().decode(flat.data, lod=1)


def test_levels_setting_is_checked():
    for bad in (0, 17, True, 2.0):
        with pytest.raises(InputError, match="levels"):
            Encoder(levels=bad)
    with pytest.raises(InputError, match="refinement"):
        Encoder(levels=2, refine=10)


def test_a_scene_in_one_leaf_still_gets_coarse_levels():
    scene = random_scene(900, seed=8)
    report = Encoder(hyperprior=False, levels=2).encode_with_report(scene)
    index = tile_index(report.data)
    assert [(t.level, t.parent) for t in index.tiles] == [(1, None), (0, 0)]
    assert index.tiles[0].count == -(-900 // 8)
    assert Decoder().decode(report.data).equals(report.reconstruction)


def test_leaves_share_one_depth():
    p = np.random.default_rng(9).normal(size=(5000, 3))
    tree = LevelTree.build(p, 700, 3)
    assert tree.depth == leaf_depth(5000, 700) == 3
    assert len(tree.leaves) == 8 and all(len(rows) in (625,) for rows in tree.leaves)
    assert np.array_equal(np.sort(np.concatenate(tree.leaves)), np.arange(5000))
    assert tree.tile_count == 8 + 1 + 1
    assert [tree.parent(0, j) for j in range(8)] == [1] * 8 and tree.parent(2, 0) is None


def _entry(level, parent):
    return TileInfo(10, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), level, parent)


def test_index_version_two_round_trips():
    index = TileIndex((_entry(1, None), _entry(0, 0), _entry(0, 0)))
    data = index.to_bytes()
    assert data[0] == 2
    assert TileIndex.from_bytes(data) == index
    flat = TileIndex((_entry(0, None), _entry(0, None)))
    assert flat.to_bytes()[0] == 1 and TileIndex.from_bytes(flat.to_bytes()) == flat


@pytest.mark.parametrize("tiles, message", [
    ((_entry(1, None), _entry(0, None)), "has no parent"),
    ((_entry(1, 0), _entry(0, 0)), "top level 1 and has a parent"),
    ((_entry(1, None), _entry(0, 1)), "is not a tile of level 1"),
    ((_entry(1, None), _entry(0, 5)), "is not a tile of level 1"),
    ((_entry(2, None), _entry(1, 0), _entry(0, 0)), "is not a tile of level 1"),
    ((_entry(1, None), _entry(1, None), _entry(0, 0)), "no tile's parent"),
])
def test_malformed_trees_are_refused_naming_tidx(tiles, message):
    data = _raw_index(tiles)
    with pytest.raises(FormatError, match=message) as caught:
        TileIndex.from_bytes(data, 100)
    assert caught.value.chunk == "TIDX" and caught.value.offset >= 100


def test_a_level_above_fifteen_and_an_all_zero_version_two_are_refused():
    with pytest.raises(FormatError, match="level 16"):
        TileIndex.from_bytes(_raw_index((_entry(16, None), _entry(15, 0))))
    with pytest.raises(FormatError, match="all of level 0"):
        TileIndex.from_bytes(_raw_index((_entry(0, None),)))


def _raw_index(tiles) -> bytes:
    """A version-2 payload of ``tiles`` as given (to_bytes writes version 1 when every tile
    is of level 0)."""
    out = bytearray([2, len(tiles)])
    for t in tiles:
        out += bytes([t.count]) + np.asarray(t.lower + t.upper, "<f4").tobytes()
        out += bytes([t.level, 0 if t.parent is None else t.parent + 1])
    return bytes(out)


def test_cli_encodes_levels_and_decodes_one(tmp_path, capsys):
    ply = tmp_path / "scene.ply"
    write_ply(random_scene(2000, seed=2), ply)
    out = tmp_path / "scene.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--levels", "2", "--tile-size", "500",
                 "--no-hyperprior", "--quiet"]) == 0
    assert "5 tiles in 2 levels of detail" in capsys.readouterr().out
    assert main(["decode", str(out), "-o", str(tmp_path / "coarse.ply"), "--lod", "1",
                 "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "250 Gaussians" in printed and "level 1 of 2" in printed
    assert main(["info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "2,000 Gaussians" in printed and "level 1          250 Gaussians in 1 tiles" in printed
    assert main(["decode", str(out), "-o", str(tmp_path / "x.ply"), "--lod", "2",
                 "--quiet"]) == 2
    assert "level 2 is not in the file" in capsys.readouterr().err
    assert main(["encode", str(ply), "-o", str(tmp_path / "y.csgs"), "--levels", "0",
                 "--quiet"]) == 2


def test_coarser_levels_code_with_coarser_steps():
    from csgs_codec.codec.level_encoder import level_settings
    from csgs_codec.decisions.presets import preset

    base = preset(5)
    assert level_settings(base, 0) == base
    two = level_settings(base, 2)
    assert two.dc_step == 4 * base.dc_step and two.rotation_step == 4 * base.rotation_step
    assert two.semantic_step == base.semantic_step and two.position_bits == base.position_bits
