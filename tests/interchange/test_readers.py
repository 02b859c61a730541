"""Each reader on files made by the format's own tools: it must agree with splat-transform
3.7.0's decoding of the same bytes (the oracle) and with the scene the file was made from,
within the format's quantization."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.files import read_scene_with_report
from tests.interchange.helpers import (
    DATA,
    alphas,
    colors,
    matched,
    oracle_columns,
    oracle_scene_arrays,
    rotation_error,
)

#: fixture -> (format, version, SH degree, Gaussians)
FIXTURES = {
    "brush_sh3.compressed.ply": ("compressed-ply", None, 3, 200),
    "donut_sh0.compressed.ply": ("compressed-ply", None, 0, 300),
    "brush_sh3.sog": ("sog", "2", 3, 200),
    "donut_sh0_sog": ("sog", "2", 0, 300),
    "donut_sh0_sog/meta.json": ("sog", "2", 0, 300),
    "brush_sh1_sog_v1": ("sog", "1", 1, 200),
    "brush_sh3.v2.spz": ("spz", "2", 3, 200),
    "brush_sh3.v3.spz": ("spz", "3", 3, 200),
    "brush_sh3.v4.spz": ("spz", "4", 3, 200),
    "donut_sh0.v4.spz": ("spz", "4", 0, 300),
    "brush_sh3.l0.ksplat": ("ksplat", "0.1", 2, 200),
    "brush_sh3.l1.ksplat": ("ksplat", "0.1", 2, 200),
    "brush_sh3.l2.ksplat": ("ksplat", "0.1", 2, 200),
    "brush_sh3.l2_sh1.ksplat": ("ksplat", "0.1", 1, 200),
    "donut_sh0.l1.ksplat": ("ksplat", "0.1", 0, 293),  # made dropping alpha < 1/255
    "brush_sh3.splat": ("splat", None, 0, 200),
    "donut_sh0.splat": ("splat", None, 0, 300),
}


@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_reader_agrees_with_splat_transform(name):
    scene, source = read_scene_with_report(DATA / name)
    fmt, version, degree, count = FIXTURES[name]
    assert (source.format, source.version, source.lossy) == (fmt, version, True)
    assert (len(scene), scene.sh_degree_stored) == (count, degree)
    oracle = oracle_scene_arrays(oracle_columns(name if name != "donut_sh0_sog/meta.json"
                                                else "donut_sh0_sog"))
    for key in ("positions", "sh_dc", "sh_rest", "scales"):
        np.testing.assert_allclose(getattr(scene, key), oracle[key], rtol=1e-6, atol=1e-7,
                                   err_msg=key)
    # splat-transform writes +-inf logits for alpha 0 and 255 where csgs clamps at +-13.8.
    finite = np.isfinite(oracle["opacity"])
    np.testing.assert_allclose(scene.opacity[finite], oracle["opacity"][finite], rtol=1e-6,
                               atol=1e-6)
    assert np.all(np.sign(scene.opacity[~finite]) == np.sign(oracle["opacity"][~finite]))
    # .splat: csgs reads rotation bytes as (b - 128) / 128 (the reference viewer), the
    # oracle as b / 127.5 - 1: half a step apart.
    tolerance = 1e-4 if source.format == "splat" else 1e-6
    assert rotation_error(scene.rotations, oracle["rotations"]).max() < tolerance


SH3, SH0 = "brush_sh3.ply", "donut_sh0.ply"
SPZ_COLOR = 0.5 / (0.15 * 255) * 0.28209479177387814  # half a color step, color units
SPZ_REACH = 127.5 / (0.15 * 255) * 0.28209479177387814  # color reach around 0.5
#: fixture -> (source, max position error as a share of the scene's extent, color, alpha,
#: log-scale (None: checked as float16 linear scale), rotation 1 - |dot|, SH error)
PRECISION = {
    # 11/10/11-bit positions and log-scales per 256-Gaussian chunk; 8-bit color, alpha, SH
    "brush_sh3.compressed.ply": (SH3, 1 / 1023, 1 / 255, 1 / 255, 2 ** -6, 1e-5, 8 / 256),
    "donut_sh0.compressed.ply": (SH0, 1 / 1023, 1 / 255, 1 / 255, 2 ** -6, 1e-5, 0),
    # 16-bit log positions; codebooks; SH palette (k-means: bounded loosely)
    "brush_sh3.sog": (SH3, 2 ** -12, 2 / 255, 1 / 255, 2 ** -5, 1e-3, 0.25),
    "donut_sh0_sog": (SH0, 2 ** -12, 2 / 255, 1 / 255, 2 ** -5, 1e-3, 0),
    "brush_sh1_sog_v1": (SH3, 2 ** -12, 1 / 255, 1 / 255, 2 ** -5, 1e-3, 2 / 255),
    # 12 fractional bits (2^-13 abs.); color step 1 / (0.15 * 255) of f_dc; log-scale step
    # 1/16; SH to 5 bits (degree 1) and 4 bits (2-3) of 8: up to 8.5/128
    "brush_sh3.v2.spz": (SH3, 2 ** -17, SPZ_COLOR, 1 / 255, 1 / 32, 1e-2, 8.5 / 128),
    "brush_sh3.v3.spz": (SH3, 2 ** -17, SPZ_COLOR, 1 / 255, 1 / 32, 1e-5, 8.5 / 128),
    "brush_sh3.v4.spz": (SH3, 2 ** -17, SPZ_COLOR, 1 / 255, 1 / 32, 1e-5, 8.5 / 128),
    "donut_sh0.v4.spz": (SH0, 2 ** -10, SPZ_COLOR, 1 / 255, 1 / 32, 1e-5, 0),
    # level 0 floats; 1-2 u16 bucket offsets and float16; color and alpha truncated to u8
    "brush_sh3.l0.ksplat": (SH3, 1e-7, 1 / 255, 1 / 255, 1e-6, 1e-6, 1e-6),
    "brush_sh3.l1.ksplat": (SH3, 2 ** -18, 1 / 255, 1 / 255, None, 1e-6, 2 ** -11),
    "brush_sh3.l2.ksplat": (SH3, 2 ** -18, 1 / 255, 1 / 255, None, 1e-6, 3 / 255),
    "brush_sh3.l2_sh1.ksplat": (SH3, 2 ** -18, 1 / 255, 1 / 255, None, 1e-6, 3 / 255),
    "donut_sh0.l1.ksplat": (SH0, 2 ** -11, 1 / 255, 1 / 255, None, 1e-6, 0),
    "brush_sh3.splat": (SH3, 1e-7, 1 / 255, 1 / 255, 1e-6, 1e-4, 0),
    "donut_sh0.splat": (SH0, 1e-7, 1 / 255, 1 / 255, 1e-6, 1e-4, 0),
}
#: What each format can represent: (color range, log-scale range), None where unlimited.
RANGES = {"spz": ((0.5 - SPZ_REACH, 0.5 + SPZ_REACH), (-10.0, 5.9375)),
          "ksplat": ((0.0, 1.0), None), "splat": ((0.0, 1.0), None),
          "compressed-ply": (None, None), "sog": (None, None)}


@pytest.mark.parametrize("name", sorted(PRECISION))
def test_reader_values_match_the_source_scene_within_the_formats_precision(name):
    source_name, pos_share, color_tol, alpha_tol, scale_tol, rot_tol, sh_tol = PRECISION[name]
    scene, info = read_scene_with_report(DATA / name)
    original = matched(read_scene_with_report(DATA / source_name)[0], scene)
    extent = float(np.ptp(original.positions, axis=0).max())
    assert np.abs(scene.positions - original.positions).max() <= pos_share * extent
    color_range, scale_range = RANGES[info.format]
    want = colors(original)
    if color_range is not None:
        want = np.clip(want, *color_range)
    # A Gaussian stored with alpha 0 is invisible: SOG does not keep its color.
    visible = alphas(scene) > 1e-5
    assert np.abs(colors(scene) - want)[visible].max() <= color_tol + 1e-6
    assert np.abs(alphas(scene) - alphas(original)).max() <= alpha_tol + 1e-6
    want_scales = original.scales.astype(np.float64)
    if scale_range is not None:
        want_scales = np.clip(want_scales, *scale_range)
    if scale_tol is None:  # float16 linear scales, truncated (three.js): one step, 2^-10
        linear, want_linear = np.exp(scene.scales.astype(np.float64)), np.exp(want_scales)
        assert np.all(np.abs(linear - want_linear) <= 2 ** -10 * want_linear + 2 ** -24)
    else:
        assert np.abs(scene.scales - want_scales).max() <= scale_tol + 1e-6
    assert rotation_error(scene.rotations, original.rotations).max() <= rot_tol
    b = scene.sh_rest.shape[1]
    if b:
        want_sh = original.sh_rest[:, :b].astype(np.float64)
        if info.format == "spz":
            want_sh = np.clip(want_sh, -1.0, 127 / 128)
        assert np.abs(scene.sh_rest - want_sh).max() <= sh_tol + 1e-6


def test_brush_ply_with_alphabetical_properties_and_no_normals_reads_by_name():
    """Brush writes f_dc, f_rest_0, f_rest_1, f_rest_10, ..., opacity, rot, scale, x, y, z:
    each column must land in its attribute, whatever its place in the file."""
    path = DATA / "brush_sh3.ply"
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    names = [line.split()[2] for line in data[:end].decode().split("\n")
             if line.startswith("property")]
    assert names[:5] == ["f_dc_0", "f_dc_1", "f_dc_2", "f_rest_0", "f_rest_1"]
    assert names[5] == "f_rest_10" and names[-3:] == ["x", "y", "z"] and "nx" not in names
    rows = np.frombuffer(data, np.dtype([(n, "<f4") for n in names]), offset=end)
    scene, source = read_scene_with_report(path)
    assert source.format == "ply" and not source.lossy and scene.sh_degree_stored == 3
    np.testing.assert_array_equal(scene.positions[:, 2], rows["z"])
    np.testing.assert_array_equal(scene.scales[:, 1], rows["scale_1"])
    np.testing.assert_array_equal(scene.rotations[:, 0], rows["rot_0"])
    # f_rest_k is channel-major: coefficient k % 15 of channel k // 15.
    np.testing.assert_array_equal(scene.sh_rest[:, 10, 0], rows["f_rest_10"])
    np.testing.assert_array_equal(scene.sh_rest[:, 2, 1], rows["f_rest_17"])
    np.testing.assert_array_equal(scene.sh_rest[:, 14, 2], rows["f_rest_44"])


def test_glb_from_splat_transform_reads_back_the_scene_it_was_made_from():
    scene, source = read_scene_with_report(DATA / "brush_sh3.glb")
    original = read_scene_with_report(DATA / SH3)[0]
    assert (source.format, source.lossy) == ("glb", False)
    np.testing.assert_array_equal(scene.positions, original.positions)
    np.testing.assert_array_equal(scene.sh_dc, original.sh_dc)
    np.testing.assert_array_equal(scene.sh_rest, original.sh_rest)
    np.testing.assert_allclose(scene.rotations, original.rotations, atol=2e-7)
    np.testing.assert_allclose(scene.scales, original.scales, atol=1e-6)
    # float32 opacity in [0, 1]: the logit keeps about 1e-4 at |logit| ~ 10
    np.testing.assert_allclose(alphas(scene), alphas(original), atol=1e-7)


def test_spz_of_sh_degree_0_with_bytes_after_its_blocks_is_refused():
    """A legacy SPZ whose header says SH degree 0 has an empty SH block; zlib reads a read
    limit of 0 as "no limit", so the reader once took every byte after the blocks as SH
    coefficients and failed with a ValueError (found by the interchange fuzz test)."""
    import gzip

    from csgs_codec.errors import InputError
    from csgs_codec.interchange.spz import parse_spz, spz_bytes
    from tests.codec.helpers import random_scene

    body = gzip.decompress(spz_bytes(random_scene(50, sh_degree=0), version=3))
    with pytest.raises(InputError, match="bytes follow the attribute blocks"):
        parse_spz(gzip.compress(body + bytes(600), mtime=0), "junk.spz")
    scene, _ = parse_spz(gzip.compress(body, mtime=0), "plain.spz")
    assert len(scene) == 50 and scene.sh_rest.shape[1] == 0
