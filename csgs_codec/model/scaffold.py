"""The Scaffold-GS MLPs and the view-dependent decode of anchors into neural Gaussians.

Follows the official renderer (github.com/city-super/Scaffold-GS,
``gaussian_renderer/__init__.py`` ``generate_neural_gaussians``): for a camera centre c and
anchor i, ``d = x_i - c``, view direction ``d / |d|`` and distance ``|d|``; each head sees
``[f_i, d / |d|, (|d|), (appearance)]``. Opacity is the tanh head's output and a Gaussian
exists only where it is > 0 (masked offsets get opacity 0 and so vanish); color is the
sigmoid head's RGB; scale is ``exp(l[3:]) * sigmoid(cov[:3])``; rotation is ``cov[3:7]``
normalized (w, x, y, z); position is ``x + O_k * exp(l[:3])``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.nn import functional

from csgs_codec.errors import ModelError
from csgs_codec.scene.anchor_scene import AnchorScene, MLPWeights, ScaffoldMLPWeights
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Degree-0 spherical harmonic constant: rgb = 0.5 + C0 * sh_dc.
SH_C0 = 0.28209479177387814
#: Opacities are capped just below 1 before the logit so it stays finite in float32.
MAX_OPACITY = 1.0 - 2.0**-24


def _head(in_dim: int, hidden: int, out_dim: int, activation: nn.Module | None,
          device: torch.device | str) -> nn.Sequential:
    layers: list[nn.Module] = [nn.Linear(in_dim, hidden, device=device), nn.ReLU(True),
                               nn.Linear(hidden, out_dim, device=device)]
    if activation is not None:
        layers.append(activation)
    return nn.Sequential(*layers)


class ScaffoldMLPs(nn.Module):
    """The three Scaffold-GS heads (and optional appearance embedding) as torch modules.

    Each head is ``nn.Sequential(Linear(D, H), ReLU, Linear(H, O)[, activation])`` with the
    official state-dict keys (``0.weight``, ``0.bias``, ``2.weight``, ``2.bias``).

    Args:
        feat_dim: anchor feature width F.
        n_offsets: offsets per anchor K.
        hidden: hidden width H (Scaffold-GS uses F).
        opacity_dist, cov_dist, color_dist: whether each head takes the distance input
            (HAC and CSGaussian: all True; Scaffold-GS defaults: all False).
        appearance_count, appearance_dim: size of the per-camera appearance embedding table
            (0 for none); its vector is appended to the color head's input.
        device: where the parameters are made.
    """

    def __init__(self, feat_dim: int = 50, n_offsets: int = 10, hidden: int | None = None, *,
                 opacity_dist: bool = True, cov_dist: bool = True, color_dist: bool = True,
                 appearance_count: int = 0, appearance_dim: int = 0,
                 device: torch.device | str = "cpu") -> None:
        super().__init__()
        hidden = feat_dim if hidden is None else hidden
        self.feat_dim, self.n_offsets = feat_dim, n_offsets
        self.opacity_dist, self.cov_dist, self.color_dist = opacity_dist, cov_dist, color_dist
        self.opacity = _head(feat_dim + 3 + opacity_dist, hidden, n_offsets, nn.Tanh(), device)
        self.cov = _head(feat_dim + 3 + cov_dist, hidden, 7 * n_offsets, None, device)
        self.color = _head(feat_dim + 3 + color_dist + appearance_dim, hidden, 3 * n_offsets,
                           nn.Sigmoid(), device)
        self.appearance = (nn.Embedding(appearance_count, appearance_dim, device=device)
                           if appearance_count and appearance_dim else None)

    @classmethod
    def from_weights(cls, weights: ScaffoldMLPWeights, feat_dim: int, n_offsets: int, *,
                     device: torch.device | str = "cpu") -> ScaffoldMLPs:
        """Modules holding exactly ``weights`` (validated against F and K first), on
        ``device``.

        Raises:
            InputError: the weights do not fit F and K.
        """
        weights.validate(feat_dim, n_offsets)
        appearance = weights.appearance
        module = cls(feat_dim, n_offsets, int(weights.opacity.w1.shape[0]),
                     opacity_dist=weights.uses_distance("opacity", feat_dim),
                     cov_dist=weights.uses_distance("cov", feat_dim),
                     color_dist=weights.uses_distance("color", feat_dim),
                     appearance_count=0 if appearance is None else appearance.shape[0],
                     appearance_dim=weights.appearance_dim, device=device)
        for name, head in weights.heads().items():
            seq = getattr(module, name)
            if seq[0].out_features != head.w1.shape[0] or seq[2].in_features != head.w2.shape[1]:
                seq[0] = nn.Linear(head.in_dim, head.w1.shape[0], device=device)
                seq[2] = nn.Linear(head.w1.shape[0], head.out_dim, device=device)
            with torch.no_grad():
                seq[0].weight.copy_(torch.as_tensor(head.w1, device=device))
                seq[0].bias.copy_(torch.as_tensor(head.b1, device=device))
                seq[2].weight.copy_(torch.as_tensor(head.w2, device=device))
                seq[2].bias.copy_(torch.as_tensor(head.b2, device=device))
        if module.appearance is not None:
            with torch.no_grad():
                module.appearance.weight.copy_(torch.as_tensor(appearance, device=device))
        return module.eval()

    def to_weights(self) -> ScaffoldMLPWeights:
        """The current weights as numpy float32 arrays."""

        def arr(t: torch.Tensor) -> np.ndarray:
            return t.detach().to(torch.float32).cpu().numpy().copy()

        heads = {name: MLPWeights(arr(seq[0].weight), arr(seq[0].bias), arr(seq[2].weight),
                                  arr(seq[2].bias))
                 for name, seq in (("opacity", self.opacity), ("cov", self.cov),
                                   ("color", self.color))}
        appearance = None if self.appearance is None else arr(self.appearance.weight)
        return ScaffoldMLPWeights(appearance=appearance, **heads)

    def appearance_vector(self, index: int | None) -> torch.Tensor | None:
        """(A,) embedding of training camera ``index``; the table mean when None."""
        if self.appearance is None:
            return None
        table = self.appearance.weight
        if index is None:
            return table.mean(dim=0)
        if not 0 <= index < table.shape[0]:
            raise ModelError(f"appearance index {index} outside 0..{table.shape[0] - 1}",
                             property="appearance")
        return table[index]

    def forward(self, features: torch.Tensor, view_dir: torch.Tensor, dist: torch.Tensor,
                appearance_index: int | None = None, *, merge_first_layers: bool = False
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Evaluate the heads for M anchors.

        Args:
            features: [M, F] anchor features.
            view_dir: [M, 3] unit vectors from the camera centre to the anchors.
            dist: [M, 1] anchor-camera distances, world units.
            appearance_index: training camera whose appearance vector the color head gets
                (None: the mean vector); ignored without an appearance table.
            merge_first_layers: where the three heads see the same input (the same distance
                flag, no appearance table), run their first layers as one matrix product
                (training on a GPU, bound by operator launches, takes this; the sums may
                round differently, so decoding does not).

        Returns:
            opacity [M, K] in (-1, 1); cov [M, K, 7] (3 scale logits, 4 quaternion w,x,y,z);
            color [M, K, 3] RGB in (0, 1).
        """
        m, k = features.shape[0], self.n_offsets
        inputs: dict[bool, torch.Tensor] = {}

        def head_input(with_distance: bool) -> torch.Tensor:
            if with_distance not in inputs:
                parts = [features, view_dir, dist] if with_distance else [features, view_dir]
                inputs[with_distance] = torch.cat(parts, dim=1)
            return inputs[with_distance]

        heads = (self.opacity, self.cov, self.color)
        if (merge_first_layers and self.appearance is None
                and self.opacity_dist == self.cov_dist == self.color_dist):
            first = [head[0] for head in heads]
            hidden = functional.relu(functional.linear(
                head_input(self.opacity_dist), torch.cat([layer.weight for layer in first]),
                torch.cat([layer.bias for layer in first])))
            parts = hidden.split([layer.out_features for layer in first], dim=1)
            opacity, cov, color = (head[2:](part) for head, part in zip(heads, parts))
            return opacity, cov.reshape(m, k, 7), color.reshape(m, k, 3)
        opacity = self.opacity(head_input(self.opacity_dist))
        cov = self.cov(head_input(self.cov_dist)).reshape(m, k, 7)
        color_in = head_input(self.color_dist)
        vector = self.appearance_vector(appearance_index)
        if vector is not None:
            color_in = torch.cat([color_in, vector.expand(m, -1)], dim=1)
        color = self.color(color_in).reshape(m, k, 3)
        return opacity, cov, color


