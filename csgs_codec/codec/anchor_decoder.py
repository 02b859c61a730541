"""AnchorDecoder: .csgs bytes of an anchor scene -> AnchorScene, reading only the layers asked
for. Numpy and constriction only (never torch).

A file is an anchor scene when its base layer holds an ``ANCH`` chunk (a Gaussian scene has
``SCNE`` instead); :func:`is_anchor_file` tells them apart from the TOC alone.
"""

from __future__ import annotations

import os

import numpy as np

from csgs_codec.chunks.anchor_payloads import (
    AnchorHeader,
    mlps_from_bytes,
)
from csgs_codec.chunks.semantic import read_label_payload
from csgs_codec.chunks.semantic_names import names_from_bytes
from csgs_codec.codec.anchor_grid import dequantize
from csgs_codec.codec.decoder import check_layers
from csgs_codec.entropy.anchor_attributes import (
    FRAC_BITS,
    decode_block,
    decode_features,
    hyper_params,
    masked_params,
)
from csgs_codec.entropy.geometry import decode_positions
from csgs_codec.entropy.intnet import IntMLP
from csgs_codec.entropy.intnet_bytes import intnet_from_bytes
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.entropy.offset_masks import decode_masks
from csgs_codec.entropy.residual import from_grid
from csgs_codec.errors import FormatError
from csgs_codec.format import read_layers
from csgs_codec.format.primitives import ByteReader
from csgs_codec.scene.anchor_scene import AnchorScene

#: Most semantic channels a decoder accepts.
MAX_SEMANTIC_CHANNELS = 4096


def is_anchor_file(source) -> bool:
    """True when the container's TOC lists an ``ANCH`` chunk (reads header and TOC only)."""
    return any(e.type == "ANCH" for e in read_layers(source, layers="base").toc)


def _streams(data: bytes, offset: int, chunk: str, count: int) -> list[tuple[bytes, int]]:
    r = ByteReader(data, base_offset=offset, chunk=chunk)
    n = r.varint("stream_count", maximum=64)
    if n != count:
        raise r.error(f"{n} streams, expected {count}")
    out = []
    for _ in range(n):
        stream = r.byte_string("stream")
        out.append((stream, r.offset - len(stream)))
    r.expect_end(f"the {chunk} payload")
    return out


def _floats(values: np.ndarray) -> np.ndarray:
    return from_grid(values.reshape(-1), FRAC_BITS).astype(np.float32).reshape(values.shape)


class AnchorDecoder:
    """Decodes anchor-scene .csgs bitstreams written by ``AnchorEncoder``."""

    def decode(self, source, layers="color") -> AnchorScene:
        """Decode ``source`` (bytes, a path or a seekable binary file).

        Args:
            layers: "color" (anchors, MLPs, f / offsets / scaling; never reads a semantic
                byte) or "color,semantic" (also the semantic features and labels).

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
        header = AnchorHeader.from_bytes(*container.single_payload("ANCH"))
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
        hyper = self._position_net(container, "AHYP", pos_bits)
        data, offset = container.single_payload("ACRM")
        carm = [IntDenseMLP.from_bytes(d, chunk="ACRM", base_offset=o)
                for d, o in _streams(data, offset, "ACRM", header.carm_groups - 1)]
        data, offset = container.single_payload("AMSK")
        mask = decode_masks(data, m, k, chunk="AMSK", base_offset=offset)
        mlps = None
        if header.has_mlps:
            data, offset = container.single_payload("AMLP")
            mlps = mlps_from_bytes(data, f, k, offset)

        p_f, p_off, p_scl = hyper_params(hyper, cells, [f, 3 * k, 6], "AHYP")
        data, offset = container.single_payload("AFEA")
        features = decode_features(_streams(data, offset, "AFEA", header.carm_groups), p_f,
                                   carm, chunk="AFEA")
        data, offset = container.single_payload("AOFF")
        kept = decode_block(data, masked_params(p_off, mask), chunk="AOFF",
                            base_offset=offset)
        data, offset = container.single_payload("ASCL")
        scaling = decode_block(data, p_scl, chunk="ASCL", base_offset=offset)
        offsets = np.zeros((m, k, 3), dtype=np.float32)
        offsets[mask] = _floats(kept)
        scene = AnchorScene(positions, _floats(features), offsets, _floats(scaling), mask,
                            mlps=mlps)
        for name in ("features", "offsets", "scaling"):
            if not np.all(np.isfinite(getattr(scene, name))):
                raise FormatError(f"decoded {name} overflow float32",
                                  chunk={"features": "AFEA", "offsets": "AOFF"}.get(name,
                                                                                    "ASCL"))
        if "semantic" in wanted:
            self._semantic(container, cells, pos_bits, scene)
        return scene

    def _position_net(self, container, code: str, pos_bits: int) -> IntMLP:
        data, offset = container.single_payload(code)
        net = intnet_from_bytes(data, chunk=code, base_offset=offset)
        if net.pos_bits != pos_bits:
            raise FormatError(f"network pos_bits {net.pos_bits} differs from the grid's "
                              f"{pos_bits}", chunk=code, offset=offset)
        return net

    def _semantic(self, container, cells: np.ndarray, pos_bits: int,
                  scene: AnchorScene) -> None:
        present = {e.type for e in container.toc}
        m = len(cells)
        if ("ASEM" in present) != ("SHYP" in present):
            raise FormatError("ASEM and SHYP must both be present or both absent",
                              chunk="ASEM" if "ASEM" not in present else "SHYP")
        if "ASEM" in present:
            hyper = self._position_net(container, "SHYP", pos_bits)
            data, offset = container.single_payload("ASEM")
            r = ByteReader(data, base_offset=offset, chunk="ASEM")
            names = names_from_bytes(r, MAX_SEMANTIC_CHANNELS)
            stream = r.byte_string("stream")
            r.expect_end("the semantic payload")
            (params,) = hyper_params(hyper, cells, [len(names)], "SHYP")
            values = decode_block(stream, params, chunk="ASEM",
                                  base_offset=r.offset - len(stream))
            scene.semantic, scene.semantic_names = _floats(values), names
            if not np.all(np.isfinite(scene.semantic)):
                raise FormatError("decoded semantic features overflow float32", chunk="ASEM")
        if "SEML" in present:
            scene.labels = read_label_payload(*container.single_payload("SEML"), m)
