"""Per-scene step allocation: how finely each attribute of a standard scene is coded.

A quality preset fixes one ratio between the steps of positions, DC colour, each SH band,
opacity, scales and rotations. What a step is worth to the picture depends on the scene: on
full-precision SH-3 captures the ladder over-codes the higher SH bands and under-codes the
rotations or the scales, by a different amount on each capture (benchmarks/step_allocation.py).
The encoder therefore moves each group's step from the preset in half-octave steps (positions
in whole grid bits) to minimise the Lagrangian cost

    J = D + lambda * R,

D the foreground mean squared error of probe renders of the coded scene against the original
(squared 8-bit levels, :class:`csgs_codec.decisions.rate_control.RenderProbe`'s measure, on
12 small views of the viewing distribution, :func:`probe_cameras`), R the planned bits of
every stream (each stream's own plan, before the hyperprior:
:func:`csgs_codec.attributes.float_stream.plan_float_stream`, and the octree's bytes for
positions), and lambda the slope of the preset's own ladder at the
preset (:func:`ladder_slope`: every step moved together up to an octave either way). The
descent sets the ratio between the steps; every step then moves together back to the
preset's probe error (:func:`_recentre`), so a quality keeps its level with fewer bits.

Everything chosen here is the encoder's decision: each stream's record carries its step and
the grid header its bits, so the format and the decoder do not change. Scenes over
:data:`SAMPLE` Gaussians are probed on a fixed random subset of that many.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from csgs_codec.attributes.derived_steps import rotation_classes
from csgs_codec.attributes.float_stream import plan_float_stream
from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.attributes.streams import SceneStreams, join_streams, split_streams
from csgs_codec.decisions.axis_order import sorted_axes_pay
from csgs_codec.decisions.presets import Preset, preset_steps
from csgs_codec.entropy.geometry import encode_positions
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Groups whose step the allocation moves (float stream names, and the position grid).
GROUPS = ("dc", "rest1", "rest2", "rest3", "opacity", "scale", "rot", "position")
#: A group's step moves by at most this many half octaves from the preset's (3 octaves);
#: the grid by at most this many bits (fruit_drops took all 4 of an earlier bound at every
#: quality and 5 at qualities 6-8 once it could, at 0.86-0.92x the presets' bytes there
#: against 0.89-0.93x).
MAX_OFFSET = 6
MAX_BIT_OFFSET = 6
#: Coordinate-descent passes over the groups.
PASSES = 2
#: The allocation is kept only when it plans at least this share fewer bits than the preset
#: at the preset's probe error (:func:`_rate_at_error`). With the whole-view probe the
#: estimate tracks the held-out views at the near-lossless end, where the savings are small:
#: on the three SH-3 captures at qualities 9-11 the five allocations estimated at 0.93-0.97x
#: whose points lie inside the presets' curve came out at 0.93-0.99x the presets' bytes at
#: equal held-out PSNR (the 8% this was with the window probe threw them away, and the grid
#: alone gave 0.96-0.99x there); the one estimated at 0.99x (yashica_t4_top8192, quality 11)
#: coded a point above the curve about 2% larger than the slope there predicts.
MIN_SAVING = 0.03
#: At most this many half-octave shifts of every step together bring the probe error back
#: to the preset's (:func:`_recentre`).
RECENTRE_STEPS = 4
#: Scenes below this count keep the preset (the probe costs more than it can save there).
MIN_GAUSSIANS = 1024
#: Scenes above this count are probed on a fixed random subset of this many Gaussians.
SAMPLE = 32_768
#: Probe views: 12 directions on the viewing distribution's sphere at its framing distance,
#: each the whole view at a quarter of its width and height (a 16th of its pixels). Whole
#: views see what the held-out views see: with windows of a sixth of each view around its
#: centre at full size (the probe until 2026-11-28) the allocation saw a rotation step
#: halved on leica_sofort_top8192 at quality 7 as +0.8-1.2 dB where 28 held-out 800x600
#: views saw +2.5 dB (whole views at 200x150: +1.8 dB), kept few allocations, and coded
#: the three SH-3 captures at 0.89-0.95x the presets' bytes at equal held-out PSNR (mean of
#: q1-11); whole views 0.84-0.88x. Scenes whose median Gaussian would span under
#: :data:`PROBE_MIN_SIGMA` probe pixels are probed at a finer scale, cropped to the same
#: number of pixels (:func:`probe_scale`): at 200x150 a probe did not see Gaussians a
#: tenth of a view pixel wide and coarsened their steps by 3 octaves (-3.5 dB held out).
#: Scenes over :data:`SAMPLE` Gaussians keep the windows: whole views of a 13% sample of
#: playbot (248k Gaussians, holes between them) chose allocations that coded it at 0.96x
#: the bytes 1.0 dB lower at quality 3 and 1.05x 0.3 dB lower at quality 5.
PROBE_DIRECTIONS = 12
PROBE_DISTANCES = (1.0,)
PROBE_SCALE = 4
PROBE_MIN_SIGMA = 0.2
PROBE_WINDOW = 6
PROBE_VIEWS = 12
#: Each probe window renders only the Gaussians that can reach it: those whose footprint, a
#: sphere as wide as the Gaussian's longest axis (a coarse rotation step may turn that axis
#: anywhere) grown by this factor and by :data:`REACH_OPACITY` in opacity logit, meets the
#: window grown by :data:`REACH_PIXELS` on each side, in the original scene. A candidate's
#: steps move a Gaussian by a fraction of its own size, so the windows render
#: as they would with every Gaussian (checked in tests/codec/test_step_allocation.py) without
#: projecting the rest of the scene for every candidate (15% off the allocation's time on
#: 5-10k Gaussians, where the compositing itself dominates).
REACH_SCALE = 2.0
REACH_OPACITY = 2.0
REACH_PIXELS = 16
#: Groups whose steps move Gaussians, their shapes or opacities; the others (colour) leave
#: every probe pixel's blending weights as they are. A candidate that differs from an
#: earlier one in colour steps alone has its probe views recoloured from the earlier one's
#: recorded weights (:mod:`csgs_codec.render.blend_record`: the same images bit for bit, in
#: a fifth of the time), which the descent's colour groups (dc, rest1-3: about 40% of the
#: trials) do.
GEOMETRY_GROUPS = ("opacity", "scale", "rot", "position")
#: Recording stops when a view walks more tile slots than this less the pairs the views
#: before it kept (8 bytes a slot while recording one view, 8 bytes a pair kept; a pixel
#: blends about 40% of the slots it walks on real captures' probe views).
MAX_RECORDED_SLOTS = 40_000_000


@dataclass(frozen=True)
class StepAllocation:
    """The allocation the encoder chose for one scene.

    Attributes:
        offsets: group name -> half octaves its step moved from the preset's (positive:
            coarser); ``"position"`` -> grid bits added (negative: fewer bits). Groups the
            scene does not code are absent; empty when the preset's steps were kept (a
            small scene, or a saving under :data:`MIN_SAVING` and no coarser grid that
            lowers the cost on its own), ``{"position": -k}`` alone when only the grid
            moved.
        lambda_: the ladder's slope the cost used, squared 8-bit levels per planned bit.
        trials: probe renders made (one per candidate allocation).
        cost_ratio: J of the chosen allocation over J of the preset.
        rate_ratio: planned bits of the allocation the search found over the preset's, at
            a probe error no higher than the preset's (unless every step is already at its
            finest allowed move); above 1 - :data:`MIN_SAVING` the preset's steps were
            kept (and this is the planned bits of the coarser grid, when one was).
    """

    offsets: dict[str, int] = field(default_factory=dict)
    lambda_: float = 0.0
    trials: int = 0
    cost_ratio: float = 1.0
    rate_ratio: float = 1.0

    def apply(self, preset: Preset) -> Preset:
        """``preset`` with this allocation's steps and grid bits."""
        def factor(name: str) -> float:
            return 2.0 ** (self.offsets.get(name, 0) / 2.0)

        return replace(
            preset,
            position_bits=int(np.clip(preset.position_bits + self.offsets.get("position", 0),
                                      1, 21)),
            dc_step=preset.dc_step * factor("dc"),
            rest_band_factors=tuple(preset.rest_band_factors[b] * factor(f"rest{b + 1}")
                                    for b in range(3)),
            opacity_step=preset.opacity_step * factor("opacity"),
            scale_step=preset.scale_step * factor("scale"),
            rotation_step=preset.rotation_step * factor("rot"))

    def summary(self) -> str:
        """One line for a user: which steps moved."""
        moved = [f"{name} {'+' if v > 0 else ''}{v}{' bits' if name == 'position' else '/2 oct'}"
                 for name, v in self.offsets.items() if v]
        if list(self.offsets) == ["position"]:
            return (f"the preset's steps on a grid {-self.offsets['position']} bits coarser "
                    f"(planned {self.rate_ratio:.2f}x the preset's bits)")
        if moved:
            return (f"steps moved from the preset: {', '.join(moved)} (planned "
                    f"{self.rate_ratio:.2f}x the preset's bits at its probe error)")
        if self.trials and self.rate_ratio > 1.0 - MIN_SAVING:
            return (f"steps as the preset has them (the best allocation found planned "
                    f"{self.rate_ratio:.2f}x its bits, a saving the probe cannot resolve)")
        return "steps as the preset has them"