@dataclass
class NeuralGaussians:
    """The neural Gaussians of one view, activated, as torch tensors (differentiable).

    Attributes:
        positions: [N, 3] world units.
        colors: [N, 3] RGB in (0, 1).
        opacities: [N] in [0, 1) (0 only for the hidden slots of an ``all_slots`` spawn).
        log_scales: [N, 3] natural-log scales.
        rotations: [N, 4] quaternions (w, x, y, z), unit length except in an ``all_slots``
            spawn, which leaves normalising to the rasterizer (both do it).
        anchor_index: [N] int64 anchor of each Gaussian.
        offset_index: [N] int64 offset slot k of each Gaussian.
        keep: [M * K] bool, which anchor-offset slots produced a Gaussian.
        all_slots: True when N = M * K, every slot in order, those not kept with opacity 0
            (see :func:`neural_gaussians`).
    """

    positions: torch.Tensor
    colors: torch.Tensor
    opacities: torch.Tensor
    log_scales: torch.Tensor
    rotations: torch.Tensor
    anchor_index: torch.Tensor
    offset_index: torch.Tensor
    keep: torch.Tensor
    all_slots: bool = False

    @property
    def scales(self) -> torch.Tensor:
        """[N, 3] scales, world units (exp of ``log_scales``)."""
        return torch.exp(self.log_scales)


