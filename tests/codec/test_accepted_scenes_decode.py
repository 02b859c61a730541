"""Property: every scene the encoder accepts decodes with the default decoder, and the decode
equals the encoder's reconstruction bit for bit (issue #20: "whatever the encoder writes, the
default decoder reads").

Scenes are small (no hyperprior fit) but span what breaks limits: all-identical Gaussians in
numbers far above the file's bytes, SH degrees 0-3, extreme and special float values,
semantic channels with long or non-ASCII names, labels, duplicate positions and far
floaters. A scene the encoder refuses must be refused with an InputError, never another error.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgs_codec import Decoder, Encoder
from csgs_codec.errors import InputError
from csgs_codec.scene import GaussianScene

SPECIAL = st.sampled_from([0.0, -0.0, 1e-40, -1e-30, 1.0, 65504.0, -1e6, 87.9, -88.0, 88.5,
                           1e15, 2.0**52, 3e38])
BANDS = {0: 0, 1: 3, 2: 8, 3: 15}


@st.composite
def scenes(draw) -> GaussianScene:
    """A small scene, optionally of identical Gaussians, with a few special values."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    degree = draw(st.integers(0, 3))
    identical = draw(st.booleans())
    n = draw(st.integers(20_000, 60_000)) if identical else draw(st.integers(0, 300))
    rows = 1 if identical else n
    f = lambda *shape, s=1.0, m=0.0: (rng.normal(m, s, size=shape)).astype(np.float32)  # noqa: E731
    extent = draw(st.sampled_from([1e-3, 1.0, 1e3]))
    scene = GaussianScene(positions=f(rows, 3, s=extent), sh_dc=f(rows, 3),
                          sh_rest=f(rows, BANDS[degree], 3, s=0.1), opacity=f(rows, s=3.0),
                          scales=f(rows, 3, s=1.0, m=-4.0), rotations=f(rows, 4))
    channels = draw(st.integers(0, 3))
    if channels:
        scene.semantic = f(rows, channels)
        name = draw(st.text(min_size=1, max_size=140))
        scene.semantic_names = tuple(f"{name}{i}" for i in range(channels))
    if draw(st.booleans()):
        scene.labels = rng.integers(-5, 5, size=rows).astype(np.int32)
    if identical:
        return scene.subset(np.zeros(n, np.int64))
    if n and draw(st.booleans()):  # duplicates and a far floater
        scene.positions[n // 2:] = scene.positions[: n - n // 2]
        scene.positions[0] = np.float32(draw(st.sampled_from([1e4, 1e7, -3e38])))
    for _ in range(draw(st.integers(0, 3)) if n else 0):
        attribute = draw(st.sampled_from(["sh_dc", "sh_rest", "opacity", "scales",
                                          "rotations", "semantic"]))
        values = getattr(scene, attribute)
        if values is None or not values.size:
            continue
        flat = values.reshape(-1)
        flat[draw(st.integers(0, flat.size - 1))] = np.float32(draw(SPECIAL))
    return scene


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scene=scenes(), quality=st.integers(1, 9))
def test_every_scene_the_encoder_accepts_decodes_to_its_reconstruction(scene, quality):
    try:
        result = Encoder(quality=quality, hyperprior=False).encode_with_report(scene)
    except InputError:
        return  # refused up front, by name: allowed
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert len(decoded) == len(scene)
    assert decoded.equals(result.reconstruction)
    assert len(result.data) * 64 >= len(scene)
