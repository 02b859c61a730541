"""Scaffold-GS checkpoint folders: official layout, csgs writer round trip, malformed input."""

from __future__ import annotations

import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from plyfile import PlyData, PlyElement
from torch import nn

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.interchange.scaffold_io import find_checkpoint_folder, read_scaffold, write_scaffold
from csgs_codec.model.scaffold import ScaffoldMLPs
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene


# --------------------------------------------------------------------------- official folders
class OfficialEmbedding(nn.Module):
    """Stands in for Scaffold-GS's ``Embedding`` wrapper (an ``embedding`` attribute)."""

    def __init__(self, cameras: int, width: int) -> None:
        super().__init__()
        self.embedding = nn.Embedding(cameras, width)

    def forward(self, index):
        return self.embedding(index)


def official_heads(feat: int, k: int, dist: bool, appearance: int) -> dict[str, nn.Module]:
    """The three heads built as the official trainer's ``__init__`` builds them."""
    torch.manual_seed(0)
    d = int(dist)
    return {
        "opacity": nn.Sequential(nn.Linear(feat + 3 + d, feat), nn.ReLU(True),
                                 nn.Linear(feat, k), nn.Tanh()),
        "cov": nn.Sequential(nn.Linear(feat + 3 + d, feat), nn.ReLU(True),
                             nn.Linear(feat, 7 * k)),
        "color": nn.Sequential(nn.Linear(feat + 3 + d + appearance, feat), nn.ReLU(True),
                               nn.Linear(feat, 3 * k), nn.Sigmoid()),
    }


def official_anchor_ply(path: Path, anchors: np.ndarray, offsets: np.ndarray,
                        feats: np.ndarray, scales: np.ndarray,
                        masks: np.ndarray | None = None) -> None:
    """Write the anchor PLY with plyfile in the official property order (HAC adds f_mask)."""
    m, k = offsets.shape[:2]
    names = ["x", "y", "z", "nx", "ny", "nz"] + [f"f_offset_{i}" for i in range(3 * k)]
    columns = [anchors, np.zeros_like(anchors), offsets.transpose(0, 2, 1).reshape(m, 3 * k)]
    if masks is not None:
        names += [f"f_mask_{i}" for i in range(k)]
        columns.append(masks)
    names += [f"f_anchor_feat_{i}" for i in range(feats.shape[1])] + ["opacity"]
    names += [f"scale_{i}" for i in range(6)] + [f"rot_{i}" for i in range(4)]
    rot = np.zeros((m, 4))
    rot[:, 0] = 1
    columns += [feats, np.full((m, 1), np.log(0.1 / 0.9)), scales, rot]
    values = np.concatenate(columns, axis=1)
    rows = np.empty(m, dtype=[(n, "f4") for n in names])
    rows[:] = list(map(tuple, values))
    PlyData([PlyElement.describe(rows, "vertex")]).write(str(path))


