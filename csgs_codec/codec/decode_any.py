"""One entry point for every .csgs file: :func:`decode` reads the table of contents and hands
the file to the decoder of its kind (standard 3DGS scenes or Scaffold-GS anchor scenes)."""

from __future__ import annotations

from csgs_codec.codec.anchor_decoder import AnchorDecoder, is_anchor_file
from csgs_codec.codec.decoder import Decoder, check_layers
from csgs_codec.errors import InputError


def decode(source, layers="color", *, tiles=None, region=None, threads: int | None = None):
    """Decode the .csgs ``source`` whatever scene kind it holds.

    Args:
        source: bytes, a path, a seekable binary file, or an object with ``size`` and
            ``read_range(offset, size)`` (see :class:`~csgs_codec.codec.decoder.Decoder`).
        layers: "color" (default: stops before the semantic layer) or "color,semantic"; or
            ``Layer.COLOR`` / ``Layer.SEMANTIC`` (:class:`csgs_codec.Layer`).
        tiles, region: which tiles of a tiled standard file to decode (see
            :meth:`Decoder.decode_with_report`); anchor files have no tiles, so both must be
            None for them.
        threads: decoder threads for standard files (None: up to 2); anchor files decode
            on one.

    Returns:
        A :class:`~csgs_codec.scene.gaussian_scene.GaussianScene` for a standard file, an
        :class:`~csgs_codec.scene.anchor_scene.AnchorScene` for an anchor file.

    Raises:
        FormatError: a malformed file, naming the chunk and byte offset.
        InputError: bad arguments, or tiles/region asked of an anchor file.
    """
    check_layers(layers)
    if is_anchor_file(source):  # the header and TOC only; a file is read by offset
        if tiles is not None or region is not None:
            raise InputError("an anchor-scene file has no tiles: decode it whole (tiles and "
                             "region None)", property="tiles" if tiles is not None
                             else "region")
        return AnchorDecoder().decode(source, layers=layers)
    return Decoder(threads=threads).decode(source, layers=layers, tiles=tiles, region=region)
