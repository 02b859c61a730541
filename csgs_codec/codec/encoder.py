"""Encoder: a GaussianScene -> a layered .csgs bitstream (orchestration only).

Pipeline: validate -> optional pruning -> position grid (dense core) -> geometry (canonical
order) and far points coded apart (far_points.py) ->
attribute streams in that order -> chunks -> container. The encoder computes its own
reconstruction with exactly the integer arithmetic the decoder runs, so
``Decoder().decode(Encoder().encode(s))`` equals ``EncodeReport.reconstruction`` bit for bit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from csgs_codec.attributes.derived_steps import rotation_classes
from csgs_codec.attributes.float_stream import plan_float_stream
from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.attributes.sh_colour_transform import apply_inverse, choose_transforms
from csgs_codec.attributes.sh_colour_transform import forward as forward_colour_transform
from csgs_codec.attributes.streams import SceneStreams, join_streams, split_streams
from csgs_codec.chunks.color_prior import prior_cells
from csgs_codec.chunks.color_streams import STREAM_CHUNKS, color_stream_payload
from csgs_codec.chunks.scene_header import SceneHeader
from csgs_codec.chunks.semantic import feature_payload, smallest_label_chunk
from csgs_codec.chunks.semantic_codebook import (
    codebook_of,
    instance_embeddings,
    write_codebook,
)
from csgs_codec.chunks.sh_colour_transform import colour_transform_payload
from csgs_codec.chunks.view_record import ViewRecord
from csgs_codec.codec.encode_report import EncodeReport
from csgs_codec.codec.encoder_checks import check_count, check_encodable, decodable_container
from csgs_codec.codec.encoder_config import EncoderConfig
from csgs_codec.codec.tiling import effective_tile_size
from csgs_codec.decisions.axis_order import sorted_axes_pay
from csgs_codec.decisions.color_prior_choice import (
    PriorChoice,
    choose_prior,
)
from csgs_codec.decisions.far_points import plan_far_points
from csgs_codec.decisions.presets import (
    Preset,
    preset,
    preset_steps,
    scaled_preset,
)
from csgs_codec.decisions.view_pruning import decide
from csgs_codec.entropy.geometry import canonical_order, encode_positions
from csgs_codec.errors import InputError, require_type
from csgs_codec.format import Chunk
from csgs_codec.format.primitives import ByteWriter
from csgs_codec.progress import announce, ignore_progress
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.scene.instance_table import InstanceTable

#: Scenes with fewer Gaussians are not view-pruned: the sensitivity pass is not worth it and
#: tiny test scenes stay whole.
MIN_PRUNED_SCENE = 1024


@dataclass
class CodedScene:
    """One scene or tile coded: its ``chunks`` (tile 0, in layer order), the
    ``reconstruction`` the decoder will output and ``order`` (N,) int64, the index of each
    decoded Gaussian in the coded scene; ``sorted_axes``: its axes coded largest scale
    first."""

    chunks: list[Chunk]
    reconstruction: GaussianScene
    order: np.ndarray
    sorted_axes: bool = False


#: The stages whose steps :attr:`Encoder.progress` is told of (the others only start).
COUNTED_STAGES = ("step allocation", "view sensitivity", "refinement", "color hyperprior",
                  "tiles")


class Encoder:
    """Encodes standard 3DGS scenes to .csgs.

    ``Encoder(config, progress=...)`` with an :class:`EncoderConfig`, or ``Encoder(**fields)``
    with its fields as keywords (``Encoder(7)`` is quality 7); ``encoder.config`` is the
    config either way. Encoders may run on several threads at once, each writing the bytes
    it writes alone. The fields:

    Args:
        quality: preset 1 (smallest) .. 12 (near-lossless); see
            csgs_codec/decisions/presets.py. Default 5.
        target_psnr: instead of the preset, the smallest encode whose renders reach this
            foreground PSNR (dB) on the rate control's probe views
            (:mod:`csgs_codec.decisions.rate_control`; several encodes and renders).
        lambda_: instead of a quality or target, the encode minimising J = D + lambda * R on
            the probe views: D the foreground MSE in squared 8-bit levels, R the file's bits
            per Gaussian (:func:`~csgs_codec.decisions.rate_control.lambda_search`).
        fast: no color hyperprior fit, and shorter searches: target PSNR with fewer trial
            encodes and a looser tolerance (the target is still met; the file may be
            larger), lambda with fewer encodes on half the probe views.
        hyperprior: fit the color layer's INR hyperprior (a few seconds; scenes of at
            least 8,192 Gaussians) and use it for the channels where it makes the file
            smaller. It changes the rate only: the decoded scene is the same either way.
        prior_fit: how that fit runs and when its network is kept
            (:class:`~csgs_codec.decisions.color_prior_choice.PriorFitPolicy`); the default
            is what the CLI uses. Shorter fits change the bytes, never the decoded scene.
        semantic: "auto" writes the semantic layer when the scene has semantic channels or
            labels; "none" never writes it.
        prune_opacity: drop Gaussians whose opacity sigmoid(logit) is below this (lossy,
            opt-in); None keeps every Gaussian.
        view_pruning: leave out the Gaussians that contribute least to renders over the
            viewing distribution, within a budget of the quantization's own error
            (:mod:`csgs_codec.decisions.view_pruning`; scenes of 1,024+ Gaussians, needs
            numba; lossy). None (default): on exactly when ``cameras`` are given (the views
            the scene will be seen from), as ``csgs encode`` does; True: also on the default
            sphere of views (``--view-prune``); False codes every Gaussian.
        cameras: the views the scene will be seen from (e.g. its capture cameras), or None
            for the default sphere of views around it
            (:func:`csgs_codec.render.view_distribution.default_distribution`).
        view_budget: the pruning budget, a fraction of the quantization's squared error on
            the views (default 0.1: at most about 0.4 dB).
        rotation_steps: how each Gaussian's rotation step follows its decoded attributes, at
            no per-Gaussian cost (FORMAT §12.8): ``"footprint"`` (default) by its area,
            opacity and anisotropy (scored steps: coarser where a rotation barely shows;
            :func:`csgs_codec.attributes.derived_steps.footprint_steps`; scenes of 4,096+
            Gaussians), ``"uniform"`` one step for every Gaussian.
        step_allocation: move each attribute group's step (DC, each SH band, opacity,
            scales, rotations) and the position grid's bits from the preset's, per scene,
            where probe renders say the file gets smaller at equal quality
            (:mod:`csgs_codec.decisions.step_allocation`; quality encodes of scenes of 1,024+
            Gaussians in one tile, not in fast mode). None (default): for scenes that code
            SH bands (three SH-3 captures, qualities 2-9: 0.81-0.99x the preset's bytes at
            equal held-out PSNR at every preset, 16 of the 24 by a coarser grid alone; four
            SH-0 scenes 0.97-1.00x on average for seconds of probing); True: for every
            scene; False: never. The preset's error bounds (:mod:`csgs_codec.decisions.presets`)
            hold for the steps actually used (``EncodeReport.allocation``).
        refine: Adam steps that move each coded value to the lattice point whose decoded
            scene renders closest to the original over the viewing distribution (``cameras``
            or the default sphere; :mod:`csgs_codec.decisions.refinement`). Same format and
            decoder, lower render error at about the same size; seconds to minutes on a
            CPU. 0 (default) codes each value at its nearest lattice point. Scenes of one
            tile.
        tile_size: split the scene into spatial tiles of at most this many Gaussians
            (k-d cells, :mod:`csgs_codec.codec.tiling`), each coded on its own; None
            (default) tiles only scenes of more than 2,000,000 Gaussians, into tiles of at
            most 1,000,000. A scene that fits one tile is written exactly as without tiles.
            A scene it would tile is refused (InputError, when encoding) below a tile size
            of 1,000, or of a 16th of a scene under 16,000 Gaussians, or when it makes more
            than 4,095 tiles (:func:`csgs_codec.codec.tiling.check_tiling`).
        workers: local processes coding tiles side by side (default 1: in this process).
            The file is the same for any count.
        ray: the address of a Ray cluster whose workers code the tiles instead
            (``"local"`` starts one on this machine; needs ``pip install ray``); the file is
            the same as with local workers.
        levels: levels of detail (default 1: none). With L > 1 the file also holds L - 1
            coarser versions of the scene, each about 1/8 of the Gaussians of the one below
            (neighbours merged), in tiles of their own that a viewer fetches first
            (:mod:`csgs_codec.codec.level_encoder`; FORMAT §12.22); the scene is cut into
            tiles of ``tile_size``, default 65,536. The decoder outputs level 0, the scene,
            unless asked for another (``Decoder.decode(..., lod=k)``).
        progress: not a config field: ``progress(stage, done, total)``, told when a stage
            starts (``done == total == 0``) and of the steps of the stages that count
            them (:data:`COUNTED_STAGES`: hyperprior fit steps, views, tiles, refinement
            steps, allocation probes), or None.
    """

    def __init__(self, config: EncoderConfig | int | None = None, *, progress=None,
                 **fields) -> None:
        if isinstance(config, EncoderConfig):
            base = config
        else:
            base = EncoderConfig()
            if config is not None:
                fields = {"quality": config, **fields}
        unknown = set(fields) - EncoderConfig.field_names()
        if unknown:
            raise InputError(f"unknown encoder setting(s) {sorted(unknown)}; the settings are "
                             f"the fields of EncoderConfig", property=sorted(unknown)[0])
        self.config: EncoderConfig = replace(base, **fields) if fields else base
        #: The steps the encode starts from (the config's quality); experiments may set a
        #: :class:`Preset` of their own here.
        self.preset: Preset = preset(self.config.effective_quality)
        self.progress = progress or ignore_progress
        self._sensitivity = None  # (W (N,) of the scene being encoded, ViewDistribution)

    def _stage(self, name: str) -> None:
        """Tell :attr:`progress` that stage ``name`` starts."""
        self.progress(name, 0, 0)

    def _steps(self, stage: str):
        """A ``(done, total)`` callback that tells :attr:`progress` of ``stage``'s steps."""
        return partial(self.progress, stage)

    def encode(self, scene: GaussianScene) -> bytes:
        """The .csgs bytes of ``scene``."""
        return self.encode_with_report(scene).data

    def encode_with_report(self, scene: GaussianScene) -> EncodeReport:
        """Encode ``scene`` and report the reconstruction, order and bytes per chunk.

        ``report.order`` (M,) int64 gives, for each decoded Gaussian, the row of ``scene`` it
        came from (pruned Gaussians appear nowhere): per-Gaussian data kept beside the scene,
        ``extra`` (N, ...), lines up with the decoded scene as ``extra[report.order]``."""
        start = time.perf_counter()
        require_type(scene, GaussianScene, "scene",
                     "read a file with csgs_codec.codec.files.read_scene(path) first")
        scene.validate()
        # What the format cannot carry is refused here, before any coding.
        check_encodable(scene, semantic=self.config.semantic != "none")
        pruned, kept = 0, None
        if self.config.prune_opacity is not None and len(scene):
            with np.errstate(over="ignore"):  # exp(-logit) is inf below -709: alpha 0
                alpha = 1.0 / (1.0 + np.exp(-scene.opacity.astype(np.float64)))
            keep = alpha >= self.config.prune_opacity
            pruned = int((~keep).sum())
            original, scene = scene, scene.subset(keep)
            kept = np.flatnonzero(keep)
        else:
            original = scene
        if len(scene) <= effective_tile_size(len(scene), self.config.leaf_tile_size):
            check_count(len(scene))  # a tiled scene's limit is per tile
        self._sensitivity = self._render_sensitivity(scene)
        if (self.config.target_psnr is None and self.config.lambda_ is None) or not len(original):
            allocation = self._allocate(scene)
            settings = self.preset if allocation is None else allocation.apply(self.preset)
            result = self._encode(scene, settings)
            result.allocation = allocation
        else:
            result = self._search(scene, original)
        result.pruned = pruned
        if kept is not None:  # the order indexes the scene given, not the pruned one
            result.order = kept[result.order]
        result.seconds = time.perf_counter() - start
        return result

    def _allocate(self, scene: GaussianScene):
        """The :class:`StepAllocation` of ``scene`` around the preset, or None when the
        allocation is off or the scene too small for it."""
        from csgs_codec.decisions.step_allocation import MIN_GAUSSIANS, allocate_steps

        # A tiled scene keeps the preset: its streamed encode (csgs encode of a large binary
        # PLY) never holds the whole scene, and must write what a whole read writes.
        if (self.config.fast or self.config.step_allocation is False or len(scene) < MIN_GAUSSIANS
                or self.config.levels > 1
                or len(scene) > effective_tile_size(len(scene), self.config.tile_size)
                or (self.config.step_allocation is None and not scene.sh_degree_in_use())):
            return None
        self._stage("step allocation")
        return allocate_steps(scene, self.preset, rotation_rule=self.config.rotation_steps,
                              cameras=self.config.cameras, progress=self._steps("step allocation"))

    def _render_sensitivity(self, scene: GaussianScene):
        """(color sensitivity W (N,), its ViewDistribution) of ``scene``, or None when view
        pruning is off or the scene is too small for it."""
        if not self.config.prunes_views or len(scene) < MIN_PRUNED_SCENE:
            return None
        from csgs_codec.render.sensitivity import blend_sensitivity

        self._stage("view sensitivity")
        views = self._viewing_distribution(scene)
        weights = blend_sensitivity(scene, views.cameras, self._steps("view sensitivity"))
        return weights.weight_sq, views

    def _viewing_distribution(self, scene: GaussianScene):
        """The ViewDistribution ``scene`` is seen from: the encoder's cameras, or the
        default sphere of views around it."""
        from csgs_codec.render.view_distribution import (
            camera_distribution,
            default_distribution,
        )

        return (default_distribution(scene) if self.config.cameras is None
                else camera_distribution(self.config.cameras, "the given cameras"))

    def _search(self, scene: GaussianScene, original: GaussianScene) -> EncodeReport:
        """The target-PSNR or lambda search over the step multiplier (rate_control.py),
        scored on probe renders of ``original``; the report goes to ``rate_control``."""
        from csgs_codec.decisions import rate_control as rc

        self._stage("rate control")
        # A target is a promise about the probe views, so only the lambda search (a trade
        # between rate and distortion anyway) scores on fewer views in fast mode.
        fewer_views = self.config.fast and self.config.lambda_ is not None
        probe = (rc.RenderProbe(original, views=rc.FAST_PROBE_VIEWS) if fewer_views
                 else rc.RenderProbe(original))

        told = partial(announce, self.progress)  # each trial's message, as a stage
        if self.config.lambda_ is not None:
            steps = rc.FAST_LAMBDA_STEPS if self.config.fast else rc.LAMBDA_STEPS
            search = rc.lambda_search(scene, self.config.lambda_, probe=probe, progress=told,
                                      steps=steps)
        else:
            limits = ({"search_steps": rc.FAST_SEARCH_STEPS, "tolerance": rc.FAST_TOLERANCE}
                      if self.config.fast else {})
            search = rc.target_search(scene, self.config.target_psnr, probe=probe, progress=told,
                                      **limits)
        # The hyperprior changes the rate only, so the search (which scores renders) runs
        # without its fit; the kept settings are encoded once more with it below.
        settings = next(search)
        while True:
            try:
                settings = search.send(self._encode(scene, settings, hyperprior=False,
                                                    refine=False))
            except StopIteration as done:
                result, report = done.value
                break
        kept = self.config.refine > 0
        if self.config.refine:
            # Refinement lowers the render error at about the same size; the searched
            # encode stays when the refined one renders worse on the probe views (a target
            # missed, or a lambda search's distortion raised).
            self._stage("final encode")
            final = self._encode(scene, scaled_preset(report.multiplier))
            refined_psnr = probe.psnr(final.reconstruction)
            floor = (self.config.target_psnr if self.config.lambda_ is None
                     else probe.psnr(result.reconstruction))
            kept = refined_psnr >= floor
            if kept:
                result = final
                if self.config.lambda_ is None:
                    report = replace(report, psnr=refined_psnr)
        if self.config.fits_hyperprior and not kept:
            # The hyperprior changes the rate only: the search's settings coded with it.
            self._stage("final encode")
            final = self._encode(scene, scaled_preset(report.multiplier), refine=False)
            if len(final.data) < len(result.data):
                result = final
        result.rate_control = report
        return result

    def _encode(self, scene: GaussianScene, settings: Preset, *,
                hyperprior: bool | None = None, refine: bool = True) -> EncodeReport:
        """Encode a validated scene with ``settings``, leaving out the Gaussians view pruning
        removes (``order`` indexes ``scene``; see :meth:`_encode_all` for the rest)."""
        if self._sensitivity is None:
            return self._encode_all(scene, settings, hyperprior=hyperprior, refine=refine)
        weights, views = self._sensitivity
        trial = self._encode_all(scene, settings, hyperprior=False)
        self._stage("view pruning")
        in_input_order = trial.reconstruction.subset(np.argsort(trial.order, kind="stable"))
        decision = decide(scene, in_input_order, weights, views.cameras, self.config.view_budget)
        record = ViewRecord(views.source, len(views.cameras), decision.dropped,
                            views.description)
        kept = np.flatnonzero(decision.keep)
        result = self._encode_all(scene.subset(decision.keep), settings, hyperprior=hyperprior,
                                  record=Chunk("vdis", "base", record.to_bytes()),
                                  refine=refine)
        result.order = kept[result.order]
        result.view_pruned = decision.dropped
        result.views = views.description
        return result

    def _encode_all(self, scene: GaussianScene, settings: Preset, *,
                    hyperprior: bool | None = None, record: Chunk | None = None,
                    refine: bool = True) -> EncodeReport:
        """Encode every Gaussian of a validated (and pruned) scene with ``settings`` (and
        the color hyperprior when ``hyperprior``, default: the encoder's setting);
        ``record`` (a ``vdis`` chunk) ends the base layer when given; ``refine``: run the
        encoder's refinement steps. A scene of more than the tile size is split into spatial
        tiles (:mod:`csgs_codec.codec.tile_encoder`)."""
        start = time.perf_counter()
        self._stage("geometry")
        grid = PositionGrid.fit(scene.positions, settings.position_bits)
        tile_size = effective_tile_size(len(scene), self.config.leaf_tile_size)
        if self.config.levels > 1:
            from csgs_codec.codec.level_encoder import encode_levels

            result = encode_levels(self, scene, grid, settings, tile_size, self.config.levels,
                                   hyperprior=hyperprior, record=record)
        elif len(scene) > tile_size:
            from csgs_codec.codec.tile_encoder import encode_tiled

            if self.config.refine:
                raise InputError(f"refinement works on scenes of one tile: this one has "
                                 f"{len(scene):,} Gaussians, more than the tile size "
                                 f"{tile_size:,}", property="refine")

            result = encode_tiled(self, scene, grid, settings, tile_size,
                                  hyperprior=hyperprior, record=record)
        else:
            cells, inside = grid.quantize(scene.positions)
            coded = self.code_scene(scene, settings, grid, cells, inside,
                                    hyperprior=hyperprior, record=record,
                                    refine=refine and self.config.refine > 0)
            self._stage("container")
            data = decodable_container(coded.chunks, len(scene))
            result = EncodeReport(data=data, reconstruction=coded.reconstruction,
                                  order=coded.order,
                                  stream_bytes={c.type: len(c.payload) for c in coded.chunks},
                                  sorted_axes=coded.sorted_axes)
        result.seconds = time.perf_counter() - start
        return result

    def code_scene(self, scene: GaussianScene, settings: Preset, grid: PositionGrid,
                   cells: np.ndarray, inside: np.ndarray, *, hyperprior: bool | None = None,
                   record: Chunk | None = None, refine: bool = False) -> CodedScene:
        """The chunks (tile 0) of one scene or tile whose points sit at ``cells`` (N, 3)
        int64 on ``grid``, ``inside`` (N,) bool marking those inside it (the others are far
        points), with its reconstruction and order; ``refine``: run the encoder's
        refinement steps on the color streams first."""
        inside_idx = np.flatnonzero(inside)
        far = plan_far_points(scene.positions, np.flatnonzero(~inside), grid,
                              settings.position_bits)
        perm = canonical_order(cells[inside_idx], grid.bits)
        order = np.concatenate([inside_idx[perm], far.order]).astype(np.int64)
        geometry = encode_positions(cells[inside_idx], grid.bits)
        positions = np.concatenate([grid.dequantize(cells[inside_idx][perm]),
                                    far.positions]).astype(np.float32)
        far_count = len(far.order)
        ordered = scene.subset(order)

        sorted_axes = sorted_axes_pay(ordered, self.preset)
        streams = split_streams(ordered, sorted_axes)
        header = SceneHeader(
            count=len(ordered), sh_degree_stored=streams.sh_degree_stored,
            sh_degree_coded=sum(1 for k in streams.float_streams if k.startswith("rest")),
            quality=settings.quality, grid_origin=grid.origin, grid_cell=grid.cell,
            grid_bits=grid.bits, far_count=far_count)
        chunks = [Chunk("SCNE", "base", header.to_bytes()), Chunk("GEOM", "base", geometry),
                  *far.chunks, *([record] if record is not None else [])]

        self._stage("color")
        use_prior = self.config.fits_hyperprior if hyperprior is None else hyperprior
        cells_in_order = (prior_cells(cells[inside_idx][perm], far_count) if use_prior
                          else None)
        plans = self._plan_color(streams.float_streams, settings)
        transforms, sh_plans = choose_transforms(plans, streams.float_streams,
                                                 preset_steps(settings))
        plans.update(sh_plans)
        if refine:  # refinement moves the values in the space they are coded in
            for name in sh_plans:
                streams.float_streams[name] = forward_colour_transform(
                    streams.float_streams[name])
            plans = self._refined_plans(ordered, streams, plans, positions, settings,
                                        transforms)
        decoded_streams = self._color_chunks(streams, plans, chunks, cells_in_order,
                                              max(grid.bits, 1), transforms)
        reconstruction = join_streams(decoded_streams, positions)

        if self.config.semantic == "auto" and (ordered.semantic is not None or
                                        ordered.labels is not None):
            self._stage("semantic")
            self._semantic_chunks(ordered, reconstruction, chunks, settings)
        return CodedScene(chunks, reconstruction, order, sorted_axes)

    # ------------------------------------------------------------------ layers
    def _plan_color(self, values: dict[str, np.ndarray], p: Preset,
                     lattices: dict | None = None) -> dict:
        """The plan of each color stream (name -> StreamPlan) of coding-form ``values``
        with the steps of ``p``; ``lattices`` (name -> Lattice) fixes where a stream's
        values may land (refinement)."""
        steps = preset_steps(p)
        plans = {}
        lattices = lattices or {}
        for name, stream in values.items():
            # A lattice comes from a plan with one step, which it keeps.
            derive = (self._rotation_classes(plans) if name == "rot" and name not in lattices
                      else None)
            plans[name] = plan_float_stream(stream, steps[name], derive, lattices.get(name))
        return plans

    def _rotation_classes(self, plans: dict):
        """What makes the rotation stream's step classes from the planned scales and
        opacities (``derive`` of :func:`plan_float_stream`), or None for one step."""
        return rotation_classes(self.config.rotation_steps, plans["scale"].recon,
                                plans["opacity"].recon)

    def _refined_plans(self, ordered: GaussianScene, streams: SceneStreams, plans: dict,
                       positions: np.ndarray, p: Preset,
                       transforms: tuple[int, ...] = ()) -> dict:
        """The color plans after refinement (:mod:`csgs_codec.decisions.refinement`): the
        refined values planned on the lattices of ``plans``. ``streams`` (the SH bands
        ``transforms`` marks opponent in opponent colours) is updated in place to the
        refined values."""
        from csgs_codec.decisions.refinement import RefineSettings, refine_streams

        self._stage("refinement")
        views = self._viewing_distribution(ordered)
        target = {"log_scales": ordered.scales, "opacity_logits": ordered.opacity,
                  "quats": ordered.rotations}
        target_sh = np.concatenate([ordered.sh_dc[:, None, :], ordered.sh_rest], axis=1)
        refined = refine_streams(streams, plans, positions, target_sh, target, views.cameras,
                                 RefineSettings(steps=self.config.refine),
                                 self._steps("refinement"), transforms)
        if not refined:
            return plans
        streams.float_streams.update(refined)
        return self._plan_color(streams.float_streams, p,
                                 {name: plans[name].lattice() for name in refined})

    def _color_chunks(self, streams: SceneStreams, plans: dict, chunks: list[Chunk],
                       cells: np.ndarray | None, pos_bits: int,
                       transforms: tuple[int, ...] = ()) -> SceneStreams:
        """Append the color layer of planned ``streams`` (CHYP when the hyperprior pays,
        SHXF when a band is colour-transformed, then one chunk per stream); ``cells`` (N, 3)
        are the hyperprior's inputs, None to skip it; ``transforms`` one id per SH band."""
        choice = PriorChoice()
        if cells is not None:
            self._stage("color hyperprior")
            choice = choose_prior(plans, cells, pos_bits, self._steps("color hyperprior"),
                                  self.config.prior_fit)
        if choice.payload is not None:
            chunks.append(Chunk("CHYP", "color", choice.payload))
        if any(transforms):
            chunks.append(Chunk("SHXF", "color", colour_transform_payload(transforms)))
        for name, plan in plans.items():
            chunks.append(Chunk(STREAM_CHUNKS[name], "color", color_stream_payload(
                name, plan, choice.channels.get(name), streams.rot_axis)))
        decoded = {name: plan.recon for name, plan in plans.items()}
        apply_inverse(decoded, transforms)
        return SceneStreams(decoded, streams.rot_axis.copy(), streams.sh_degree_stored)

    def _semantic_chunks(self, ordered: GaussianScene, reconstruction: GaussianScene,
                         chunks: list[Chunk], settings: Preset) -> None:
        instances = None  # (ids, K) of the SEMC written, which SEMR may map to labels
        if ordered.semantic is not None:
            payload, reconstruction.semantic = feature_payload(
                ordered.semantic_names, ordered.semantic, settings.semantic_step)
            reconstruction.semantic_names = ordered.semantic_names
            chunk = Chunk("SEMF", "semantic", payload)
            codebook = codebook_of(ordered.semantic)
            embeddings = instance_embeddings(ordered, codebook)
            if codebook is not None:
                # Few distinct feature rows (segmented scenes): exact, and kept when smaller
                # (always when it carries the instances' embeddings, which SEMF cannot).
                exact = ByteWriter()
                stored = write_codebook(exact, ordered.semantic_names, *codebook, embeddings)
                if embeddings is not None or len(exact) <= len(chunk.payload):
                    chunk = Chunk("SEMC", "semantic", exact.getvalue())
                    reconstruction.semantic = ordered.semantic.astype(np.float32, copy=True)
                    reconstruction.instances = (None if stored is None
                                                else InstanceTable(codebook[0], stored))
                    instances = (codebook[1], len(codebook[0]))
            chunks.append(chunk)
        if ordered.labels is not None:
            reconstruction.labels = ordered.labels.copy()
            code, payload = smallest_label_chunk(ordered.labels, instances)
            chunks.append(Chunk(code, "semantic", payload))


