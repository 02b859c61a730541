"""Other people's 3DGS compressors, wrapped to take and give standard 3DGS PLY files.

Each peer is a :class:`PeerCodec`: ``name``, ``available()`` / ``why_unavailable()``,
``encode(ply_path, out_dir) -> EncodeResult(bytes, seconds, path)`` and
``decode(encoded_path, out_ply) -> DecodeResult(seconds, path, fixups)``, whose PLY
``csgs_codec.interchange.ply_io.read_ply`` reads. :func:`all_peers` lists every wrapper, installed
or not: PlayCanvas splat-transform's SOG and compressed PLY, Niantic SPZ (written by
splat-transform with Niantic's library), and Draco (DracoPy) with a plain attribute mapping.
:func:`roundtrip_report` compares a decoded scene with its original.
"""

from __future__ import annotations

from .base import DecodeResult, EncodeResult, PeerCodec, PeerToolError
from .draco import DracoCodec
from .roundtrip import match_to_original, roundtrip_report
from .splat_transform import FORMATS as SPLAT_TRANSFORM_FORMATS
from .splat_transform import SplatTransformCodec

__all__ = ["PeerCodec", "EncodeResult", "DecodeResult", "PeerToolError", "SplatTransformCodec",
           "SPLAT_TRANSFORM_FORMATS", "DracoCodec",
           "all_peers", "peer_by_name", "roundtrip_report", "match_to_original"]


def all_peers() -> list[PeerCodec]:
    """Every peer wrapper, in benchmark order (check ``available()`` before use). Draco
    comes three times: 8-bit attributes (a compact baseline), 10 and 12 bits (the
    near-lossless end: 56-71 dB foreground PSNR on the full-precision SH-3 scenes)."""
    return [*(SplatTransformCodec(fmt) for fmt in SPLAT_TRANSFORM_FORMATS), DracoCodec(),
            *(DracoCodec(position_bits=16, attribute_bits=bits) for bits in (10, 12))]


def peer_by_name(name: str) -> PeerCodec:
    """The peer whose ``name`` is ``name`` (e.g. ``"playcanvas-sog"``).

    Raises:
        csgs_codec.errors.InputError: no peer has that name.
    """
    from csgs_codec.errors import InputError

    for peer in all_peers():
        if peer.name == name:
            return peer
    raise InputError(f"no peer named {name!r}; known: {[p.name for p in all_peers()]}")
