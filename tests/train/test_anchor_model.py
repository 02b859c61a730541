"""The trainable anchor model, its rate model and anchor growth (stage 1's parts)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.model.scaffold import ScaffoldDecoder
from csgs_codec.scene.camera import Camera
from csgs_codec.train.anchor_growth import GrowthStats, grow_and_prune, view_counts
from csgs_codec.train.anchor_model import MASK_THRESHOLD, AnchorGrid, AnchorModel, grid_for_points
from csgs_codec.train.anchor_rate import AnchorRateModel
from tests.train.stage1_data import tiny_dataset


def _model(cells=None, **kwargs) -> AnchorModel:
    cells = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 1]]) if cells is None else cells
    return AnchorModel(cells, AnchorGrid(np.zeros(3), 0.1), feat_dim=4, n_offsets=3, **kwargs)


def test_grid_voxel_gives_about_the_requested_anchor_count():
    points = np.random.default_rng(0).uniform(-1, 1, (20000, 3))
    for target in (50, 500, 5000):
        grid = grid_for_points(points, target)
        occupied = len(np.unique(grid.cells_of(points), axis=0))
        assert 0.5 * target <= occupied <= target


def test_grid_for_fewer_points_than_anchors_keeps_voxels_at_the_point_spacing():
    points = np.random.default_rng(1).uniform(-1, 1, (600, 3))
    grid = grid_for_points(points, 2000)
    occupied = len(np.unique(grid.cells_of(points), axis=0))
    assert 150 <= occupied <= 300
    assert grid.voxel > 0.05  # mean spacing of 600 points in a 2-unit cube: about 0.24


def test_grid_refuses_empty_points_and_bad_targets():
    with pytest.raises(InputError, match="points"):
        grid_for_points(np.zeros((0, 3)), 10)
    with pytest.raises(InputError, match="anchors"):
        grid_for_points(np.zeros((4, 3)), 0)


def test_anchor_positions_are_voxel_centres():
    model = _model()
    expected = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.2, 0.1]], np.float32)
    np.testing.assert_allclose(model.positions.numpy(), expected, atol=1e-7)


def test_export_matches_what_the_decoder_spawns():
    """The AnchorScene a model exports decodes (ScaffoldDecoder) to the model's own Gaussians."""
    model = _model(seed=3)
    with torch.no_grad():
        model.features.normal_()
        model.mask_logits[0, 1] = -10.0  # one slot masked
    scene = model.to_anchor_scene()
    assert not scene.offset_mask[0, 1] and scene.offset_mask.sum() == 8
    assert scene.offsets[0, 1].tolist() == [0.0, 0.0, 0.0]
    camera = Camera(32, 24, 30.0, 30.0, 16.0, 12.0, np.array(
        [[1, 0, 0, -0.05], [0, 1, 0, -0.1], [0, 0, 1, 2.0], [0, 0, 0, 1]], np.float64))
    with torch.no_grad():
        ours = model.spawn(camera)
    theirs = ScaffoldDecoder(scene).decode(camera.position)
    np.testing.assert_array_equal(theirs.anchor_index, ours.anchor_index.numpy())
    np.testing.assert_allclose(theirs.gaussians.positions, ours.positions.numpy(), atol=1e-6)


def test_mask_is_hard_forward_and_soft_backward():
    model = _model()
    with torch.no_grad():
        model.mask_logits[1, 0] = -20.0
    mask = model.mask()
    assert mask[1, 0].item() == 0.0 and mask[0, 0].item() == 1.0
    mask.sum().backward()
    assert model.mask_logits.grad.abs().sum() > 0
    assert torch.sigmoid(torch.tensor(-20.0)) < MASK_THRESHOLD


def test_resize_keeps_survivors_and_seeds_new_anchors_from_their_parents():
    model = _model()
    with torch.no_grad():
        model.features.copy_(torch.arange(12, dtype=torch.float32).reshape(3, 4))
    keep = torch.tensor([True, False, True])
    model.resize(keep, np.array([[5, 5, 5]]), torch.tensor([1]))
    assert model.count == 3
    np.testing.assert_array_equal(model.cells.numpy(), [[0, 0, 0], [0, 2, 1], [5, 5, 5]])
    np.testing.assert_array_equal(model.features.detach().numpy()[2], [4, 5, 6, 7])
    np.testing.assert_array_equal(model.features.detach().numpy()[1], [8, 9, 10, 11])


