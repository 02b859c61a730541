"""Stage 1 and ``csgs train`` under odd inputs and interrupted runs: each test pins one rule
a review found broken ("Was:" says how it failed before the fix) or checked and found right.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.train.anchor_growth import GrowthStats
from csgs_codec.train.checkpoint import load_checkpoint, save_checkpoint
from csgs_codec.train.color_stage import initial_state, make_optimizers, train_color_stage
from csgs_codec.train.initial_points import read_ply_points
from csgs_codec.train.pipeline import CHECKPOINT_FILE, train_scene
from csgs_codec.train.quantization import add_quantization_noise
from csgs_codec.train.synthetic import make_synthetic_dataset
from csgs_codec.train.views import TrainingView
from tests.train.stage1_data import tiny_color_settings, tiny_dataset, tiny_train_settings

# The shortest run the CLI tests need: they fail (or should fail) before or right after
# stage 1 starts.
FAST = ["--iterations", "3", "--anchors", "20", "--semantic-iterations", "2", "-q"]


def _state(**overrides):
    data = tiny_dataset()
    return initial_state(data.views, data.scene.positions, tiny_color_settings(**overrides))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A tiny transforms.json dataset on disk (4 views of 24x18, masks, scene.ply)."""
    folder = tmp_path_factory.mktemp("review_data")
    make_synthetic_dataset(2, objects=2, gaussians_per_object=40, views=4, width=24,
                           height=18).write(folder)
    return folder


# --- stage 1 maths and state -------------------------------------------------------------


def test_the_bits_per_parameter_denominator_carries_no_gradient():
    # Was: anchor_rate.py:129 counts coded values as m*(F+6) + 3*mask.sum() with the
    # straight-through mask, so d(R/P)/d(mask logit) gains -3R/P^2: every slot whose offsets
    # cost fewer bits than the average value is pushed ON by the rate term (measured: 24% of
    # the slots of the tiny scene at initialisation). HAC divides by a constant count.
    # Fix: `coded = (...).detach()` (or count every slot, as HAC does).
    state = _state()
    model = state.model
    noisy = {name: add_quantization_noise(getattr(model, name), step)
             for name, step in state.settings.steps().items()}
    estimate = state.rate_model.estimate(model.cells, noisy, model.mask())
    assert not estimate.parameters.requires_grad


def test_a_growth_round_keeps_the_adam_state_of_the_surviving_anchors():
    # Was: color_stage.py:317-320 calls make_optimizers after every growth round, even one
    # that grew and pruned nothing, so every per-anchor Adam moment and step count restarts
    # (the first step after the round moves every anchor parameter by about lr * sign(grad)).
    # Scaffold-GS keeps the state of surviving rows and zero-fills new rows. Fix: rebuild
    # only when the round changed the anchors, and then carry exp_avg / exp_avg_sq[keep]
    # over (zeros for new rows) and keep "step".
    state = _state(iterations=31, growth_every=30, growth_start=0.0, growth_end=1.0,
                   rate_start=1.0, grow_fraction=0.0, min_opacity=0.0)
    data = tiny_dataset()
    count = state.model.count
    train_color_stage(data.views, state)
    assert state.model.count == count  # the round at step 30 changed nothing
    adam = state.anchor_optimizer.state[state.model.features]
    assert int(adam["step"]) == 31


def test_a_resumed_run_draws_the_same_new_anchor_offsets(tmp_path):
    # Was: checkpoint.py does not save AnchorModel._generator (anchor_model.py:113), the
    # generator resize() draws new anchors' offsets from; load re-creates it from the seed
    # and draws M offsets, so it only matches an uninterrupted run when no anchor was ever
    # pruned before the checkpoint. Fix: save `model._generator.get_state()` and restore it.
    state = _state()
    model = state.model
    keep = torch.ones(model.count, dtype=torch.bool)
    keep[0] = False  # one anchor pruned before the checkpoint
    model.resize(keep, np.zeros((0, 3), np.int64), torch.zeros(0, dtype=torch.int64))
    make_optimizers(state, keep_shared=True)
    state.stats = GrowthStats.empty(model.count, model.n_offsets)
    buffer_path = tmp_path / "generator.pt"
    save_checkpoint(state, buffer_path)
    resumed = load_checkpoint(buffer_path)
    new_cell = model.cells.numpy().max(axis=0, keepdims=True) + 5
    for m in (model, resumed.model):
        m.resize(torch.ones(m.count, dtype=torch.bool), new_cell,
                 torch.zeros(1, dtype=torch.int64))
    torch.testing.assert_close(resumed.model.offsets[-1], model.offsets[-1], rtol=0, atol=0)


