"""Refinement (``Encoder(refine=N)``, ``--refine N``): the encoder nudges the values it is
about to quantize so that the *decoded* scene renders like the original.

The first plan of the color streams fixes each stream's lattice (grid, step and channel
means, :class:`~csgs_codec.attributes.float_stream.Lattice`). N Adam steps then optimise the
coding-form values (DC and higher SH bands, each band in the colours or opponent colours it
is coded in (FORMAT §12.24), opacity logits, log-scales, smallest-three rotation components;
positions stay where the geometry decodes them) against renders of the
original over the viewing distribution, with straight-through rounding onto those lattices:
the forward pass renders exactly what the decoder would output, the gradient passes the
rounding. The encoder then plans the refined values on the same lattices, so each value
lands on the lattice point the optimisation chose, and codes them as usual: the bitstream
and the decoder do not change, only which lattice point each value takes.

The fit runs on one torch thread from a fixed seed, so the same scene, settings and views
give the same bytes on any machine with the same torch build.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import torch

from csgs_codec.attributes.float_stream import StreamPlan
from csgs_codec.attributes.sh_colour_transform import (
    INVERSE_A,
    INVERSE_B,
    INVERSE_C,
    INVERSE_D,
    OPPONENT,
)
from csgs_codec.attributes.streams import SceneStreams
from csgs_codec.entropy.residual import step_size
from csgs_codec.render.projection import quaternions_from_smallest_three
from csgs_codec.render.rasterize_torch import rasterize_gaussians
from csgs_codec.scene.camera import Camera


@dataclass(frozen=True)
class RefineSettings:
    """How refinement runs.

    Attributes:
        steps: Adam steps (each renders ``views_per_step`` views forward and backward).
        views_per_step: views drawn (without replacement) for each step.
        width: render width in pixels (height keeps each camera's aspect ratio).
        learning_rate: Adam's learning rate, in units of each stream's quantization step.
        seed: the view draws' seed.
    """

    steps: int = 0
    views_per_step: int = 2
    width: int = 400
    learning_rate: float = 0.02
    seed: int = 0


def refine_streams(streams: SceneStreams, plans: dict[str, StreamPlan],
                   positions: np.ndarray, target_sh: np.ndarray, target: dict[str, np.ndarray],
                   cameras: Sequence[Camera], settings: RefineSettings,
                   on_step: Callable[[int, int], None] | None = None,
                   transforms: tuple[int, ...] = ()) -> dict[str, np.ndarray]:
    """Refined coding-form values of the streams that have a plain lattice.

    Args:
        streams: the coding-form values (N, C) per stream, in coding order.
        plans: the first plan of each stream (its lattice and constant channels); streams
            whose plan follows scored steps keep their values.
        positions: (N, 3) float32 decoded positions.
        target_sh, target: the original scene in coding order: SH (N, K, 3) with DC first,
            and ``{"log_scales", "quats", "opacity_logits"}`` arrays; the renders to match.
        cameras: the viewing distribution.
        settings: the fit's settings.
        on_step: told ``(done, total)`` after each step.
        transforms: the SH colour transform of each band (``SHXF``'s ids, band 1 first):
            a band marked opponent is held in ``streams`` and refined in opponent colours,
            turned back to colours for the renders.

    Returns:
        {stream name: (N, C) float32} for every refined stream: values whose planning on the
        stream's lattice gives the refined decoded values (constant channels unchanged).
    """
    names = [name for name, plan in plans.items() if plan.scored is None]
    if settings.steps <= 0 or not names or not len(positions) or not cameras:
        return {}
    views = [_scaled(c, settings.width) for c in cameras]
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _fit(streams, plans, names, positions, target_sh, target, views, settings,
                    on_step, transforms)
    finally:
        torch.set_num_threads(threads)


class _StraightThrough:
    """One stream's lattice in torch: the decoded values forward, the identity backward."""

    def __init__(self, plan: StreamPlan, values: np.ndarray) -> None:
        self.scale = 2.0 ** plan.frac_bits
        self.step = float(step_size(np.array([plan.step_idx]))[0])
        self.means = torch.tensor([float(ch.mean) for ch in plan.channels], dtype=torch.float64)
        constant = [ch.is_constant for ch in plan.channels]
        self.constant = torch.tensor(constant)
        self.fixed = torch.as_tensor(values.astype(np.float64))
        self.low = torch.as_tensor(values.min(axis=0).astype(np.float64))
        self.high = torch.as_tensor(values.max(axis=0).astype(np.float64))
        self.step_value = self.step / self.scale

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        grid = torch.round(x.double() * self.scale)
        k = torch.floor((2 * (grid - self.means) + self.step) / (2 * self.step))
        decoded = (self.means + self.step * k) / self.scale
        decoded = torch.where(self.constant, self.fixed, decoded)
        return x + (decoded.to(x.dtype) - x).detach()

    def clamp_(self, x: torch.Tensor) -> None:
        """Keep ``x`` within the stream's original range per channel (so the grid the
        lattice was chosen for still holds it)."""
        with torch.no_grad():
            x.copy_(torch.minimum(torch.maximum(x.double(), self.low), self.high).to(x.dtype))


def _fit(streams: SceneStreams, plans: dict[str, StreamPlan], names: list[str],
         positions: np.ndarray, target_sh: np.ndarray, target: dict[str, np.ndarray],
         views: list[Camera], settings: RefineSettings, on_step,
         transforms: tuple[int, ...]) -> dict[str, np.ndarray]:
    values = streams.float_streams
    lattices = {s: _StraightThrough(plans[s], values[s]) for s in names}
    params = {s: torch.nn.Parameter(torch.as_tensor(values[s].astype(np.float32).copy()))
              for s in names}
    optimiser = torch.optim.Adam([{"params": [params[s]],
                                   "lr": settings.learning_rate * lattices[s].step_value}
                                  for s in names])
    decoded_fixed = {s: torch.as_tensor(plans[s].recon) for s in plans if s not in lattices}
    means = torch.as_tensor(np.ascontiguousarray(positions, np.float32))
    axis = torch.as_tensor(streams.rot_axis.astype(np.int64))
    n = len(positions)
    sh = torch.as_tensor(np.ascontiguousarray(target_sh, np.float32))
    goal = {k: torch.as_tensor(np.ascontiguousarray(v, np.float32)) for k, v in target.items()}
    targets: dict[int, torch.Tensor] = {}

    def target_image(v: int) -> torch.Tensor:
        """The original's render from view ``v`` (rendered when first drawn)."""
        if v not in targets:
            with torch.no_grad():
                targets[v] = rasterize_gaussians(
                    means, goal["log_scales"], goal["quats"], goal["opacity_logits"],
                    views[v], sh=sh, near_plane=views[v].near_plane,
                    compositor="auto").image
        return targets[v]

    rng = np.random.default_rng(settings.seed)
    per_step = min(settings.views_per_step, len(views))
    for done in range(1, settings.steps + 1):
        optimiser.zero_grad()
        decoded = {s: lattices[s](params[s]) if s in lattices else decoded_fixed[s]
                   for s in plans}
        coefficients = [decoded["dc"].reshape(n, 1, 3)]
        coefficients += [_as_colours(decoded[s], int(s[4:]), transforms).reshape(n, -1, 3)
                         for s in plans if s.startswith("rest")]
        sh_coded = torch.cat(coefficients, dim=1)
        quats = quaternions_from_smallest_three(axis, decoded["rot"])
        loss = 0.0
        for v in rng.choice(len(views), per_step, replace=False):
            # "auto": the numba compositor on these float32 CPU tensors (the torch
            # reference's images and gradients to float32 rounding, several times faster).
            image = rasterize_gaussians(means, decoded["scale"], quats,
                                        decoded["opacity"][:, 0], views[v],
                                        sh=_padded(sh_coded, sh.shape[1]),
                                        near_plane=views[v].near_plane,
                                        compositor="auto").image
            loss = loss + torch.mean((image - target_image(int(v))) ** 2)
        loss.backward()
        optimiser.step()
        for s in names:
            lattices[s].clamp_(params[s])
        if on_step is not None:
            on_step(done, settings.steps)
    return {s: params[s].detach().numpy().astype(np.float32) for s in names}


def _as_colours(values: torch.Tensor, band: int, transforms: tuple[int, ...]) -> torch.Tensor:
    """Band ``band``'s (N, 3K) values as colours: the opponent inverse of FORMAT §12.24 (in
    the tensor's precision, differentiable) where ``transforms`` marks the band opponent."""
    if band > len(transforms) or transforms[band - 1] != OPPONENT:
        return values
    y0, y1, y2 = values[:, 0::3] * INVERSE_A, values[:, 1::3] * INVERSE_B, values[:, 2::3]
    red = (y0 + y1) + INVERSE_C * y2
    green = y0 - INVERSE_D * y2
    blue = (y0 - y1) + INVERSE_C * y2
    return torch.stack([red, green, blue], dim=-1).reshape(values.shape)


def _padded(sh: torch.Tensor, count: int) -> torch.Tensor:
    """``sh`` (N, K, 3) with zero bands up to ``count`` coefficients (bands the codec does
    not code decode as zeros)."""
    if sh.shape[1] >= count:
        return sh
    return torch.cat([sh, sh.new_zeros(sh.shape[0], count - sh.shape[1], 3)], dim=1)


def _scaled(camera: Camera, width: int) -> Camera:
    """``camera`` rendered ``width`` pixels wide (intrinsics scaled, near plane kept)."""
    from csgs_codec.scene.cameras_io import resize_camera

    if camera.width <= width:
        return camera
    height = max(1, round(camera.height * width / camera.width))
    return replace(resize_camera(camera, width, height), near_plane=camera.near_plane)
