"""splat-transform 3.7.0 run live (skipped without ``npm ci`` in benchmarks/): it reads the
files csgs writes, and csgs reads what it writes from a scene the fixtures do not use."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from csgs_codec.codec.files import read_scene_with_report
from csgs_codec.errors import DataLossWarning
from csgs_codec.interchange import write_scene
from csgs_codec.interchange.gltf import glb_bytes
from csgs_codec.interchange.ply_io import read_ply, write_ply
from tests.conftest import SAMPLE
from tests.interchange.helpers import (
    DATA,
    alphas,
    colors,
    oracle_scene_arrays,
    rotation_error,
    splat_transform,
    splat_transform_or_skip,
)
from tests.interchange.test_writers import _glb_accessors

SH_C0 = 0.28209479177387814


@pytest.fixture(scope="module")
def donut(tmp_path_factory):
    """(PLY path, scene): 471 Gaussians of the bundled donut sample, SH degree 0."""
    splat_transform_or_skip()
    scene = read_ply(SAMPLE)
    scene = scene.subset(np.arange(0, len(scene), 97))
    path = tmp_path_factory.mktemp("live") / "donut471.ply"
    write_ply(scene, path)
    return path, scene


def _decoded_by_splat_transform(path, tmp_path):
    out = tmp_path / (path.name.replace(".", "_") + ".decoded.ply")
    splat_transform(path, out)
    from csgs_codec.interchange.ply_reader import read_vertex_columns

    _, _, columns = read_vertex_columns(out.read_bytes())
    return oracle_scene_arrays({k: np.asarray(v, np.float64) for k, v in columns.items()})


@pytest.mark.parametrize("name", ["donut", "brush"])
@pytest.mark.parametrize("suffix", [".spz", ".splat"])
def test_splat_transform_reads_csgs_writers_output(name, suffix, donut, tmp_path):
    scene = donut[1] if name == "donut" else read_scene_with_report(DATA / "brush_sh3.ply")[0]
    path = tmp_path / f"{name}{suffix}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataLossWarning)
        write_scene(scene, path)
    theirs = _decoded_by_splat_transform(path, tmp_path)
    ours = read_scene_with_report(path)[0]
    # The two readers agree on the bytes csgs wrote ...
    for key in ("positions", "sh_dc", "sh_rest", "scales"):
        np.testing.assert_allclose(getattr(ours, key), theirs[key], rtol=1e-6, atol=1e-7)
    assert rotation_error(ours.rotations, theirs["rotations"]).max() < 1e-4
    # ... and what splat-transform reads is the scene within the format's precision.
    assert np.abs(theirs["positions"] - scene.positions).max() <= (
        2 ** -13 + 1e-6 if suffix == ".spz" else 0)
    decoded_color = 0.5 + SH_C0 * theirs["sh_dc"]
    limit = (0.5 / (0.15 * 255) * SH_C0 if suffix == ".spz" else 0.5 / 255) + 1e-6
    reach = 127.5 / (0.15 * 255) * SH_C0 if suffix == ".spz" else 0.5
    want = np.clip(colors(scene), 0.5 - reach, 0.5 + reach)
    assert np.abs(decoded_color - want).max() <= limit
    decoded_alpha = 1 / (1 + np.exp(-theirs["opacity"]))
    assert np.abs(decoded_alpha - alphas(scene)).max() <= 0.5 / 255 + 1e-6
    assert rotation_error(theirs["rotations"], scene.rotations).max() < 1e-4


def test_csgs_glb_equals_splat_transforms_glb(donut, tmp_path):
    path, scene = donut
    splat_transform(path, tmp_path / "theirs.glb")
    theirs = _glb_accessors((tmp_path / "theirs.glb").read_bytes())
    ours = _glb_accessors(glb_bytes(scene))
    assert sorted(ours) == sorted(theirs)
    # donut's quaternions are not unit length: splat-transform copies them, csgs normalises
    # them as the extension requires.
    rotation = "KHR_gaussian_splatting:ROTATION"
    theirs[rotation] = theirs[rotation] / np.linalg.norm(theirs[rotation], axis=1,
                                                         keepdims=True)
    for name in theirs:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=2e-6, atol=2e-7,
                                   err_msg=name)


@pytest.mark.parametrize("suffix", [".compressed.ply", ".sog", ".spz", "/meta.json"])
def test_csgs_reads_splat_transforms_output_as_splat_transform_does(suffix, donut, tmp_path):
    path, _ = donut
    target = tmp_path / ("sog_folder/meta.json" if suffix == "/meta.json"
                         else f"donut{suffix}")
    target.parent.mkdir(exist_ok=True)
    splat_transform(path, target)
    theirs = _decoded_by_splat_transform(target, tmp_path)
    ours, source = read_scene_with_report(target)
    assert source.lossy and len(ours) == len(theirs["positions"])
    for key in ("positions", "sh_dc", "sh_rest", "scales"):
        np.testing.assert_allclose(getattr(ours, key), theirs[key], rtol=1e-6, atol=1e-7)
    finite = np.isfinite(theirs["opacity"])
    np.testing.assert_allclose(ours.opacity[finite], theirs["opacity"][finite], atol=1e-6)
    assert rotation_error(ours.rotations, theirs["rotations"]).max() < 1e-6


@pytest.mark.parametrize("suffix", [".spz", ".ply"])
def test_splat_transform_reads_a_baked_anchor_scene(suffix, tmp_path):
    """`csgs decode anchors.csgs -o a.spz` (default settings) writes a file an independent
    reader opens: splat-transform reads the Gaussians csgs's own reader reads."""
    splat_transform_or_skip()
    from csgs_cli.main import main
    from csgs_codec.interchange.scaffold_io import write_scaffold
    from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene

    folder = write_scaffold(synthetic_anchor_scene(2, 40, seed=4), tmp_path / "ckpt")
    assert main(["encode", str(folder), "-o", str(tmp_path / "a.csgs"), "-q"]) == 0
    out = tmp_path / f"baked{suffix}"
    assert main(["decode", str(tmp_path / "a.csgs"), "-o", str(out), "-q"]) == 0
    theirs = _decoded_by_splat_transform(out, tmp_path)
    ours = read_scene_with_report(out)[0]
    assert len(ours) == len(theirs["positions"]) > 100 and ours.sh_degree_stored == 3
    for key in ("positions", "sh_dc", "sh_rest", "scales"):
        np.testing.assert_allclose(getattr(ours, key), theirs[key], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(ours.opacity, theirs["opacity"], atol=1e-5)
    assert rotation_error(ours.rotations, theirs["rotations"]).max() < 1e-4
