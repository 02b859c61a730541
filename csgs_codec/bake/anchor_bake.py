"""Bake an anchor scene into a standard 3DGS scene that any viewer and format can show.

An anchor's neural Gaussians depend on where they are seen from (the Scaffold-GS heads take
the view direction and distance). A standard scene cannot: its opacity, scale and rotation are
fixed and its colour is spherical harmonics of the view direction. The bake evaluates the
heads from a set of view origins and fits, for every anchor-offset slot:

* **kept or dropped**: a slot the opacity head turns off (opacity <= 0) from more than
  ``1 - keep_fraction`` of the views, or whose offset is masked, is dropped;
* **opacity**: the mean of ``max(opacity, 0)`` over the views that see it on;
* **scale**: the opacity-weighted mean of the log-scales;
* **rotation**: the opacity-weighted principal axis of ``q q^T`` (sign-free quaternion mean);
* **colour**: SH coefficients of ``sh_degree`` fitted by weighted least squares to the colour
  head's RGB over the views, with the direction from each view origin to the Gaussian (the one
  a 3DGS renderer evaluates SH at), weights ``max(opacity, 0)``, and a small ridge on the
  non-DC coefficients so slots seen from few directions stay tame.

The view origins are the given cameras' centres, else the scene's stored training origins
(``AnchorScene.view_origins``, a file's ``vorg`` chunk), else :func:`bake_origins`: spheres
around the anchors at three distances, framed as the encoder's default viewing distribution
frames a scene. csgs_codec/js/anchor_bake.mjs is the same bake in JavaScript (the browser
page's), to float tolerance.
Positions are view-independent already; semantic features and labels are the anchor's,
repeated per Gaussian. The result is deterministic for a given scene, origins and settings on
one machine (it feeds no range coder; nothing decodes it bit for bit).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from torch.nn import functional

from csgs_codec.errors import InputError
from csgs_codec.model.scaffold import MAX_OPACITY, ScaffoldMLPs
from csgs_codec.render.sh import SH_BASIS_COUNTS, sh_basis
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene

#: The default origins' framing: a 40-degree frame (vertical, 800 x 600) that the anchors'
#: robust box fills to 70%, as the encoder's default viewing distribution frames a scene.
_FOV_Y_DEG = 40.0
_FILL = 0.7
#: Most refinement steps a bake takes.
MAX_REFINE_STEPS = 100_000
#: Anchors evaluated together (bounds memory: anchors x offsets x basis^2 doubles).
ANCHOR_BATCH = 2048
#: Least opacity weight a view gives a slot's colour fit, so that a slot on from few views
#: still gets a defined colour (relative to the largest weight of the slot).
MIN_COLOR_WEIGHT = 1e-4


@dataclass(frozen=True)
class BakeSettings:
    """How an anchor scene is baked.

    Attributes:
        sh_degree: SH degree of the baked colour, 0..3.
        keep_fraction: a slot is kept when its opacity is > 0 from at least this fraction of
            the view origins, in (0, 1].
        ridge: weight of the penalty on the non-DC SH coefficients, relative to the slot's
            total colour weight (0 for plain least squares).
        directions: view directions per shell of the default sphere of origins.
        distances: shells of the default sphere, as multiples of the framing distance.
        refine_steps: Adam steps refining the bake against the exact renders from the
            origins (:mod:`csgs_codec.bake.refine`; 0: none, the browser page's bake).
        refine_size: side in pixels of those renders.
    """

    sh_degree: int = 3
    keep_fraction: float = 0.5
    ridge: float = 1e-3
    directions: int = 32
    distances: tuple[float, ...] = (0.65, 1.0, 1.5)
    refine_steps: int = 0
    refine_size: int = 256

    def check(self) -> None:
        """Raise :class:`InputError` naming the first setting out of range."""
        if self.sh_degree not in SH_BASIS_COUNTS:
            raise InputError(f"SH degree must be 0..3, got {self.sh_degree}",
                             property="sh_degree")
        if not 0.0 < self.keep_fraction <= 1.0:
            raise InputError(f"keep fraction must be in (0, 1], got {self.keep_fraction}",
                             property="keep_fraction")
        if not (math.isfinite(self.ridge) and self.ridge >= 0.0):
            raise InputError(f"ridge must be finite and >= 0, got {self.ridge}",
                             property="ridge")
        if not 0 <= self.refine_steps <= MAX_REFINE_STEPS:
            raise InputError(f"refine steps must be 0..{MAX_REFINE_STEPS:,}, got "
                             f"{self.refine_steps}", property="refine_steps")
        if not 16 <= self.refine_size <= 2048:
            raise InputError(f"refine size must be 16..2048 pixels, got {self.refine_size}",
                             property="refine_size")
        if self.directions < 1 or not self.distances or min(self.distances) <= 0:
            raise InputError("the default sphere needs directions and positive distances",
                             property="directions")


def bake_origins(scene: AnchorScene, settings: BakeSettings = BakeSettings()) -> np.ndarray:
    """(V, 3) float64 view origins for a scene that stores none, world units (FORMAT §17.13).

    Fibonacci spheres of ``settings.directions`` points around the centre of the anchors'
    2nd-98th percentile box, at ``settings.distances`` times the distance at which that box's
    largest side fills 70% of a 40-degree frame (the framing of the encoder's default viewing
    distribution), each shell turned about z by 2 pi shell / (shells x directions). Anchor
    positions alone decide it, so any receiver computes the same origins.
    """
    from csgs_codec.render.view_distribution import sphere_directions

    positions = scene.positions.astype(np.float64)
    if len(positions) == 0:
        positions = np.zeros((1, 3))
    low = np.percentile(positions, 2.0, axis=0)
    high = np.percentile(positions, 98.0, axis=0)
    extent = float(np.max(high - low))
    if not extent > 0:
        extent = 1.0
    base = extent * (0.5 / _FILL / math.tan(math.radians(_FOV_Y_DEG / 2)) + 0.5)
    centre = (low + high) / 2
    shells = settings.distances
    out = []
    for shell, factor in enumerate(shells):
        turn = 2.0 * math.pi * shell / (len(shells) * settings.directions)
        c, s = math.cos(turn), math.sin(turn)
        d = sphere_directions(settings.directions)
        turned = np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1], d[:, 2]], 1)
        out.append(centre + base * factor * turned)
    return np.concatenate(out)


def bake_view_origins(scene: AnchorScene, *, cameras: list[Camera] | None = None,
                      origins: np.ndarray | None = None,
                      settings: BakeSettings = BakeSettings()) -> np.ndarray:
    """(V, 3) float64 view origins a bake of ``scene`` uses: the ``cameras``' centres, else
    ``origins``, else the scene's stored ``view_origins``, else :func:`bake_origins`.

    Raises:
        InputError: no origin, or one that is not finite.
    """
    if cameras is not None:
        origins = np.stack([np.asarray(c.position, np.float64) for c in cameras]) \
            if cameras else np.zeros((0, 3))
    elif origins is None:
        origins = (scene.view_origins if scene.view_origins is not None
                   else bake_origins(scene, settings))
    origins = np.asarray(origins, np.float64).reshape(-1, 3)
    if len(origins) == 0 or not np.all(np.isfinite(origins)):
        raise InputError("the bake needs at least one finite view origin", property="origins")
    return origins


def bake_anchor_scene(scene: AnchorScene, *, cameras: list[Camera] | None = None,
                      origins: np.ndarray | None = None,
                      settings: BakeSettings = BakeSettings(),
                      device: torch.device | str = "cpu",
                      progress: Callable[[int, int], None] | None = None) -> GaussianScene:
    """The standard 3DGS scene that ``scene``'s anchors generate (see the module notes).

    Args:
        scene: an anchor scene with its MLPs.
        cameras: view origins as cameras (their centres), e.g. the capture's training views;
            else ``origins``; else the scene's own ``view_origins`` (what ``csgs train``
            stores); else :func:`bake_origins`.
        origins: (V, 3) view origins, world units (when ``cameras`` is None).
        settings: SH degree, drop rule, ridge and the default sphere.
        device: where the heads run and the fits are solved.
        progress: called with (anchors done, anchors in all) after each batch.

    Returns:
        The baked Gaussians, anchor-major and offsets in order (the kept slots only), SH of
        ``settings.sh_degree``, with the anchors' semantic features and labels repeated.

    Raises:
        InputError: the scene has no MLPs, bad settings, or no finite view origin.
    """
    settings.check()
    scene.validate()
    if scene.mlps is None:
        raise InputError("the anchor scene has no Scaffold-GS MLPs to bake", property="mlps")
    origins = bake_view_origins(scene, cameras=cameras, origins=origins, settings=settings)
    mlps = ScaffoldMLPs.from_weights(scene.mlps, scene.feat_dim, scene.n_offsets,
                                     device=device)
    origin_tensor = torch.as_tensor(origins, dtype=torch.float32, device=device)
    parts = []
    for start in range(0, len(scene), ANCHOR_BATCH):
        batch = slice(start, min(start + ANCHOR_BATCH, len(scene)))
        parts.append(_bake_batch(scene, batch, mlps, origin_tensor, settings))
        if progress is not None:
            progress(batch.stop, len(scene))
    baked = _assemble(scene, parts, settings.sh_degree)
    if settings.refine_steps:
        from csgs_codec.bake.refine import refine_bake

        baked = refine_bake(baked, scene, origins, steps=settings.refine_steps,
                            size=settings.refine_size, device=device)
    return baked


@dataclass
class _BakedSlots:
    """The kept slots of one anchor batch (numpy, float32 unless said)."""

    anchor_index: np.ndarray  # (n,) int64, into the whole scene
    positions: np.ndarray
    sh: np.ndarray  # (n, basis, 3)
    opacity: np.ndarray  # (n,) in (0, 1)
    log_scales: np.ndarray
    rotations: np.ndarray


def _bake_batch(scene: AnchorScene, batch: slice, mlps: ScaffoldMLPs, origins: torch.Tensor,
                settings: BakeSettings) -> _BakedSlots:
    """Evaluate the heads of the anchors in ``batch`` from every origin and fit their slots."""
    device = origins.device
    positions, features, offsets, scaling, mask = (
        torch.as_tensor(getattr(scene, name)[batch], device=device)
        for name in ("positions", "features", "offsets", "scaling", "offset_mask"))
    m, k = offsets.shape[0], offsets.shape[1]
    basis_count = SH_BASIS_COUNTS[settings.sh_degree]
    centers = positions[:, None, :] + offsets * torch.exp(scaling[:, None, :3])  # [m, k, 3]
    on_count = torch.zeros(m, k, dtype=torch.float64, device=device)
    weight_sum = torch.zeros(m, k, dtype=torch.float64, device=device)
    log_scale_sum = torch.zeros(m, k, 3, dtype=torch.float64, device=device)
    rotation_moment = torch.zeros(m, k, 4, 4, dtype=torch.float64, device=device)
    normal = torch.zeros(m, k, basis_count, basis_count, dtype=torch.float64, device=device)
    target = torch.zeros(m, k, basis_count, 3, dtype=torch.float64, device=device)
    keep_mask = mask.to(torch.float64)
    views = []
    with torch.no_grad():
        for origin in origins:
            delta = positions - origin.reshape(1, 3)
            dist = delta.norm(dim=1, keepdim=True)
            view_dir = delta / dist.clamp_min(torch.finfo(delta.dtype).tiny)
            opacity, cov, color = mlps(features, view_dir, dist)
            weight = opacity.to(torch.float64).clamp_min(0.0) * keep_mask  # [m, k]
            views.append((weight, color))
            on_count += (weight > 0).to(torch.float64)
            weight_sum += weight
            log_scales = scaling[:, None, 3:] + functional.logsigmoid(cov[..., :3])
            log_scale_sum += weight[..., None] * log_scales.to(torch.float64)
            quat = functional.normalize(cov[..., 3:7].to(torch.float64), dim=-1)
            rotation_moment += weight[..., None, None] * quat[..., :, None] * quat[..., None, :]
        peak = torch.stack([w for w, _ in views]).amax(dim=0)  # [m, k]
        for origin, (weight, color) in zip(origins, views):
            to_gaussian = centers - origin.reshape(1, 1, 3)
            unit = functional.normalize(to_gaussian.to(torch.float64), dim=-1)
            basis = sh_basis(unit, settings.sh_degree)  # [m, k, basis]
            w = torch.maximum(weight, MIN_COLOR_WEIGHT * peak)
            normal += w[..., None, None] * basis[..., :, None] * basis[..., None, :]
            target += (w[..., None, None] * basis[..., :, None]
                       * (color.to(torch.float64) - 0.5)[..., None, :])
    kept = (on_count >= settings.keep_fraction * len(origins)) & mask & (weight_sum > 0)
    slots = torch.nonzero(kept.reshape(-1)).reshape(-1)
    anchor_local = slots // k
    flat = lambda t: t.reshape(m * k, *t.shape[2:])[slots]  # noqa: E731
    total = flat(weight_sum)
    normal, target = flat(normal), flat(target)
    if settings.ridge > 0 and basis_count > 1:
        penalty = torch.ones(basis_count, dtype=torch.float64, device=device)
        penalty[0] = 0.0
        scale = settings.ridge * normal.diagonal(dim1=-2, dim2=-1).sum(-1) / basis_count
        normal = normal + scale[:, None, None] * torch.diag(penalty)
    # A floor on the diagonal keeps a slot seen from fewer origins than basis functions
    # solvable when the ridge is off.
    floor = 1e-9 * normal.diagonal(dim1=-2, dim2=-1).sum(-1).clamp_min(1e-300)
    normal = normal + floor[:, None, None] * torch.eye(basis_count, dtype=torch.float64,
                                                      device=device)
    # The solution c gives colour - 0.5 = sum_k c_k Y_k(d): the 3DGS SH layout as it is.
    sh = torch.linalg.solve(normal, target) if len(slots) else target
    opacity = (total / flat(on_count)).clamp(0.0, MAX_OPACITY)
    rotation = torch.linalg.eigh(flat(rotation_moment)).eigenvectors[..., -1]
    rotation = rotation * torch.where(rotation[:, :1] < 0, -1.0, 1.0)
    return _BakedSlots(
        anchor_index=(anchor_local + batch.start).cpu().numpy().astype(np.int64),
        positions=flat(centers).cpu().numpy().astype(np.float32),
        sh=sh.cpu().numpy().astype(np.float32),
        opacity=opacity.cpu().numpy(),
        log_scales=(flat(log_scale_sum) / total[:, None]).cpu().numpy().astype(np.float32),
        rotations=rotation.cpu().numpy().astype(np.float32))


def _assemble(scene: AnchorScene, parts: list[_BakedSlots], sh_degree: int) -> GaussianScene:
    """One :class:`GaussianScene` from the batches' kept slots."""
    join = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
    basis_count = SH_BASIS_COUNTS[sh_degree]
    if parts:
        anchor_index, sh = join("anchor_index"), join("sh")
        opacity = join("opacity").astype(np.float64)
        positions, log_scales, rotations = join("positions"), join("log_scales"), \
            join("rotations")
    else:
        anchor_index = np.zeros(0, np.int64)
        sh = np.zeros((0, basis_count, 3), np.float32)
        opacity = np.zeros(0)
        positions, log_scales = np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32)
        rotations = np.zeros((0, 4), np.float32)
    return GaussianScene(
        positions=positions, sh_dc=np.ascontiguousarray(sh[:, 0, :]),
        sh_rest=np.ascontiguousarray(sh[:, 1:, :]),
        opacity=(np.log(opacity) - np.log1p(-opacity)).astype(np.float32),
        scales=log_scales, rotations=rotations,
        semantic=None if scene.semantic is None else scene.semantic[anchor_index],
        semantic_names=scene.semantic_names if scene.semantic is not None else (),
        labels=None if scene.labels is None else scene.labels[anchor_index])
