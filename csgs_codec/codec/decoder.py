"""Decoder: .csgs bytes -> GaussianScene, reading only the layers asked for.

Imports numpy and constriction only (never torch), so decoding starts fast and runs where
torch is not installed.
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from csgs_codec.codec.colour_prior import (
    ColourPrior,
    channel_priors,
    modelled_streams,
    prior_cells,
    prior_from_bytes,
)
from csgs_codec.codec.container_access import parse_layers, single_payload
from csgs_codec.codec.far_payload import read_far_payload
from csgs_codec.codec.float_stream import ChannelPrior, read_float_stream
from csgs_codec.codec.payloads import (
    CHUNK_STREAMS,
    MAX_SEMANTIC_CHANNELS,
    STREAM_CHANNELS,
    STREAM_CHUNKS,
    SceneHeader,
    check_finite,
    names_from_bytes,
)
from csgs_codec.codec.streams import SceneStreams, join_streams
from csgs_codec.entropy.categorical import decode_categorical
from csgs_codec.entropy.geometry import decode_positions
from csgs_codec.entropy.residual import decode_symbols
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import read_layers
from csgs_codec.format.primitives import ByteReader
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.scene.position_grid import PositionGrid

#: Decoder limits against decompression bombs (FORMAT §10.1): a file may declare at most
#: this many Gaussians, and at most this many per byte of the file (real files hold well
#: under one per byte). The encoder keeps to both: it refuses larger scenes and pads a scene
#: that codes smaller (e.g. many identical Gaussians) with a `fill` chunk.
MAX_GAUSSIANS = 1 << 24
MAX_GAUSSIANS_PER_BYTE = 64


class Decoder:
    """Decodes .csgs bitstreams written by :class:`csgs_codec.codec.encoder.Encoder`.

    Args:
        max_gaussians: refuse files declaring more Gaussians than this.
        max_gaussians_per_byte: refuse files declaring more Gaussians per byte of the file
            than this (files of this package's encoder always pass the defaults).
        threads: threads decoding the geometry and the colour streams side by side (default
            2, or 1 on a one-core machine); the output is the same for any count.
    """

    def __init__(self, *, max_gaussians: int = MAX_GAUSSIANS,
                 max_gaussians_per_byte: int = MAX_GAUSSIANS_PER_BYTE,
                 threads: int | None = None) -> None:
        self.max_gaussians = max_gaussians
        self.max_gaussians_per_byte = max_gaussians_per_byte
        self.threads = min(2, os.cpu_count() or 1) if threads is None else int(threads)
        if self.threads < 1:
            raise InputError(f"threads must be at least 1, got {threads}", property="threads")

    def decode(self, source, layers="color") -> GaussianScene:
        """Decode ``source`` (bytes, a path or a seekable binary file).

        Args:
            layers: "color" (geometry + colour; never reads semantic bytes) or
                "color,semantic".

        Returns:
            The decoded scene in canonical (geometry) order.

        Raises:
            FormatError: any malformed, missing or inconsistent chunk, naming it and the
                byte offset.
        """
        wanted = parse_layers(layers)
        try:
            container = read_layers(source, layers=wanted)
            header = SceneHeader.from_bytes(*single_payload(container, "SCNE"))
            self._check_count(header, container.source_size)
            prior = (self._colour_prior(container, header)
                     if any(e.type == "CHYP" for e in container.toc) else None)
            pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
            try:
                # Geometry and each attribute stream are independent, except that streams
                # with hyperprior channels need the decoded cells: decode side by side
                # (numpy releases the GIL). Results are taken in a fixed order, so the
                # output and the first error raised do not depend on scheduling.
                positions_job = _submit(pool, self._positions, container, header)
                streams = self._colour_streams(container, header, pool, prior, positions_job)
                positions, _ = positions_job.result()
            finally:
                if pool is not None:
                    pool.shutdown()
            scene = join_streams(streams, positions)
            if "semantic" in wanted:
                self._semantic(container, header, scene)
        except FormatError as err:
            if err.file is None and isinstance(source, (str, os.PathLike)):
                err.file = str(source)
            raise
        return scene

    def _check_count(self, header: SceneHeader, source_size: int) -> None:
        """FormatError when the declared Gaussian count breaks this decoder's limits."""
        limit = min(self.max_gaussians, self.max_gaussians_per_byte * source_size)
        if header.count > limit:
            raise FormatError(
                f"declares {header.count} Gaussians in a {source_size}-byte file, above this "
                f"decoder's limit of {limit} (max_gaussians={self.max_gaussians}, "
                f"max_gaussians_per_byte={self.max_gaussians_per_byte}; raise them to decode "
                "it)", chunk="SCNE")

    # ------------------------------------------------------------------ base layer
    def _positions(self, container, header: SceneHeader) -> tuple[np.ndarray, np.ndarray]:
        """(positions (N, 3) float32, grid cells (N - far_count, 3)) of the base layer."""
        grid_count = header.count - header.far_count
        data, offset = single_payload(container, "GEOM")
        try:
            cells = decode_positions(data, max_points=grid_count)
        except FormatError as err:
            err.chunk, err.offset = "GEOM", offset + (err.offset or 0)
            raise
        if len(cells) != grid_count:
            raise FormatError(f"geometry holds {len(cells)} points, the header says "
                              f"{grid_count}", chunk="GEOM", offset=offset)
        if header.grid_bits < 21 and len(cells) and cells.max() >= 1 << max(header.grid_bits, 1):
            raise FormatError("a point lies outside the header's grid", chunk="GEOM",
                              offset=offset)
        grid = PositionGrid(header.grid_origin, header.grid_cell, max(header.grid_bits, 1))
        positions = grid.dequantize(cells)
        if header.far_count:
            far = _far_positions(container, header)
        else:
            for code in ("OUTQ", "OUTL"):
                _refuse_chunk(container, code, "the header declares no far points")
        check_finite(positions, "GEOM")
        if header.far_count:
            positions = np.concatenate([positions, far])
        return positions, cells

    # ------------------------------------------------------------------ colour layer
    def _colour_prior(self, container, header: SceneHeader) -> ColourPrior:
        """The colour hyperprior of the CHYP chunk (parsed, not yet evaluated)."""
        data, offset = single_payload(container, "CHYP")
        pos_bits = max(header.grid_bits, 1)
        if pos_bits > 32:
            raise FormatError(f"the colour hyperprior needs a grid of at most 32 bits, the "
                              f"header has {pos_bits}", chunk="CHYP", offset=offset)
        return prior_from_bytes(data, base_offset=offset, names=_stream_names(header),
                                pos_bits=pos_bits)

    def _colour_streams(self, container, header: SceneHeader, pool: ThreadPoolExecutor | None,
                        prior: ColourPrior | None, positions_job: Future) -> SceneStreams:
        """Decode the colour streams; those with hyperprior channels after the geometry
        (``positions_job``) and the network's evaluation, the others right away."""
        names = _stream_names(header)
        present = {e.type for e in container.toc}
        extra = present & set(CHUNK_STREAMS) - {STREAM_CHUNKS[n] for n in names}
        if extra:
            raise FormatError(f"unexpected colour chunk(s) {sorted(extra)} for SH degree "
                              f"{header.sh_degree_coded}", chunk=sorted(extra)[0])
        modelled = modelled_streams(prior, names) if prior is not None else set()
        # Rotations may derive their steps from the decoded scales (mode 6): they are
        # submitted after the scales, and wait for them only when a channel asks.
        later = modelled | ({"rot"} if "scale" in modelled else set())
        jobs: dict[str, Future] = {}

        def scales() -> np.ndarray:
            return jobs["scale"].result()[0]

        def submit(name: str, priors=None) -> None:
            jobs[name] = _submit(pool, _colour_stream, container, header, name, priors,
                                 scales if name == "rot" else None)

        for name in names:
            if name not in later:
                submit(name)
        if later:
            priors = {}
            if modelled:
                _, cells = positions_job.result()
                if len(cells) and int(cells.max()) >= 1 << prior.net.pos_bits:
                    raise FormatError(f"the colour hyperprior needs cells below "
                                      f"2^{prior.net.pos_bits}", chunk="CHYP")
                priors = channel_priors(prior, prior_cells(cells, header.far_count), names)
            for name in names:
                if name in later:
                    submit(name, priors.get(name))
        results = [jobs[name].result() for name in names]  # in order: the first error wins
        decoded = {name: values for name, (values, _) in zip(names, results)}
        rot_axis = results[-1][1]
        return SceneStreams(decoded, rot_axis.astype(np.uint8), header.sh_degree_stored)

    # ------------------------------------------------------------------ semantic layer
    def _semantic(self, container, header: SceneHeader, scene: GaussianScene) -> None:
        present = {e.type for e in container.toc}
        if "SEMF" in present:
            data, offset = single_payload(container, "SEMF")
            r = ByteReader(data, base_offset=offset, chunk="SEMF")
            names = names_from_bytes(r, MAX_SEMANTIC_CHANNELS)
            values = read_float_stream(r, header.count, len(names))
            r.expect_end("the semantic feature stream")
            check_finite(values, "SEMF")
            scene.semantic, scene.semantic_names = values, names
        if "SEML" in present:
            data, offset = single_payload(container, "SEML")
            r = ByteReader(data, base_offset=offset, chunk="SEML")
            base = r.svarint("label_base")
            table = r.fixed("u8", "scale_index")
            stream = r.byte_string("label_stream")
            r.expect_end("the label stream")
            if table >= 64:
                raise r.error(f"scale index {table} out of range")
            labels = decode_symbols(stream, np.full(header.count, table, np.int64),
                                    chunk="SEML", base_offset=r.offset - len(stream)) + base
            if labels.size and (labels.min() < -(1 << 31) or labels.max() >= 1 << 31):
                raise r.error("label outside the int32 range")
            scene.labels = labels.astype(np.int32)


def _submit(pool: ThreadPoolExecutor | None, fn, *args) -> Future:
    """``fn(*args)`` on the pool, or run now (no pool) as a completed future holding its
    result or its exception."""
    if pool is not None:
        return pool.submit(fn, *args)
    future = Future()
    try:
        future.set_result(fn(*args))
    except Exception as exc:  # re-raised by .result(), in the caller's order
        future.set_exception(exc)
    return future


def _far_positions(container, header: SceneHeader) -> np.ndarray:
    """(far_count, 3) float32 positions of the far points: those of OUTQ (relative
    precision, when present) then those of OUTL (exact float32), FORMAT §12.4."""
    parts = []
    if any(e.type == "OUTQ" for e in container.toc):
        data, offset = single_payload(container, "OUTQ")
        parts.append(read_far_payload(data, offset, header.far_count))
    exact = header.far_count - sum(len(p) for p in parts)
    if not exact:
        _refuse_chunk(container, "OUTL", "OUTQ holds every far point")
        return np.concatenate(parts)
    data, offset = single_payload(container, "OUTL")
    r = ByteReader(data, base_offset=offset, chunk="OUTL")
    n = r.varint("far_count", maximum=exact)
    if n != exact:
        raise r.error(f"{n} outliers, the header and OUTQ leave {exact}")
    far = r.array(n * 3, "<f4", "positions").reshape(n, 3).astype(np.float32)
    r.expect_end("the outlier list")
    check_finite(far, "OUTL")
    return np.concatenate(parts + [far])


def _refuse_chunk(container, code: str, why: str) -> None:
    """FormatError at the chunk when ``container`` holds a ``code`` chunk it must not."""
    entry = next((e for e in container.toc if e.type == code), None)
    if entry is not None:
        raise FormatError(f"unexpected {code} chunk: {why}", chunk=code, offset=entry.offset)


def _stream_names(header: SceneHeader) -> list[str]:
    """The colour streams a scene with this header has, in order."""
    return (["dc"] + [f"rest{b}" for b in range(1, header.sh_degree_coded + 1)]
            + ["opacity", "scale", "rot"])


def _colour_stream(container, header: SceneHeader, name: str,
                   priors: dict[int, ChannelPrior] | None = None, log_scales=None
                   ) -> tuple[np.ndarray, np.ndarray | None]:
    """(values (N, C) float32, dropped-component index per Gaussian for "rot" else None) of
    one colour stream; ``priors`` are the hyperprior's for its modelled channels, and
    ``log_scales`` (rotations only) returns the decoded scales mode 6 derives steps from."""
    code = STREAM_CHUNKS[name]
    data, offset = single_payload(container, code)
    r = ByteReader(data, base_offset=offset, chunk=code)
    rot_axis = None
    if name == "rot":
        axis_stream = r.byte_string("axis_stream")
        rot_axis = decode_categorical(axis_stream, header.count, chunk=code,
                                      base_offset=r.offset - len(axis_stream))
        if rot_axis.size and rot_axis.max() > 3:
            raise r.error("dropped-component index above 3")
    values = read_float_stream(r, header.count, STREAM_CHANNELS[name], priors,
                               log_scales)
    r.expect_end(f"the {name} stream")
    check_finite(values, code)
    return values, rot_axis
