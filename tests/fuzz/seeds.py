"""Seed .csgs files for the decoder fuzzer, made by the encoder at fuzz time.

Seeds: a 300-Gaussian subset of samples/donut.ply (SH 0), the same with four Gaussians moved
1e4 to 1e6 units away (so the file has far outliers, chunk OUTL), a 300-Gaussian subset of the
SH-3 fixture ../shared/data/fixtures/sh3_iter7000.ply, and a 200-Gaussian random scene with
four semantic channels and labels, the same with labels that follow the positions (SEMR
runs) or its instances (SEMR map), each at qualities 2 and 8; multi-tile files (TIDX,
FORMAT §12.22) of the semantic scene in 4 tiles and of the outlier scene in 4 tiles (far
points in a tile of their own grid), at quality 5; a file with levels of detail (TIDX
version 2, FORMAT §12.22): a 3,000-Gaussian random scene with semantics and labels in 3
levels, 16 leaves of at most 200 Gaussians, 2 level-1 tiles and a root (19 tiles); plus every
.csgs under
spec/vectors/scenes and (anchor scenes, where present) spec/vectors/anchors. The large donut
vectors (45,624 Gaussians) get a small weight so they
are fuzzed without dominating the run time.

Anchor seeds (:func:`build_anchor_seeds`, for the JavaScript receiver's differential
campaign): the anchor vectors and two encodes of small anchor scenes, one with view origins
(vorg) and an appearance table, one at the default F = 50, K = 10 with five CARM groups.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgs_codec.codec.encoder import Encoder
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.scene.gaussian_scene import GaussianScene
from tests.codec.helpers import random_scene
from tests.conformance import VECTORS_DIR, current
from tests.conftest import FIXTURES, SAMPLE
from tests.fuzz.container_edit import RawChunk, split_chunks

QUALITIES = (2, 8)
SUBSET = 300
#: Seeds above this many bytes are drawn this much less often than the small ones.
LARGE_BYTES = 100_000
LARGE_WEIGHT = 0.02
#: Seed scenes also encoded in spatial tiles of this many Gaussians (quality 5).
TILED = {"semantic200": 50, "outliers300": 75, "instances200": 50}
#: Seed scenes also encoded with levels of detail: (Gaussians, levels, tile size, quality).
LEVELS = {"levels3000": (3000, 3, 200, 5)}
#: Vector folders whose .csgs files are seeds (a missing folder adds none).
SEED_VECTOR_FAMILIES = ("scenes", "anchors")


@dataclass(frozen=True)
class Seed:
    """One seed file: its name, bytes, chunks (file order) and drawing weight."""

    name: str
    data: bytes
    chunks: tuple[RawChunk, ...]
    weight: float


def _subset(scene: GaussianScene, count: int, seed: int) -> GaussianScene:
    rng = np.random.default_rng(seed)
    keep = np.sort(rng.choice(len(scene), min(count, len(scene)), replace=False))
    return scene.subset(keep)


def seed_scenes() -> dict[str, GaussianScene]:
    """The scenes the encoder makes seeds from (the SH-3 fixture only where present)."""
    donut = _subset(read_ply(SAMPLE), SUBSET, 1)
    far = donut.subset(np.arange(len(donut)))
    far.positions[:4] = np.array([[1e4, 0, 0], [-3e4, 5, 1], [0, 2e5, 0], [7, 7, -1e6]],
                                 np.float32)
    semantic = random_scene(200, sh_degree=1, seed=2, semantic=4, labels=True)
    # Every Gaussian its label's prototype, as `csgs segment` writes: coded as SEMC.
    instances = semantic.subset(np.arange(len(semantic)))
    prototypes = np.random.default_rng(5).normal(size=(int(instances.labels.max()) + 1, 4))
    instances.semantic = prototypes[instances.labels].astype(np.float32)
    instances.labels = None
    # Labels that follow the positions (runs in Morton order: SEMR source 0), and labels
    # that follow the instances (a map of SEMC's ids: SEMR source 1), FORMAT §12.25.
    runs = semantic.subset(np.arange(len(semantic)))
    runs.semantic = runs.semantic_names = None
    octant = (runs.positions > 0) @ np.array([1, 2, 4])
    runs.labels = (octant + 10).astype(np.int32)
    mapped = instances.subset(np.arange(len(instances)))
    mapped.labels = (semantic.labels % 3 - 1).astype(np.int32)
    scenes = {"donut300": donut, "outliers300": far, "semantic200": semantic,
              "instances200": instances, "labelruns200": runs, "labelmap200": mapped}
    sh3 = FIXTURES / "sh3_iter7000.ply"
    if sh3.exists():
        scenes["sh3_300"] = _subset(read_ply(sh3), SUBSET, 3)
    return scenes


def level_seed_scene(count: int) -> GaussianScene:
    """The scene of the levels seeds: ``count`` random Gaussians (SH 1) with four semantic
    channels and labels, so the coarse levels merge colours, features and labels."""
    return random_scene(count, sh_degree=1, seed=9, semantic=4, labels=True)


def _seed(name: str, data: bytes) -> Seed:
    weight = LARGE_WEIGHT if len(data) > LARGE_BYTES else 1.0
    return Seed(name, data, tuple(split_chunks(data)), weight)


def build_seeds(vectors_dir: Path = VECTORS_DIR) -> list[Seed]:
    """Every seed: the encoded ones, then the vectors of :data:`SEED_VECTOR_FAMILIES`."""
    seeds = []
    for name, scene in seed_scenes().items():
        for quality in QUALITIES:
            seeds.append(_seed(f"{name}_q{quality}", Encoder(quality=quality).encode(scene)))
        if name in TILED:
            data = Encoder(quality=5, tile_size=TILED[name]).encode(scene)
            seeds.append(_seed(f"{name}_tiled", data))
    for name, (count, levels, tile_size, quality) in LEVELS.items():
        data = Encoder(quality=quality, levels=levels, tile_size=tile_size).encode(
            level_seed_scene(count))
        seeds.append(_seed(f"{name}_l{levels}", data))
    for family in SEED_VECTOR_FAMILIES:
        for path in current(sorted((vectors_dir / family).glob("*.csgs"))):
            seeds.append(_seed(f"vector:{path.stem}", path.read_bytes()))
    return seeds


def build_anchor_seeds(vectors_dir: Path = VECTORS_DIR) -> list[Seed]:
    """Anchor-scene seeds: the anchor vectors, then encodes (fast fit) of
    ``scene_with_origins_and_appearance`` (vorg, appearance) and of a 100-anchor default
    scene."""
    from csgs_codec.codec.anchor_encoder import AnchorEncoder
    from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
    from tests.anchors.helpers import FAST_FIT, scene_with_origins_and_appearance

    seeds = [_seed(f"vector:{path.stem}", path.read_bytes())
             for path in current(sorted((vectors_dir / "anchors").glob("*.csgs")))]
    seeds.append(_seed("anchors_vorg_q6", AnchorEncoder(6, fit=FAST_FIT).encode(
        scene_with_origins_and_appearance())))
    seeds.append(_seed("anchors_default_q4", AnchorEncoder(4, fit=FAST_FIT).encode(
        synthetic_anchor_scene(2, 50, seed=6))))
    return seeds
