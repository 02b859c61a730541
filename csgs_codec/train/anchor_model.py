"""The trainable Scaffold-GS scene of stage 1: anchors on a voxel grid, their MLPs and masks.

Anchors sit at fixed voxel centres ``origin + cell * voxel`` (Scaffold-GS does not move them; a
grid also lets the encoder code them losslessly). Each anchor has a feature f (F), K offsets
(in units of ``exp(scaling[:3])``), a log scaling l (6) and K offset-mask logits. The mask
follows HAC: a slot is kept when ``sigmoid(logit) > MASK_THRESHOLD``, with a straight-through
gradient to the soft value, so the mask loss can switch slots off. Spawning the neural Gaussians
of a view is :func:`csgs_codec.model.scaffold.neural_gaussians`, the rule the decoder uses.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from csgs_codec.errors import InputError
from csgs_codec.model.scaffold import NeuralGaussians, ScaffoldMLPs, neural_gaussians
from csgs_codec.model.seeded_init import seeded_global_rng
from csgs_codec.render.device_constants import camera_tensors
from csgs_codec.render.differentiable import (
    rasterize_for_training,
    resolve_training_rasterizer,
)
from csgs_codec.render.rasterize_torch import RasterTensors
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.camera import Camera

#: A slot is kept when its mask probability exceeds this (HAC's rule).
MASK_THRESHOLD = 0.01
#: Initial mask logit: probability 0.73, well above the threshold.
INITIAL_MASK_LOGIT = 1.0
#: Initial offsets are uniform in +-this (units of exp(scaling[:3]), i.e. voxels).
INITIAL_OFFSET_SPREAD = 0.5
#: Seeded initial values (MLP weights, offsets) are drawn here, then moved to the model's
#: device: a seed gives the same starting anchors on every device, and the offset generator's
#: state, which checkpoints keep, carries over between devices.
INIT_DEVICE = torch.device("cpu")  # cpu: seeded initial values equal on every device


@dataclass(frozen=True)
class AnchorGrid:
    """The voxel grid anchors live on.

    Attributes:
        origin: (3,) float64 world position of cell (0, 0, 0).
        voxel: cell edge, world units.
    """

    origin: np.ndarray
    voxel: float

    def cells_of(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) int64 nearest cell of each point ((N, 3) world units)."""
        return np.floor((np.asarray(points, np.float64) - self.origin) / self.voxel
                        + 0.5).astype(np.int64)

    def centres(self, cells: np.ndarray) -> np.ndarray:
        """(N, 3) float32 world positions of ``cells``."""
        return (self.origin + cells.astype(np.float64) * self.voxel).astype(np.float32)