class _Probe:
    """Planned bits and probe-render error of candidate allocations of one scene."""

    def __init__(self, scene: GaussianScene, preset: Preset, rotation_rule: str,
                 cameras: list) -> None:
        from csgs_codec.metrics.comparison import render_references, to_unit_range
        from csgs_codec.metrics.image import foreground_mask

        self.scene = scene
        self.preset = preset
        self.rotation_rule = rotation_rule
        self.cameras = cameras
        self.streams: SceneStreams = split_streams(scene, sorted_axes_pay(scene, preset))
        self.steps = preset_steps(preset)
        from csgs_codec.render.rasterizer import scene_tensors

        self._tensors = scene_tensors(scene)
        self.reach = [window_reach(self._tensors, cam) for cam in cameras]
        self._grid_reach: dict[int, list[np.ndarray]] = {}
        refs = render_references(scene, cameras, backend="auto")
        self.masks = [foreground_mask(r.alpha) for r in refs]
        self.references = [to_unit_range(r.image)[m].astype(np.float64)
                           for r, m in zip(refs, self.masks)]
        self._plans: dict = {}
        self._positions: dict = {}
        self._scores: dict = {}  # the descent and the recentring meet some candidates twice
        self.trials = 0
        from csgs_codec.render.rasterizer import resolve_backend

        # Recolouring replays the numba backend's sums; other backends render every trial.
        self._recolours = resolve_backend("auto") == "numba"
        self._geometries: set = set()
        self._recorded: tuple | None = None  # (geometry key, a BlendRecord per view)

    def groups(self) -> list[str]:
        """The groups this scene codes."""
        present = [g for g in GROUPS[:-1] if g in self.streams.float_streams]
        return present + ["position"]

    def _plan(self, name: str, offsets: dict[str, int]):
        key = (name, offsets.get(name, 0))
        if key not in self._plans:
            derive = None
            if name == "rot":
                # Rotation classes follow the preset's decoded scales and opacities: a
                # half-octave move of those barely moves the classes, and replanning the
                # rotations for every such move would double the probe's time.
                derive = rotation_classes(self.rotation_rule, self._plan("scale", {})[1],
                                          self._plan("opacity", {})[1])
            plan = plan_float_stream(self.streams.float_streams[name],
                                     self.steps[name] * 2.0 ** (offsets.get(name, 0) / 2.0),
                                     derive)
            self._plans[key] = (float(sum(ch.cost for ch in plan.channels)), plan.recon)
        return self._plans[key]

    def _position(self, bits: int):
        if bits not in self._positions:
            positions = self.scene.positions
            grid = PositionGrid.fit(positions, bits)
            cells, inside = grid.quantize(positions)
            decoded = positions.astype(np.float32, copy=True)
            decoded[inside] = grid.dequantize(cells[inside])
            # Far points are coded apart at about the same relative precision: counted as
            # exact here (few, and the same for every candidate).
            size = len(encode_positions(cells[inside], grid.bits))
            self._positions[bits] = (8.0 * size, decoded)
        return self._positions[bits]

    def rate_distortion(self, offsets: dict[str, int]) -> tuple[float, float]:
        """(planned bits R, probe MSE D in squared 8-bit levels) of ``offsets``."""
        key = tuple(sorted((g, v) for g, v in offsets.items() if v))
        if key not in self._scores:
            self._scores[key] = self._measure(offsets)
        return self._scores[key]

    def grid_bits(self, offsets: dict[str, int]) -> int:
        """The position grid's bits under ``offsets``."""
        return int(np.clip(self.preset.position_bits + offsets.get("position", 0), 1, 21))

    def coded(self, offsets: dict[str, int]) -> tuple[float, GaussianScene]:
        """(planned bits, the decoded scene in input order) of ``offsets``."""
        bits, positions = self._position(self.grid_bits(offsets))
        decoded = {}
        for name in self.streams.float_streams:
            cost, recon = self._plan(name, offsets)
            bits += cost
            decoded[name] = recon
        return bits, join_streams(SceneStreams(decoded, self.streams.rot_axis,
                                               self.streams.sh_degree_stored), positions)

    def reach_on_grid(self, bits: int) -> list[np.ndarray]:
        """Each window's Gaussians (:func:`window_reach`) when positions decode on a grid of
        ``bits``: those that reach it from their own positions or from their decoded ones.
        A coarse grid moves a small Gaussian by more than its own size, which the steps'
        moves never do, so the windows of such a grid take the Gaussians it moves into
        them as well."""
        import torch

        if bits not in self._grid_reach:
            _, positions = self._position(bits)
            means = self._tensors["means"]
            moved = {**self._tensors, "means": torch.as_tensor(positions, dtype=means.dtype,
                                                               device=means.device)}
            self._grid_reach[bits] = [np.union1d(own, window_reach(moved, cam))
                                      for own, cam in zip(self.reach, self.cameras)]
        return self._grid_reach[bits]

    def _measure(self, offsets: dict[str, int]) -> tuple[float, float]:
        from csgs_codec.metrics.comparison import to_unit_range

        bits, coded = self.coded(offsets)
        images = self._probe_images(offsets, coded)
        errors = []
        for image, mask, ref in zip(images, self.masks, self.references):
            if image is not None:
                image = to_unit_range(image)[mask]
                errors.append(float(np.mean((image.astype(np.float64) - ref) ** 2)))
        self.trials += 1
        return bits, (float(np.mean(errors)) * 255.0 ** 2 if errors else 0.0)

    def _probe_images(self, offsets: dict[str, int], coded: GaussianScene) -> list:
        """The (H, W, 3) render of ``coded`` in each probe view (None where the original
        shows nothing): recoloured from the recorded weights when the recorded candidate
        has the same geometry, recorded when an earlier candidate had it (the descent then
        tries colour steps on it), else rendered."""
        from csgs_codec.render.blend_record import render_recording
        from csgs_codec.render.rasterizer import render

        key = tuple(self.grid_bits(offsets) if g == "position" else offsets.get(g, 0)
                    for g in GEOMETRY_GROUPS)
        views = zip(self.cameras, self.reach_on_grid(self.grid_bits(offsets)), self.masks)
        if self._recorded is not None and self._recorded[0] == key:
            return [record.recolour(coded.subset(reach)) if mask.any() else None
                    for (_, reach, mask), record in zip(views, self._recorded[1])]
        record = self._recolours and key in self._geometries
        self._geometries.add(key)
        images, records, budget = [], [], MAX_RECORDED_SLOTS
        for cam, reach, mask in views:
            if not mask.any():
                images.append(None)
                records.append(None)
            elif record:
                image, kept = render_recording(coded.subset(reach), cam, max_slots=budget)
                images.append(image)
                records.append(kept)
                if kept is None:
                    record = False
                else:
                    budget -= int(kept.starts[-1])
            else:
                images.append(render(coded.subset(reach), cam, backend="auto").image)
        if record:
            self._recorded = (key, records)
        return images