def test_a_view_that_sees_no_anchor_does_not_crash_stage_one():
    # Was: color_stage.py:300 calls loss.backward() on a loss with no grad_fn when no
    # Gaussian reaches the image (a view looking away from the points, or every opacity <= 0)
    # before the rate term starts: RuntimeError "element 0 of tensors does not require grad".
    # Fix: `if not loss.requires_grad:` count the step as done (record history) and go on.
    data = tiny_dataset()
    first = data.views[0]
    turned = np.diag([-1.0, 1.0, -1.0, 1.0]) @ first.camera.world_to_camera  # looks away
    camera = dataclasses.replace(first.camera, world_to_camera=turned, name="away")
    views = [*data.views, TrainingView(np.zeros_like(first.image), camera, None, "away")]
    # One epoch without the rate term: every view, the turned one included, is rendered.
    state = initial_state(views, data.scene.positions,
                          tiny_color_settings(iterations=len(views), rate_start=1.0))
    train_color_stage(views, state)  # the empty view is skipped, the others train
    assert state.step == len(views)
    assert len(state.history["loss"]) == len(views) - 1


def test_resuming_with_fewer_views_than_the_checkpoint_is_an_input_error(tmp_path):
    # Was: nothing records which views a checkpoint was trained on; color_stage.py:222
    # pops view indices saved in the checkpoint, so resuming on a dataset with fewer views
    # dies with IndexError (and one with as many, but other, views trains silently on the
    # wrong images). Fix: save the view count and names in the checkpoint and compare them
    # in train_color_stage / train_scene, raising InputError naming the checkpoint.
    data = tiny_dataset()
    state = _state(iterations=12)
    train_color_stage(data.views, state, stop_at=1)
    path = tmp_path / "fewer.pt"
    save_checkpoint(state, path)
    resumed = load_checkpoint(path)
    with pytest.raises(InputError):
        train_color_stage(data.views[:2], resumed)


# --- checkpoints ---------------------------------------------------------------------------


def test_a_checkpoint_with_fields_of_the_wrong_type_is_an_input_error(tmp_path):
    # Was: checkpoint.py:78 catches KeyError/TypeError/ValueError/RuntimeError but not
    # AttributeError (or IndexError): a format-tagged dict whose "settings" is a list ends in
    # a traceback (`csgs train --resume` exits 1). Fix: catch Exception there, as the
    # torch.load branch does, or check each field's type.
    path = tmp_path / "stage1.pt"
    torch.save({"format": "csgs-train-checkpoint/1", "settings": [], "step": 0}, path)
    with pytest.raises(InputError):
        load_checkpoint(path)


@pytest.mark.skipif(torch.cuda.is_available(), reason="shows the CPU-only machine's failure")
def test_a_checkpoint_written_on_cuda_resumes_on_a_cpu_only_machine(tmp_path):
    # Was: checkpoint.py:96/102 moves the model and makes the noise generator on the
    # device saved in the checkpoint; pipeline.py:143 only overrides settings.device after
    # that, so a GPU run's checkpoint cannot be resumed with --device cpu (AssertionError
    # "Torch not compiled with CUDA enabled"), and a CPU checkpoint resumed with --device
    # cuda leaves the model on the CPU while the targets go to CUDA.
    # Fix: load_checkpoint(path, device=...) sets settings.device before building anything.
    data = tiny_dataset()
    settings = tiny_train_settings(color={"iterations": 4})
    state = initial_state(data.views, data.scene.positions, settings.color)
    state.settings = dataclasses.replace(state.settings, device="cuda")  # as a GPU run saves
    save_checkpoint(state, tmp_path / CHECKPOINT_FILE)
    result = train_scene(data.views, data.scene.positions, settings, checkpoint_dir=tmp_path,
                         resume=True)
    assert result.color_state.step == 4


