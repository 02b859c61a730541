"""Coding a scene as spatial tiles (FORMAT §6.3, §12.22), tiles side by side.

The scene is cut into k-d cells (:mod:`csgs_codec.codec.tiling`); every tile is coded on
its own, as a scene of its own (geometry frame, far points, color hyperprior, streams), by
:func:`encode_tile`, in this process, local processes or on Ray
(:mod:`csgs_codec.codec.parallel`). The file holds a ``TIDX`` chunk, then every tile's base
chunks in tile order, then their color chunks, then their semantic chunks. Decoding all
tiles gives tile 0's Gaussians, then tile 1's, and so on, each tile in its own decoded order.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.chunks.tile_index import TileIndex, TileInfo, tile_info
from csgs_codec.codec.encode_report import EncodeReport
from csgs_codec.codec.parallel import run_jobs
from csgs_codec.codec.tiling import effective_tile_size, split_tiles, tile_grid
from csgs_codec.decisions.presets import Preset
from csgs_codec.errors import InputError
from csgs_codec.format import Chunk
from csgs_codec.scene.gaussian_scene import GaussianScene


@dataclass
class TileJob:
    """What one worker needs to code one tile.

    Attributes:
        scene: the tile's Gaussians, or None when they are read from ``source``.
        source: a binary PLY the tile's rows are read from (memory-mapped), or None.
        rows: (M,) int64 rows of the tile in the input, increasing.
        grid: the whole scene's position grid (the worker places the tile on it: keeping
            every tile's cells in the planning process would hold 33 bytes per Gaussian of
            the scene there).
        settings: the preset's steps (the whole scene's, whatever rate search chose them).
        config: the calling encoder's :class:`~csgs_codec.codec.encoder_config.EncoderConfig`
            as a tile codes with it (one tile, one worker, no view pruning).
        encoder_class: the calling encoder's class, which the worker makes from ``config``
            (passed in, so that this module does not import the encoder that calls it; it
            pickles by name).
        keep_reconstruction: send the tile's reconstruction back (not when streaming a
            scene larger than memory).
    """

    scene: GaussianScene | None
    source: str | None
    rows: np.ndarray
    grid: PositionGrid
    settings: Preset
    config: object
    encoder_class: type
    keep_reconstruction: bool = True


@dataclass
class TileOutput:
    """One coded tile: chunks (tile 0), its tile index entry, order (indices into the
    tile) and reconstruction (None unless the job keeps it)."""

    chunks: list[Chunk]
    info: TileInfo
    order: np.ndarray
    reconstruction: GaussianScene | None


def encode_tile(job: TileJob) -> TileOutput:
    """Code one tile (runs in a worker; module level so that it pickles by name)."""
    scene = job.scene
    if scene is None:
        from csgs_codec.codec.encoder_checks import check_encodable
        from csgs_codec.interchange.ply_mmap import read_ply_rows

        scene = read_ply_rows(job.source, job.rows)
        try:
            check_encodable(scene, semantic=job.config.semantic != "none")
        except InputError as err:
            if err.index is not None:
                err.index = int(job.rows[err.index])
            err.file = err.file or job.source
            err.args = (str(err),)
            raise
    cells, inside = job.grid.quantize(scene.positions)
    local_grid, local = tile_grid(cells[inside], job.grid)
    tile_cells = np.zeros_like(cells)
    tile_cells[inside] = local
    encoder = job.encoder_class(job.config)
    coded = encoder.code_scene(scene, job.settings, local_grid, tile_cells, inside)
    return TileOutput(coded.chunks, tile_info(coded.reconstruction.positions), coded.order,
                      coded.reconstruction if job.keep_reconstruction else None)


def plan_jobs(encoder, positions: np.ndarray, grid: PositionGrid, settings: Preset,
              tile_size: int, *, hyperprior: bool, scene: GaussianScene | None = None,
              source: str | None = None, keep_reconstruction: bool = True) -> list[TileJob]:
    """One job per tile of the scene whose positions are ``positions`` (N, 3), on the
    whole scene's ``grid``, coded with ``encoder``'s config (the hyperprior fitted when
    ``hyperprior``); tiles carry their Gaussians from ``scene`` or name ``source``."""
    config = replace(encoder.config, hyperprior=hyperprior, tile_size=None, workers=1,
                     ray=None, view_pruning=False, cameras=None)
    return [TileJob(None if scene is None else scene.subset(rows), source, rows, grid,
                    settings, config, type(encoder), keep_reconstruction)
            for rows in split_tiles(positions, tile_size)]


def encode_tiled(encoder, scene: GaussianScene, grid: PositionGrid, settings: Preset,
                 tile_size: int, *, hyperprior: bool | None = None,
                 record: Chunk | None = None):
    """Encode ``scene`` (validated, more than ``tile_size`` Gaussians) as tiles with the
    ``encoder``'s settings; returns its :class:`~csgs_codec.codec.encoder.EncodeReport`.
    ``record`` (a ``vdis`` chunk) goes into tile 0, after its base chunks."""
    use_prior = encoder.config.fits_hyperprior if hyperprior is None else hyperprior
    jobs = plan_jobs(encoder, scene.positions, grid, settings, tile_size,
                     hyperprior=use_prior, scene=scene)
    outputs = _run_tiles(encoder, jobs)
    return assemble(encoder, jobs, outputs, len(scene), record)


def assemble(encoder, jobs: list[TileJob], outputs: list[TileOutput], count: int,
             record: Chunk | None = None, links: list[tuple[int, int | None]] | None = None):
    """The EncodeReport of coded tiles: the container (TIDX first), the reconstruction
    (tiles in order; None when the tiles did not keep theirs) and the order into the input.
    ``links`` gives each tile's (level, parent) in a file with levels of detail: the
    reconstruction and order are then those of the level-0 tiles (the scene's own
    Gaussians), and ``count`` counts the Gaussians of every level."""
    from csgs_codec.codec.encoder_checks import decodable_container

    encoder.progress("container", 0, 0)
    infos = [out.info for out in outputs]
    if links is not None:
        infos = [replace(info, level=level, parent=parent)
                 for info, (level, parent) in zip(infos, links)]
    index = TileIndex(tuple(infos))
    chunks = [Chunk("TIDX", "base", index.to_bytes())]
    for number, out in enumerate(outputs):
        chunks += [replace(c, tile=number) for c in out.chunks]
        if number == 0 and record is not None:
            chunks.append(record)
    stream_bytes: dict[str, int] = {}
    for c in chunks:
        stream_bytes[c.type] = stream_bytes.get(c.type, 0) + len(c.payload)
    data = decodable_container(chunks, count)
    full = [i for i, info in enumerate(infos) if info.level == 0]
    order = np.concatenate([jobs[i].rows[outputs[i].order] for i in full])
    kept = [outputs[i].reconstruction for i in full]
    reconstruction = None if any(r is None for r in kept) else GaussianScene.concatenate(kept)
    return EncodeReport(data=data, reconstruction=reconstruction, order=order,
                        stream_bytes=stream_bytes, tiles=len(outputs),
                        levels=index.levels)


def _run_tiles(encoder, jobs: list[TileJob]) -> list[TileOutput]:
    """Code ``jobs`` with ``encoder``'s workers (or Ray), telling its progress of the tiles."""
    encoder.progress("tiles", 0, 0)
    return run_jobs(encode_tile, jobs, workers=encoder.config.workers, ray=encoder.config.ray,
                    progress=partial(encoder.progress, "tiles"))


