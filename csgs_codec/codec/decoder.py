"""Decoder: .csgs bytes -> GaussianScene, reading only the layers asked for.

Imports numpy and constriction only (never torch), so decoding starts fast and runs where
torch is not installed.
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor, as_completed
from dataclasses import dataclass, replace

import numpy as np

from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.attributes.streams import SceneStreams, join_streams
from csgs_codec.chunks.checks import check_finite
from csgs_codec.chunks.color_prior import (
    ColorPrior,
    channel_priors,
    modelled_streams,
    prior_cells,
    read_color_prior,
)
from csgs_codec.chunks.color_streams import CHUNK_STREAMS, STREAM_CHUNKS, read_color_stream
from csgs_codec.chunks.far_points import read_far_positions
from csgs_codec.chunks.scene_header import SceneHeader
from csgs_codec.chunks.semantic import read_semantic_layer
from csgs_codec.chunks.sh_colour_transform import read_colour_transform
from csgs_codec.chunks.tile_index import TileIndex, TileInfo
from csgs_codec.codec.container_access import parse_layers
from csgs_codec.entropy.geometry import decode_positions
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import Container
from csgs_codec.format.chunk import to_layer_set
from csgs_codec.format.layout import Layer
from csgs_codec.format.reader import name_source, needed_entries, read_frame
from csgs_codec.format.source import CountingSource, open_source
from csgs_codec.format.toc import read_toc
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Decoder limits against decompression bombs (FORMAT §10.1): a file may declare at most
#: this many Gaussians, and at most this many per byte of the file (real files hold well
#: under one per byte). The encoder keeps to both: it refuses larger scenes and pads a scene
#: that codes smaller (e.g. many identical Gaussians) with a `fill` chunk.
MAX_GAUSSIANS = 1 << 24
MAX_GAUSSIANS_PER_BYTE = 64


@dataclass
class DecodeReport:
    """What :meth:`Decoder.decode_with_report` returns.

    Attributes:
        scene: the decoded Gaussians (None when a region met no tile).
        tiles: the tile numbers decoded, increasing.
        tile_count: tiles in the file (1 for a file without a tile index), every level's.
        level: the level of detail decoded (0: the scene's own Gaussians; None when
            ``tiles`` chose them).
        levels: levels of detail in the file (1 without levels).
        bytes_read: bytes read from the source (header, TOC, tile index and the chunks of
            the tiles and layers decoded).
        file_bytes: bytes of the whole file (from its TOC).
    """

    scene: GaussianScene | None
    tiles: list[int]
    tile_count: int
    bytes_read: int
    file_bytes: int
    level: int | None = 0
    levels: int = 1


def check_region(region) -> tuple[float, ...] | None:
    """``region`` as 6 floats (xmin, ymin, zmin, xmax, ymax, zmax), or None.

    Raises:
        InputError: not 6 finite numbers, or a minimum above its maximum.
    """
    if region is None:
        return None
    try:
        values = tuple(float(v) for v in region)
    except (TypeError, ValueError):
        raise InputError(f"region must be 6 numbers xmin,ymin,zmin,xmax,ymax,zmax, got "
                         f"{region!r}", property="region") from None
    if len(values) != 6 or not all(np.isfinite(values)):
        raise InputError(f"region must be 6 finite numbers xmin,ymin,zmin,xmax,ymax,zmax, "
                         f"got {region!r}", property="region")
    if any(values[a] > values[a + 3] for a in range(3)):
        raise InputError(f"region {values}: a minimum is above its maximum",
                         property="region")
    return values


#: What a ``layers`` argument may be, for error messages.
LAYERS_ACCEPTED = ("'color' or 'color,semantic' (a comma-separated string, a Layer, or a "
                   "list of those)")


def check_layers(layers) -> set[str]:
    """The layer names of a ``layers`` argument: a string such as "color" or
    "color,semantic", a :class:`~csgs_codec.format.layout.Layer` (``Layer.SEMANTIC``), or an
    iterable (list, tuple, set) of such names or Layers; the color layer is always decoded.

    Raises:
        InputError: anything else (None, a number, bytes, a name of another type), an
            unknown layer name, or no layer at all.
    """
    if isinstance(layers, Layer):
        return parse_layers(layers.label)
    if isinstance(layers, str):
        return parse_layers(layers)
    if isinstance(layers, list | tuple | set | frozenset) and layers and all(
            isinstance(name, str | Layer) for name in layers):
        return parse_layers([name.label if isinstance(name, Layer) else name
                             for name in layers])
    raise InputError(f"layers must be {LAYERS_ACCEPTED}, got {layers!r}", property="layers")


def check_tiles(tiles) -> frozenset[int] | None:
    """``tiles`` (an iterable of tile numbers) as a set, or None (every tile).

    Raises:
        InputError: something that is not a non-negative integer, or no tile at all (an
            empty list would decode nothing: pass None for every tile).
    """
    if tiles is None:
        return None
    try:
        numbers = list(tiles)
    except TypeError:
        raise InputError(f"tiles must be a list of tile numbers, got {tiles!r}",
                         property="tiles") from None
    for n in numbers:
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            raise InputError(f"tile number {n!r} is not an integer >= 0", property="tiles")
    if not numbers:
        raise InputError("no tile given (an empty list); give tile numbers, or None for "
                         "every tile", property="tiles")
    return frozenset(int(n) for n in numbers)


def check_lod(lod, tiles) -> int | None:
    """``lod`` as a level number, or None (level 0 unless ``tiles`` are given).

    Raises:
        InputError: not an integer >= 0, or given with ``tiles`` (which name their tiles,
            whatever their level).
    """
    if lod is None:
        return None
    if isinstance(lod, bool) or not isinstance(lod, int | np.integer) or lod < 0:
        raise InputError(f"lod must be a level number >= 0, got {lod!r}", property="lod")
    if tiles is not None:
        raise InputError("give tiles or lod, not both (tile numbers name tiles of any "
                         "level)", property="lod")
    return int(lod)


class Decoder:
    """Decodes .csgs bitstreams written by :class:`csgs_codec.codec.encoder.Encoder`.

    Args:
        max_gaussians: refuse files declaring more Gaussians than this.
        max_gaussians_per_byte: refuse files declaring more Gaussians per byte of the file
            than this (files of this package's encoder always pass the defaults).
        threads: threads decoding the geometry and the color streams side by side (default
            2, or 1 on a one-core machine); the output is the same for any count.

    One decoder may serve several threads at once; each call decodes as it would alone.
    """

    def __init__(self, *, max_gaussians: int = MAX_GAUSSIANS,
                 max_gaussians_per_byte: int = MAX_GAUSSIANS_PER_BYTE,
                 threads: int | None = None) -> None:
        self.max_gaussians = max_gaussians
        self.max_gaussians_per_byte = max_gaussians_per_byte
        self.threads = min(2, os.cpu_count() or 1) if threads is None else int(threads)
        if self.threads < 1:
            raise InputError(f"threads must be at least 1, got {threads}", property="threads")

    def decode(self, source, layers="color", *, tiles=None, region=None,
               lod=None) -> GaussianScene:
        """Decode ``source`` (bytes, a path, a seekable binary file or a range reader:
        :mod:`csgs_codec.format.source`).

        Args:
            layers: "color" or ``Layer.COLOR`` (geometry + color; never reads semantic
                bytes), or "color,semantic" or ``Layer.SEMANTIC`` (see :func:`check_layers`).
            tiles, region: decode only some spatial tiles (see :meth:`decode_with_report`).
            lod: the level of detail to decode, 0 (default: the scene's own Gaussians) ..
                levels - 1 (the coarsest) of a file with levels (FORMAT §12.22).

        Returns:
            The decoded scene: in canonical (geometry) order, tile after tile in a tiled file.

        Raises:
            FormatError: any malformed, missing or inconsistent chunk, naming it and the
                byte offset.
            InputError: a bad ``layers``, an empty or malformed tile list, a tile number the
                file does not have, a malformed region, a region that meets no tile, or a
                level the file does not have.
        """
        report = self.decode_with_report(source, layers, tiles=tiles, region=region, lod=lod)
        if report.scene is None:
            raise InputError("no tile meets the region (nothing to decode)", property="region",
                             file=source if isinstance(source, str | os.PathLike) else None)
        return report.scene

    def decode_with_report(self, source, layers="color", *, tiles=None, region=None,
                           lod=None, progress=None) -> DecodeReport:
        """Decode ``source`` as :meth:`decode` does, reading only the chunks of the tiles
        asked for, and report which tiles and how many bytes were read.

        Args:
            tiles: tile numbers to decode (any order; decoded in increasing order; of any
                level), or None.
            region: (xmin, ymin, zmin, xmax, ymax, zmax) world units: decode the tiles whose
                bounding box (from the tile index) meets this closed box, or None. With
                both None, every tile is decoded. A file without tiles is one tile (0),
                whose box is not known before decoding: a region always selects it. The
                tiles are decoded whole (their Gaussians outside the region included).
            lod: the level of detail (default 0): the tiles of that level (those meeting
                ``region`` when given). Not with ``tiles``.
            progress: called as ``progress(done, total)`` as tiles finish, or None.

        Returns:
            A :class:`DecodeReport`: the scene (the chosen tiles' Gaussians, tile after tile;
            None when the region meets no tile), the tile numbers, ``bytes_read`` (bytes
            fetched from the source) and the file size.

        Raises:
            As :meth:`decode`, but a region that meets no tile is no error here.
        """
        wanted = check_layers(layers)
        box = check_region(region)
        chosen = check_tiles(tiles)
        level = check_lod(lod, tiles)
        src = CountingSource(open_source(source))
        levels = 1
        try:
            toc = read_toc(src)
            if any(e.type == "TIDX" for e in toc.entries):
                scene, numbers, count, levels = self._decode_tiled(
                    src, toc, wanted, chosen, box, level, progress)
            else:
                if chosen is not None and chosen - {0}:
                    raise InputError(f"tile {max(chosen)} is not in the file (it has one "
                                     "tile: 0)", property="tiles")
                _check_level(level, 1)
                numbers, count = [0], 1
                container = _read_container(src, toc, toc.entries, wanted)
                scene = self._decode_container(container, wanted, self.threads)
                if progress is not None:
                    progress(1, 1)
        except FormatError as err:
            name_source(err, src.inner)
            if err.file is None and isinstance(source, (str, os.PathLike)):
                err.file = str(source)
            raise
        finally:
            src.close()
        return DecodeReport(scene, numbers, count, src.bytes_read, toc.file_size,
                            None if chosen is not None else level or 0, levels)

    def _decode_tiled(self, src, toc, wanted: set[str], chosen, box, level, progress):
        """(scene, tile numbers decoded, tiles in the file, levels) of a file with a tile
        index: the tiles ``chosen``, else those of ``level`` (default 0), meeting ``box``."""
        index = _tile_index(src, toc)
        count = len(index.tiles)
        limit = self.max_gaussians_per_byte * src.size
        if index.count > limit:
            raise FormatError(f"the tile index declares {index.count} Gaussians in a "
                              f"{src.size}-byte file, above this decoder's limit of {limit} "
                              f"(max_gaussians_per_byte={self.max_gaussians_per_byte})",
                              chunk="TIDX", offset=toc.entries[0].offset + 8)
        if chosen is not None and max(chosen, default=-1) >= count:
            raise InputError(f"tile {max(chosen)} is not in the file (it has {count} tiles: "
                             f"0..{count - 1})", property="tiles")
        _check_level(level, index.levels)
        numbers = set(index.level_tiles(level or 0)) if chosen is None else set(chosen)
        if box is not None:
            numbers &= set(index.select(box[:3], box[3:]))
        numbers = sorted(numbers)
        entries = toc.entries[1:]
        container = _read_container(src, toc, [e for e in entries if e.tile in numbers],
                                    wanted)
        containers = [replace(container, toc=tuple(e for e in entries if e.tile == t))
                      for t in numbers]
        jobs = [(c, number, index.tiles[number]) for c, number in zip(containers, numbers)]
        scenes = self._decode_tiles(jobs, wanted, progress)
        for (container, number, _), scene in zip(jobs, scenes):
            _check_same_kind(scene, number, scenes[0], numbers[0], container)
        if not scenes:
            return None, numbers, count, index.levels
        return GaussianScene.concatenate(scenes), numbers, count, index.levels

    def _decode_tiles(self, jobs, wanted, progress) -> list[GaussianScene]:
        """The scenes of the tiles ``jobs`` ((container, number, TileInfo) each), tiles side
        by side on the decoder's threads (one thread each; a lone tile gets them all).
        Results and the first error raised are in tile order."""
        total = len(jobs)
        if total <= 1 or self.threads <= 1:
            out = []
            for job in jobs:
                out.append(self._decode_tile(*job, wanted, self.threads))
                if progress is not None:
                    progress(len(out), total)
            return out
        with ThreadPoolExecutor(min(self.threads, total)) as pool:
            futures = [pool.submit(self._decode_tile, *job, wanted, 1) for job in jobs]
            for done, _ in enumerate(as_completed(futures), 1):
                if progress is not None:
                    progress(done, total)
            return [future.result() for future in futures]

    def _decode_tile(self, container, number: int, info: TileInfo, wanted: set[str],
                     threads: int) -> GaussianScene:
        """One tile's scene, checked against its tile index entry (count, box)."""
        scene = self._decode_container(container, wanted, threads)
        if len(scene) != info.count:
            raise FormatError(f"tile {number} holds {len(scene)} Gaussians, the tile index "
                              f"says {info.count}", chunk="SCNE",
                              offset=container.single_payload("SCNE")[1])
        p = scene.positions
        if len(p) and (np.any(p.min(axis=0) < np.float32(info.lower))
                       or np.any(p.max(axis=0) > np.float32(info.upper))):
            raise FormatError(f"tile {number} has a Gaussian outside its box in the tile "
                              "index", chunk="GEOM", offset=container.single_payload("GEOM")[1])
        return scene

    def _decode_container(self, container, wanted: set[str], threads: int) -> GaussianScene:
        """The scene of one tile's chunks (``container`` holds only that tile's entries)."""
        header = SceneHeader.from_bytes(*container.single_payload("SCNE"))
        self._check_count(header, container.source_size)
        prior = (read_color_prior(container, _stream_names(header), header.grid_bits)
                 if any(e.type == "CHYP" for e in container.toc) else None)
        pool = ThreadPoolExecutor(threads) if threads > 1 else None
        try:
            # Geometry and each attribute stream are independent, except that streams
            # with hyperprior channels need the decoded cells: decode side by side
            # (numpy releases the GIL). Results are taken in a fixed order, so the
            # output and the first error raised do not depend on scheduling.
            colour_transform = read_colour_transform(container, header.sh_degree_coded)
            positions_job = _submit(pool, self._positions, container, header)
            streams = self._color_streams(container, header, pool, prior, positions_job,
                                          colour_transform)
            positions, _ = positions_job.result()
        finally:
            if pool is not None:
                pool.shutdown()
        scene = join_streams(streams, positions)
        if "semantic" in wanted:
            self._semantic(container, header, scene)
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
        data, offset = container.single_payload("GEOM")
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
        far = read_far_positions(container, header.far_count)
        check_finite(positions, "GEOM")
        if header.far_count:
            positions = np.concatenate([positions, far])
        return positions, cells

    # ------------------------------------------------------------------ color layer
    def _color_streams(self, container, header: SceneHeader, pool: ThreadPoolExecutor | None,
                        prior: ColorPrior | None, positions_job: Future,
                        colour_transform: tuple[tuple[int, ...], int] | None = None
                        ) -> SceneStreams:
        """Decode the color streams; those with hyperprior channels after the geometry
        (``positions_job``) and the network's evaluation, the others right away."""
        names = _stream_names(header)
        present = {e.type for e in container.toc}
        extra = present & set(CHUNK_STREAMS) - {STREAM_CHUNKS[n] for n in names}
        if extra:
            raise FormatError(f"unexpected color chunk(s) {sorted(extra)} for SH degree "
                              f"{header.sh_degree_coded}", chunk=sorted(extra)[0])
        modelled = modelled_streams(prior, names) if prior is not None else set()
        # Rotations may take scored steps from the decoded scales and opacities: they are
        # submitted after those, and wait for them only when a channel asks.
        later = modelled | ({"rot"} if modelled & {"scale", "opacity"} else set())
        jobs: dict[str, Future] = {}

        def scales() -> np.ndarray:
            return jobs["scale"].result()[0]

        def opacities() -> np.ndarray:
            return jobs["opacity"].result()[0]

        def submit(name: str, priors=None) -> None:
            derive_from = (scales, opacities) if name == "rot" else (None, None)
            transform = colour_transform if name.startswith("rest") else None
            jobs[name] = _submit(pool, read_color_stream, container, header.count, name, priors,
                                 *derive_from, transform)

        for name in names:
            if name not in later:
                submit(name)
        if later:
            priors = {}
            if modelled:
                _, cells = positions_job.result()
                if len(cells) and int(cells.max()) >= 1 << prior.net.pos_bits:
                    raise FormatError(f"the color hyperprior needs cells below "
                                      f"2^{prior.net.pos_bits}", chunk="CHYP")
                priors = channel_priors(prior, prior_cells(cells, header.far_count), names,
                                        pool)
            for name in names:
                if name in later:
                    submit(name, priors.get(name))
        results = [jobs[name].result() for name in names]  # in order: the first error wins
        decoded = {name: values for name, (values, _) in zip(names, results)}
        rot_axis = results[-1][1]
        return SceneStreams(decoded, rot_axis.astype(np.uint8), header.sh_degree_stored)

    # ------------------------------------------------------------------ semantic layer
    def _semantic(self, container, header: SceneHeader, scene: GaussianScene) -> None:
        read_semantic_layer(container, header.count, scene)


def _check_level(level: int | None, levels: int) -> None:
    """InputError when ``level`` is not one of a file's ``levels`` levels of detail."""
    if level is not None and level >= levels:
        have = "one level (0)" if levels == 1 else f"levels 0..{levels - 1}"
        raise InputError(f"level {level} is not in the file (it has {have})", property="lod")


def _read_container(src, toc, entries, wanted: set[str]) -> Container:
    """The container of ``entries`` (a tile's or all of them) with the payloads of the
    base and ``wanted`` layers read from ``src``."""
    layers = to_layer_set(wanted)
    payloads = {e.index: read_frame(src, e) for e in needed_entries(entries, layers)}
    return Container(toc.major_version, toc.minor_version, toc.flags, tuple(entries),
                     payloads, layers, toc.source_size, toc.header_and_toc_size)


def _tile_index(src, toc) -> TileIndex:
    """The TIDX of a tiled file, after checking it is the first chunk, in tile 0, alone,
    and that every other chunk's tile is in it."""
    found = [e for e in toc.entries if e.type == "TIDX"]
    if len(found) > 1:
        raise FormatError(f"chunk TIDX appears {len(found)} times", chunk="TIDX",
                          offset=found[1].toc_offset)
    entry = found[0]
    if entry.index != 0 or entry.tile != 0:
        raise FormatError("the tile index must be the first chunk, in tile 0",
                          chunk="TIDX", offset=entry.toc_offset)
    index = TileIndex.from_bytes(read_frame(src, entry), entry.offset + 8)
    for e in toc.entries[1:]:
        if e.tile >= len(index.tiles):
            raise FormatError(f"tile {e.tile} is not in the tile index ({len(index.tiles)} "
                              "tiles)", chunk=e.type, offset=e.toc_offset)
    return index


def _check_same_kind(scene: GaussianScene, number: int, first: GaussianScene,
                     first_number: int, container) -> None:
    """FormatError when a decoded tile differs from the first tile decoded in SH degree,
    semantic channel names or whether it has semantic features or labels."""
    same = (scene.sh_degree_stored == first.sh_degree_stored
            and scene.semantic_names == first.semantic_names
            and (scene.semantic is None) == (first.semantic is None)
            and (scene.labels is None) == (first.labels is None))
    if not same:
        raise FormatError(f"tile {number} differs from tile {first_number} in SH degree or "
                          "semantic layer", chunk="SCNE",
                          offset=container.single_payload("SCNE")[1])


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


def _stream_names(header: SceneHeader) -> list[str]:
    """The color streams a scene with this header has, in order."""
    return (["dc"] + [f"rest{b}" for b in range(1, header.sh_degree_coded + 1)]
            + ["opacity", "scale", "rot"])