def window_reach(tensors: dict, camera) -> np.ndarray:
    """(K,) int64 indices, ascending, of the Gaussians of a scene (``tensors``, its
    :func:`~csgs_codec.render.rasterizer.scene_tensors`) that can show in the window
    ``camera`` when their attributes move by a quantization step (see
    :data:`REACH_SCALE`)."""
    import math

    from csgs_codec.render.projection import project_gaussians

    grown = replace(camera, width=camera.width + 2 * REACH_PIXELS,
                    height=camera.height + 2 * REACH_PIXELS, cx=camera.cx + REACH_PIXELS,
                    cy=camera.cy + REACH_PIXELS)
    t = tensors
    longest = t["log_scales"].max(dim=1, keepdim=True).values.expand_as(t["log_scales"])
    projected = project_gaussians(t["means"], longest + math.log(REACH_SCALE),
                                  t["quats"], t["opacity_logits"] + REACH_OPACITY, grown,
                                  near_plane=camera.near_plane)
    return np.flatnonzero(projected.visible.numpy()).astype(np.int64)


def ladder_slope(points: list[tuple[float, float]]) -> float | None:
    """lambda = -dD/dR at the first of ``points`` ((R bits, D) of the preset with every
    step moved together by 0, -1, -2, +1, +2 half octaves, in any order after the first),
    from the exponential model D = exp(a + b R) fitted to them all by least squares: local
    secants of two probes scatter by 2x between neighbouring presets, the fit by about
    1.3x, and it keeps lambda falling with the step as the presets do. None when a D is 0
    (nothing shows on the probe views) or the fit does not fall with the rate."""
    rates = np.array([r for r, _ in points], np.float64)
    errors = np.array([d for _, d in points], np.float64)
    if np.any(errors <= 0.0) or np.ptp(rates) <= 0.0:
        return None
    slope, intercept = np.polyfit(rates, np.log(errors), 1)
    lam = -slope * np.exp(intercept + slope * rates[0])
    return float(lam) if np.isfinite(lam) and lam > 0.0 else None


