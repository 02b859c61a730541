"""GaussianScene: validation and the derived facts a codec decides on."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.scene import GaussianScene


def tiny_scene(n: int = 4, bands: int = 3) -> GaussianScene:
    rng = np.random.default_rng(0)
    f = lambda *s: rng.normal(size=s).astype(np.float32)  # noqa: E731
    return GaussianScene(f(n, 3), f(n, 3), f(n, bands, 3), f(n), f(n, 3), f(n, 4))


def test_valid_scene_passes_validation():
    assert tiny_scene().validate() is None  # raises InputError when anything is wrong


def test_validate_names_property_and_first_bad_index():
    scene = tiny_scene()
    scene.scales[2, 1] = np.inf
    scene.scales[3, 0] = np.nan
    with pytest.raises(InputError) as info:
        scene.validate("s.ply")
    assert info.value.property == "scale_1" and info.value.index == 2
    assert "s.ply" in str(info.value) and "index 2" in str(info.value)


def test_validate_rejects_wrong_dtype_and_shape():
    scene = tiny_scene()
    scene.opacity = scene.opacity.astype(np.float64)
    with pytest.raises(InputError, match="float32"):
        scene.validate()
    scene = tiny_scene()
    scene.rotations = scene.rotations[:, :3]
    with pytest.raises(InputError, match="rotations"):
        scene.validate()


def test_sh_degree_in_use_is_highest_nonzero_band():
    scene = tiny_scene(bands=15)
    scene.sh_rest[:, 3:, :] = 0  # bands 2 and 3 zero
    assert scene.sh_degree_stored == 3
    assert scene.sh_degree_in_use() == 1
    assert scene.zero_sh_bands() == [2, 3]
    scene.sh_rest[1, 14, 2] = 1e-30
    assert scene.sh_degree_in_use() == 3


def test_constant_channels_found_per_attribute():
    scene = tiny_scene()
    scene.rotations[:, 0] = 1.0
    scene.opacity[:] = -2.0
    const = scene.constant_channels()
    assert const["rotations"] == [0]
    assert const["opacity"] == [0]
    assert "positions" not in const


def test_robust_extent_ignores_a_far_floater():
    rng = np.random.default_rng(1)
    scene = tiny_scene(n=1000)
    scene.positions = rng.uniform(-1, 1, size=(1000, 3)).astype(np.float32)
    scene.positions[0] = [1e6, 0, 0]
    centre, extent = scene.robust_center_and_extent()
    assert extent < 2.1
    assert np.all(np.abs(centre) < 0.1)
    lo, hi = scene.bounding_box()
    assert hi[0] == pytest.approx(1e6)


def test_subset_and_nonfinite_rows():
    scene = tiny_scene(n=5)
    scene.sh_rest[3, 0, 0] = np.nan
    bad = scene.nonfinite_rows()
    assert bad.tolist() == [False, False, False, True, False]
    assert len(scene.subset(~bad)) == 4
