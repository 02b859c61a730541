"""Opening any scene file, ``.csgs`` included: the one entry point above the codec (which
decodes ``.csgs``) and :mod:`csgs_codec.interchange` (which reads every other format)."""

from __future__ import annotations

import os
from pathlib import Path

from csgs_codec.errors import UnsupportedError
from csgs_codec.interchange import SceneSource, detect_format, read_interchange
from csgs_codec.scene.gaussian_scene import GaussianScene


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
            :meth:`csgs_codec.Decoder.decode`) or "color,semantic".

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
