"""Baking anchor scenes into standard 3DGS scenes, and the ``vorg`` view origins they use."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.bake.anchor_bake import BakeSettings, bake_anchor_scene
from csgs_codec.chunks.view_origins import (
    MAX_ORIGINS,
    even_sample,
    parse_view_origins,
    view_origins_payload,
)
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.chunk import Chunk
from csgs_codec.format.writer import write_container
from csgs_codec.model.scaffold import ScaffoldDecoder
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.anchors.helpers import FAST_FIT


@pytest.fixture(scope="module")
def scene():
    return synthetic_anchor_scene(n_objects=2, anchors_per_object=40, seed=5)


def test_a_bake_from_one_origin_at_sh_degree_0_is_that_view_s_neural_gaussians(scene):
    origin = np.array([0.3, -2.0, 0.7])
    baked = bake_anchor_scene(scene, origins=origin[None],
                              settings=BakeSettings(sh_degree=0, ridge=0.0))
    view = ScaffoldDecoder(scene).decode(origin)
    exact = view.gaussians
    assert len(baked) == len(exact) > 0
    np.testing.assert_array_equal(baked.positions, exact.positions)
    np.testing.assert_allclose(baked.sh_dc, exact.sh_dc, atol=1e-4)
    np.testing.assert_allclose(baked.opacity, exact.opacity, atol=1e-3)
    np.testing.assert_allclose(baked.scales, exact.scales, atol=1e-5)
    # Quaternions agree up to sign.
    dots = np.abs(np.sum(baked.rotations * exact.rotations, axis=1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-5)
    np.testing.assert_array_equal(baked.labels, scene.labels[view.anchor_index])
    np.testing.assert_array_equal(baked.semantic, scene.semantic[view.anchor_index])


def test_slots_off_from_most_origins_are_dropped(scene):
    origins = np.array([[0.0, -2.0, 0.5], [0.0, 2.0, 0.5], [2.0, 0.0, 0.5]])
    loose = bake_anchor_scene(scene, origins=origins, settings=BakeSettings(keep_fraction=0.3))
    strict = bake_anchor_scene(scene, origins=origins, settings=BakeSettings(keep_fraction=1.0))
    decoder = ScaffoldDecoder(scene)
    on = [set(zip(v.anchor_index, v.offset_index))
          for v in (decoder.decode(o) for o in origins)]
    assert len(strict) == len(on[0] & on[1] & on[2])
    assert len(loose) == len(on[0] | on[1] | on[2])


def test_the_baked_colour_follows_the_view_with_sh(scene):
    origins = np.array([[np.cos(a) * 2, np.sin(a) * 2, 0.4] for a in np.linspace(0, 6, 24)])
    flat = bake_anchor_scene(scene, origins=origins, settings=BakeSettings(sh_degree=0))
    full = bake_anchor_scene(scene, origins=origins, settings=BakeSettings(sh_degree=3))
    assert full.sh_degree_stored == 3 and flat.sh_degree_stored == 0
    assert np.abs(full.sh_rest).max() > 0
    np.testing.assert_array_equal(flat.positions, full.positions)


def test_bad_settings_and_origins_are_refused(scene):
    with pytest.raises(InputError, match="SH degree"):
        bake_anchor_scene(scene, settings=BakeSettings(sh_degree=4))
    with pytest.raises(InputError, match="origin"):
        bake_anchor_scene(scene, origins=np.array([[np.nan, 0.0, 0.0]]))
    no_mlps = synthetic_anchor_scene(n_objects=1, anchors_per_object=10, with_mlps=False)
    with pytest.raises(InputError, match="MLPs"):
        bake_anchor_scene(no_mlps)


def test_view_origins_travel_in_the_file_and_the_bake_uses_them(scene):
    with_origins = scene.subset(np.arange(len(scene)))
    with_origins.view_origins = np.random.default_rng(1).normal(size=(40, 3)).astype(np.float32)
    report = AnchorEncoder(6, fit=FAST_FIT).encode_with_report(with_origins)
    decoded = AnchorDecoder().decode(report.data, layers="color,semantic")
    assert decoded.view_origins.shape == (MAX_ORIGINS, 3)
    np.testing.assert_array_equal(decoded.view_origins, even_sample(with_origins.view_origins))
    assert decoded.equals(report.reconstruction)
    baked = bake_anchor_scene(decoded)
    again = bake_anchor_scene(decoded, origins=decoded.view_origins)
    np.testing.assert_array_equal(baked.sh_rest, again.sh_rest)
    plain = AnchorEncoder(6, fit=FAST_FIT).encode_with_report(scene)
    assert "vorg" not in plain.chunk_bytes
    assert len(report.data) - len(plain.data) < 12 * MAX_ORIGINS + 32


def test_an_invalid_vorg_payload_is_ignored_not_fatal(scene):
    report = AnchorEncoder(6, fit=FAST_FIT).encode_with_report(scene)
    from csgs_codec.format import read_layers

    container = read_layers(report.data, layers="color,semantic")
    chunks = [Chunk(e.type, e.layer.label, bytes(container.payloads[e.index]))
              for e in container.toc]
    chunks.insert(5, Chunk("vorg", "base", b"\x01\x02" + b"\xff" * 24))  # NaN origins
    decoded = AnchorDecoder().decode(write_container(chunks), layers="color,semantic")
    assert decoded.view_origins is None
    assert decoded.subset(np.arange(len(decoded))).positions.shape == scene.positions.shape


@pytest.mark.parametrize("payload, message", [
    (b"\x02\x01" + bytes(12), "version"),
    (b"\x01\x00", "origin_count is 0"),
    (b"\x01\x21" + bytes(12 * 33), "origin_count"),
    (b"\x01\x01" + bytes(8), "truncated"),
    (b"\x01\x01" + bytes(13), "unexpected bytes"),
])
def test_vorg_payload_rules(payload, message):
    with pytest.raises(FormatError, match=message) as info:
        parse_view_origins(payload, base_offset=100)
    assert info.value.chunk == "vorg" and info.value.offset >= 100


def test_vorg_payload_round_trips():
    origins = np.arange(15, dtype=np.float32).reshape(5, 3)
    np.testing.assert_array_equal(parse_view_origins(view_origins_payload(origins)), origins)


@pytest.mark.slow  # trains a scene: ~20 s alone, more beside other tests
def test_a_trained_scene_bakes_within_half_a_db_of_its_exact_render(tmp_path):
    """What users make: `csgs train` with the demo's settings, then `csgs decode -o x.ply`;
    on the held-out photos the bake stays within 0.5 dB of the exact per-view render."""
    from csgs_cli.main import main
    from csgs_codec import read_scene
    from csgs_codec.metrics.image import psnr
    from csgs_codec.model.anchor_views import SceneViews
    from csgs_codec.render.rasterizer import render
    from csgs_codec.train.datasets import load_dataset
    from csgs_codec.train.evaluation import split_views

    data, out = tmp_path / "synthetic", tmp_path / "scene.csgs"
    assert main(["synthetic", str(data), "--views", "12", "--size", "64x48", "--gaussians",
                 "200", "-q"]) == 0
    assert main(["train", str(data), "-o", str(out), "--iterations", "300", "--anchors",
                 "150", "--features", "16", "--offsets", "5", "--semantic-iterations", "60",
                 "--test-every", "4", "-q"]) == 0
    assert main(["decode", str(out), "-o", str(tmp_path / "baked.ply"), "-q"]) == 0
    baked = read_scene(tmp_path / "baked.ply")
    exact = SceneViews(AnchorDecoder().decode(out))
    assert exact.scene.view_origins is not None  # csgs train stores its training origins
    _, test = split_views(load_dataset(data, read_masks=False), 4)

    def mean_psnr(gaussians_for):
        return np.mean([psnr(v.image, np.clip(render(gaussians_for(v.camera), v.camera,
                                                     backend="numba").image, 0, 1))
                        for v in test])

    assert mean_psnr(lambda c: baked) >= mean_psnr(exact.gaussians) - 0.5


def test_refining_brings_the_bake_closer_to_the_exact_renders_of_other_views():
    """The refinement fits the bake to exact renders from the origins; from origins it never
    saw (between them) the bake renders closer to the anchors than before, positions kept,
    the unrefined bake untouched."""
    from csgs_codec.bake.refine import refine_bake, target_cameras
    from csgs_codec.model.anchor_views import SceneViews
    from csgs_codec.render.rasterizer import render

    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=30, seed=8)
    exact = SceneViews(scene)
    centre = scene.positions.mean(axis=0)
    angles = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    ring = np.stack([centre + 0.4 * np.array([np.cos(a), np.sin(a), 0.5]) for a in angles])
    origins, unseen = ring[0::2], ring[1::2]
    baked = bake_anchor_scene(scene, origins=origins)
    before = baked.subset(np.arange(len(baked)))
    refined = refine_bake(baked, scene, origins, steps=120, size=64)
    np.testing.assert_array_equal(baked.sh_dc, before.sh_dc)
    np.testing.assert_array_equal(refined.positions, baked.positions)

    def error(gaussians):
        return np.mean([np.abs(render(gaussians, c, backend="numba").image
                               - render(exact.gaussians(c), c, backend="numba").image).mean()
                        for c in target_cameras(scene, unseen, 64)])

    assert error(refined) < 0.9 * error(baked)
    again = refine_bake(baked, scene, origins, steps=120, size=64)
    np.testing.assert_array_equal(again.sh_dc, refined.sh_dc)  # seeded: it repeats


@pytest.mark.parametrize("settings, field", [(BakeSettings(refine_steps=-1), "refine_steps"),
                                             (BakeSettings(refine_size=8), "refine_size")])
def test_bad_refine_settings_are_refused(settings, field):
    with pytest.raises(InputError) as info:
        settings.check()
    assert info.value.property == field
