"""AnchorDecoder: .csgs bytes of an anchor scene -> AnchorScene, reading only the layers asked
for. Numpy and constriction only (never torch).

A file is an anchor scene when its base layer holds an ``ANCH`` chunk (a Gaussian scene has
``SCNE`` instead); :func:`is_anchor_file` tells them apart from the TOC alone.

The payloads are parsed in :mod:`csgs_codec.chunks` (``anchor_payloads``, ``anchor_networks``,
``anchor_streams``, ``anchor_semantic``, ``semantic``); this module decodes the anchor cells
and orders the reads.
"""

from __future__ import annotations

import os

import numpy as np

from csgs_codec.attributes.anchor_grid import dequantize
from csgs_codec.chunks.anchor_networks import color_channels, read_carm, read_hyperprior
from csgs_codec.chunks.anchor_payloads import AnchorHeader, read_mlps
from csgs_codec.chunks.anchor_semantic import read_anchor_semantic
from csgs_codec.chunks.anchor_streams import (
    read_anchor_features,
    read_anchor_offsets,
    read_anchor_scaling,
    read_offset_masks,
)
from csgs_codec.chunks.semantic import read_labels
from csgs_codec.chunks.view_origins import read_view_origins
from csgs_codec.codec.decoder import check_layers
from csgs_codec.entropy.anchor_attributes import hyper_params
from csgs_codec.entropy.geometry import decode_positions
from csgs_codec.errors import FormatError
from csgs_codec.format import read_layers
from csgs_codec.scene.anchor_scene import AnchorScene

#: Decoder limit against decompression bombs (FORMAT §10.1): a file may declare at most this
#: many anchor values (M x (F + 3K + 6)) per byte present. Trained files hold 2-3 values a
#: byte; the encoder pads a file that codes smaller with a ``fill`` chunk.
MAX_ANCHOR_VALUES_PER_BYTE = 256


def anchor_values(header: AnchorHeader) -> int:
    """M x (F + 3K + 6): the values the header's anchors carry (FORMAT §10.1)."""
    return header.count * (header.feat_dim + 3 * header.n_offsets + 6)


def is_anchor_file(source) -> bool:
    """True when the container's TOC lists an ``ANCH`` chunk (reads header and TOC only)."""
    return any(e.type == "ANCH" for e in read_layers(source, layers="base").toc)


class AnchorDecoder:
    """Decodes anchor-scene .csgs bitstreams written by ``AnchorEncoder``.

    Args:
        max_values_per_byte: refuse files whose anchors carry more values (M x (F + 3K + 6))
            per byte present than this (FORMAT §10.1).
    """

    def __init__(self, *, max_values_per_byte: int = MAX_ANCHOR_VALUES_PER_BYTE) -> None:
        self.max_values_per_byte = max_values_per_byte

    def decode(self, source, layers="color") -> AnchorScene:
        """Decode ``source`` (bytes, a path or a seekable binary file).

        Args:
            layers: "color" (anchors, MLPs, f / offsets / scaling; never reads a semantic
                byte) or "color,semantic" (also the semantic features and labels); or
                ``Layer.COLOR`` / ``Layer.SEMANTIC``.

        Returns:
            The scene, anchors in canonical order; masked offsets are zero.

        Raises:
            FormatError: a malformed, missing or inconsistent chunk, naming it and the offset.
            InputError: ``layers`` is not one of the accepted values (see
                :func:`csgs_codec.codec.decoder.check_layers`).
        """
        wanted = check_layers(layers)
        try:
            container = read_layers(source, layers=wanted)
            return self._decode(container, wanted)
        except FormatError as err:
            if err.file is None and isinstance(source, (str, os.PathLike)):
                err.file = str(source)
            raise

    def _decode(self, container, wanted: set[str]) -> AnchorScene:
        anch, anch_offset = container.single_payload("ANCH")
        header = AnchorHeader.from_bytes(anch, anch_offset)
        limit = self.max_values_per_byte * container.source_size
        if anchor_values(header) > limit:
            raise FormatError(
                f"declares {header.count} anchors ({anchor_values(header)} values) in a "
                f"{container.source_size}-byte file, above this decoder's limit of {limit} "
                f"values (max_values_per_byte={self.max_values_per_byte})", chunk="ANCH",
                offset=anch_offset)
        m, f, k = header.count, header.feat_dim, header.n_offsets
        data, offset = container.single_payload("GEOM")
        try:
            cells = decode_positions(data, max_points=m).astype(np.int64)
        except FormatError as err:
            err.chunk, err.offset = "GEOM", offset + (err.offset or 0)
            raise
        if len(cells) != m:
            raise FormatError(f"geometry holds {len(cells)} anchors, the header {m}",
                              chunk="GEOM", offset=offset)
        pos_bits = max(header.grid_bits, 1)
        if m and cells.max() >= 1 << pos_bits:
            raise FormatError("an anchor cell lies outside the header's grid", chunk="GEOM",
                              offset=offset)
        positions = dequantize(cells, header.origin, header.voxel_size)
        if not np.all(np.isfinite(positions)):
            raise FormatError("anchor positions overflow float32", chunk="ANCH")
        hyper = read_hyperprior(container, pos_bits, f, k)
        carm = read_carm(container, f, header.carm_groups)
        mask = read_offset_masks(container, m, k)
        mlps = read_mlps(container, header)
        p_f, p_off, p_scl = hyper_params(hyper, cells, color_channels(f, k))
        scene = AnchorScene(positions, read_anchor_features(container, p_f, carm),
                            read_anchor_offsets(container, p_off, mask),
                            read_anchor_scaling(container, p_scl), mask, mlps=mlps,
                            view_origins=read_view_origins(container))
        if "semantic" in wanted:
            semantic = read_anchor_semantic(container, cells, pos_bits)
            if semantic is not None:
                scene.semantic_names, scene.semantic = semantic
            scene.labels = read_labels(container, m)
        return scene
