"""Far floaters (issue #20.1): the preset's position bound holds for every Gaussian.

A scene is a subset of samples/donut.ply (every 8th Gaussian, 5,703 of them) in which a share
of the Gaussians is moved to about ``distance`` units in random directions. The bound the
preset documents (csgs_codec/decisions/presets.py, FORMAT §12.5 and §12.20) is asserted:

- on every Gaussian that reaches a pixel — here: opacity sigmoid >= 1/255 and within the
  dense core's viewing distance, taken as 100 times the core's extent from its centre (the
  untouched donut Gaussians): at most half a cell of the grid the *clean* subset gets at the
  preset's bits (floaters must not coarsen it), plus float32 rounding;
- on every far point (visible or not): at most 2^-bits x its Chebyshev distance from the
  core's centre per axis, plus one float32 ulp.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.attributes.far_positions import quantize_far
from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.chunks.far_points import relative_far_payload
from csgs_codec.chunks.scene_header import SceneHeader
from csgs_codec.decisions.presets import preset
from csgs_codec.errors import CsgsWarning, FormatError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.interchange.ply_io import read_ply
from tests.conftest import SAMPLE

QUALITY = 5


@pytest.fixture(scope="module")
def donut_subset():
    scene = read_ply(SAMPLE)
    return scene.subset(np.arange(0, len(scene), 8))


def with_floaters(scene, share: float, distance: float, seed: int = 0):
    """(scene with ``share`` of its Gaussians moved to 0.5..1 x ``distance`` units from the
    origin, opacity -8 for most and +2 for every fifth, and the mask of the moved ones)."""
    rng = np.random.default_rng(seed)
    out = scene.subset(np.arange(len(scene)))
    k = max(1, int(round(share * len(scene))))
    idx = rng.choice(len(scene), k, replace=False)
    dirs = rng.normal(size=(k, 3))
    dirs /= np.abs(dirs).max(axis=1, keepdims=True)
    out.positions[idx] = (dirs * distance * rng.uniform(0.5, 1.0, (k, 1))).astype(np.float32)
    out.opacity[idx] = np.where(np.arange(k) % 5 == 0, 2.0, -8.0).astype(np.float32)
    moved = np.zeros(len(scene), dtype=bool)
    moved[idx] = True
    return out, moved


@pytest.mark.parametrize("distance", [1e4, 1e30])
@pytest.mark.parametrize("share", [0.005, 0.02, 0.05, 0.2])
def test_preset_bound_holds_on_every_visible_gaussian(donut_subset, share, distance):
    bits = preset(QUALITY).position_bits
    clean_grid = PositionGrid.fit(donut_subset.positions, bits)
    scene, moved = with_floaters(donut_subset, share, distance)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = Encoder(quality=QUALITY, hyperprior=False).encode_with_report(scene)
    messages = [str(w.message) for w in caught if issubclass(w.category, CsgsWarning)]
    assert any(m.startswith(f"{moved.sum()} Gaussians") and "coded apart" in m
               for m in messages), messages
    assert result.stream_bytes["OUTQ"] > 0 and "OUTL" not in result.stream_bytes

    decoded = Decoder().decode(result.data)
    assert np.array_equal(decoded.positions, result.reconstruction.positions)
    assert np.all(np.isfinite(decoded.positions))
    ref = scene.subset(result.order)
    moved = moved[result.order]
    err = np.abs(decoded.positions.astype(np.float64) - ref.positions.astype(np.float64))

    # Reaches a pixel: opaque enough and within 100 core extents of the core's centre.
    centre = np.asarray(PositionGrid.fit(scene.positions, bits).centre)
    extent = clean_grid.cell * (2**bits - 1)
    alpha = 1.0 / (1.0 + np.exp(-ref.opacity.astype(np.float64)))
    near = np.max(np.abs(ref.positions - centre), axis=1) <= 100 * extent
    visible = (alpha >= 1 / 255) & near
    assert visible.sum() >= 0.75 * len(ref) and not (visible & moved).any()
    assert err[visible].max() <= clean_grid.max_error

    r = np.max(np.abs(ref.positions[moved].astype(np.float64) - centre), axis=1, keepdims=True)
    ulp = np.spacing(np.abs(decoded.positions[moved])).astype(np.float64)
    assert np.all(err[moved] <= r * 2.0**-bits + ulp)


@pytest.mark.parametrize(("share", "distance"), [
    (0.005, 1e4), (0.2, 1e4), (0.45, 1e4), (0.45, 1e30),
    (0.02, 1.0), (0.2, 1.0),  # a floater shell 5-10x the donut's size, inside the grid
])
def test_floaters_do_not_change_the_cell(donut_subset, share, distance):
    clean = PositionGrid.fit(donut_subset.positions, 12)
    scene, moved = with_floaters(donut_subset, share, distance, seed=3)
    grid = PositionGrid.fit(scene.positions, 12)
    assert grid.cell == pytest.approx(clean.cell, rel=0.03)
    cells, inside = grid.quantize(scene.positions)
    assert inside[~moved].all()
    assert inside[moved].all() == (distance < 100)


def test_a_handful_of_far_points_stays_exact(donut_subset):
    scene, moved = with_floaters(donut_subset, 10 / len(donut_subset), 1e6)
    with pytest.warns(CsgsWarning, match="10 Gaussians .* 10 exactly"):
        result = Encoder(quality=QUALITY, hyperprior=False).encode_with_report(scene)
    assert "OUTQ" not in result.stream_bytes and "OUTL" in result.stream_bytes
    decoded = Decoder().decode(result.data)
    np.testing.assert_array_equal(decoded.positions[-10:],
                                  scene.positions[result.order[-10:]])


def test_far_points_at_the_float32_limit_fall_back_to_exact(donut_subset):
    scene, moved = with_floaters(donut_subset, 0.02, 1e4)
    last = np.flatnonzero(moved)[-1]
    scene.positions[last] = (3.4e38, -3.4e38, 1.0)
    with pytest.warns(CsgsWarning, match="1 exactly"):
        result = Encoder(quality=QUALITY, hyperprior=False).encode_with_report(scene)
    decoded = Decoder().decode(result.data)
    assert decoded.positions[-1].tolist() == scene.positions[last].tolist()


def test_relative_quantizer_values():
    # b = 4. 40 = 0.625 * 2^6: e = 6, step 2^(6 - 4) = 4, m = rint(v / 4). 1000 = 0.977 * 2^10
    # and 15.9 = 0.994 * 2^4 round up to 2^b at their frexp exponent: one exponent more.
    exps, mants, ok = quantize_far(np.array([[1000.0, -3.0, 500.0], [15.9, 0, 0],
                                             [40.0, -20.0, 5.0]]), (0.0, 0.0, 0.0), 4)
    assert ok.all()
    assert exps.tolist() == [11, 5, 6]
    assert mants.tolist() == [[8, 0, 4], [8, 0, 0], [10, -5, 1]]


def _far_file(payload: bytes, far_count: int = 2) -> bytes:
    header = SceneHeader(count=far_count, sh_degree_stored=0, sh_degree_coded=0, quality=5,
                         grid_origin=(0.0, 0.0, 0.0), grid_cell=1.0, grid_bits=1,
                         far_count=far_count)
    good = Encoder(quality=5, hyperprior=False).encode(_two_gaussians())
    container = read_layers(good, layers={"color"})
    chunks = [Chunk("SCNE", "base", header.to_bytes()),
              Chunk("GEOM", "base", _empty_geometry()), Chunk("OUTQ", "base", payload)]
    chunks += [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
               for e in container.toc if e.layer.label == "color"]
    return write_container(chunks)


def _two_gaussians():
    from tests.codec.helpers import random_scene

    return random_scene(2, sh_degree=0)


def _empty_geometry() -> bytes:
    from csgs_codec.entropy.geometry import encode_positions

    return encode_positions(np.zeros((0, 3), np.int64), 1)


def test_a_valid_hand_made_outq_decodes_exactly():
    payload = relative_far_payload((1.0, 2.0, 3.0), 4, np.array([10, -2]),
                          np.array([[15, -16, 0], [1, 2, -3]]))
    positions = Decoder().decode(_far_file(payload)).positions
    expected = [[1 + 15 * 2.0**6, 2 - 16 * 2.0**6, 3], [1 + 2.0**-6, 2 + 2 * 2.0**-6,
                                                          3 - 3 * 2.0**-6]]
    np.testing.assert_array_equal(positions, np.array(expected, np.float32))


@pytest.mark.parametrize(("damage", "message"), [
    (lambda p: b"\x00" + p[1:], "at least one point"),
    (lambda p: b"\x03" + p[1:], "exceeds the limit"),
    (lambda p: p[:1] + b"\x00" + p[2:], "mantissa_bits"),
    (lambda p: p[:1] + b"\x1f" + p[2:], "mantissa_bits"),
    (lambda p: p[:2] + np.float64(np.inf).tobytes() + p[10:], "centre"),
    (lambda p: p[:-1], "truncated"),
    (lambda p: p + b"\x00", "unexpected bytes"),
    (lambda p: p[:-1] + bytes([p[-1] | 0x80]), "padding"),
    (lambda p: p[:2] + np.float64(3.4e38).tobytes() + p[10:26] + b"\xff" + p[27:],
     "float32 range"),
])
def test_damaged_outq_is_refused_naming_chunk_and_offset(damage, message):
    payload = relative_far_payload((0.0, 0.0, 0.0), 4, np.array([10, -2]),
                          np.array([[15, -16, 0], [1, 2, -3]]))
    assert len(payload) == 1 + 1 + 24 + 2 + 4  # 6 fields x 5 bits = 30 bits -> 4 bytes
    with pytest.raises(FormatError, match=message) as info:
        Decoder().decode(_far_file(damage(payload)))
    assert info.value.chunk == "OUTQ" and info.value.offset is not None


def test_outq_without_far_points_is_refused(donut_subset):
    data = Encoder(quality=5, hyperprior=False).encode(donut_subset.subset(np.arange(50)))
    container = read_layers(data, layers={"color"})
    chunks = [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
              for e in container.toc]
    chunks.insert(2, Chunk("OUTQ", "base", relative_far_payload((0, 0, 0), 4, np.array([1]),
                                                       np.zeros((1, 3), np.int64))))
    with pytest.raises(FormatError, match="unexpected OUTQ") as info:
        Decoder().decode(write_container(chunks))
    assert info.value.chunk == "OUTQ"


def test_core_of_a_scene_mostly_on_one_point():
    # 60% of the points on the median, 30% in a 2-unit cube, 10% about 1e4 away: the core is
    # the cube (its 1-99 percentile box, about 1.9 wide), not the duplicates nor the floaters.
    rng = np.random.default_rng(0)
    p = np.concatenate([np.zeros((600, 3)), rng.uniform(-1, 1, (300, 3)),
                        rng.normal(size=(100, 3)) * 1e4])
    grid = PositionGrid.fit(p, 12)
    assert 1.8 <= grid.cell * 4095 <= 2.0
    assert grid.quantize(p)[1][:900].all()
