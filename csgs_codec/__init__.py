"""csgs: a codec for 3D Gaussian Splatting scenes with semantics (CSGaussian, WACV 2026).

Public API (imported on first use, so ``import csgs_codec`` stays light)::

    from csgs_codec import Encoder, Decoder, read_scene, write_scene
    data = Encoder(quality=5).encode(read_scene("scene.spz"))    # -> bytes (any scene format)
    scene = Decoder().decode(data, layers="color")               # -> GaussianScene
    write_scene(scene, "scene.glb")                              # format by extension

The decode path (format, entropy, codec.decoder) imports numpy and constriction only;
torch is imported by the model and training code alone.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from csgs_codec.errors import (
    CompoundedLossWarning,
    CsgsError,
    CsgsWarning,
    DataLossWarning,
    FallbackWarning,
    FormatError,
    InputError,
    ModelError,
    UnsupportedError,
)

if TYPE_CHECKING:  # what the lazy names below resolve to, for IDEs and type checkers
    from csgs_codec.bake.anchor_bake import bake_anchor_scene
    from csgs_codec.codec.anchor_decoder import AnchorDecoder
    from csgs_codec.codec.anchor_encoder import AnchorEncoder
    from csgs_codec.codec.decoder import Decoder
    from csgs_codec.codec.encoder import Encoder, EncodeReport
    from csgs_codec.codec.files import decode_file, encode_file, read_scene, read_scene_with_report
    from csgs_codec.format.layout import Layer
    from csgs_codec.interchange import write_scene
    from csgs_codec.interchange.ply_io import read_ply, write_ply
    from csgs_codec.interchange.scaffold_io import read_scaffold, write_scaffold
    from csgs_codec.scene.anchor_scene import AnchorScene
    from csgs_codec.scene.gaussian_scene import GaussianScene
    from csgs_codec.semantic.selection import select_at_click

__version__ = "0.1.0"

_LAZY = {
    "Encoder": "csgs_codec.codec.encoder",
    "EncoderConfig": "csgs_codec.codec.encoder_config",
    "EncodeReport": "csgs_codec.codec.encoder",
    "Decoder": "csgs_codec.codec.decoder",
    "decode": "csgs_codec.codec.decode_any",
    "encode_file": "csgs_codec.codec.files",
    "decode_file": "csgs_codec.codec.files",
    "GaussianScene": "csgs_codec.scene.gaussian_scene",
    "read_ply": "csgs_codec.interchange.ply_io",
    "write_ply": "csgs_codec.interchange.ply_io",
    "AnchorScene": "csgs_codec.scene.anchor_scene",
    "AnchorEncoder": "csgs_codec.codec.anchor_encoder",
    "AnchorDecoder": "csgs_codec.codec.anchor_decoder",
    "bake_anchor_scene": "csgs_codec.bake.anchor_bake",
    "read_scaffold": "csgs_codec.interchange.scaffold_io",
    "write_scaffold": "csgs_codec.interchange.scaffold_io",
    "select_at_click": "csgs_codec.semantic.selection",
    "read_scene": "csgs_codec.codec.files",
    "read_scene_with_report": "csgs_codec.codec.files",
    "write_scene": "csgs_codec.interchange",
    "Layer": "csgs_codec.format.layout",
}
__all__ = [
    "__version__",
    "Encoder", "EncoderConfig", "EncodeReport", "Decoder", "decode", "Layer", "encode_file",
    "decode_file",
    "GaussianScene", "read_ply", "write_ply",
    "AnchorScene", "AnchorEncoder", "AnchorDecoder", "read_scaffold", "write_scaffold",
    "bake_anchor_scene",
    "select_at_click", "read_scene", "read_scene_with_report", "write_scene",
    "CsgsError", "InputError", "FormatError", "UnsupportedError", "ModelError",
    "CsgsWarning", "DataLossWarning", "CompoundedLossWarning", "FallbackWarning",
]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'csgs_codec' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public names, lazy ones included (module ``__getattr__`` hides them otherwise)."""
    return sorted(__all__)
