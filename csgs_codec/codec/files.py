"""File-level helpers: scene file -> .csgs and .csgs -> scene file in one call each."""

from __future__ import annotations

import os

from csgs_codec.atomic_write import check_output, write_atomically
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder, EncodeReport
from csgs_codec.interchange import read_interchange, warn_if_lossy, write_scene


def encode_file(ply_path: str | os.PathLike, csgs_path: str | os.PathLike, *,
                quality: int = 5, semantic: str = "auto", prune_opacity: float | None = None,
                sanitize: bool = False) -> EncodeReport:
    """Encode the scene at ``ply_path`` (a 3DGS PLY or any format
    :func:`csgs_codec.interchange.read_interchange` reads; a lossy one warns) into ``csgs_path``
    (written atomically; an output that is the input, not a regular file or not writable is
    refused up front)."""
    check_output(csgs_path, [ply_path])
    scene, source = read_interchange(ply_path, sanitize=sanitize)
    warn_if_lossy(source, ply_path)
    result = Encoder(quality=quality, semantic=semantic,
                     prune_opacity=prune_opacity).encode_with_report(scene)
    write_atomically(csgs_path, result.data, [ply_path])
    return result


def decode_file(csgs_path: str | os.PathLike, ply_path: str | os.PathLike, *,
                layers: str = "color") -> int:
    """Decode ``csgs_path`` (only ``layers``) into ``ply_path``, written in the format its
    suffix names (.ply, .splat, .spz, .glb); returns N."""
    from csgs_codec.interchange.writers import writer_for

    check_output(ply_path, [csgs_path])
    writer_for(ply_path)
    scene = Decoder().decode(csgs_path, layers=layers)
    write_scene(scene, ply_path, [csgs_path])
    return len(scene)
