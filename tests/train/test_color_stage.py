"""Stage 1: it learns the views, its rate term works, and it is reproducible and resumable."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import InputError, ModelError
from csgs_codec.train.checkpoint import load_checkpoint, save_checkpoint
from csgs_codec.train.color_stage import initial_state, train_color_stage
from tests.train.stage1_data import tiny_color_settings, tiny_dataset


def _train(**overrides):
    data = tiny_dataset()
    state = initial_state(data.views, data.scene.positions, tiny_color_settings(**overrides))
    return train_color_stage(data.views, state)


@pytest.fixture(scope="module")
def trained():
    return _train()


def _parameters(state) -> dict[str, np.ndarray]:
    out = {k: v.detach().numpy().copy() for k, v in state.model.state_dict().items()}
    out.update({f"rate.{k}": v.detach().numpy().copy()
                for k, v in state.rate_model.state_dict().items()})
    return out


def test_training_raises_the_view_psnr(trained):
    psnr = np.asarray(trained.history["psnr"])
    assert psnr[-10:].mean() > psnr[:5].mean() + 8.0
    assert np.isfinite(trained.history["loss"]).all()
    assert trained.skipped_steps == 0


def test_rate_term_starts_after_warm_up_and_falls(trained):
    bits = np.asarray(trained.history["bits_per_parameter"])
    start = int(0.3 * len(bits))
    assert (bits[:start] == 0).all()
    assert bits[start] > 0 and bits[-1] < bits[start]


def test_view_frequency_masking_drops_anchors_few_views_see():
    data = tiny_dataset()
    points = np.concatenate([data.scene.positions, [[1e4, 1e4, 1e4]]])
    settings = tiny_color_settings(initial_anchors=40)
    state = initial_state(data.views, points, settings)
    far = state.model.grid.cells_of(np.array([[1e4, 1e4, 1e4]]))[0].tolist()
    assert far not in state.model.cells.numpy().tolist()


def test_no_overlap_between_points_and_cameras_is_refused():
    data = tiny_dataset()
    with pytest.raises(InputError, match="points"):
        initial_state(data.views, np.full((10, 3), 1e5), tiny_color_settings())


def test_bad_settings_are_refused_by_name():
    data = tiny_dataset()
    for name, value in (("iterations", 0), ("rate_weight", float("nan")), ("quality", 10)):
        with pytest.raises(InputError, match=name):
            initial_state(data.views, data.scene.positions, tiny_color_settings(**{name: value}))


def test_training_is_bit_reproducible_from_the_seed(trained):
    again = _train()
    ours, theirs = _parameters(trained), _parameters(again)
    assert ours.keys() == theirs.keys()
    for key in ours:
        np.testing.assert_array_equal(ours[key], theirs[key], err_msg=key)


def test_a_resumed_run_equals_an_uninterrupted_one(trained, tmp_path):
    data = tiny_dataset()
    state = initial_state(data.views, data.scene.positions, tiny_color_settings())
    train_color_stage(data.views, state, stop_at=55)  # mid-interval: stats and order saved
    save_checkpoint(state, tmp_path / "stage1.pt")
    resumed = load_checkpoint(tmp_path / "stage1.pt")
    assert resumed.step == 55
    train_color_stage(data.views, resumed)
    ours, theirs = _parameters(trained), _parameters(resumed)
    for key in ours:
        np.testing.assert_array_equal(ours[key], theirs[key], err_msg=key)
    assert resumed.history["loss"] == trained.history["loss"]


def test_damaged_or_foreign_checkpoints_are_refused_naming_the_file(tmp_path):
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint")
    foreign = tmp_path / "foreign.pt"
    torch.save({"format": "something else"}, foreign)
    for path in (garbage, foreign, tmp_path / "missing.pt"):
        with pytest.raises(InputError) as error:
            load_checkpoint(path)
        assert path.name in str(error.value)


def test_a_checkpoint_of_an_earlier_format_is_refused_saying_so(tmp_path):
    old = tmp_path / "old.pt"
    torch.save({"format": "csgs-train-checkpoint/2"}, old)
    with pytest.raises(InputError, match="earlier version.*start the stage again") as error:
        load_checkpoint(old)
    assert "old.pt" in str(error.value)


def test_a_diverging_loss_stops_the_stage_with_a_model_error(monkeypatch):
    data = tiny_dataset()
    state = initial_state(data.views, data.scene.positions, tiny_color_settings())
    monkeypatch.setattr("csgs_codec.train.color_stage.photometric_loss",
                        lambda *args: torch.tensor(float("nan"), requires_grad=True))
    with pytest.raises(ModelError, match="diverged"):
        train_color_stage(data.views, state)
    assert state.skipped_steps == 20
