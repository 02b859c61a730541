"""View pruning: Gaussians that add least to the views are left out, within the budget."""

from __future__ import annotations

import json

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import MIN_PRUNED_SCENE, Encoder
from csgs_codec.decisions.view_pruning import decide, drop_costs, probe_cameras, render_images
from csgs_codec.interchange.ply_io import read_ply, write_ply
from csgs_codec.render.sensitivity import blend_sensitivity
from csgs_codec.render.view_distribution import default_distribution
from tests.conftest import SAMPLE

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def donut_part():
    """Every 12th Gaussian of the sample (3,802): big enough to prune, quick to encode."""
    scene = read_ply(SAMPLE)
    return scene.subset(np.arange(0, len(scene), 12))


@pytest.fixture(scope="module")
def pruned(donut_part):
    """The default path once: the default sphere of views, at its full size (16 s: its tests
    run under -m slow; test_cli_view_prune_reports_what_it_left_out takes the same path
    through the CLI in the default run)."""
    return Encoder(quality=5, hyperprior=False, view_pruning=True).encode_with_report(
        donut_part)


@pytest.fixture(scope="module")
def small_views(donut_part):
    """A quicker distribution for the tests that do not test the default one."""
    return default_distribution(donut_part, directions=6, size=(200, 150))


@pytest.mark.slow
def test_pruned_file_decodes_to_the_encoders_reconstruction(pruned, donut_part):
    decoded = Decoder().decode(pruned.data)
    assert decoded.equals(pruned.reconstruction)
    assert len(decoded) == len(donut_part) - pruned.view_pruned
    assert 0 < pruned.view_pruned < len(donut_part)
    assert pruned.views == "48 views on a sphere at 3 distances"


@pytest.mark.slow
def test_order_names_each_kept_gaussian_once(pruned, donut_part):
    order = pruned.order
    assert len(np.unique(order)) == len(order) == len(pruned.reconstruction)
    assert order.min() >= 0 and order.max() < len(donut_part)
    kept = donut_part.subset(order)
    # Kept Gaussians decode near their own inputs (DC within the quality-5 step).
    assert np.abs(kept.sh_dc - pruned.reconstruction.sh_dc).max() < 0.04


def test_pruning_stays_within_the_budget_on_the_probe_views(donut_part, small_views):
    encoder = Encoder(quality=5, hyperprior=False)
    full = encoder.encode_with_report(donut_part)
    views = small_views
    weights = blend_sensitivity(donut_part, views.cameras).weight_sq
    in_input_order = full.reconstruction.subset(np.argsort(full.order))
    decision = decide(donut_part, in_input_order, weights, views.cameras, budget=0.1)
    probes = probe_cameras(views.cameras)
    reference = render_images(donut_part, probes)
    pruned = in_input_order.subset(decision.keep)
    per_view = lambda scene: np.array([float(np.sum((a - b) ** 2)) for a, b in  # noqa: E731
                                       zip(reference, render_images(scene, probes))])
    quantized = per_view(in_input_order)
    assert quantized.sum() == pytest.approx(decision.quantization_sse)
    assert np.all(per_view(pruned) <= 1.1 * quantized)  # every probe view within budget
    assert decision.dropped == int((~decision.keep).sum()) > 0
    # Unseen Gaussians always go; the rest go in order of their drop cost.
    unseen = weights <= 0
    assert not decision.keep[unseen].any()
    costs = drop_costs(donut_part, weights)
    dropped_seen = ~decision.keep & ~unseen
    if dropped_seen.any() and decision.keep.any():
        assert costs[dropped_seen].max() <= costs[decision.keep].min()


def test_a_zero_budget_removes_only_what_no_view_reaches(donut_part, small_views):
    full = Encoder(quality=5, hyperprior=False).encode_with_report(donut_part)
    views = small_views
    weights = blend_sensitivity(donut_part, views.cameras).weight_sq
    in_input_order = full.reconstruction.subset(np.argsort(full.order))
    decision = decide(donut_part, in_input_order, weights, views.cameras, budget=0.0)
    assert decision.dropped >= decision.unseen == int((weights <= 0).sum())
    assert decision.dropped <= decision.unseen + len(donut_part) // 50


def test_pruning_is_deterministic(donut_part, small_views):
    def encode():
        return Encoder(quality=5, hyperprior=False, view_pruning=True,
                       cameras=small_views.cameras).encode_with_report(donut_part)

    first, second = encode(), encode()
    assert first.data == second.data and first.view_pruned > 0
    assert Decoder().decode(first.data).equals(first.reconstruction)


def test_small_scenes_are_not_pruned(donut_part):
    small = donut_part.subset(np.arange(MIN_PRUNED_SCENE - 1))
    result = Encoder(quality=5, hyperprior=False, view_pruning=True).encode_with_report(small)
    assert result.view_pruned == 0 and result.views is None
    assert len(result.reconstruction) == len(small)


def test_off_by_default(donut_part):
    result = Encoder(quality=5, hyperprior=False).encode_with_report(donut_part)
    assert result.view_pruned == 0 and len(result.reconstruction) == len(donut_part)


def test_cli_view_prune_reports_what_it_left_out(tmp_path, capsys, donut_part):
    src = tmp_path / "part.ply"
    small = donut_part.subset(np.arange(0, len(donut_part), 3))  # 1,268 Gaussians
    write_ply(small, src)
    out = tmp_path / "part.csgs"
    assert main(["encode", str(src), "-o", str(out), "--view-prune", "--no-hyperprior",
                 "--quiet"]) == 0
    assert "left out" in capsys.readouterr().out
    assert len(Decoder().decode(out.read_bytes())) < len(small)


