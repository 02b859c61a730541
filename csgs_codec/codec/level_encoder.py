"""Coding a scene with levels of detail (FORMAT §12.22, tile index version 2).

The scene's own Gaussians are level 0, cut into the leaves of a :class:`LevelTree`; every
coarser level merges groups of about 8 Gaussians of the level below, within each of its
tiles (:mod:`csgs_codec.levels`). Every tile of every level is then coded as a tile of a
tiled scene (:func:`~csgs_codec.codec.tile_encoder.encode_tile`: its own geometry, priors
and streams, decodable alone), level l on the whole scene's grid with cells 2**l times as
wide and with colour, opacity, scale and rotation steps 2**l times the preset's (its
Gaussians are about 2**l times as large and seen from 2**l times as far: on the sample,
level 1's and 2's bytes fell 16% for at most 0.04 dB at the screen sizes the page draws them
at). Level 0's tiles code exactly as in a file of the same tiles without levels.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.codec.level_tree import LevelTree
from csgs_codec.codec.tile_encoder import TileJob, _run_tiles, assemble
from csgs_codec.codec.tiling import check_tiling
from csgs_codec.decisions.presets import Preset
from csgs_codec.format import Chunk
from csgs_codec.levels.groups import GROUP_SIZE, group_ids
from csgs_codec.levels.merge import merge_groups
from csgs_codec.scene.gaussian_scene import GaussianScene


def level_scenes(scene: GaussianScene, tree: LevelTree,
                 visibility: np.ndarray | None = None) -> list[list[GaussianScene]]:
    """Per level (0 first), the scenes of its tiles in node order: level 0 the scene's own
    Gaussians per leaf, each coarser level the one below merged in groups of
    :data:`GROUP_SIZE` within each of its tiles, colours weighted by ``visibility`` (N,)
    (see :func:`~csgs_codec.levels.merge.merge_groups`) when given."""
    levels = [[scene.subset(rows) for rows in tree.leaves]]
    seen = None if visibility is None else np.concatenate(
        [np.asarray(visibility)[rows] for rows in tree.leaves])
    for level in range(1, tree.levels):
        below = levels[-1]
        owner = tree.children(level)
        whole = GaussianScene.concatenate(below)
        segments = np.repeat(owner, [len(s) for s in below])
        groups = group_ids(whole.positions, segments, GROUP_SIZE)
        merged, seen = merge_groups(whole, groups, seen)
        # groups are numbered node by node: each node's merged Gaussians are one run
        per_node = np.bincount(segments[np.unique(groups, return_index=True)[1]],
                               minlength=tree.node_count(level))
        bounds = np.r_[0, np.cumsum(per_node)]
        levels.append([merged.subset(np.arange(bounds[j], bounds[j + 1]))
                       for j in range(tree.node_count(level))])
    return levels


#: Views the visibility of a scene's Gaussians is measured in when the encoder has no
#: cameras: orbits at two elevations, this many each, small (only shares of views count).
VISIBILITY_VIEWS = 8
#: Their width in pixels (height 3/4 of it).
VISIBILITY_WIDTH = 200


def scene_visibility(scene: GaussianScene, cameras=None) -> np.ndarray | None:
    """(N,) each Gaussian's blending weights summed over ``cameras`` (a list of
    :class:`~csgs_codec.scene.camera.Camera`), or without cameras over orbits at 20 and 60
    degrees of elevation (:data:`VISIBILITY_VIEWS` each); None where the renderer cannot run
    (numba not installed: colours then merge by footprint alone)."""
    from csgs_codec.render.numba_loader import numba_available

    if not len(scene) or not numba_available():
        return None
    from csgs_codec.render.sensitivity import blend_sensitivity
    from csgs_codec.scene.orbit import orbit_cameras

    views = list(cameras) if cameras else [
        camera for elevation in (20.0, 60.0)
        for camera in orbit_cameras(scene, VISIBILITY_VIEWS, width=VISIBILITY_WIDTH,
                                    height=VISIBILITY_WIDTH * 3 // 4, elevation_deg=elevation)]
    return blend_sensitivity(scene, views).weight_sum


def level_settings(settings: Preset, level: int) -> Preset:
    """The steps level ``level``'s tiles are coded with: ``settings``' colour, opacity, scale
    and rotation steps times 2**level (semantic steps kept)."""
    f = float(1 << level)
    return replace(settings, dc_step=settings.dc_step * f, rest_step=settings.rest_step * f,
                   opacity_step=settings.opacity_step * f, scale_step=settings.scale_step * f,
                   rotation_step=settings.rotation_step * f)


def level_grid(grid: PositionGrid, level: int) -> PositionGrid:
    """The grid level ``level``'s tiles are coded on: ``grid`` with cells 2**level wide."""
    return PositionGrid(grid.origin, grid.cell * (1 << level), grid.bits)


def encode_levels(encoder, scene: GaussianScene, grid: PositionGrid, settings: Preset,
                  tile_size: int, levels: int, *, hyperprior: bool | None = None,
                  record: Chunk | None = None):
    """Encode ``scene`` (validated) with ``levels`` levels of detail, leaves of at most
    ``tile_size`` Gaussians, with the ``encoder``'s settings; returns its
    :class:`~csgs_codec.codec.encoder.EncodeReport` (reconstruction and order: level 0's).
    ``record`` (a ``vdis`` chunk) goes into tile 0."""
    check_tiling(len(scene), tile_size)
    encoder.progress("levels", 0, 0)
    tree = LevelTree.build(scene.positions, tile_size, levels)
    scenes = level_scenes(scene, tree, scene_visibility(scene, encoder.config.cameras))
    use_prior = encoder.config.fits_hyperprior if hyperprior is None else hyperprior
    config = replace(encoder.config, hyperprior=use_prior, tile_size=None, workers=1,
                     ray=None, view_pruning=False, cameras=None, levels=1)
    jobs, links = [], []
    for level in reversed(range(levels)):
        level_rows = tree.leaves if level == 0 else [
            np.arange(len(s), dtype=np.int64) for s in scenes[level]]
        for node, (part, rows) in enumerate(zip(scenes[level], level_rows)):
            jobs.append(TileJob(part, None, rows, level_grid(grid, level),
                                level_settings(settings, level), config, type(encoder)))
            links.append((level, tree.parent(level, node)))
    outputs = _run_tiles(encoder, jobs)
    total = sum(len(job.scene) for job in jobs)
    return assemble(encoder, jobs, outputs, total, record, links)
