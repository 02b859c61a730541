"""The forms stage 1 takes to launch fewer operators a step (a GPU's step is bound by them)
give the same values and gradients as the plain forms, on the CPU."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.entropy.anchor_attributes import group_bounds
from csgs_codec.errors import InputError
from csgs_codec.model.scaffold import ScaffoldMLPs
from csgs_codec.render.device_constants import background_tensor, camera_tensors
from csgs_codec.train.anchor_growth import GrowthStats
from csgs_codec.train.anchor_model import AnchorGrid, AnchorModel
from csgs_codec.train.anchor_rate import ATTRIBUTES, AnchorRateModel
from csgs_codec.train.color_stage import _growth_ahead, initial_state, train_color_stage
from csgs_codec.train.quantization import gaussian_rate_bits
from tests.train.stage1_data import tiny_color_settings, tiny_dataset

STEPS = {"features": 0.1, "offsets": 0.05, "scaling": 0.2}


def _model() -> AnchorModel:
    data = tiny_dataset()
    model = AnchorModel(np.unique(np.floor(data.scene.positions / 0.25).astype(np.int64),
                                  axis=0),
                        AnchorGrid(np.zeros(3), 0.25), feat_dim=8, n_offsets=4, seed=3)
    with torch.no_grad():  # varied features and masks: some slots hidden, some kept
        model.features.normal_(0.0, 0.5, generator=torch.Generator().manual_seed(1))
        model.mask_logits.normal_(0.0, 6.0, generator=torch.Generator().manual_seed(2))
    return model


def _render_and_gradients(model: AnchorModel, all_slots: bool):
    model.zero_grad(set_to_none=True)
    camera = tiny_dataset().views[0].camera
    out, gaussians = model.render(camera, rasterizer="torch", all_slots=all_slots)
    (out.image.square().sum() + out.alpha.sum()).backward()
    grads = {name: p.grad.clone() for name, p in model.named_parameters()
             if p.grad is not None}
    return out, gaussians, grads


def test_all_slot_spawn_renders_and_differentiates_like_the_kept_slots():
    model = _model()
    kept_out, kept, kept_grads = _render_and_gradients(model, all_slots=False)
    all_out, every, all_grads = _render_and_gradients(model, all_slots=True)
    m, k = model.count, model.n_offsets
    assert every.all_slots and len(every.opacities) == m * k
    assert 0 < len(kept.opacities) < m * k  # some slots are hidden
    # Kept slots have the same Gaussians; hidden ones have opacity 0.
    index = torch.nonzero(kept.keep).reshape(-1)
    torch.testing.assert_close(every.positions[index], kept.positions)
    torch.testing.assert_close(every.opacities[index], kept.opacities)
    torch.testing.assert_close(every.log_scales[index], kept.log_scales)
    rotations = every.rotations[index]
    torch.testing.assert_close(rotations / rotations.norm(dim=1, keepdim=True),
                               kept.rotations)
    assert float(every.opacities.detach()[~every.keep].abs().max()) == 0.0
    torch.testing.assert_close(all_out.image, kept_out.image, atol=1e-5, rtol=1e-4)
    torch.testing.assert_close(all_out.alpha, kept_out.alpha, atol=1e-5, rtol=1e-4)
    assert set(all_grads) == set(kept_grads)
    for name, grad in kept_grads.items():
        scale = float(grad.abs().max()) + 1e-12
        np.testing.assert_allclose(all_grads[name].numpy() / scale, grad.numpy() / scale,
                                   atol=1e-4, err_msg=name)


def test_stage_one_with_all_slots_trains_like_the_kept_slots():
    data = tiny_dataset()
    states = []
    for all_slots in (False, True):
        settings = tiny_color_settings(iterations=40, growth_every=10, all_slots=all_slots,
                                       rasterizer="torch")
        state = initial_state(data.views, data.scene.positions, settings)
        states.append(train_color_stage(data.views, state))
    kept, every = states
    assert kept.model.count == every.model.count  # growth saw the same statistics
    np.testing.assert_allclose(every.history["psnr"], kept.history["psnr"], atol=0.05)
    np.testing.assert_allclose(every.history["bits_per_parameter"],
                               kept.history["bits_per_parameter"], rtol=1e-3, atol=1e-4)


def test_growth_statistics_from_all_slots_equal_those_from_kept_slots():
    model = _model()
    camera = tiny_dataset().views[0].camera
    seen = np.ones(model.count, bool)
    stats = []
    for all_slots in (False, True):
        model.zero_grad(set_to_none=True)
        out, gaussians = model.render(camera, rasterizer="torch", all_slots=all_slots)
        gaussians.positions.retain_grad()
        out.image.square().sum().backward()
        record = GrowthStats.empty(model.count, model.n_offsets)
        record.record(gaussians, camera, model.n_offsets, seen)
        stats.append(record)
    kept, every = stats
    torch.testing.assert_close(every.grad_count, kept.grad_count)
    torch.testing.assert_close(every.grad_sum, kept.grad_sum, rtol=1e-4, atol=1e-9)
    torch.testing.assert_close(every.opacity_sum, kept.opacity_sum)


def test_merged_first_layers_give_the_heads_outputs():
    torch.manual_seed(0)
    mlps = ScaffoldMLPs(8, 4, 12)
    features, view_dir, dist = torch.randn(30, 8), torch.randn(30, 3), torch.rand(30, 1)
    plain = mlps(features, view_dir, dist)
    merged = mlps(features, view_dir, dist, merge_first_layers=True)
    for a, b in zip(plain, merged):
        torch.testing.assert_close(a, b)
    mixed = ScaffoldMLPs(8, 4, 12, cov_dist=False)  # inputs differ: the plain form runs
    for a, b in zip(mixed(features, view_dir, dist),
                    mixed(features, view_dir, dist, merge_first_layers=True)):
        assert torch.equal(a, b)


def _per_group_reference(rate: AnchorRateModel, features: torch.Tensor, params: torch.Tensor):
    """The CARM as G - 1 separate networks read out of the masked blocks."""
    f, width = features.shape[1], params.shape[1] // 2
    mean, log_sigma = params[:, :width].clone(), params[:, width:].clone()
    half = rate.carm_first.shape[0] // (len(rate.bounds) - 1)
    for g, (start, end) in enumerate(rate.bounds[1:]):
        rows = slice(g * half, (g + 1) * half)
        hidden = torch.relu(features[:, :start] @ rate.carm_first[rows, :start].T
                            + rate.carm_first_bias[rows])
        for out, at in ((mean, start), (log_sigma, width + start)):
            block = slice(at, at + end - start)
            delta = hidden @ rate.carm_second[block, rows].T + rate.carm_second_bias[block]
            out[:, start:end] += delta
    assert f == rate.widths["features"]
    return mean, log_sigma


def test_masked_carm_is_the_per_group_networks_and_stays_autoregressive():
    torch.manual_seed(0)
    cells = torch.as_tensor(np.stack(np.meshgrid(*[np.arange(3)] * 3), -1).reshape(-1, 3))
    rate = AnchorRateModel(10, 2, STEPS, groups=4)
    assert rate.bounds == group_bounds(10, 4)
    features = torch.randn(len(cells), 10)
    mean, log_sigma = rate.entropy_parameters(cells, features)
    params = rate.hyper(rate._embedding(cells))
    ref_mean, ref_log_sigma = _per_group_reference(rate, features, params)
    torch.testing.assert_close(mean, ref_mean)
    torch.testing.assert_close(log_sigma, ref_log_sigma)
    # Group g's parameters do not move when features from group g on change.
    for start, end in rate.bounds:
        changed = features.clone()
        changed[:, start:] += 5.0
        again_mean, again_sigma = rate.entropy_parameters(cells, changed)
        torch.testing.assert_close(again_mean[:, :end], mean[:, :end])
        torch.testing.assert_close(again_sigma[:, :end], log_sigma[:, :end])
    # Training keeps the masked weights at zero.
    optimizer = torch.optim.Adam(rate.parameters(), lr=0.05)
    noisy = {"features": features, "offsets": torch.randn(len(cells), 2, 3),
             "scaling": torch.randn(len(cells), 6)}
    for _ in range(5):
        optimizer.zero_grad()
        rate.estimate(cells, noisy, torch.ones(len(cells), 2)).bits_per_parameter.backward()
        optimizer.step()
    assert float(rate.carm_first.detach()[rate.carm_first_mask == 0].abs().max()) == 0.0
    assert float(rate.carm_second.detach()[rate.carm_second_mask == 0].abs().max()) == 0.0
    assert float(rate.carm_second_bias.detach()[rate.carm_second_bias_mask == 0]
                 .abs().max()) == 0.0


def test_rate_estimate_sums_each_attributes_bits_with_masked_offsets_free():
    torch.manual_seed(1)
    cells = torch.as_tensor(np.stack(np.meshgrid(*[np.arange(3)] * 3), -1).reshape(-1, 3))
    m = len(cells)
    rate = AnchorRateModel(6, 3, STEPS, groups=3)
    noisy = {"features": torch.randn(m, 6), "offsets": torch.randn(m, 3, 3),
             "scaling": torch.randn(m, 6)}
    mask = (torch.rand(m, 3) > 0.4).float()
    estimate = rate.estimate(cells, noisy, mask)
    mean, log_sigma = rate.entropy_parameters(cells, noisy["features"])
    at, expected = 0, {}
    for name in ATTRIBUTES:
        width = rate.widths[name]
        step = STEPS[name]
        bits = gaussian_rate_bits(noisy[name].reshape(m, width), mean[:, at:at + width],
                                  torch.exp(log_sigma[:, at:at + width]) * step, step)
        if name == "offsets":
            bits = bits * mask.repeat_interleave(3, dim=1)
        expected[name] = bits.sum()
        at += width
    for name in ATTRIBUTES:
        torch.testing.assert_close(estimate.bits[name], expected[name])
    torch.testing.assert_close(estimate.total, sum(expected.values()))
    assert float(estimate.parameters) == m * (6 + 6) + 3 * float(mask.sum())


def test_rate_bits_gradients_match_finite_differences():
    generator = torch.Generator().manual_seed(5)
    values = torch.randn(40, dtype=torch.float64, generator=generator) * 3
    mean = torch.randn(1, dtype=torch.float64, generator=generator)  # broadcast
    sigma = torch.rand(40, dtype=torch.float64, generator=generator) * 2 + 0.2
    sigma[:4] = torch.tensor([0.01, 0.02, 80.0, 100.0])  # clamped to [0.11, 128] x 0.5
    values[4:6] = torch.tensor([40.0, -60.0])  # far in the tail: the probability floor
    inputs = tuple(t.requires_grad_() for t in (values, mean, sigma))
    assert torch.autograd.gradcheck(lambda v, m, s: gaussian_rate_bits(v, m, s, 0.5), inputs)


def test_written_out_rate_gradient_equals_the_recorded_one():
    from csgs_codec.train.quantization import _clamped_bin_mass

    generator = torch.Generator().manual_seed(8)
    shape = (200, 12)
    values = torch.randn(shape, generator=generator) * 4
    mean = torch.randn(shape, generator=generator)
    sigma = torch.rand(shape, generator=generator) * 3 + 0.01
    step = torch.rand((1, 12), generator=generator) + 0.1
    grads = []
    for written in (True, False):
        inputs = [t.clone().requires_grad_() for t in (values, mean, sigma)]
        if written:
            bits = gaussian_rate_bits(*inputs, step)
        else:
            bits = 1.0 - torch.log2(_clamped_bin_mass(*inputs, step)[0])
        (bits * torch.linspace(0.5, 2.0, 12)).sum().backward()
        grads.append([bits.detach()] + [t.grad for t in inputs])
    for ours, recorded in zip(*grads):
        torch.testing.assert_close(ours, recorded, rtol=2e-4, atol=1e-5)


def test_growth_statistics_stop_after_the_last_growth_round():
    data = tiny_dataset()
    settings = tiny_color_settings(iterations=100, growth_every=20, growth_start=0.1,
                                   growth_end=0.5)
    state = initial_state(data.views, data.scene.positions, settings)
    ahead = []
    for step in range(100):
        state.step = step
        ahead.append(_growth_ahead(state))
    # Rounds follow steps 20, 40 (growth_start 10 < t <= growth_end 50): statistics are
    # gathered through step 39 (the step that brings the count to 40), not after.
    assert ahead[:40] == [True] * 40 and not any(ahead[40:])
    off = tiny_color_settings(iterations=100, growth_start=1.0, growth_end=1.0)
    state = initial_state(data.views, data.scene.positions, off)
    assert not _growth_ahead(state)


def test_camera_and_background_tensors_are_made_once_and_hold_the_cameras_values():
    camera = tiny_dataset().views[1].camera
    first = camera_tensors(camera, "cpu")
    assert camera_tensors(camera, torch.device("cpu")) is first
    np.testing.assert_allclose(first.world_to_camera.numpy(), camera.world_to_camera,
                               rtol=1e-6)
    np.testing.assert_allclose(first.position.numpy(), camera.position, rtol=1e-5,
                               atol=1e-6)
    assert first.intrinsics.tolist() == [[pytest.approx(camera.fx), 0.0,
                                          pytest.approx(camera.cx)],
                                         [0.0, pytest.approx(camera.fy),
                                          pytest.approx(camera.cy)], [0.0, 0.0, 1.0]]
    other = tiny_dataset().views[2].camera
    assert camera_tensors(other, "cpu") is not first
    assert background_tensor((0.1, 0.2, 0.3), "cpu") is background_tensor([0.1, 0.2, 0.3],
                                                                          "cpu")
    assert background_tensor(None, "cpu").tolist() == [0.0, 0.0, 0.0]


def test_training_rasterizer_takes_exactly_one_opacity_form():
    from csgs_codec.render.differentiable import rasterize_for_training

    camera = tiny_dataset().views[0].camera
    args = (torch.zeros(1, 3), torch.zeros(1, 3), torch.tensor([[1.0, 0, 0, 0]]))
    with pytest.raises(InputError, match="opacit"):
        rasterize_for_training(*args, None, camera, colors=torch.zeros(1, 3))
    with pytest.raises(InputError, match="opacit"):
        rasterize_for_training(*args, torch.zeros(1), camera, colors=torch.zeros(1, 3),
                               opacities=torch.ones(1))