def probe_cameras(scene: GaussianScene, cameras: list | None = None, *,
                  whole: bool = True) -> list:
    """The allocation's probe views: :data:`PROBE_VIEWS` of ``cameras`` (evenly spread;
    None: :data:`PROBE_DIRECTIONS` directions of the default viewing distribution at
    :data:`PROBE_DISTANCES`).

    ``whole``: each view with 1/:data:`PROBE_SCALE` of its width and height in pixels, the
    whole view scaled down by :func:`probe_scale` and, where that is less than
    :data:`PROBE_SCALE`, cropped around its centre. Otherwise a window of
    1/:data:`PROBE_WINDOW` of its width and height at its own pixel size, the windows taking
    turns over the four quarters around the image centre (for a sample of a larger scene,
    see :data:`PROBE_SCALE`)."""
    if cameras is None:
        from csgs_codec.render.view_distribution import default_distribution

        cameras = default_distribution(scene, directions=PROBE_DIRECTIONS,
                                       distances=PROBE_DISTANCES).cameras
    spread = np.unique(np.linspace(0, len(cameras) - 1, PROBE_VIEWS).astype(int))
    picked = [cameras[i] for i in spread]
    if not whole:
        return [_centre_window(cam, i) for i, cam in enumerate(picked)]
    scale = probe_scale(scene, picked)
    views = []
    for cam in picked:
        width = max(round(cam.width / scale), 1)
        height = max(round(cam.height / scale), 1)
        sx, sy = width / cam.width, height / cam.height
        x0 = (width - max(round(cam.width / PROBE_SCALE), 1)) // 2
        y0 = (height - max(round(cam.height / PROBE_SCALE), 1)) // 2
        views.append(replace(cam, width=width - 2 * x0, height=height - 2 * y0,
                             fx=cam.fx * sx, fy=cam.fy * sy, cx=cam.cx * sx - x0,
                             cy=cam.cy * sy - y0))
    return views