def trace_save(module: nn.Module, example: torch.Tensor, path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.jit.trace(module.eval(), (example,)).save(str(path))


def jit_load(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return torch.jit.load(str(path))


@pytest.fixture
def official_folder(tmp_path):
    """A hand-built Scaffold-GS checkpoint with the trainer's defaults (no distance inputs,
    appearance_dim > 0), under MODEL/point_cloud/iteration_30000/."""
    rng = np.random.default_rng(3)
    m, feat, k, cams, app = 4, 8, 3, 5, 4
    folder = tmp_path / "model" / "point_cloud" / "iteration_30000"
    folder.mkdir(parents=True)
    data = {"anchors": rng.standard_normal((m, 3)).astype(np.float32),
            "offsets": rng.standard_normal((m, k, 3)).astype(np.float32),
            "feats": rng.standard_normal((m, feat)).astype(np.float32),
            "scales": rng.standard_normal((m, 6)).astype(np.float32)}
    official_anchor_ply(folder / "point_cloud.ply", **data)
    heads = official_heads(feat, k, dist=False, appearance=app)
    for name, module in heads.items():
        trace_save(module, torch.rand(1, module[0].in_features), folder / f"{name}_mlp.pt")
    trace_save(OfficialEmbedding(cams, app), torch.zeros((1,), dtype=torch.long),
               folder / "embedding_appearance.pt")
    return folder, data


def test_official_folder_reads_anchor_values(official_folder):
    folder, data = official_folder
    scene = read_scaffold(folder)
    assert np.array_equal(scene.positions, data["anchors"])
    assert np.array_equal(scene.offsets, data["offsets"])
    assert np.array_equal(scene.features, data["feats"])
    assert np.array_equal(scene.scaling, data["scales"])
    assert scene.offset_mask.all() and scene.semantic is None


def test_official_folder_found_from_model_root_taking_the_last_iteration(official_folder):
    folder, _ = official_folder
    earlier = folder.parent / "iteration_7000"
    earlier.mkdir()
    (earlier / "point_cloud.ply").write_bytes(b"")
    assert find_checkpoint_folder(folder.parent.parent) == folder
    assert len(read_scaffold(folder.parent.parent)) == 4


def test_official_traced_heads_give_the_same_outputs(official_folder):
    folder, data = official_folder
    scene = read_scaffold(folder)
    assert scene.mlps.appearance.shape == (5, 4)
    ours = ScaffoldMLPs.from_weights(scene.mlps, scene.feat_dim, scene.n_offsets)
    assert not (ours.opacity_dist or ours.cov_dist or ours.color_dist)
    feats = torch.from_numpy(data["feats"])
    view = torch.nn.functional.normalize(torch.randn(4, 3), dim=1)
    dist = torch.rand(4, 1) * 5
    official = {n: jit_load(folder / f"{n}_mlp.pt") for n in ("opacity", "cov", "color")}
    appearance = jit_load(folder / "embedding_appearance.pt")(torch.full((4,), 2))
    with torch.no_grad():
        opacity, cov, color = ours(feats, view, dist, appearance_index=2)
        base = torch.cat([feats, view], dim=1)
        assert torch.allclose(opacity, official["opacity"](base), atol=1e-6)
        assert torch.allclose(cov.reshape(4, -1), official["cov"](base), atol=1e-6)
        expected = official["color"](torch.cat([base, appearance], dim=1))
        assert torch.allclose(color.reshape(4, -1), expected, atol=1e-6)


def test_hac_checkpoint_with_state_dict_and_masks_reads(tmp_path):
    rng = np.random.default_rng(4)
    m, feat, k = 3, 50, 10
    masks = np.full((m, k), 1.0, np.float32)
    masks[0, 2] = -6.0  # sigmoid < 0.01: pruned
    official_anchor_ply(tmp_path / "point_cloud.ply", rng.standard_normal((m, 3)),
                        rng.standard_normal((m, k, 3)), rng.standard_normal((m, feat)),
                        rng.standard_normal((m, 6)), masks)
    heads = official_heads(feat, k, dist=True, appearance=0)
    state = {f"{n}_mlp": h.state_dict() for n, h in heads.items()}
    state["grid_mlp"] = nn.Linear(2, 2).state_dict()  # HAC's entropy model: ignored
    torch.save(state, tmp_path / "checkpoint.pth")
    scene = read_scaffold(tmp_path)
    assert scene.offset_mask.sum() == m * k - 1 and not scene.offset_mask[0, 2]
    assert scene.mlps.uses_distance("color", feat) and scene.mlps.appearance is None
    assert np.array_equal(scene.mlps.cov.w2, heads["cov"][2].weight.detach().numpy())


# --------------------------------------------------------------------------- csgs writer
def test_written_checkpoint_reads_back_equal(tmp_path):
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=25, seed=1)
    write_scaffold(scene, tmp_path / "ckpt")
    back = read_scaffold(tmp_path / "ckpt")
    assert back.equals(scene)


def test_written_checkpoint_mlps_give_the_same_outputs(tmp_path):
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=25, seed=2)
    write_scaffold(scene, tmp_path)
    back = read_scaffold(tmp_path)
    a = ScaffoldMLPs.from_weights(scene.mlps, 50, 10)
    b = ScaffoldMLPs.from_weights(back.mlps, 50, 10)
    feats = torch.from_numpy(scene.features)
    view = torch.nn.functional.normalize(torch.randn(len(scene), 3), dim=1)
    dist = torch.rand(len(scene), 1)
    with torch.no_grad():
        for x, y in zip(a(feats, view, dist), b(feats, view, dist)):
            assert torch.equal(x, y)


def test_written_heads_load_with_torch_jit_like_the_official_loader(tmp_path):
    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=10, seed=3)
    write_scaffold(scene, tmp_path)
    traced = jit_load(tmp_path / "opacity_mlp.pt")
    ours = ScaffoldMLPs.from_weights(scene.mlps, 50, 10)
    x = torch.randn(6, 54)
    with torch.no_grad():
        assert torch.allclose(traced(x), ours.opacity(x), atol=1e-6)


def test_written_appearance_embedding_round_trips(tmp_path):
    from csgs_codec.scene.synthetic_anchors import synthetic_mlps

    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=10, seed=3)
    scene.mlps = synthetic_mlps(50, 10, seed=3, appearance=(7, 16))
    write_scaffold(scene, tmp_path)
    assert (tmp_path / "embedding_appearance.pt").exists()
    assert read_scaffold(tmp_path).mlps.equals(scene.mlps)


