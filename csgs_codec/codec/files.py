"""Whole scene files in one call: read any scene file (``.csgs`` included), encode a scene
file to ``.csgs``, decode a ``.csgs`` to a scene file.

The one entry point above the codec (which decodes ``.csgs``) and
:mod:`csgs_codec.interchange` (which reads and writes every other format). The codec is
imported on first use, so reading a PLY imports no encoder.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from csgs_codec.atomic_write import check_output, write_atomically
from csgs_codec.errors import UnsupportedError
from csgs_codec.interchange import (
    SceneSource,
    detect_format,
    read_interchange,
    warn_if_lossy,
    write_scene,
)
from csgs_codec.scene.gaussian_scene import GaussianScene

if TYPE_CHECKING:
    from csgs_codec.codec.encode_report import EncodeReport
    from csgs_codec.codec.encoder_config import EncoderConfig


def read_scene_with_report(path: str | os.PathLike, *, sanitize: bool = False,
                           layers: str = "color") -> tuple[GaussianScene, SceneSource]:
    """Read the scene in ``path`` whatever its format, recognised by content (see
    :func:`csgs_codec.interchange.detect_format`): 3DGS PLY, PlayCanvas compressed PLY,
    ``.splat``, ``.ksplat``, SPZ, SOG (``.sog``, a folder or its ``meta.json``), GLB with
    ``KHR_gaussian_splatting``, or a ``.csgs`` bitstream.

    Args:
        path: the file or SOG folder.
        sanitize: PLY only: drop Gaussians with NaN/Inf values instead of failing.
        layers: ``.csgs`` only: the layers to decode, "color" (default, as
            :meth:`csgs_codec.Decoder.decode`) or "color,semantic" (or a
            :class:`~csgs_codec.format.layout.Layer`).

    Returns:
        (scene in INRIA PLY conventions, what the file was).

    Raises:
        InputError: unreadable or malformed input, naming the file and byte offset,
            property or chunk.
        FormatError: a malformed ``.csgs``.
        UnsupportedError: something well formed csgs does not read (an anchor-scene
            ``.csgs``, SPZ SH degree 4, a missing optional package).
    """
    path = Path(path)
    if detect_format(path) != "csgs":
        return read_interchange(path, sanitize=sanitize)
    from csgs_codec.codec.anchor_decoder import is_anchor_file
    from csgs_codec.codec.decoder import Decoder

    if is_anchor_file(path):
        raise UnsupportedError("an anchor-scene .csgs (Scaffold-GS anchors, not Gaussians): "
                               "AnchorDecoder reads it", file=path)
    scene = Decoder().decode(path, layers=layers)
    return scene, SceneSource("csgs", "csgs bitstream", lossy=True)


def read_scene(path: str | os.PathLike, *, sanitize: bool = False,
               layers: str = "color") -> GaussianScene:
    """The Gaussian scene in ``path``, any format csgs reads; with what the file was:
    :func:`read_scene_with_report`."""
    return read_scene_with_report(path, sanitize=sanitize, layers=layers)[0]


def encode_file(scene_path: str | os.PathLike, csgs_path: str | os.PathLike,
                config: EncoderConfig | int | None = None, *, sanitize: bool = False,
                progress=None, **fields) -> EncodeReport:
    """Encode the scene at ``scene_path`` (any format :func:`read_scene` reads but
    ``.csgs``; a lossy one warns) into ``csgs_path``, written atomically (an output that is
    the input, not a regular file or not writable is refused up front).

    ``config``, ``progress`` and ``fields`` are what :class:`~csgs_codec.Encoder` takes
    (``encode_file(src, dst, quality=7)``, or an :class:`EncoderConfig`); ``sanitize``
    drops a PLY's Gaussians with NaN/Inf values instead of failing.
    """
    from csgs_codec.codec.encoder import Encoder

    check_output(csgs_path, [scene_path])
    encoder = Encoder(config, progress=progress, **fields)  # bad settings: before reading
    scene, source = read_interchange(scene_path, sanitize=sanitize)
    warn_if_lossy(source, scene_path)
    result = encoder.encode_with_report(scene)
    write_atomically(csgs_path, result.data, [scene_path])
    return result


def decode_file(csgs_path: str | os.PathLike, scene_path: str | os.PathLike, *,
                layers: str = "color") -> int:
    """Decode ``csgs_path`` (only ``layers``) into ``scene_path``, written in the format its
    suffix names (.ply, .splat, .spz, .glb); returns N, the Gaussians written."""
    from csgs_codec.codec.decoder import Decoder
    from csgs_codec.interchange.writers import writer_for

    check_output(scene_path, [csgs_path])
    writer_for(scene_path)
    scene = Decoder().decode(csgs_path, layers=layers)
    write_scene(scene, scene_path, [csgs_path])
    return len(scene)