def grid_for_points(points: np.ndarray, target_anchors: int) -> AnchorGrid:
    """A grid whose voxel puts about ``target_anchors`` occupied cells on ``points``.

    The voxel is searched by bisection on a log scale between the points' extent and
    1e-6 of it (25 steps), counting occupied cells each time. The count aimed at is at most
    half the distinct points: with more anchors asked than points (a sparse SfM cloud) any
    voxel below the points' spacing meets the count, and the search would end at 1e-6 of
    the extent, where anchors start invisibly small and barely learn (a real capture,
    mary_rose at 128 px, held out at 2.7 dB after 400 steps).
    """
    points = np.asarray(points, np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise InputError(f"initial points must be (N, 3) with N >= 1, got {points.shape}",
                         property="points")
    if target_anchors < 1:
        raise InputError(f"target anchor count must be >= 1, got {target_anchors}",
                         property="anchors")
    target_anchors = min(target_anchors, max(1, len(np.unique(points, axis=0)) // 2))
    low, high = points.min(axis=0), points.max(axis=0)
    extent = float((high - low).max()) or 1.0
    lo, hi = math.log(extent * 1e-6), math.log(extent)
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        grid = AnchorGrid(low, math.exp(mid))
        occupied = len(np.unique(grid.cells_of(points), axis=0))
        if occupied > target_anchors:
            lo = mid
        else:
            hi = mid
    return AnchorGrid(low, math.exp(hi))


class AnchorModel(nn.Module):
    """Anchors, their Scaffold-GS MLPs and offset masks as torch parameters.

    Args:
        cells: (M, 3) int64 occupied cells of ``grid``.
        grid: the voxel grid.
        feat_dim: F; n_offsets: K.
        seed: seeds the initial offsets and MLP weights.
        initial_log_scale: the initial anchors' log scaling (default: log of the voxel; stage
            1 starts coarse anchors on a finer grid, so that growth can add anchors between
            them, and gives them the coarse voxel's scale). Grown anchors get the grid's.
        device: where the parameters and buffers live (random initial values are drawn on
            :data:`INIT_DEVICE` first, so they do not depend on it).
    """

    def __init__(self, cells: np.ndarray, grid: AnchorGrid, *, feat_dim: int = 32,
                 n_offsets: int = 10, seed: int = 0, initial_log_scale: float | None = None,
                 device: torch.device | str = "cpu") -> None:
        super().__init__()
        if len(cells) == 0:
            raise InputError("stage 1 needs at least one anchor", property="anchors")
        self.grid = grid
        self.feat_dim, self.n_offsets = feat_dim, n_offsets
        generator = torch.Generator(device=INIT_DEVICE).manual_seed(seed)
        # nn.Linear initialisation draws from the global generator: seed it inside a fork so
        # the caller's random state is left alone.
        with seeded_global_rng(seed):
            self.mlps = ScaffoldMLPs(feat_dim, n_offsets, device=INIT_DEVICE).to(device)
        m = len(cells)
        self.register_buffer("cells", torch.as_tensor(np.asarray(cells, np.int64),
                                                      device=device))
        self.register_buffer("positions", torch.as_tensor(grid.centres(cells), device=device))
        self.features = nn.Parameter(torch.zeros(m, feat_dim, device=device))
        self.offsets = nn.Parameter(self._initial_offsets(m, generator).to(device))
        log_scale = math.log(grid.voxel) if initial_log_scale is None else initial_log_scale
        self.scaling = nn.Parameter(torch.full((m, 6), float(log_scale), device=device))
        self.mask_logits = nn.Parameter(torch.full((m, n_offsets), INITIAL_MASK_LOGIT,
                                                   device=device))
        self.generator = generator

    def _initial_offsets(self, m: int, generator: torch.Generator) -> torch.Tensor:
        """(m, K, 3) random initial offsets, on ``generator``'s device."""
        return (torch.rand(m, self.n_offsets, 3, generator=generator,
                           device=generator.device) * 2 - 1) * INITIAL_OFFSET_SPREAD

    @property
    def count(self) -> int:
        """Number of anchors M."""
        return int(self.positions.shape[0])

    def anchor_tensors(self) -> dict[str, torch.Tensor]:
        """The per-anchor parameters by name (what growth and pruning resize)."""
        return {"features": self.features, "offsets": self.offsets, "scaling": self.scaling,
                "mask_logits": self.mask_logits}

    def mask(self, probabilities: torch.Tensor | None = None) -> torch.Tensor:
        """(M, K) float {0, 1} kept slots, straight-through gradient to the probabilities
        (``sigmoid(mask_logits)``, computed here unless given)."""
        soft = torch.sigmoid(self.mask_logits) if probabilities is None else probabilities
        hard = (soft > MASK_THRESHOLD).to(soft.dtype)
        return hard + soft - soft.detach()

    def spawn(self, camera: Camera, values: dict[str, torch.Tensor] | None = None, *,
              mask: torch.Tensor | None = None, all_slots: bool = False) -> NeuralGaussians:
        """The neural Gaussians ``camera`` sees, from ``values`` (default: the parameters;
        stage 1 passes noisy copies of features, offsets and scaling) and ``mask`` (default
        :meth:`mask`); ``all_slots``: see :func:`csgs_codec.model.scaffold.neural_gaussians`."""
        v = values or {}
        centre = camera_tensors(camera, self.positions.device).position.to(
            self.positions.dtype)
        return neural_gaussians(self.mlps, self.positions, v.get("features", self.features),
                                v.get("offsets", self.offsets), v.get("scaling", self.scaling),
                                self.mask() if mask is None else mask, centre,
                                all_slots=all_slots)

    def render(self, camera: Camera, values: dict[str, torch.Tensor] | None = None,
               background: tuple[float, float, float] | None = None,
               rasterizer: str = "auto", *, mask: torch.Tensor | None = None,
               all_slots: bool | None = None) -> tuple[RasterTensors, NeuralGaussians]:
        """Render ``camera``'s view differentiably through ``rasterizer`` (see
        :func:`csgs_codec.render.differentiable.resolve_training_rasterizer`).

        ``mask``: as for :meth:`spawn`. ``all_slots``: spawn every slot (see
        :func:`csgs_codec.model.scaffold.neural_gaussians`); None: when the rasterizer is
        gsplat, whose step is bound by operator launches, not by Gaussians.

        Returns:
            (maps: image [H, W, 3], alpha [H, W], depth [H, W] or None (gsplat skips it);
            the N neural Gaussians).
        """
        if all_slots is None:
            all_slots = resolve_training_rasterizer(rasterizer,
                                                    self.positions.device) == "gsplat"
        g = self.spawn(camera, values, mask=mask, all_slots=all_slots)
        out = rasterize_for_training(g.positions, g.log_scales, g.rotations, None, camera,
                                     opacities=g.opacities, colors=g.colors,
                                     background=background, rasterizer=rasterizer,
                                     with_depth=False)
        return out, g

    def slot_positions(self) -> torch.Tensor:
        """(M, K, 3) centres of every slot (view independent), no gradient."""
        with torch.no_grad():
            step = torch.exp(self.scaling[:, :3])
            return self.positions[:, None, :] + self.offsets * step[:, None, :]

    def resize(self, keep: torch.Tensor, new_cells: np.ndarray,
               parents: torch.Tensor) -> None:
        """Keep the anchors selected by ``keep`` ((M,) bool) and append anchors at
        ``new_cells`` ((A, 3) int64), each starting from its parent anchor's feature
        (``parents`` (A,) int64 indices into the current anchors) as Scaffold-GS grows."""
        with torch.no_grad():
            a = len(new_cells)
            device = self.positions.device
            additions = {
                "features": self.features[parents.to(self.features.device)].clone(),
                "offsets": self._initial_offsets(a, self.generator),
                "scaling": torch.full((a, 6), math.log(self.grid.voxel), device=device),
                "mask_logits": torch.full((a, self.n_offsets), INITIAL_MASK_LOGIT,
                                          device=device),
            }
            keep = keep.to(device)
            for name, tensor in self.anchor_tensors().items():
                addition = additions[name].to(device=device, dtype=tensor.dtype)
                setattr(self, name, nn.Parameter(torch.cat([tensor.detach()[keep], addition])))
            self.cells = torch.cat([self.cells[keep],
                                    torch.as_tensor(new_cells.astype(np.int64), device=device)])
            self.positions = torch.as_tensor(self.grid.centres(self.cells.cpu().numpy()),
                                             device=device)

    def to_anchor_scene(self) -> AnchorScene:
        """The trained anchors as an :class:`AnchorScene` (masks hardened, MLP weights
        exported); anchors whose every slot is masked are left out."""
        with torch.no_grad():
            mask = (torch.sigmoid(self.mask_logits) > MASK_THRESHOLD).cpu().numpy()
            alive = mask.any(axis=1)
            offsets = self.offsets.cpu().numpy().copy()
            offsets[~mask] = 0.0
            scene = AnchorScene(
                positions=self.positions.cpu().numpy().astype(np.float32),
                features=self.features.cpu().numpy().astype(np.float32),
                offsets=offsets.astype(np.float32),
                scaling=self.scaling.cpu().numpy().astype(np.float32),
                offset_mask=mask, mlps=copy.deepcopy(self.mlps).cpu().to_weights())
        return scene.subset(alive)