def encode_ply_tiled(encoder, path: str) -> object:
    """Encode the binary PLY at ``path`` tile by tile without loading it whole: positions
    are read from the memory-mapped body, each worker reads its tile's rows itself, and no
    reconstruction is kept (``reconstruction`` is None). The bytes are those of
    ``encoder.encode(read_ply(path))``. Only for a plain preset encode (no rate control,
    pruning or view pruning) of a scene the encoder tiles (more than its tile size).

    Raises:
        InputError: the file cannot be mapped or holds something the format cannot carry.
    """
    from csgs_codec.attributes.position_grid import PositionGrid
    from csgs_codec.codec.encoder_checks import check_count
    from csgs_codec.interchange.ply_mmap import MappedPly
    from csgs_codec.interchange.ply_reader import warn_unknown_properties

    ply = MappedPly(path)
    # Said here, once: the workers read their rows without it (as a whole read says it once).
    warn_unknown_properties(ply.properties, ply.path, stacklevel=3)
    settings = encoder.preset
    encoder.progress("geometry", 0, 0)
    positions = ply.positions()
    tile_size = effective_tile_size(len(positions), encoder.config.tile_size)
    if len(positions) <= tile_size:
        check_count(len(positions))
    grid = PositionGrid.fit(positions, settings.position_bits)
    jobs = plan_jobs(encoder, positions, grid, settings, tile_size,
                     hyperprior=encoder.config.fits_hyperprior, source=ply.path,
                     keep_reconstruction=False)
    del positions
    outputs = _run_tiles(encoder, jobs)
    return assemble(encoder, jobs, outputs, ply.count)