def test_rate_model_prices_masked_offsets_at_zero():
    model = _model()
    rate = AnchorRateModel(4, 3, {"features": 0.1, "offsets": 0.1, "scaling": 0.1}, groups=2)
    noisy = {"features": model.features, "offsets": model.offsets, "scaling": model.scaling}
    full = rate.estimate(model.cells, noisy, torch.ones(3, 3))
    masked = rate.estimate(model.cells, noisy, torch.zeros(3, 3))
    assert float(masked.bits["offsets"].detach()) == 0.0
    assert float(full.bits["offsets"].detach()) > 0
    assert float(masked.parameters) == 3 * (4 + 6)
    assert float(full.parameters) == 3 * (4 + 6) + 27


def test_rate_model_learns_to_price_concentrated_values_lower():
    torch.manual_seed(0)
    model = _model(cells=np.stack(np.meshgrid(*[np.arange(4)] * 3), -1).reshape(-1, 3))
    rate = AnchorRateModel(4, 3, {"features": 0.05, "offsets": 0.05, "scaling": 0.05})
    noisy = {"features": 0.02 * torch.randn(64, 4), "offsets": torch.zeros(64, 3, 3),
             "scaling": torch.zeros(64, 6)}
    mask = torch.ones(64, 3)
    optimizer = torch.optim.Adam(rate.parameters(), lr=0.01)
    before = float(rate.estimate(model.cells, noisy, mask).bits_per_parameter.detach())
    for _ in range(150):
        optimizer.zero_grad()
        estimate = rate.estimate(model.cells, noisy, mask)
        estimate.bits_per_parameter.backward()
        optimizer.step()
    after = float(rate.estimate(model.cells, noisy, mask).bits_per_parameter.detach())
    assert after < 0.5 * before


def test_view_counts_count_the_cameras_that_see_each_point():
    views = tiny_dataset().views
    cameras = [v.camera for v in views]
    centre = np.asarray(tiny_dataset().scene.positions, np.float64).mean(axis=0)
    far = centre + 1e6
    counts = view_counts(np.stack([centre, far]), cameras)
    assert counts.tolist() == [len(cameras), 0]


def test_growth_adds_anchors_where_gradients_are_large_and_prunes_transparent_ones():
    model = _model()
    stats = GrowthStats.empty(3, 3)
    stats.grad_count[:] = 1
    stats.grad_sum[:] = 1e-6
    stats.grad_sum[4] = 1.0  # anchor 1, slot 1
    stats.visits[:] = 1
    stats.opacity_sum[:] = torch.tensor([0.5, 0.5, 0.0], dtype=torch.float64)
    with torch.no_grad():
        model.offsets.zero_()
        model.offsets[1, 1] = torch.tensor([3.0, 0.0, 0.0])  # 3 voxels from its anchor
    grown, pruned = grow_and_prune(model, stats, grow_fraction=0.1, min_opacity=0.01,
                                   max_anchors=10)
    assert (grown, pruned) == (1, 1)
    assert model.count == 3
    assert [4, 0, 0] in model.cells.numpy().tolist()
    assert [0, 2, 1] not in model.cells.numpy().tolist()


def test_growth_respects_the_anchor_limit():
    model = _model()
    stats = GrowthStats.empty(3, 3)
    stats.grad_count[:] = 1
    stats.grad_sum[:] = torch.linspace(1, 2, 9, dtype=torch.float64)
    with torch.no_grad():
        model.offsets.copy_(torch.linspace(-40, 40, 27).reshape(3, 3, 3))
    grown, _ = grow_and_prune(model, stats, grow_fraction=1.0, min_opacity=0.0,
                              max_anchors=4)
    assert grown == 1 and model.count == 4
