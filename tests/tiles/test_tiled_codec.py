"""Spatial tiles (FORMAT §12.22): the split, the tile index, whole and partial decodes."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.chunks.tile_index import TileIndex
from csgs_codec.codec.tiling import split_tiles
from csgs_codec.decisions.step_allocation import MIN_GAUSSIANS
from csgs_codec.errors import CsgsWarning, FormatError, InputError
from csgs_codec.format import Chunk, read_layers, write_container
from tests.codec.helpers import random_scene


@pytest.fixture(scope="module")
def scene():
    return random_scene(3000, sh_degree=2, seed=3, semantic=2, labels=True)


@pytest.fixture(scope="module")
def tiled(scene):
    return Encoder(quality=5, hyperprior=False, tile_size=800).encode_with_report(scene)


class RangeReader:
    """A byte-range reader over bytes, as an HTTP client would be (FORMAT source protocol)."""

    def __init__(self, data: bytes) -> None:
        self.data, self.size, self.calls = data, len(data), []

    def read_range(self, offset: int, size: int) -> bytes:
        self.calls.append((offset, size))
        return self.data[offset:offset + size]


def test_split_is_a_partition_of_bounded_tiles():
    p = np.random.default_rng(0).normal(size=(1000, 3)).astype(np.float32)
    tiles = split_tiles(p, 130)
    rows = np.sort(np.concatenate(tiles))
    assert np.array_equal(rows, np.arange(1000))
    assert all(65 <= len(t) <= 130 for t in tiles)
    assert all(np.all(np.diff(t) > 0) for t in tiles)
    again = split_tiles(p.copy(), 130)
    assert all(np.array_equal(a, b) for a, b in zip(tiles, again))


def test_far_outlier_goes_to_an_outer_tile_without_moving_the_cuts():
    p = np.random.default_rng(1).uniform(-1, 1, size=(400, 3)).astype(np.float32)
    moved = p.copy()
    moved[7] = (1e6, 0.0, 0.0)
    a, b = split_tiles(p, 100), split_tiles(moved, 100)
    # The robust box chooses the axes, so the outlier changes no cut axis: only the
    # membership of point 7 and the median ranks can change.
    tile_of_7 = next(i for i, t in enumerate(b) if 7 in t)
    assert moved[b[tile_of_7]][:, 0].max() == np.float32(1e6)
    assert len(a) == len(b) == 4


def test_single_tile_files_are_unchanged(scene):
    # Above MIN_GAUSSIANS, so the step allocation runs, and a third of the scene (2.9 s an
    # encode rather than 6.2).
    part = scene.subset(np.arange(MIN_GAUSSIANS + 76))
    plain = Encoder(quality=5, hyperprior=False).encode(part)
    assert Encoder(quality=5, hyperprior=False, tile_size=len(part)).encode(part) == plain
    assert b"TIDX" not in plain[:200]


def test_tiled_file_layout(tiled):
    container = read_layers(tiled.data, "color,semantic")
    toc = container.toc
    assert toc[0].type == "TIDX" and toc[0].tile == 0
    index = TileIndex.from_bytes(container.payloads[0])
    assert tiled.tiles == len(index.tiles) == 4
    assert [t.count for t in index.tiles] == [750] * 4
    for number in range(4):
        types = [e.type for e in toc if e.tile == number and e.type != "TIDX"]
        assert types.count("SCNE") == 1 and types.count("GEOM") == 1
        assert "SEMF" in types and "SEML" in types
    assert [int(e.layer) for e in toc] == sorted(int(e.layer) for e in toc)


def test_all_tiles_decode_to_the_reconstruction(scene, tiled):
    decoded = Decoder().decode(tiled.data, layers="color,semantic")
    assert decoded.equals(tiled.reconstruction)
    assert np.array_equal(np.sort(tiled.order), np.arange(len(scene)))
    # Positions are quantized as in the untiled encode (the whole scene's grid cell) with the
    # preset's steps, which a tiled scene keeps (no step allocation across tiles).
    untiled = Encoder(quality=5, hyperprior=False,
                      step_allocation=False).encode_with_report(scene)
    a = tiled.reconstruction.positions[np.argsort(tiled.order)]
    b = untiled.reconstruction.positions[np.argsort(untiled.order)]
    assert np.abs(a - b).max() <= 1e-6
    assert np.array_equal(decoded.labels, scene.labels[tiled.order])


def test_decoder_threads_do_not_change_the_tiled_decode(tiled):
    one = Decoder(threads=1).decode(tiled.data)
    two = Decoder(threads=2).decode(tiled.data)
    assert one.equals(two) and one.equals(Decoder(threads=3).decode(tiled.data))


def test_chosen_tiles_read_only_their_chunks(tiled, tmp_path):
    full = Decoder().decode_with_report(tiled.data, layers="color,semantic")
    part = Decoder().decode_with_report(tiled.data, tiles=[3, 1], layers="color,semantic")
    assert part.tiles == [1, 3] and part.tile_count == 4
    rows = np.r_[750:1500, 2250:3000]
    assert part.scene.equals(tiled.reconstruction.subset(rows))
    container = read_layers(tiled.data, "color,semantic")
    expected = container.header_and_toc_size + sum(
        e.frame_size for e in container.toc if e.tile in (1, 3) or e.type == "TIDX")
    assert part.bytes_read == expected < full.bytes_read == len(tiled.data)
    path = tmp_path / "scene.csgs"
    path.write_bytes(tiled.data)
    reader = RangeReader(tiled.data)
    with open(path, "rb") as handle:
        for source in (path, str(path), handle, reader, bytearray(tiled.data)):
            got = Decoder().decode_with_report(source, tiles=[1, 3], layers="color,semantic")
            assert got.scene.equals(part.scene) and got.bytes_read == part.bytes_read
    assert sum(size for _, size in reader.calls) == part.bytes_read


def test_region_selects_the_tiles_its_box_meets(tiled):
    index = TileIndex.from_bytes(read_layers(tiled.data).payloads[0])
    box = index.tiles[2]
    inner = [v + 1e-3 for v in box.lower] + [v - 1e-3 for v in box.upper]
    got = Decoder().decode_with_report(tiled.data, region=inner)
    assert 2 in got.tiles
    assert got.tiles == index.select(inner[:3], inner[3:])
    everywhere = Decoder().decode_with_report(tiled.data, region=(-9, -9, -9, 9, 9, 9))
    assert everywhere.tiles == [0, 1, 2, 3]
    nowhere = Decoder().decode_with_report(tiled.data, region=(5, 5, 5, 6, 6, 6))
    assert nowhere.tiles == [] and nowhere.scene is None
    container = read_layers(tiled.data)
    assert nowhere.bytes_read == container.header_and_toc_size + container.toc[0].frame_size


@pytest.mark.parametrize("kwargs", [
    {"tiles": [4]}, {"tiles": [-1]}, {"tiles": ["a"]}, {"tiles": 3},
    {"region": (0, 0, 0, 1, 1)}, {"region": (1, 0, 0, 0, 1, 1)},
    {"region": (0, 0, 0, 1, 1, float("nan"))}, {"region": "abc"}])
def test_bad_tiles_and_regions_are_input_errors(tiled, kwargs):
    with pytest.raises(InputError):
        Decoder().decode(tiled.data, **kwargs)


def test_untiled_file_is_tile_zero(scene):
    data = Encoder(quality=5, hyperprior=False, step_allocation=False).encode(scene)
    report = Decoder().decode_with_report(data, region=(5, 5, 5, 6, 6, 6))
    assert report.tiles == [0] and report.tile_count == 1 and len(report.scene) == len(scene)
    with pytest.raises(InputError, match="tile 1"):
        Decoder().decode(data, tiles=[1])


def test_far_points_per_tile():
    scene = random_scene(1200, seed=5)
    scene.positions[::97] *= 1e5
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CsgsWarning)
        result = Encoder(quality=6, hyperprior=False, tile_size=400).encode_with_report(scene)
    assert result.tiles == 4
    assert Decoder().decode(result.data).equals(result.reconstruction)


def _rewrite(data: bytes, edit) -> bytes:
    container = read_layers(data, "color,semantic")
    chunks = [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
              for e in container.toc]
    return write_container(edit(chunks))


def _index_with(data: bytes, change) -> bytes:
    def edit(chunks):
        index = TileIndex.from_bytes(chunks[0].payload)
        chunks[0] = Chunk("TIDX", "base", TileIndex(change(list(index.tiles))).to_bytes())
        return chunks
    return _rewrite(data, edit)


def test_damaged_tile_index_is_rejected(tiled):
    from dataclasses import replace

    cases = {
        "count": _index_with(tiled.data, lambda t: [replace(t[0], count=t[0].count - 1)]
                             + t[1:]),
        "box": _index_with(tiled.data, lambda t: [replace(t[0], upper=t[0].lower)] + t[1:]),
        "missing tile": _index_with(tiled.data, lambda t: t[:3]),
        "not first": _rewrite(tiled.data, lambda c: c[1:2] + c[:1] + c[2:]),
        "twice": _rewrite(tiled.data, lambda c: c[:1] + c),
    }
    for name, bad in cases.items():
        with pytest.raises(FormatError) as err:
            Decoder().decode(bad)
        assert err.value.chunk is not None, name
    with pytest.raises(FormatError, match="version"):
        TileIndex.from_bytes(b"\x03\x01")
    with pytest.raises(FormatError, match="tile_count"):
        TileIndex.from_bytes(b"\x01\x05" + bytes(30))


def test_tiled_file_truncated_anywhere_is_a_format_error(tiled):
    data = tiled.data
    color_end = read_layers(data).layer_end("color")
    for cut in list(range(0, 200, 7)) + list(range(200, len(data), max(len(data) // 60, 1))):
        try:
            Decoder().decode(data[:cut], layers="color")
        except FormatError:
            continue
        assert cut >= color_end, cut


def test_bad_tile_size_is_refused():
    for bad in (0, -3, 1.5, True, 1 << 25):
        with pytest.raises(InputError):
            Encoder(tile_size=bad)


@pytest.mark.slow
def test_view_pruning_and_lambda_search_work_on_tiles():
    from csgs_codec import read_ply
    from tests.conftest import SAMPLE

    scene = read_ply(SAMPLE).subset(np.arange(0, 45624, 12))
    pruned = Encoder(quality=5, hyperprior=False, view_pruning=True,
                     tile_size=1500).encode_with_report(scene)
    assert pruned.tiles > 1 and pruned.view_pruned > 0
    assert Decoder().decode(pruned.data).equals(pruned.reconstruction)
    searched = Encoder(lambda_=0.25, fast=True, tile_size=1500).encode_with_report(scene)
    assert searched.tiles > 1
    assert Decoder().decode(searched.data).equals(searched.reconstruction)


def test_info_counts_every_tile(tiled):
    from csgs_codec.codec.describe import describe_bitstream

    facts = describe_bitstream(tiled.data)
    assert facts["gaussians"] == 3000 and facts["tiles"] == 4
    assert facts["bits_per_gaussian"] == pytest.approx(8 * len(tiled.data) / 3000)