def test_cli_cameras_file_is_used(tmp_path, capsys, donut_part):
    src = tmp_path / "part.ply"
    write_ply(donut_part, src)
    views = default_distribution(donut_part, directions=4, distances=(1.0,))
    entries = []
    for i, cam in enumerate(views.cameras):
        c2w = cam.camera_to_world
        entries.append({"id": i, "img_name": cam.name, "width": cam.width,
                        "height": cam.height, "position": c2w[:3, 3].tolist(),
                        "rotation": c2w[:3, :3].tolist(), "fx": cam.fx, "fy": cam.fy})
    cameras = tmp_path / "cameras.json"
    cameras.write_text(json.dumps(entries))
    out = tmp_path / "part.csgs"
    assert main(["encode", str(src), "-o", str(out), "--cameras", str(cameras),
                 "--no-hyperprior", "--quiet"]) == 0
    assert "4 of 4 cameras from the given cameras" in capsys.readouterr().out


def test_cli_bad_cameras_file_is_a_clear_error(tmp_path, capsys, donut_part):
    src = tmp_path / "part.ply"
    write_ply(donut_part, src)
    cameras = tmp_path / "cameras.json"
    cameras.write_text('[{"id": 0, "width": 10}]')
    out = tmp_path / "part.csgs"
    assert main(["encode", str(src), "-o", str(out), "--cameras", str(cameras),
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "cameras.json" in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.slow
def test_the_file_records_the_distribution_and_info_reports_it(tmp_path, capsys, pruned):
    from csgs_codec.codec.describe import describe_bitstream

    path = tmp_path / "p.csgs"
    path.write_bytes(pruned.data)
    facts = describe_bitstream(path)
    assert facts["views"] == {"source": "default-sphere", "count": 48,
                              "left_out": pruned.view_pruned,
                              "description": "48 views on a sphere at 3 distances"}
    assert main(["info", str(path)]) == 0
    assert "48 views on a sphere at 3 distances (default-sphere)" in capsys.readouterr().out


def test_view_record_round_trips_and_refuses_damage():
    from csgs_codec.chunks.view_record import ViewRecord
    from csgs_codec.errors import FormatError

    record = ViewRecord("cameras", 96, 1234, "96 of 311 cameras from cams.json")
    data = record.to_bytes()
    assert ViewRecord.from_bytes(data) == record
    for bad in (b"\x02" + data[1:], data[:1] + b"\x07" + data[2:], data + b"\x00", data[:-3]):
        with pytest.raises(FormatError) as err:
            ViewRecord.from_bytes(bad, base_offset=100)
        assert err.value.chunk == "vdis" and err.value.offset >= 100


def test_an_unreadable_view_record_is_reported_not_refused(capsys):
    """§12.21: a bad vdis payload does not make the file invalid."""
    from tests.conftest import REPO

    path = REPO / "spec" / "vectors" / "scenes" / "view_pruned_vdis_version_9.csgs"
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "record unreadable, ignored" in out and "unknown view-distribution version 9" in out
    import json

    record = json.loads(path.with_suffix(".json").read_text())
    assert len(Decoder().decode(path)) == record["reads"][0]["gaussians"] < 45624 // 12 + 1


def _inria_folder(root, scene, cameras):
    """An INRIA output folder: cameras.json and two point-cloud iterations."""
    for iteration, part in ((7000, scene.subset(np.arange(1100))), (30000, scene)):
        folder = root / "point_cloud" / f"iteration_{iteration}"
        folder.mkdir(parents=True)
        write_ply(part, folder / "point_cloud.ply")
    entries = []
    for i, cam in enumerate(cameras):
        c2w = cam.camera_to_world
        entries.append({"id": i, "img_name": cam.name, "width": cam.width,
                        "height": cam.height, "position": c2w[:3, 3].tolist(),
                        "rotation": c2w[:3, :3].tolist(), "fx": cam.fx, "fy": cam.fy})
    (root / "cameras.json").write_text(json.dumps(entries))
    return root


def test_an_inria_output_folder_encodes_its_latest_cloud_with_its_cameras(
        tmp_path, capsys, donut_part):
    views = default_distribution(donut_part, directions=3, distances=(1.0,), size=(160, 120))
    folder = _inria_folder(tmp_path / "run", donut_part, views.cameras)
    out = tmp_path / "run.csgs"
    assert main(["encode", str(folder), "-o", str(out), "--no-hyperprior", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "3 of 3 cameras from the given cameras" in printed
    decoded = Decoder().decode(out.read_bytes())
    assert 1100 < len(decoded) < len(donut_part)  # iteration 30000, pruned for its cameras


def test_an_inria_folder_without_pruning_keeps_every_gaussian(tmp_path, capsys, donut_part):
    views = default_distribution(donut_part, directions=3, distances=(1.0,), size=(160, 120))
    folder = _inria_folder(tmp_path / "run", donut_part, views.cameras)
    out = tmp_path / "run.csgs"
    assert main(["encode", str(folder), "-o", str(out), "--no-view-prune", "--no-hyperprior",
                 "--quiet"]) == 0
    assert len(Decoder().decode(out.read_bytes())) == len(donut_part)
