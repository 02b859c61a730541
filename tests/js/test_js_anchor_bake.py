"""The browser's bake (csgs_codec/js/anchor_bake.mjs) against the reference decoder's
(csgs_codec.bake.anchor_bake): the same Gaussians kept, their values to float tolerance (the
reference runs the heads in float32, JavaScript in float64). Skipped without ``node``."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from benchmarks._js_receiver import REPO, node_executable
from csgs_codec.bake.anchor_bake import BakeSettings, bake_anchor_scene, bake_origins
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.anchors.helpers import FAST_FIT
from tests.js.array_bundle import pack, unpack

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

RUNNER = REPO / "tests" / "js" / "anchor_bake_runner.mjs"


def js_bake(scene: AnchorScene, options: dict | None = None,
            origins: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The JavaScript bake of ``scene`` (arrays by name, plus ``ms``)."""
    arrays = {"positions": scene.positions, "features": scene.features,
              "offsets": scene.offsets, "scaling": scene.scaling,
              "offset_mask": scene.offset_mask.astype(np.uint8)}
    for name, head in scene.mlps.heads().items():
        arrays.update({f"{name}.{key}": value for key, value in head.arrays().items()})
    if scene.mlps.appearance is not None:
        arrays["appearance"] = scene.mlps.appearance
    if scene.view_origins is not None:
        arrays["view_origins"] = scene.view_origins
    if origins is not None:
        arrays["origins"] = np.asarray(origins, np.float64)
    if scene.semantic is not None:
        arrays["semantic"] = scene.semantic
    if scene.labels is not None:
        arrays["labels"] = scene.labels
    meta = {"feat_dim": scene.feat_dim, "n_offsets": scene.n_offsets,
            "semantic_names": list(scene.semantic_names or ()), "options": options or {}}
    done = subprocess.run([node_executable(), str(RUNNER)], input=pack(arrays, meta),
                          capture_output=True, timeout=600)
    assert done.returncode == 0, done.stderr.decode()[-3000:]
    out, meta = unpack(done.stdout)
    return {**out, "ms": meta["ms"]}


def assert_same_bake(scene: AnchorScene, ours: dict, reference, *, sh_atol: float = 1e-4):
    """Kept slots identical (positions match to float32); values to float tolerance (the
    observed differences are 100x below these bounds)."""
    assert len(ours["positions"]) == len(reference) > 0
    np.testing.assert_allclose(ours["positions"], reference.positions, rtol=0, atol=1e-6)
    np.testing.assert_allclose(ours["opacity"], reference.opacity, atol=1e-4, rtol=1e-4)
    np.testing.assert_allclose(ours["scales"], reference.scales, atol=2e-5)
    dots = np.abs(np.sum(ours["rotations"] * reference.rotations, axis=1))
    assert dots.min() > 1 - 1e-5
    np.testing.assert_allclose(ours["sh_dc"], reference.sh_dc, atol=sh_atol)
    np.testing.assert_allclose(ours["sh_rest"], reference.sh_rest, atol=sh_atol)
    if reference.labels is not None:
        np.testing.assert_array_equal(ours["labels"], reference.labels)
    if reference.semantic is not None:
        np.testing.assert_array_equal(ours["semantic"], reference.semantic)


@pytest.fixture(scope="module")
def decoded() -> AnchorScene:
    """What a receiver decodes from a default-quality encode of a labelled synthetic scene
    (semantic layer included)."""
    scene = synthetic_anchor_scene(n_objects=3, anchors_per_object=40, seed=11)
    data = AnchorEncoder(fit=FAST_FIT).encode(scene)
    return AnchorDecoder().decode(data, layers="color,semantic")


def test_the_default_origins_are_the_reference_s(decoded):
    ours = js_bake(decoded, {"shDegree": 0})
    reference = bake_anchor_scene(decoded, settings=BakeSettings(sh_degree=0))
    assert decoded.view_origins is None  # so both use their default spheres
    assert len(bake_origins(decoded)) == 96
    assert_same_bake(decoded, ours, reference)


@pytest.mark.parametrize("degree", [1, 3])
def test_stored_origins_bake_as_the_reference_at_every_degree(decoded, degree):
    rng = np.random.default_rng(degree)
    directions = rng.normal(size=(24, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    centre = decoded.positions.mean(axis=0)
    stored = AnchorScene(**{**decoded.__dict__,
                            "view_origins": (centre + 3.0 * directions).astype(np.float32)})
    ours = js_bake(stored, {"shDegree": degree})
    reference = bake_anchor_scene(stored, settings=BakeSettings(sh_degree=degree))
    assert_same_bake(stored, ours, reference)


def test_given_origins_and_settings_are_honoured(decoded):
    origins = bake_origins(decoded)[::5]
    settings = BakeSettings(sh_degree=2, keep_fraction=0.25, ridge=0.0)
    ours = js_bake(decoded, {"shDegree": 2, "keepFraction": 0.25, "ridge": 0.0}, origins)
    reference = bake_anchor_scene(decoded, origins=origins, settings=settings)
    assert_same_bake(decoded, ours, reference, sh_atol=1e-3)
