"""`EncodeReport.order` carries per-Gaussian data across a round trip (issue #55 item 5.3):
for each decoded Gaussian, the row of the scene given to the encoder it came from, pruned
Gaussians absent, tiled or not."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions.presets import preset
from tests.codec.helpers import random_scene

COUNT = 2000


def _opacity(scene) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-scene.opacity.astype(np.float64)))


def check_order(scene, order: np.ndarray, decoded, quality: int, prune: float | None) -> None:
    """``order`` lines ``scene`` up with ``decoded``: positions within half a grid cell,
    the labels (an exact per-Gaussian column) equal, every kept Gaussian exactly once."""
    kept = np.arange(len(scene)) if prune is None else np.flatnonzero(_opacity(scene) >= prune)
    assert order.dtype == np.int64 and order.shape == (len(decoded),)
    assert np.array_equal(np.sort(order), kept)
    # The grid is fitted to the Gaussians coded (after pruning).
    cell = PositionGrid.fit(scene.positions[kept], preset(quality).position_bits).cell
    error = np.abs(decoded.positions.astype(np.float64) - scene.positions[order]).max()
    assert error <= 0.5 * cell * 1.001 + 1e-7
    assert np.array_equal(decoded.labels, scene.labels[order])


@pytest.mark.parametrize("prune", [None, 0.3])
@pytest.mark.parametrize("tile_size", [None, 500], ids=["untiled", "tiled"])
@pytest.mark.parametrize("quality", [3, 5])
def test_order_maps_each_decoded_gaussian_to_its_input_row(quality, tile_size, prune):
    scene = random_scene(COUNT, sh_degree=0, labels=True, seed=quality)
    result = Encoder(quality=quality, tile_size=tile_size, prune_opacity=prune,
                     hyperprior=False, step_allocation=False).encode_with_report(scene)
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert result.tiles == (1 if tile_size is None else 4)
    if prune is not None:
        assert 0 < result.pruned == len(scene) - len(decoded)
    check_order(scene, result.order, decoded, quality, prune)



@pytest.mark.slow  # view pruning's probe renders: about 10 s on 2 cores
def test_order_composes_view_pruning_with_opacity_pruning():
    scene = random_scene(1400, sh_degree=0, labels=True, seed=7)
    result = Encoder(quality=5, prune_opacity=0.1, view_pruning=True, hyperprior=False,
                     step_allocation=False).encode_with_report(scene)
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert result.view_pruned > 0 and len(decoded) == 1400 - result.pruned - result.view_pruned
    kept = np.flatnonzero(_opacity(scene) >= 0.1)
    assert np.isin(result.order, kept).all() and len(np.unique(result.order)) == len(decoded)
    cell = PositionGrid.fit(scene.positions[kept], preset(5).position_bits).cell
    error = np.abs(decoded.positions.astype(np.float64) - scene.positions[result.order]).max()
    assert error <= 0.5 * cell * 1.001 + 1e-7
    assert np.array_equal(decoded.labels, scene.labels[result.order])