def test_write_without_mlps_is_rejected(tmp_path):
    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=5, with_mlps=False)
    with pytest.raises(InputError) as err:
        write_scaffold(scene, tmp_path)
    assert err.value.property == "mlps"


# --------------------------------------------------------------------------- malformed input
def test_missing_mlp_file_is_named(official_folder):
    folder, _ = official_folder
    (folder / "cov_mlp.pt").unlink()
    with pytest.raises(InputError) as err:
        read_scaffold(folder)
    assert err.value.file.endswith("cov_mlp.pt") and err.value.property == "cov"


def test_folder_without_any_mlp_is_rejected_unless_allowed(official_folder):
    folder, _ = official_folder
    for name in ("opacity", "cov", "color"):
        (folder / f"{name}_mlp.pt").unlink()
    with pytest.raises(InputError, match="no MLP weights") as err:
        read_scaffold(folder)
    assert err.value.file.endswith("opacity_mlp.pt")
    assert read_scaffold(folder, require_mlps=False).mlps is None


def test_head_with_wrong_offset_count_is_named(official_folder):
    folder, _ = official_folder
    wrong = official_heads(8, 4, dist=False, appearance=4)["color"]  # 4 offsets, not 3
    trace_save(wrong, torch.rand(1, 8 + 3 + 4), folder / "color_mlp.pt")
    with pytest.raises(InputError, match="expected 3 x 3 offsets") as err:
        read_scaffold(folder)
    assert err.value.file.endswith("color_mlp.pt") and err.value.property == "color.w2"


def test_head_with_wrong_input_width_is_named(official_folder):
    folder, _ = official_folder
    wrong = official_heads(10, 3, dist=False, appearance=0)["opacity"]  # 10 features, not 8
    trace_save(wrong, torch.rand(1, 13), folder / "opacity_mlp.pt")
    with pytest.raises(InputError, match="do not match feature width 8") as err:
        read_scaffold(folder)
    assert err.value.file.endswith("opacity_mlp.pt") and err.value.property == "opacity.w1"


def test_garbage_mlp_file_is_an_input_error(official_folder):
    folder, _ = official_folder
    (folder / "opacity_mlp.pt").write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(InputError, match="not a TorchScript module") as err:
        read_scaffold(folder)
    assert err.value.file.endswith("opacity_mlp.pt")


def test_head_with_a_different_graph_is_unsupported(official_folder):
    folder, _ = official_folder
    gelu = nn.Sequential(nn.Linear(11, 8), nn.GELU(), nn.Linear(8, 3), nn.Tanh())
    trace_save(gelu, torch.rand(1, 11), folder / "opacity_mlp.pt")
    with pytest.raises(UnsupportedError, match="not the Scaffold-GS head"):
        read_scaffold(folder)


def test_feature_bank_checkpoint_is_unsupported(official_folder):
    folder, _ = official_folder
    (folder / "feature_bank_mlp.pt").write_bytes(b"")
    with pytest.raises(UnsupportedError, match="feature-bank"):
        read_scaffold(folder)


class _Exploit:
    def __reduce__(self):
        return (Path.touch, (Path(_Exploit.target),))


def test_state_dict_file_never_runs_pickled_code(tmp_path):
    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=5, seed=4)
    write_scaffold(scene, tmp_path)
    for name in ("opacity", "cov", "color"):
        (tmp_path / f"{name}_mlp.pt").unlink()
    _Exploit.target = str(tmp_path / "pwned")
    with open(tmp_path / "checkpoint.pth", "wb") as fh:
        pickle.dump({"opacity_mlp": _Exploit()}, fh)
    with pytest.raises(InputError, match="weights-only") as err:
        read_scaffold(tmp_path)
    assert err.value.file.endswith("checkpoint.pth")
    assert not (tmp_path / "pwned").exists()


def test_state_dict_missing_head_is_named(tmp_path):
    scene = synthetic_anchor_scene(n_objects=1, anchors_per_object=5, seed=5)
    write_scaffold(scene, tmp_path)
    for name in ("opacity", "cov", "color"):
        (tmp_path / f"{name}_mlp.pt").unlink()
    heads = official_heads(50, 10, dist=True, appearance=0)
    torch.save({"opacity_mlp": heads["opacity"].state_dict(),
                "color_mlp": heads["color"].state_dict()}, tmp_path / "checkpoints.pth")
    with pytest.raises(InputError) as err:
        read_scaffold(tmp_path)
    assert err.value.file.endswith("checkpoints.pth") and err.value.property == "cov_mlp"


def test_missing_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="no point_cloud.ply"):
        read_scaffold(tmp_path / "nowhere")
