"""antimatter15 ``.splat``: 32-byte records, no header, no SH.

Record: position float32 x3, linear scale float32 x3, color RGBA uint8 (RGB = 255 (0.5 +
SH_C0 f_dc), A = 255 sigmoid(opacity)), rotation uint8 x4 (w, x, y, z of the unit quaternion
as 128 q + 128), all little-endian. The format has no magic: files are recognised by their
``.splat`` extension and a size that is a multiple of 32.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.interchange.binary import (
    Bytes,
    alpha_to_logit,
    color_to_dc,
    dc_to_color,
    linear_to_log_scale,
    logit_to_alpha,
    normalized_wxyz,
    to_uint8,
)
from csgs_codec.interchange.source import SceneSource
from csgs_codec.scene.gaussian_scene import GaussianScene

RECORD = np.dtype([("position", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4),
                   ("rotation", "u1", 4)])


def parse_splat(data: bytes, source: str = "<bytes>") -> tuple[GaussianScene, SceneSource]:
    """Decode ``.splat`` bytes.

    Returns:
        (scene with N = len(data) / 32 Gaussians and SH degree 0, its SceneSource).

    Raises:
        InputError: empty, or a size that is not a multiple of 32 bytes (offset of the
            partial record).
    """
    raw = Bytes(data, source)
    if not data or len(data) % RECORD.itemsize:
        raise raw.error(f"a .splat file is a whole number of 32-byte records; this one has "
                        f"{len(data)} bytes", offset=len(data) - len(data) % RECORD.itemsize)
    rows = np.frombuffer(data, RECORD)
    n = len(rows)
    # The writer stores 128 q + 128 and the reference viewer reads (b - 128) / 128.
    rotation = (rows["rotation"].astype(np.float64) - 128.0) / 128.0
    scene = GaussianScene(
        positions=np.array(rows["position"], np.float32),
        sh_dc=color_to_dc(rows["rgba"][:, :3] / 255.0),
        sh_rest=np.zeros((n, 0, 3), np.float32),
        opacity=alpha_to_logit(rows["rgba"][:, 3] / 255.0),
        scales=linear_to_log_scale(rows["scale"]),
        rotations=normalized_wxyz(rotation).astype(np.float32),
    )
    return scene, SceneSource("splat", "antimatter15 .splat", lossy=True)


def splat_bytes(scene: GaussianScene) -> bytes:
    """The scene as ``.splat`` records, in scene order (SH bands beyond DC are dropped).

    Color and alpha are rounded to the nearest of 256 levels (the reference converter
    truncates), the unit quaternion to 128 q + 128 rounded and clamped to 0..255.
    """
    scene.validate()
    rows = np.zeros(len(scene), RECORD)
    rows["position"] = scene.positions
    rows["scale"] = np.exp(scene.scales.astype(np.float64))
    rows["rgba"][:, :3] = to_uint8(255.0 * dc_to_color(scene.sh_dc))
    rows["rgba"][:, 3] = to_uint8(255.0 * logit_to_alpha(scene.opacity))
    rows["rotation"] = to_uint8(128.0 * normalized_wxyz(scene.rotations) + 128.0)
    return rows.tobytes()
