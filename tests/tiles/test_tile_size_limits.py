"""Tile sizes have a floor and tilings a ceiling (issue #29, item 9).

Rules: a scene that would be tiled is refused, before any tile is coded, when its tile size is
below 1,000 Gaussians (a scene of fewer than 16,000 may go down to a 16th of itself, so small
scenes still split into a few tiles) or when the tiling makes more tiles than a file's chunk
limit holds (4,095); the message states the minimum. A scene that fits one tile is never
refused. ``csgs encode --tile-size`` exits 2 with that one line and writes nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.codec import tile_encoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.codec.tiling import (
    MAX_ENCODED_TILES,
    MIN_TILE_SIZE,
    check_tiling,
    effective_tile_size,
    smallest_tile_size,
    split_tiles,
    tile_count,
)
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import write_ply
from tests.codec.helpers import random_scene

BIG = 20_000  # above 16,000: the 1,000 floor applies


@pytest.fixture
def no_tile_coding(monkeypatch):
    """Make coding any tile fail the test: a refusal must come before it."""
    def never(*args, **kwargs):
        raise AssertionError("tiles were coded before the tile size was checked")

    monkeypatch.setattr(tile_encoder, "run_jobs", never)


def test_the_minimum_is_a_thousand_for_large_scenes():
    assert MIN_TILE_SIZE == 1_000
    assert smallest_tile_size(BIG) == 1_000 and smallest_tile_size(10**8) == 1_000
    check_tiling(BIG, 1_000)
    for size in (1, 2, 999):
        with pytest.raises(InputError, match="minimum is 1,000 Gaussians") as info:
            check_tiling(BIG, size)
        assert info.value.property == "tile_size"


def test_small_scenes_may_use_tiles_down_to_a_sixteenth():
    assert smallest_tile_size(300) == 19 and smallest_tile_size(40) == 3
    check_tiling(300, 19)
    check_tiling(40, 12)  # the conformance vector tiled_semantic_small
    with pytest.raises(InputError, match="19 for these 300"):
        check_tiling(300, 18)


def test_a_scene_that_fits_one_tile_is_never_refused():
    check_tiling(500, 500)
    check_tiling(1, 1)
    assert effective_tile_size(50, 1_000) == 1_000


def test_too_many_tiles_are_refused_with_the_size_that_fits():
    assert MAX_ENCODED_TILES == 4_095
    with pytest.raises(InputError, match="more than the 4,095") as info:
        check_tiling(10_000_000, 1_000)
    fits = int(str(info.value).rsplit(" ", 1)[1].replace(",", ""))
    assert tile_count(10_000_000, fits) <= MAX_ENCODED_TILES < tile_count(10_000_000, fits - 1)
    check_tiling(10_000_000, fits)


@pytest.mark.parametrize("size", [1, 7, 100, 333, 1_000, 2_499, 5_000])
def test_tile_count_is_what_split_tiles_makes(size):
    points = np.random.default_rng(3).normal(size=(5_000, 3))
    assert tile_count(5_000, size) == len(split_tiles(points, size))


def test_the_encoder_refuses_a_tiny_tile_size_before_coding(no_tile_coding):
    with pytest.raises(InputError, match="minimum is 1,000"):
        Encoder(quality=5, hyperprior=False, tile_size=1).encode(random_scene(BIG, sh_degree=0))


@pytest.mark.parametrize("extra", [[], ["--sanitize"]], ids=["streamed", "read-whole"])
def test_cli_refuses_a_tiny_tile_size_with_exit_2(tmp_path, capsys, no_tile_coding, extra):
    ply = tmp_path / "big.ply"
    write_ply(random_scene(BIG, sh_degree=0), ply)
    out = tmp_path / "out.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--tile-size", "1", "--quiet",
                 "--no-hyperprior", *extra]) == 2
    err = capsys.readouterr().err
    assert "minimum is 1,000" in err and "Traceback" not in err and len(err.splitlines()) == 1
    assert not out.exists()