def neural_gaussians(mlps: ScaffoldMLPs, positions: torch.Tensor, features: torch.Tensor,
                     offsets: torch.Tensor, scaling: torch.Tensor, offset_mask: torch.Tensor,
                     camera_center: torch.Tensor, appearance_index: int | None = None, *,
                     all_slots: bool = False) -> NeuralGaussians:
    """Spawn the neural Gaussians of M anchors seen from ``camera_center`` (Scaffold's rule).

    Args:
        positions [M, 3], features [M, F], offsets [M, K, 3], scaling [M, 6] (log),
        offset_mask [M, K] bool, camera_center [3]: world units.
        all_slots: return every one of the M * K slots, those not kept with opacity 0 (a
            rasterizer draws nothing of them and gives them no gradient), instead of
            gathering the kept ones. The same image and gradients with neither a host
            synchronisation (the count of kept slots) nor gathers and their scatters in the
            backward pass: the form for a GPU, where a training step is bound by how many
            operators it launches; the gathered form suits a CPU, whose rasterizer pays for
            every Gaussian. Its rotations are not normalised (the rasterizers normalise) and
            its heads run with ``merge_first_layers``.

    Returns:
        the kept Gaussians (opacity > 0 and unmasked), anchor-major, offsets in order (or
        every slot, see ``all_slots``).
    """
    m, k = offsets.shape[0], offsets.shape[1]
    delta = positions - camera_center.reshape(1, 3)
    dist = delta.norm(dim=1, keepdim=True)
    view_dir = delta / dist.clamp_min(torch.finfo(delta.dtype).tiny)
    opacity, cov, color = mlps(features, view_dir, dist, appearance_index,
                               merge_first_layers=all_slots)
    opacity = opacity * offset_mask.to(opacity.dtype)
    keep = (opacity > 0).reshape(-1)
    if all_slots:
        slot = torch.arange(m * k, device=positions.device)
        step = torch.exp(scaling[:, :3])
        centers = positions[:, None, :] + offsets * step[:, None, :]
        scale_logits, rotations = cov.split([3, 4], dim=-1)
        log_scales = scaling[:, None, 3:] + functional.logsigmoid(scale_logits)
        return NeuralGaussians(
            positions=centers.reshape(m * k, 3), colors=color.reshape(m * k, 3),
            opacities=opacity.clamp_min(0.0).reshape(-1),
            log_scales=log_scales.reshape(m * k, 3), rotations=rotations.reshape(m * k, 4),
            anchor_index=slot // k, offset_index=slot % k, keep=keep, all_slots=True)
    slots = torch.nonzero(keep).reshape(-1)
    anchor_index, offset_index = slots // k, slots % k
    cov = cov.reshape(m * k, 7)[slots]
    step = torch.exp(scaling[:, :3])[anchor_index]  # exp per anchor, gathered per Gaussian
    log_scales = scaling[anchor_index, 3:] + functional.logsigmoid(cov[:, :3])
    centers = positions[anchor_index] + offsets.reshape(m * k, 3)[slots] * step
    return NeuralGaussians(
        positions=centers, colors=color.reshape(m * k, 3)[slots],
        opacities=opacity.reshape(-1)[slots], log_scales=log_scales,
        rotations=functional.normalize(cov[:, 3:7], dim=1), anchor_index=anchor_index,
        offset_index=offset_index, keep=keep)


@dataclass
class DecodedView:
    """A view's neural Gaussians as a standard scene plus where each Gaussian came from.

    Attributes:
        gaussians: the N Gaussians as a :class:`GaussianScene` (color as SH DC, opacity as
            logit, log-scales, normalized rotations; anchor semantic/labels repeated).
        anchor_index: (N,) int64 source anchor of each Gaussian.
        offset_index: (N,) int64 offset slot k of each Gaussian.
    """

    gaussians: GaussianScene
    anchor_index: np.ndarray
    offset_index: np.ndarray


class ScaffoldDecoder:
    """Decodes an :class:`AnchorScene` into standard Gaussians for a view.

    Args:
        scene: the anchors (validated here).
        mlps: the heads; default: built from ``scene.mlps`` on the CPU. The anchors are
            decoded on the heads' device.
        appearance_index: training camera whose appearance embedding the color head uses
            (None: the mean embedding, a neutral choice for novel views).

    Raises:
        ModelError: the scene has no MLPs and none are given.
        InputError: the scene is invalid.
    """

    def __init__(self, scene: AnchorScene, mlps: ScaffoldMLPs | None = None, *,
                 appearance_index: int | None = None) -> None:
        scene.validate()
        if mlps is None:
            if scene.mlps is None:
                raise ModelError("the anchor scene has no Scaffold-GS MLPs", property="mlps")
            mlps = ScaffoldMLPs.from_weights(scene.mlps, scene.feat_dim, scene.n_offsets)
        self.scene, self.mlps, self.appearance_index = scene, mlps.eval(), appearance_index
        self._device = next(mlps.parameters()).device
        self._tensors = [torch.as_tensor(a, device=self._device)
                         for a in (scene.positions, scene.features, scene.offsets,
                                   scene.scaling, scene.offset_mask)]

    def scene_center(self) -> np.ndarray:
        """(3,) float64 centre of the anchors' bounding box (origin for an empty scene)."""
        if len(self.scene) == 0:
            return np.zeros(3)
        p = self.scene.positions.astype(np.float64)
        return (p.min(axis=0) + p.max(axis=0)) / 2

    def decode(self, view_origin: np.ndarray) -> DecodedView:
        """The neural Gaussians seen from the point ``view_origin`` ((3,) world units)."""
        origin = torch.as_tensor(np.asarray(view_origin, np.float64).reshape(3),
                                 dtype=torch.float32, device=self._device)
        with torch.no_grad():
            g = neural_gaussians(self.mlps, *self._tensors, origin, self.appearance_index)
        anchor_index = g.anchor_index.cpu().numpy()
        opacity = np.minimum(g.opacities.cpu().numpy().astype(np.float64), MAX_OPACITY)
        s = self.scene
        scene = GaussianScene(
            positions=g.positions.cpu().numpy().astype(np.float32),
            sh_dc=((g.colors.cpu().numpy() - 0.5) / SH_C0).astype(np.float32),
            sh_rest=np.zeros((len(anchor_index), 0, 3), np.float32),
            opacity=(np.log(opacity) - np.log1p(-opacity)).astype(np.float32),
            scales=g.log_scales.cpu().numpy().astype(np.float32),
            rotations=g.rotations.cpu().numpy().astype(np.float32),
            semantic=None if s.semantic is None else s.semantic[anchor_index],
            semantic_names=s.semantic_names if s.semantic is not None else (),
            labels=None if s.labels is None else s.labels[anchor_index])
        return DecodedView(scene, anchor_index, g.offset_index.cpu().numpy())

    def to_gaussians(self, camera: Camera) -> GaussianScene:
        """The neural Gaussians for ``camera`` (view direction and distance from its centre)."""
        return self.decode(camera.position).gaussians

    def export_gaussians(self, camera: Camera | None = None,
                         origin: np.ndarray | None = None) -> GaussianScene:
        """A view-independent standard scene: the MLPs evaluated for one canonical view.

        The view origin is ``camera``'s centre, else ``origin``, else the anchors' bounding-box
        centre (each anchor then seen along the ray from the scene centre). Gaussians whose
        opacity is <= 0 from that origin are left out, as Scaffold-GS does.
        """
        if camera is not None:
            return self.to_gaussians(camera)
        return self.decode(self.scene_center() if origin is None else origin).gaussians
