"""File-level helpers: PLY -> .csgs and .csgs -> PLY in one call each."""

from __future__ import annotations

import os

from csgs_codec.atomic_write import check_output, write_atomically
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder, EncodeResult
from csgs_codec.scene.ply_io import read_ply, write_ply


def encode_file(ply_path: str | os.PathLike, csgs_path: str | os.PathLike, *,
                quality: int = 5, semantic: str = "auto", prune_opacity: float | None = None,
                sanitize: bool = False) -> EncodeResult:
    """Encode the 3DGS PLY at ``ply_path`` into ``csgs_path`` (written atomically; an
    output that is the input, not a regular file or not writable is refused up front)."""
    check_output(csgs_path, [ply_path])
    scene = read_ply(ply_path, sanitize=sanitize)
    result = Encoder(quality=quality, semantic=semantic,
                     prune_opacity=prune_opacity).encode_with_report(scene)
    write_atomically(csgs_path, result.data, [ply_path])
    return result


def decode_file(csgs_path: str | os.PathLike, ply_path: str | os.PathLike, *,
                layers: str = "color") -> int:
    """Decode ``csgs_path`` (only ``layers``) into the PLY ``ply_path``; returns N."""
    check_output(ply_path, [csgs_path])
    scene = Decoder().decode(csgs_path, layers=layers)
    write_ply(scene, ply_path, [csgs_path])
    return len(scene)
