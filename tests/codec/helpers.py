"""Small scenes for codec tests."""

from __future__ import annotations

import numpy as np

from csgs_codec.decisions.color_prior_choice import PriorFitPolicy
from csgs_codec.model.color_hyperprior import ColorFitSettings
from csgs_codec.scene import GaussianScene

#: A color hyperprior fit of 100 steps (the default runs 1,500): for tests that need a file
#: with the prior but not its full saving. It changes bytes only, never the decoded scene.
SHORT_PRIOR_FIT = PriorFitPolicy(ColorFitSettings(steps=100, batch=512))


def random_scene(n: int, *, sh_degree: int = 1, seed: int = 0, semantic: int = 0,
                 labels: bool = False, spread: float = 1.0) -> GaussianScene:
    """The tests' one random scene: anisotropic Gaussians uniformly in a cube of side
    ``2 * spread`` around the origin, attributes in typical trained ranges (log-scales
    around log(0.018 * spread)); ``semantic`` feature channels and ``labels`` on request."""
    rng = np.random.default_rng(seed)
    bands = {0: 0, 1: 3, 2: 8, 3: 15}[sh_degree]
    f = lambda *shape, s=1.0: (rng.normal(size=shape) * s).astype(np.float32)  # noqa: E731
    scene = GaussianScene(
        positions=(rng.uniform(-1, 1, size=(n, 3)) * spread).astype(np.float32),
        sh_dc=f(n, 3), sh_rest=f(n, bands, 3, s=0.1), opacity=f(n, s=3.0),
        scales=(f(n, 3, s=0.5) - 4 + np.log(spread)).astype(np.float32), rotations=f(n, 4))
    if semantic:
        scene.semantic = f(n, semantic)
        scene.semantic_names = tuple(f"ins_feat_{i}" for i in range(semantic))
    if labels:
        scene.labels = rng.integers(0, 7, size=n).astype(np.int32)
    return scene


def color_chunks(data: bytes) -> list:
    """The chunks of ``data``'s base and color layers, as :class:`Chunk` objects."""
    from csgs_codec.format import Chunk, read_layers

    container = read_layers(data, layers={"color"})
    return [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
            for e in container.toc]


def rotn_channel_reader(payload: bytes):
    """(reader just past the first coded channel's step index, its
    :class:`~csgs_codec.attributes.channel_coders.Coding`, the step index's offset) of a ROTN
    payload whose coded channels have scored steps."""
    from csgs_codec.chunks.color_streams import rotation_class_table
    from csgs_codec.format.primitives import ByteReader

    r = ByteReader(payload)
    coding = rotation_class_table(r)
    return r, coding, r.offset - 1


def steps_of(stage: str, sink: list, value=lambda done, total: (done, total)):
    """An ``Encoder(progress=...)`` callback that appends ``value(done, total)`` to ``sink``
    for each counted step of ``stage``."""
    def progress(name: str, done: int, total: int) -> None:
        if name == stage and total:
            sink.append(value(done, total))
    return progress