# --- initial points ------------------------------------------------------------------------


def test_a_truncated_binary_ply_is_an_input_error(tmp_path):
    # Was: initial_points.py:45 does not catch plyfile.PlyParseError (a plain Exception
    # subclass), so `csgs train` on a damaged scene.ply exits 1 with a traceback.
    # Fix: add plyfile.PlyParseError to the caught exceptions.
    path = tmp_path / "points.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 100\n"
                     b"property float x\nproperty float y\nproperty float z\nend_header\n\x00")
    with pytest.raises(InputError, match="points.ply"):
        read_ply_points(path)


# --- csgs train / csgs synthetic -----------------------------------------------------------


def test_an_empty_point_cloud_error_names_its_file(dataset, tmp_path, capsys):
    # Was: grid_for_points (anchor_model.py:67) raises with property="points" only; the
    # user is not told which file held no points. Fix: check len(points) in
    # find_initial_points / read_ply_points and raise with file=path.
    empty = tmp_path / "empty.ply"
    empty.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                      b"property float y\nproperty float z\nend_header\n")
    code = main(["train", str(dataset), "-o", str(tmp_path / "x.csgs"), "--points",
                 str(empty), *FAST])
    assert code == 2
    assert "empty.ply" in capsys.readouterr().err


def test_a_checkpoint_dir_that_is_a_file_exits_2_naming_it(dataset, tmp_path, capsys):
    # Was: pipeline.py:138 mkdir raises FileExistsError (traceback, exit 1).
    # Fix: in cli/commands/train.py (or train_scene) check/create the folder and raise
    # InputError(file=checkpoint_dir) on OSError.
    blocker = tmp_path / "ckpt"
    blocker.write_text("not a folder")
    code = main(["train", str(dataset), "-o", str(tmp_path / "x.csgs"), "--checkpoint-dir",
                 str(blocker), *FAST])
    assert code == 2
    assert "ckpt" in capsys.readouterr().err
    assert not (tmp_path / "x.csgs").exists()


def test_a_negative_seed_exits_2_naming_the_option(tmp_path, capsys):
    # Was: --seed is not range-checked; with no point cloud in the dataset
    # random_points (initial_points.py:141) raises numpy's ValueError "expected non-negative
    # integer" (exit 1); a seed >= 2^63 fails in torch's manual_seed likewise.
    # Fix: validate 0 <= seed < 2^63 in ColorStageSettings.validate / the CLI.
    folder = tmp_path / "no_points"
    make_synthetic_dataset(2, objects=2, gaussians_per_object=40, views=4, width=24,
                           height=18).write(folder)
    (folder / "scene.ply").unlink()
    code = main(["train", str(folder), "-o", str(tmp_path / "x.csgs"), "--seed", "-1", *FAST])
    assert code == 2
    assert "seed" in capsys.readouterr().err


def test_an_unwritable_output_is_refused_before_training(dataset, tmp_path, capsys,
                                                          monkeypatch):
    # Was: cli/commands/train.py:147 finds out that -o cannot be written only after every
    # stage has run (hours on a real scene, all lost). Fix: check that the output's folder
    # exists and is writable (os.access / a probe mkstemp) before loading the dataset.
    import csgs_codec.train.pipeline as pipeline

    def must_not_train(*args, **kwargs):
        raise AssertionError("trained although the output cannot be written")

    monkeypatch.setattr(pipeline, "train_scene", must_not_train)
    code = main(["train", str(dataset), "-o", str(tmp_path / "missing" / "x.csgs"), *FAST])
    assert code == 2
    assert "missing" in capsys.readouterr().err


