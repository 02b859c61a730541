"""Per-scene step allocation (csgs_codec/decisions/step_allocation.py): the encoder moves each
attribute group's step from the preset where probe renders say it pays."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions import step_allocation as sa
from csgs_codec.decisions.presets import PRESETS, preset_steps
from csgs_codec.decisions.step_allocation import StepAllocation, allocate_steps
from csgs_codec.errors import InputError
from tests.codec.helpers import random_scene
from tests.stability.bounds import coded_orientations


@pytest.fixture(autouse=True)
def fewer_probe_views(monkeypatch):
    # Four directions: the same search on a third of the renders; every saving kept, so
    # the tests see the search itself (the threshold has its own test).
    monkeypatch.setattr(sa, "PROBE_DIRECTIONS", 4)
    monkeypatch.setattr(sa, "MIN_SAVING", 0.0)


def test_apply_moves_each_group_by_its_half_octaves_and_the_grid_by_whole_bits():
    preset = PRESETS[5]
    moved = StepAllocation({"dc": 2, "rest3": -1, "rot": -4, "position": -2}).apply(preset)
    steps, base = preset_steps(moved), preset_steps(preset)
    assert steps["dc"] == pytest.approx(2.0 * base["dc"])
    assert steps["rest1"] == base["rest1"] and steps["rest2"] == base["rest2"]
    assert steps["rest3"] == pytest.approx(base["rest3"] / np.sqrt(2.0))
    assert steps["rot"] == pytest.approx(base["rot"] / 4.0)
    assert steps["opacity"] == base["opacity"] and steps["scale"] == base["scale"]
    assert moved.position_bits == preset.position_bits - 2
    assert StepAllocation().apply(preset) == preset


def test_small_scenes_keep_the_preset_and_write_what_they_wrote_before():
    scene = random_scene(sa.MIN_GAUSSIANS - 1, sh_degree=2)
    assert allocate_steps(scene, PRESETS[5]).offsets == {}
    on = Encoder(quality=5, hyperprior=False).encode_with_report(scene)
    off = Encoder(quality=5, hyperprior=False, step_allocation=False).encode(scene)
    assert on.allocation is None and on.data == off


def _isotropic(scene):
    # Sphere-shaped Gaussians: a rotation changes no pixel of them.
    scene.scales = np.repeat(scene.scales[:, :1], 3, axis=1)
    return scene


def test_rotations_that_never_show_go_to_the_coarsest_step():
    scene = _isotropic(random_scene(1500, sh_degree=1, seed=3))
    allocation = allocate_steps(scene, PRESETS[5])
    # The descent takes them to the bound; recentring may then move every step together.
    rot = allocation.offsets["rot"]
    assert rot >= sa.MAX_OFFSET - sa.RECENTRE_STEPS
    assert all(rot > v for g, v in allocation.offsets.items() if g != "rot")
    assert 0.0 < allocation.cost_ratio < 1.0 and allocation.lambda_ > 0.0
    assert set(allocation.offsets) == {"dc", "rest1", "opacity", "scale", "rot", "position"}


def test_the_allocation_is_the_same_on_every_run_and_the_file_decodes_to_its_reconstruction():
    scene = random_scene(1500, sh_degree=3, seed=4)
    first = allocate_steps(scene, PRESETS[4])
    assert allocate_steps(scene, PRESETS[4]) == first
    result = Encoder(quality=4, hyperprior=False).encode_with_report(scene)
    assert result.allocation == first
    assert Decoder().decode(result.data).equals(result.reconstruction)
    again = Encoder(quality=4, hyperprior=False).encode(scene)
    assert again == result.data


def test_the_chosen_steps_reach_the_coded_streams():
    scene = _isotropic(random_scene(1500, sh_degree=1, seed=5))
    on = Encoder(quality=5, hyperprior=False).encode_with_report(scene)
    off = Encoder(quality=5, hyperprior=False, step_allocation=False).encode_with_report(scene)
    # Rotations at the coarsest step: the rotation chunk shrinks, nothing renders worse
    # for it (the Gaussians are spheres).
    assert on.stream_bytes["ROTN"] < off.stream_bytes["ROTN"]
    assert len(on.data) < len(off.data)


def test_fast_mode_off_and_sh0_scenes_keep_the_preset_unless_asked():
    scene = random_scene(1500, sh_degree=1, seed=6)
    assert Encoder(quality=5, fast=True).encode_with_report(scene).allocation is None
    assert Encoder(quality=5, step_allocation=False).encode_with_report(scene).allocation is None
    flat = random_scene(1500, sh_degree=0, seed=6)
    assert Encoder(quality=5, hyperprior=False).encode_with_report(flat).allocation is None
    forced = Encoder(quality=5, hyperprior=False, step_allocation=True).encode_with_report(flat)
    assert forced.allocation is not None and "dc" in forced.allocation.offsets


def test_the_file_keeps_the_bounds_of_the_steps_it_used():
    scene = random_scene(1500, sh_degree=2, seed=7)
    result = Encoder(quality=6, hyperprior=False).encode_with_report(scene)
    used = result.allocation.apply(PRESETS[6])
    decoded, ref = Decoder().decode(result.data), scene.subset(result.order)
    # Steps snap to a 1/8-octave grid (within 4.5%), so half a step is at most 0.523 * step.
    assert np.abs(decoded.sh_dc - ref.sh_dc).max() <= 0.523 * used.dc_step + 1e-6
    _, scales = coded_orientations(ref, result.sorted_axes)  # the coded axis order
    assert np.abs(decoded.scales - scales).max() <= 0.523 * used.scale_step + 1e-6
    for band, (lo, hi) in enumerate(((0, 3), (3, 8))):
        step = used.rest_step * used.rest_band_factors[band]
        # Opponent colours: a colour is a sum of three coded values (each off by half a
        # step) with weights of at most 1 in magnitude.
        error = np.abs(decoded.sh_rest[:, lo:hi] - ref.sh_rest[:, lo:hi]).max()
        assert error <= 3 * 0.523 * step + 1e-6


def test_an_unknown_setting_is_refused():
    with pytest.raises(InputError, match="step_allocation"):
        Encoder(step_allocation="yes")


def test_the_ladder_slope_is_the_exponential_fits_derivative_at_the_preset():
    rates = [1000.0, 1400.0, 1180.0, 860.0, 750.0]
    points = [(r, float(np.exp(5.0 - 0.004 * r))) for r in rates]
    assert sa.ladder_slope(points) == pytest.approx(0.004 * np.exp(5.0 - 4.0))
    assert sa.ladder_slope([(r, 0.0) for r in rates]) is None  # nothing shows
    assert sa.ladder_slope([(r, r) for r in rates]) is None  # error rising with the rate


def test_a_saving_below_what_the_probe_resolves_keeps_the_preset(monkeypatch):
    scene = _isotropic(random_scene(1500, sh_degree=1, seed=3))
    found = allocate_steps(scene, PRESETS[5])
    assert found.offsets and found.rate_ratio < 1.0
    monkeypatch.setattr(sa, "MIN_SAVING", 1.0 - found.rate_ratio + 1e-9)
    monkeypatch.setattr(sa, "_coarser_grid", lambda r0, d0, cost, evaluate: ({}, (r0, d0)))
    kept = allocate_steps(scene, PRESETS[5])
    assert kept.offsets == {} and kept.rate_ratio == found.rate_ratio
    assert kept.apply(PRESETS[5]) == PRESETS[5]
    assert "cannot resolve" in kept.summary() and "moved" in found.summary()


def test_a_descent_the_probe_cannot_resolve_still_takes_a_coarser_grid_that_pays(
        monkeypatch):
    """Gaussians about 37 grid cells wide at quality 5: fewer grid bits barely show."""
    monkeypatch.setattr(sa, "MIN_SAVING", 1.0)  # no descent is kept
    scene = random_scene(1500, sh_degree=1, seed=3)
    allocation = allocate_steps(scene, PRESETS[5])
    assert list(allocation.offsets) == ["position"] and allocation.offsets["position"] < 0
    assert allocation.rate_ratio < 1.0 and allocation.cost_ratio < 1.0
    assert "coarser" in allocation.summary()
    result = Encoder(quality=5, hyperprior=False).encode_with_report(scene)
    assert result.allocation == allocation
    assert Decoder().decode(result.data).equals(result.reconstruction)
    # Gaussians a cell wide: a coarser grid shows, the preset keeps its grid.
    small = random_scene(1500, sh_degree=1, seed=3)
    small.scales = small.scales - 4.0
    kept = allocate_steps(small, PRESETS[5])
    assert kept.offsets == {} and kept.lambda_ > 0.0  # probed, and the grid stayed


def test_a_probe_view_renders_the_same_from_the_gaussians_that_reach_it():
    """The probe renders each view from :func:`window_reach`'s Gaussians only: at the
    coarsest steps the descent can try, they equal renders of the whole scene. Whole probe
    views of the sample reach all of it, so a quarter of each (the one above and left of
    its centre) is the window here (the probe crops so for scenes of tiny Gaussians,
    :func:`probe_scale`)."""
    from dataclasses import replace

    from csgs_codec.interchange.ply_io import read_ply
    from csgs_codec.render.rasterizer import render
    from tests.conftest import SAMPLE

    scene = read_ply(SAMPLE)
    scene = scene.subset(np.arange(0, len(scene), 4))
    cameras = [replace(c, width=c.width // 4, height=c.height // 4, cx=c.cx - c.width // 4,
                       cy=c.cy - c.height // 4) for c in sa.probe_cameras(scene)]
    probe = sa._Probe(scene, PRESETS[1], "footprint", cameras)
    coarsest = {"dc": sa.MAX_OFFSET, "opacity": sa.MAX_OFFSET, "scale": sa.MAX_OFFSET,
                "rot": sa.MAX_OFFSET, "position": -sa.MAX_BIT_OFFSET}
    _, coded = probe.coded(coarsest)
    shown = 0
    on_grid = probe.reach_on_grid(probe.grid_bits(coarsest))
    assert sum(map(len, on_grid)) > sum(map(len, probe.reach))  # 4-bit cells move Gaussians in
    for camera, reach in zip(cameras, on_grid):
        assert 0 < len(reach) < len(scene)
        whole = render(coded, camera, backend="numba")
        part = render(coded.subset(reach), camera, backend="numba")
        assert np.abs(whole.image - part.image).max() <= 1e-6
        assert np.abs(whole.alpha - part.alpha).max() <= 1e-6
        shown += int((whole.alpha > 0.5).sum())
    assert shown > 0


def test_many_copies_of_a_few_gaussians_keep_the_preset_without_probing():
    few = random_scene(sa.MIN_GAUSSIANS - 24, sh_degree=2, seed=6)
    copies = few.subset(np.arange(20 * len(few)) % len(few))
    allocation = allocate_steps(copies, PRESETS[5])
    assert allocation.offsets == {} and allocation.trials == 0


def test_probe_views_keep_their_pixels_and_crop_for_scenes_of_tiny_gaussians():
    """Whole views at a quarter size where the median Gaussian spans enough probe pixels;
    for sub-pixel Gaussians a finer scale, cropped around the centre to the same size: the
    crop is exactly that part of the finer view."""

    from csgs_codec.render.rasterizer import render
    from csgs_codec.render.view_distribution import default_distribution

    scene = random_scene(1500, sh_degree=1, seed=3)
    full = default_distribution(scene, directions=4, distances=(1.0,)).cameras
    assert sa.probe_scale(scene, full) == sa.PROBE_SCALE
    whole = sa.probe_cameras(scene)
    assert (whole[0].width, whole[0].height) == (round(full[0].width / 4),
                                                  round(full[0].height / 4))
    tiny = random_scene(1500, sh_degree=1, seed=3)
    tiny.scales = tiny.scales - 4.0  # a tenth of a view pixel
    assert sa.probe_scale(tiny, full) == 1
    cropped = sa.probe_cameras(tiny)
    assert [(c.width, c.height) for c in cropped] == [(c.width, c.height) for c in whole]
    # The crop against the whole view at full size: the same pixels.
    cam = cropped[0]
    x0, y0 = round(full[0].cx - cam.cx), round(full[0].cy - cam.cy)
    big = render(tiny, full[0], backend="numba").image
    part = render(tiny, cam, backend="numba").image
    # (float rounding only: a tile grid of another origin sums in another order)
    np.testing.assert_allclose(part, big[y0:y0 + cam.height, x0:x0 + cam.width], atol=1e-4)
    assert part.std() > 0.01  # the crop shows the scene


def test_a_sample_of_a_larger_scene_is_probed_through_windows_of_its_views():
    from csgs_codec.render.view_distribution import default_distribution

    scene = random_scene(1500, sh_degree=1, seed=3)
    full = default_distribution(scene, directions=4, distances=(1.0,)).cameras
    windows = sa.probe_cameras(scene, whole=False)
    assert len(windows) == len(full)
    for i, (window, cam) in enumerate(zip(windows, full)):
        assert (window.width, window.height) == (cam.width // sa.PROBE_WINDOW,
                                                  cam.height // sa.PROBE_WINDOW)
        assert (window.fx, window.fy) == (cam.fx, cam.fy)  # the view's own pixels
        # Quarter i % 4 around the centre: the window's corner is at the centre or one
        # window width (height) before it.
        x0, y0 = cam.cx - window.cx, cam.cy - window.cy
        assert x0 == cam.width // 2 - window.width * (1 - i % 2)
        assert y0 == cam.height // 2 - window.height * (1 - (i // 2) % 2)


@pytest.mark.skipif(not __import__("csgs_codec.render.numba_loader", fromlist=["x"])
                    .numba_available(), reason="numba not installed")
def test_recoloured_candidates_score_exactly_as_rendered_ones(monkeypatch):
    """Candidates that move colour steps only are scored from the recorded weights of an
    earlier candidate with the same geometry: every (bits, error) equals the rendered one."""
    from pathlib import Path

    from csgs_codec.interchange.ply_io import read_ply
    from csgs_codec.render.blend_record import BlendRecord

    recoloured = []
    recolour = BlendRecord.recolour
    monkeypatch.setattr(BlendRecord, "recolour",
                        lambda self, s: recoloured.append(1) or recolour(self, s))

    scene = read_ply(Path(__file__).resolve().parents[2] / "benchmarks" / "data"
                     / "yashica_t4_top8192.ply")
    scene = scene.subset(np.arange(0, len(scene), 4))
    cameras = sa.probe_cameras(scene)[:4]
    candidates = [{}, {"opacity": 1}, {"dc": 1}, {"dc": 2, "rest1": -1}, {"opacity": 1, "dc": 3},
                  {"opacity": 1, "rest2": 2, "rest3": -2}, {"position": -2, "dc": 1},
                  {"dc": -1}, {"position": -2, "rest1": 3}]
    fast = sa._Probe(scene, PRESETS[5], "footprint", cameras)
    plain = sa._Probe(scene, PRESETS[5], "footprint", cameras)
    plain._recolours = False
    for offsets in candidates:
        assert fast.rate_distortion(offsets) == plain.rate_distortion(offsets), offsets
    assert fast._recorded is not None and plain._recorded is None
    # {"dc": 2, "rest1": -1} and {"opacity": 1, "rest2": 2, "rest3": -2} replay a record.
    assert len(recoloured) == 2 * len(cameras)