def _centre_window(cam, i: int):
    """Window ``i`` of a view: 1/:data:`PROBE_WINDOW` of its width and height at its own
    pixel size, in quarter ``i % 4`` around the image centre."""
    width = max(cam.width // PROBE_WINDOW, 1)
    height = max(cam.height // PROBE_WINDOW, 1)
    x0 = cam.width // 2 - width * (1 - i % 2)
    y0 = cam.height // 2 - height * (1 - (i // 2) % 2)
    return replace(cam, width=width, height=height, cx=cam.cx - x0, cy=cam.cy - y0)


def probe_scale(scene: GaussianScene, cameras: list) -> int:
    """How many of a view's pixels, across and down, one probe pixel takes: the largest of
    :data:`PROBE_SCALE`, ..., 2, 1 at which the median Gaussian in front of ``cameras``
    still spans :data:`PROBE_MIN_SIGMA` probe pixels (its largest axis's standard
    deviation; 1 for a scene that shows in none of them)."""
    positions = np.asarray(scene.positions, np.float64)
    longest = np.exp(np.clip(np.asarray(scene.scales, np.float64).max(axis=1), -80.0, 80.0))
    sigmas = []
    for cam in cameras:
        world_to_camera = np.asarray(cam.world_to_camera, np.float64)
        depth = positions @ world_to_camera[2, :3] + world_to_camera[2, 3]
        front = depth > cam.near_plane
        sigmas.append(longest[front] * cam.fy / depth[front])
    sigma = np.concatenate(sigmas) if sigmas else np.zeros(0)
    if not len(sigma):
        return 1
    typical = float(np.median(sigma))
    scale = PROBE_SCALE
    while scale > 1 and typical / scale < PROBE_MIN_SIGMA:
        scale //= 2
    return scale


def allocate_steps(scene: GaussianScene, preset: Preset, *, rotation_rule: str = "footprint",
                   cameras: list | None = None,
                   progress: Callable[[int, int], None] | None = None) -> StepAllocation:
    """Choose each group's step for ``scene`` around ``preset`` (see the module notes).

    Args:
        scene: the validated scene as the encoder will code it (input order).
        preset: the quality preset the allocation starts from.
        rotation_rule: how rotation steps follow decoded attributes (the encoder's
            ``rotation_steps``).
        cameras: the views the scene will be seen from (the probe views are made from
            them, :func:`probe_cameras`); None: the default sphere of views around it.
        progress: ``progress(done, total)`` told of probe renders (total is an upper bound).

    Returns:
        The allocation; no offsets for scenes under :data:`MIN_GAUSSIANS` Gaussians or
        distinct positions (many copies of a few Gaussians say no more than the few), or
        when the ladder's slope cannot be measured (a scene no step changes on the probe
        views).
    """
    if len(scene) < MIN_GAUSSIANS:
        return StepAllocation()
    whole = len(scene) <= SAMPLE
    if not whole:
        keep = np.sort(np.random.default_rng(0).choice(len(scene), SAMPLE, replace=False))
        scene = scene.subset(keep)
    if len(np.unique(scene.positions, axis=0)) < MIN_GAUSSIANS:
        return StepAllocation()
    probe = _Probe(scene, preset, rotation_rule, probe_cameras(scene, cameras, whole=whole))
    groups = probe.groups()
    float_groups = [g for g in groups if g != "position"]
    budget = 5 + PASSES * 2 * len(groups) * 2 + RECENTRE_STEPS
    report = progress or (lambda done, total: None)

    def evaluate(offsets: dict[str, int]) -> tuple[float, float]:
        result = probe.rate_distortion(offsets)
        report(probe.trials, budget)
        return result

    r0, d0 = evaluate({})
    lam = ladder_slope([(r0, d0)] + [evaluate({g: k for g in float_groups})
                                     for k in (-2, -1, 1, 2)])
    if lam is None:
        return StepAllocation(trials=probe.trials)

    def cost(rd: tuple[float, float]) -> float:
        return rd[1] + lam * rd[0]

    offsets = {g: 0 for g in groups}
    start = best = cost((r0, d0))
    current = (r0, d0)
    for _ in range(PASSES):
        moved = False
        for group in groups:
            limit = MAX_BIT_OFFSET if group == "position" else MAX_OFFSET
            for direction in (1, -1):
                # Walk one way while the cost falls; the other way only if the first
                # step did not help.
                stepped = False
                while abs(offsets[group] + direction) <= limit:
                    trial = {**offsets, group: offsets[group] + direction}
                    rd = evaluate(trial)
                    if cost(rd) >= best:
                        break
                    best, offsets, current, stepped, moved = cost(rd), trial, rd, True, True
                if stepped:
                    break
        if not moved:
            break
    offsets, current = _recentre(offsets, current, d0, float_groups, evaluate)
    report(budget, budget)
    rate = _rate_at_error(offsets, current, d0, float_groups, evaluate)
    rate_ratio = float(rate / r0) if r0 > 0 else 1.0
    if rate_ratio > 1.0 - MIN_SAVING:
        # A saving the probe cannot resolve: the preset's steps, but perhaps a coarser grid.
        offsets, current = _coarser_grid(r0, d0, cost, evaluate)
        if offsets:
            rate_ratio = float(current[0] / r0)
    return StepAllocation(dict(offsets), float(lam), probe.trials,
                          float(cost(current) / start) if start > 0 else 1.0, rate_ratio)


def _coarser_grid(r0: float, d0: float, cost, evaluate
                  ) -> tuple[dict[str, int], tuple[float, float]]:
    """The preset's steps with the grid alone made coarser, a bit at a time while the cost J
    falls (at most :data:`MAX_BIT_OFFSET` bits), or no offsets when one bit fewer does not
    lower it.

    The grid's share of a file and of its error are both large enough for the probe to
    resolve: on the three SH-3 captures the descent took 1-5 bits from the preset's grid at
    every quality 2-9, and at the 16 of those 24 presets where the whole allocation was not
    kept, this fallback coded them at 0.81-0.99x the presets' bytes at equal held-out PSNR
    (mean over qualities 2-9 without / with it: fruit_drops 0.953 / 0.883,
    leica_sofort_top8192 0.943 / 0.926, yashica_t4_top8192 0.954 / 0.922;
    benchmarks/results/allocation_grid_2026-11-27.json)."""
    offsets: dict[str, int] = {}
    best, current = cost((r0, d0)), (r0, d0)
    for bits in range(1, MAX_BIT_OFFSET + 1):
        rd = evaluate({"position": -bits})
        if cost(rd) >= best:
            break
        best, current, offsets = cost(rd), rd, {"position": -bits}
    return offsets, current


def _rate_at_error(offsets: dict[str, int], current: tuple[float, float], target: float,
                   float_groups: list[str], evaluate) -> float:
    """The planned bits of ``offsets``' step ratios at exactly the probe error ``target``:
    interpolated (log error against bits) between ``current`` and its neighbour half an
    octave coarser (or finer, when ``current`` errs more than ``target``).

    :func:`_recentre` moves in half octaves, so the allocation it keeps may err well below
    the preset and cost as many bits: a higher quality, not a saving the plain bits ratio
    would show. The ratio at equal error is what :data:`MIN_SAVING` judges."""
    rate, error = current
    if error <= 0.0 or target <= 0.0 or error == target:
        return rate
    k = 1 if error < target else -1
    other_rate, other_error = evaluate(
        {**offsets, **{g: int(np.clip(offsets[g] + k, -MAX_OFFSET, MAX_OFFSET))
                       for g in float_groups}})
    if other_error <= 0.0 or other_error == error:
        return rate
    t = (np.log(target) - np.log(error)) / (np.log(other_error) - np.log(error))
    return float(rate + np.clip(t, 0.0, 1.0) * (other_rate - rate))


def _recentre(offsets: dict[str, int], current: tuple[float, float], target: float,
              float_groups: list[str], evaluate) -> tuple[dict[str, int], tuple[float, float]]:
    """Shift every float group's step together (half an octave at a time, at most
    :data:`RECENTRE_STEPS` times) to the coarsest allocation whose probe error is still at
    most the preset's ``target``: the descent sets the ratio between the steps, the preset
    its quality level, so neighbouring presets keep their order on the probe views."""
    def shifted(k: int) -> dict[str, int]:
        return {**offsets, **{g: int(np.clip(offsets[g] + k, -MAX_OFFSET, MAX_OFFSET))
                              for g in float_groups}}

    if current[1] > target:  # finer until the preset's error is met
        for k in range(1, RECENTRE_STEPS + 1):
            offsets_k = shifted(-k)
            rd = evaluate(offsets_k)
            if rd[1] <= target or k == RECENTRE_STEPS:
                return offsets_k, rd
        return offsets, current
    for k in range(1, RECENTRE_STEPS + 1):  # coarser while the preset's error is kept
        offsets_k = shifted(k)
        rd = evaluate(offsets_k)
        if rd[1] > target:
            break
        offsets, current = offsets_k, rd
    return offsets, current