def test_holding_out_every_view_names_the_test_every_option(dataset, tmp_path, capsys):
    # Was: with --test-every 1, split_views holds out all views and the error is
    # "property 'views': stage 1 needs at least one training view", which does not say
    # why. Fix: in cli/commands/train.py refuse an empty training split naming --test-every.
    code = main(["train", str(dataset), "-o", str(tmp_path / "x.csgs"), "--test-every", "1",
                 *FAST])
    assert code == 2
    assert "test-every" in capsys.readouterr().err


def test_synthetic_into_a_path_that_is_a_file_exits_2(tmp_path, capsys):
    # Was: SyntheticDataset.write raises NotADirectoryError (traceback, exit 1).
    # Fix: cli/commands/synthetic.py checks the folder (or write_transforms_dataset wraps
    # OSError in InputError(file=folder)).
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = main(["synthetic", str(blocker), "--views", "2", "--size", "16x16", "--gaussians",
                 "5", "-q"])
    assert code == 2
    assert "file" in capsys.readouterr().err


def test_a_corrupted_checkpoint_exits_2_naming_it(dataset, tmp_path, capsys):
    # Checked right at review: a truncated or random-bytes stage1.pt is an InputError
    # naming the file.
    folder = tmp_path / "ck"
    folder.mkdir()
    (folder / CHECKPOINT_FILE).write_bytes(b"PK\x03\x04" + bytes(range(256)) * 4)
    code = main(["train", str(dataset), "-o", str(tmp_path / "x.csgs"), "--checkpoint-dir",
                 str(folder), "--resume", *FAST])
    assert code == 2
    assert CHECKPOINT_FILE in capsys.readouterr().err
    assert not (tmp_path / "x.csgs").exists()



def test_no_semantic_training_reads_no_masks(dataset, tmp_path, capsys):
    import shutil

    folder = tmp_path / "broken_masks"
    shutil.copytree(dataset, folder)
    next((folder / "masks").glob("*.png")).unlink()  # one mask missing
    code = main(["train", str(folder), "-o", str(tmp_path / "c.csgs"), "--no-semantic",
                 "--features", "4", "--offsets", "2", *FAST])
    assert code == 0, capsys.readouterr().err
    from csgs_codec.codec.anchor_decoder import AnchorDecoder

    scene = AnchorDecoder().decode((tmp_path / "c.csgs").read_bytes(), "color,semantic")
    assert scene.semantic is None


def test_growth_carries_adam_moments_of_the_survivors_and_zeros_new_rows():
    from csgs_codec.train.color_stage import _resize_anchor_optimizer

    state = _state()
    model = state.model
    data = tiny_dataset()
    train_color_stage(data.views, state, stop_at=3)
    old = dict(model.anchor_tensors())
    before = {k: v.clone() if torch.is_tensor(v) else v
              for k, v in state.anchor_optimizer.state[old["features"]].items()}
    keep = torch.ones(model.count, dtype=torch.bool)
    keep[1] = False
    model.resize(keep, model.cells.numpy().max(axis=0, keepdims=True) + 3,
                 torch.zeros(1, dtype=torch.int64))
    _resize_anchor_optimizer(state, old, keep)
    after = state.anchor_optimizer.state[model.features]
    torch.testing.assert_close(after["exp_avg"][:-1], before["exp_avg"][keep])
    assert after["exp_avg"][-1].abs().sum() == 0
    assert int(after["step"]) == int(before["step"])


def test_growth_adds_anchors_between_the_initial_ones_that_views_see():
    """Initial anchors sit on every second cell of the grid, so growth has room between them;
    each grown anchor lies on the grid and is seen by at least min_views training views."""
    from csgs_codec.train.anchor_growth import view_counts

    data = tiny_dataset()
    state = _state(iterations=61, growth_every=30, growth_start=0.0, growth_end=1.0,
                   rate_start=1.0, grow_fraction=0.2)
    initial = state.model.count
    assert (state.model.cells.numpy() % 2 == 0).all()
    train_color_stage(data.views, state)
    cells = state.model.cells.numpy()
    assert state.model.count > initial
    assert (cells % 2 != 0).any(axis=1).any()  # some between the initial ones
    counts = view_counts(state.model.positions.numpy(), [v.camera for v in data.views])
    assert (counts >= state.settings.min_views).all()
