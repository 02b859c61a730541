"""The view-dependent decode of anchors into neural Gaussians and the standard-PLY export."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from csgs_codec.errors import ModelError
from csgs_codec.interchange.ply_io import read_ply, write_ply
from csgs_codec.model.scaffold import SH_C0, ScaffoldDecoder, ScaffoldMLPs
from csgs_codec.scene.anchor_scene import AnchorScene, MLPWeights, ScaffoldMLPWeights
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene


def camera_at(centre) -> Camera:
    """A camera with identity orientation whose centre is ``centre``."""
    w2c = np.eye(4)
    w2c[:3, 3] = -np.asarray(centre, np.float64)
    return Camera(64, 48, 50.0, 50.0, 32.0, 24.0, w2c)


def head(w1, b1, w2, b2) -> MLPWeights:
    return MLPWeights(*(np.asarray(a, np.float32) for a in (w1, b1, w2, b2)))


def constant_head(in_dim: int, outputs) -> MLPWeights:
    """A head whose output is ``outputs`` whatever the input (zero weights, bias only)."""
    outputs = np.asarray(outputs, np.float32).ravel()
    return head(np.zeros((2, in_dim)), np.zeros(2), np.zeros((len(outputs), 2)), outputs)


def one_anchor_scene() -> AnchorScene:
    """One anchor, F = 2, K = 4, constant heads: every value below is computed by hand."""
    logit = float(np.log(0.75 / 0.25))
    cov = np.zeros((4, 7))
    cov[:, 3] = 2.0                       # quaternion (2, 0, 0, 0) -> (1, 0, 0, 0)
    cov[3, :3] = np.log(3.0)              # sigmoid(log 3) = 0.75
    cov[3, 3:] = [0.0, 3.0, 0.0, 4.0]     # -> (0, 0.6, 0, 0.8)
    mlps = ScaffoldMLPWeights(
        opacity=constant_head(6, [np.arctanh(0.5), -0.2, 1.0, np.arctanh(0.25)]),
        cov=constant_head(6, cov), color=constant_head(6, [logit] * 12))
    return AnchorScene(
        positions=np.array([[1.0, 2.0, 3.0]], np.float32),
        features=np.array([[0.3, -0.7]], np.float32),
        offsets=np.array([[[1, 1, 1], [2, 2, 2], [3, 3, 3], [-2, 0.5, 0.25]]], np.float32),
        scaling=np.log(np.array([[0.5, 2.0, 4.0, 0.1, 0.2, 0.3]], np.float32)),
        offset_mask=np.array([[True, True, False, True]]),
        semantic=np.array([[1, 2, 3, 4, 5, 6]], np.float32),
        semantic_names=tuple(f"sem_{i}" for i in range(6)),
        labels=np.array([7], np.int32), mlps=mlps)


# --------------------------------------------------------------------------- hand-computed
def test_positions_are_anchor_plus_offset_times_exp_scaling():
    g = ScaffoldDecoder(one_anchor_scene()).to_gaussians(camera_at([0, 0, -5]))
    # Offset 1 has opacity tanh(-0.2) <= 0 and offset 2 is masked: both vanish.
    expected = np.array([[1.5, 4.0, 7.0], [0.0, 3.0, 4.0]], np.float32)
    np.testing.assert_allclose(g.positions, expected, rtol=1e-6)


def test_masked_and_non_positive_opacity_offsets_vanish():
    view = ScaffoldDecoder(one_anchor_scene()).decode(np.zeros(3))
    assert view.offset_index.tolist() == [0, 3] and view.anchor_index.tolist() == [0, 0]


def test_opacity_is_the_tanh_head_output_as_a_logit():
    g = ScaffoldDecoder(one_anchor_scene()).to_gaussians(camera_at([0, 0, -5]))
    np.testing.assert_allclose(1 / (1 + np.exp(-g.opacity)), [0.5, 0.25], rtol=1e-5)


def test_color_is_written_as_sh_dc():
    g = ScaffoldDecoder(one_anchor_scene()).to_gaussians(camera_at([0, 0, -5]))
    np.testing.assert_allclose(g.sh_dc, np.full((2, 3), 0.25 / SH_C0), rtol=1e-5)
    assert g.sh_rest.shape == (2, 0, 3)


def test_scale_is_base_scale_times_sigmoid_and_rotation_is_normalized():
    g = ScaffoldDecoder(one_anchor_scene()).to_gaussians(camera_at([0, 0, -5]))
    np.testing.assert_allclose(np.exp(g.scales), [[0.05, 0.1, 0.15], [0.075, 0.15, 0.225]],
                               rtol=1e-5)
    np.testing.assert_allclose(g.rotations, [[1, 0, 0, 0], [0, 0.6, 0, 0.8]], atol=1e-7)


def test_anchor_semantic_and_label_are_shared_by_its_gaussians():
    g = ScaffoldDecoder(one_anchor_scene()).to_gaussians(camera_at([0, 0, -5]))
    assert g.labels.tolist() == [7, 7]
    assert np.array_equal(g.semantic, np.tile(np.arange(1, 7, dtype=np.float32), (2, 1)))


def view_dependent_scene() -> AnchorScene:
    """One anchor at the origin, F = 1, K = 1. Hidden unit 0 = relu(view x), unit 1 =
    relu(distance); opacity = tanh(unit0 - 0.5); red = sigmoid(0.1 * unit1)."""
    w1 = np.zeros((2, 5))
    w1[0, 1] = 1.0   # input layout [f, view x, view y, view z, distance]
    w1[1, 4] = 1.0
    opacity = head(w1, np.zeros(2), [[1.0, 0.0]], [-0.5])
    color = head(w1, np.zeros(2), [[0.0, 0.1], [0, 0], [0, 0]], np.zeros(3))
    cov = constant_head(5, [0, 0, 0, 1, 0, 0, 0])
    return AnchorScene(
        positions=np.zeros((1, 3), np.float32), features=np.zeros((1, 1), np.float32),
        offsets=np.zeros((1, 1, 3), np.float32), scaling=np.zeros((1, 6), np.float32),
        offset_mask=np.ones((1, 1), bool),
        mlps=ScaffoldMLPWeights(opacity=opacity, cov=cov, color=color))


def test_view_direction_points_from_camera_to_anchor():
    decoder = ScaffoldDecoder(view_dependent_scene())
    assert len(decoder.to_gaussians(camera_at([-10, 0, 0]))) == 1   # view x = +1
    assert len(decoder.to_gaussians(camera_at([10, 0, 0]))) == 0    # view x = -1


def test_distance_input_is_the_anchor_camera_distance():
    g = ScaffoldDecoder(view_dependent_scene()).to_gaussians(camera_at([-10, 0, 0]))
    red = 1 / (1 + np.exp(-1.0))  # sigmoid(0.1 * 10)
    np.testing.assert_allclose(g.sh_dc[0], [(red - 0.5) / SH_C0, 0, 0], atol=1e-6)


# --------------------------------------------------------------------------- official rule
def official_rule(scene: AnchorScene, centre: np.ndarray):
    """Scaffold-GS's neural-Gaussian generation restated step by step (HAC's mask included)."""
    mlps = ScaffoldMLPs.from_weights(scene.mlps, scene.feat_dim, scene.n_offsets)
    anchor = torch.from_numpy(scene.positions)
    k = scene.n_offsets
    ob = anchor - torch.from_numpy(centre.astype(np.float32))
    dist = ob.norm(dim=1, keepdim=True)
    local = torch.cat([torch.from_numpy(scene.features), ob / dist, dist], dim=1)
    with torch.no_grad():
        opacity = mlps.opacity(local).reshape(-1, 1)
        opacity = opacity * torch.from_numpy(scene.offset_mask).float().reshape(-1, 1)
        keep = (opacity > 0).reshape(-1)
        color = mlps.color(local).reshape(-1, 3)[keep]
        cov = mlps.cov(local).reshape(-1, 7)[keep]
    scaling = torch.exp(torch.from_numpy(scene.scaling)).repeat_interleave(k, 0)[keep]
    xyz = anchor.repeat_interleave(k, 0)[keep] + torch.from_numpy(
        scene.offsets).reshape(-1, 3)[keep] * scaling[:, :3]
    return (xyz, color, opacity[keep].reshape(-1), scaling[:, 3:] * torch.sigmoid(cov[:, :3]),
            torch.nn.functional.normalize(cov[:, 3:7]))


def test_decode_matches_the_official_generation_rule():
    scene = synthetic_anchor_scene(n_objects=3, anchors_per_object=40, seed=11)
    centre = np.array([0.3, -0.4, 2.0])
    g = ScaffoldDecoder(scene).decode(centre).gaussians
    xyz, color, opacity, scale, rot = official_rule(scene, centre)
    assert len(g) == len(xyz) > 0
    np.testing.assert_allclose(g.positions, xyz.numpy(), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(g.sh_dc * SH_C0 + 0.5, color.numpy(), atol=1e-6)
    np.testing.assert_allclose(1 / (1 + np.exp(-g.opacity.astype(np.float64))),
                               opacity.numpy(), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(np.exp(g.scales), scale.numpy(), rtol=1e-5)
    np.testing.assert_allclose(g.rotations, rot.numpy(), atol=1e-6)


def test_decoded_gaussians_come_from_unmasked_offsets_only():
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=50, seed=12)
    view = ScaffoldDecoder(scene).decode(np.array([0.0, 0.0, 3.0]))
    assert scene.offset_mask[view.anchor_index, view.offset_index].all()
    expected = scene.gaussian_positions()[view.anchor_index, view.offset_index]
    np.testing.assert_allclose(view.gaussians.positions, expected, rtol=1e-6, atol=1e-7)


def test_appearance_index_selects_the_embedding_row():
    from csgs_codec.scene.synthetic_anchors import synthetic_mlps

    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=20, seed=13)
    scene.mlps = synthetic_mlps(50, 10, seed=13, appearance=(4, 8))
    scene.mlps.appearance *= 20  # large enough to change colors visibly
    cam = camera_at([0, 0, -3])
    a = ScaffoldDecoder(scene, appearance_index=0).to_gaussians(cam)
    b = ScaffoldDecoder(scene, appearance_index=3).to_gaussians(cam)
    assert np.array_equal(a.positions, b.positions)
    assert not np.allclose(a.sh_dc, b.sh_dc)
    with pytest.raises(ModelError):
        ScaffoldDecoder(scene, appearance_index=4).to_gaussians(cam)


def test_decoder_needs_mlps():
    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=5, with_mlps=False)
    with pytest.raises(ModelError) as err:
        ScaffoldDecoder(scene)
    assert err.value.property == "mlps"


def test_mlp_weights_survive_torch_modules_unchanged():
    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=5, seed=14)
    mlps = ScaffoldMLPs.from_weights(scene.mlps, 50, 10)
    assert mlps.to_weights().equals(scene.mlps)


# --------------------------------------------------------------------------- export
def test_export_round_trips_through_standard_ply(tmp_path):
    scene = synthetic_anchor_scene(n_objects=3, anchors_per_object=30, seed=15)
    exported = ScaffoldDecoder(scene).export_gaussians()
    exported.validate()
    assert 0 < len(exported) <= scene.active_offsets()
    write_ply(exported, tmp_path / "export.ply")
    back = read_ply(tmp_path / "export.ply")
    assert back.equals(exported)
    assert back.semantic_names == scene.semantic_names and back.labels is not None


def test_export_views_every_anchor_from_the_scene_centre_by_default():
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=30, seed=16)
    decoder = ScaffoldDecoder(scene)
    default = decoder.export_gaussians()
    assert default.equals(decoder.decode(decoder.scene_center()).gaussians)
    cam = camera_at([0.1, 0.2, -2.0])
    assert decoder.export_gaussians(cam).equals(decoder.to_gaussians(cam))
