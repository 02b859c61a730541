"""LLFF captures (poses_bounds.npy + images/): the cameras LLFF's axes describe, the image
folders read, the real mary_rose capture, and bad files named with exit 2."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.render.image_io import save_png
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.cameras_io import load_cameras
from csgs_codec.scene.llff_io import load_llff_capture, read_poses_bounds
from csgs_codec.train.datasets import load_dataset
from csgs_codec.train.synthetic import make_synthetic_dataset, write_transforms_dataset
from tests.conftest import shared_path

MARY_ROSE = ("captures", "mary_rose")


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(5, objects=2, gaussians_per_object=60, views=4, width=48,
                                  height=32)


def llff_rows(cameras: list[Camera], near: float = 0.5, far: float = 9.0) -> np.ndarray:
    """(N, 17) poses_bounds rows of pinhole cameras centred on their image (written from
    LLFF's definition: columns down, right, back of the camera in world coordinates)."""
    rows = []
    for camera in cameras:
        c2w = camera.camera_to_world
        right, down, forward = c2w[:3, 0], c2w[:3, 1], c2w[:3, 2]
        matrix = np.column_stack([down, right, -forward, c2w[:3, 3],
                                  [camera.height, camera.width, camera.fx]])
        rows.append(np.concatenate([matrix.ravel(), [near, far]]))
    return np.asarray(rows)


def write_llff(views, root: Path) -> Path:
    """``root/poses_bounds.npy`` + ``root/images/frame_XX.png``; returns root."""
    (root / "images").mkdir(parents=True)
    for i, view in enumerate(views):
        save_png(view.image, root / "images" / f"frame_{i:02d}.png")
    np.save(root / "poses_bounds.npy", llff_rows([v.camera for v in views]))
    return root


def test_llff_poses_give_the_cameras_of_the_same_views_transforms_json(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path / "nerf")
    write_llff(synthetic.views, tmp_path / "llff")
    from_json = load_dataset(tmp_path / "nerf", read_masks=False)
    from_llff = load_dataset(tmp_path / "llff", read_masks=False)
    assert [v.name for v in from_llff] == [f"frame_{i:02d}.png" for i in range(4)]
    for a, b in zip(from_llff, from_json):
        assert (a.camera.width, a.camera.height) == (b.camera.width, b.camera.height)
        np.testing.assert_allclose([a.camera.fx, a.camera.fy, a.camera.cx, a.camera.cy],
                                   [b.camera.fx, b.camera.fy, b.camera.cx, b.camera.cy])
        np.testing.assert_allclose(a.camera.world_to_camera, b.camera.world_to_camera,
                                   atol=1e-12)
        np.testing.assert_array_equal(a.image, b.image)


def test_llff_camera_looks_along_minus_its_back_column():
    # One camera at (0, 0, 5) whose back axis is +z (it looks at the origin), down is -y and
    # right +x: the origin projects to the image centre and world +x to the right of it.
    row = np.zeros(17)
    row[:15] = np.column_stack([[0, -1, 0], [1, 0, 0], [0, 0, 1], [0, 0, 5],
                                [40, 60, 50]]).ravel()
    row[15:] = 1, 10
    poses = _poses_from(row)
    w2c = np.linalg.inv(poses.camera_to_world[0])
    for point, expected in (([0, 0, 0], (0, 0, 5)), ([1, 0, 0], (1, 0, 5)),
                            ([0, 1, 0], (0, -1, 5))):
        np.testing.assert_allclose((w2c @ [*point, 1])[:3], expected, atol=1e-12)


def _poses_from(row: np.ndarray):
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "poses_bounds.npy"
        np.save(path, row[None])
        return read_poses_bounds(path)


def test_images_n_folder_is_read_for_a_downscale_and_full_size_masks_follow(tmp_path,
                                                                            synthetic):
    root = write_llff(synthetic.views, tmp_path)
    (root / "images_2").mkdir()
    (root / "masks").mkdir()
    for i, view in enumerate(synthetic.views):
        name = f"frame_{i:02d}.png"
        Image.open(root / "images" / name).resize((24, 16), Image.Resampling.BOX).save(
            root / "images_2" / name)
        Image.fromarray(view.mask.astype(np.uint8)).save(root / "masks" / name)
    capture = load_llff_capture(root, downscale=2.0)
    assert capture.folder == root / "images_2" and capture.remaining_downscale == 1.0
    assert load_llff_capture(root, downscale=1.5).folder == root / "images"
    views = load_dataset(root, downscale=2.0)
    full = synthetic.views[0].camera
    camera = views[0].camera
    assert views[0].image.shape == (16, 24, 3) and views[0].mask.shape == (16, 24)
    np.testing.assert_allclose([camera.fx, camera.cx, camera.cy], [full.fx / 2, 12, 8])
    np.testing.assert_array_equal(views[0].mask, synthetic.views[0].mask[1::2, 1::2])
    # A downscale beyond images_2 reads images_2 and resizes what remains.
    quarter = load_dataset(root, downscale=4.0)
    assert quarter[0].image.shape == (8, 12, 3) and quarter[0].mask.shape == (8, 12)


def test_the_cameras_of_llff_are_those_of_its_full_size_images(tmp_path, synthetic):
    root = write_llff(synthetic.views, tmp_path)
    cameras = load_cameras(root / "poses_bounds.npy")
    assert [(c.width, c.height) for c in cameras] == [(48, 32)] * 4


# --------------------------------------------------------------------------- mary_rose
def test_mary_rose_capture_loads_its_69_views():
    root = shared_path(*MARY_ROSE)
    views = load_dataset(root, downscale=6.0, read_masks=False)
    assert len(views) == 69
    names = [v.name for v in views]
    assert names == sorted(names) and names[0] == "IMG_9669.jpg"
    assert views[0].image.shape == (128, 128, 3)
    poses = read_poses_bounds(root / "poses_bounds.npy")
    assert views[0].camera.fx == pytest.approx(poses.hwf[0, 2] / 6.0)


def test_mary_rose_poses_triangulate_points_inside_the_bounds_and_the_masks(tmp_path):
    """pycolmap triangulates SIFT matches at the loaded poses; with the axes right the points
    lie in front of every camera, at the depths LLFF's bounds give (from COLMAP's own points)
    and on the object (its foreground masks). LLFF's columns read as OpenCV's triangulate
    almost nothing."""
    pytest.importorskip("pycolmap")
    from csgs_codec.train.sfm_points import triangulate_views

    root = shared_path(*MARY_ROSE)
    views = load_dataset(root, downscale=4.0)[:4]
    points = triangulate_views(views, cache=tmp_path / "right").points
    assert len(points) >= 40
    bounds = read_poses_bounds(root / "poses_bounds.npy").bounds
    for view, (near, far) in zip(views, bounds):
        c = view.camera
        local = points @ c.world_to_camera[:3, :3].T + c.world_to_camera[:3, 3]
        assert (local[:, 2] > 0).all()
        inside = (local[:, 2] > 0.95 * near) & (local[:, 2] < 1.05 * far)
        assert inside.mean() > 0.9
        u = np.clip((c.fx * local[:, 0] / local[:, 2] + c.cx).astype(int), 0, c.width - 1)
        v = np.clip((c.fy * local[:, 1] / local[:, 2] + c.cy).astype(int), 0, c.height - 1)
        assert (view.mask[v, u] > 0).mean() > 0.85
    for view in views:  # the LLFF matrix taken as an OpenCV camera-to-world
        c = view.camera
        c2w = c.camera_to_world
        wrong = np.eye(4)
        wrong[:3, :] = np.column_stack([c2w[:3, 1], c2w[:3, 0], -c2w[:3, 2], c2w[:3, 3]])
        view.camera = Camera(c.width, c.height, c.fx, c.fy, c.cx, c.cy, np.linalg.inv(wrong),
                             name=c.name)
    assert len(triangulate_views(views, cache=tmp_path / "wrong").points) < len(points) / 4


# --------------------------------------------------------------------------- bad input
def _corrupt(root: Path, case: str) -> str:
    """Break the capture at ``root`` one way; return a fragment the error must name."""
    path = root / "poses_bounds.npy"
    rows = np.load(path)
    if case == "shape":
        np.save(path, rows[:, :15])
        return "(N, 17)"
    if case == "non-finite":
        rows[2, 14] = np.nan
        np.save(path, rows)
        return "focal"
    if case == "rotation":
        rows[1, 0] = 3.0
        np.save(path, rows)
        return "row 1"
    if case == "not-npy":
        path.write_bytes(b"not numpy")
        return "poses_bounds.npy"
    if case == "count":
        (root / "images" / "frame_03.png").unlink()
        return "3 images"
    if case == "no-images":
        shutil.rmtree(root / "images")
        return "images"
    if case == "aspect":
        Image.new("RGB", (48, 48)).save(root / "images" / "frame_01.png")
        return "frame_01.png"
    if case == "mask-size":
        (root / "masks").mkdir()
        for i in range(4):
            Image.new("L", (48, 32) if i != 2 else (30, 30)).save(
                root / "masks" / f"frame_{i:02d}.png")
        return "frame_02.png"
    raise AssertionError(case)


@pytest.mark.parametrize("case", ["shape", "non-finite", "rotation", "not-npy", "count",
                                  "no-images", "aspect", "mask-size"])
def test_a_bad_llff_capture_exits_2_with_one_line_naming_the_fault(tmp_path, synthetic,
                                                                   capsys, case):
    root = write_llff(synthetic.views, tmp_path / "capture")
    fragment = _corrupt(root, case)
    with pytest.raises(InputError):
        load_dataset(root, segment_missing=False)
    out = tmp_path / "x.csgs"
    assert main(["train", str(root), "-o", str(out), "--iterations", "1", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert fragment in err
    assert not out.exists()


@pytest.mark.slow
def test_csgs_train_runs_on_mary_rose_and_info_reads_the_file(tmp_path, monkeypatch, capsys):
    root = shared_path(*MARY_ROSE)
    monkeypatch.setenv("CSGS_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "mary.csgs"
    assert main(["train", str(root), "-o", str(out), "--resolution", "48", "--iterations",
                 "12", "--anchors", "100", "--features", "8", "--offsets", "4",
                 "--no-semantic", "--test-every", "23"]) == 0
    printed = capsys.readouterr().out
    assert "66 training views, 3 held out, 48x48" in printed
    assert "held-out views: PSNR" in printed
    assert main(["info", str(out)]) == 0
    assert f"{out.stat().st_size:,} bytes (complete)" in capsys.readouterr().out
