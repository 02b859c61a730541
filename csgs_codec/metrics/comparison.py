"""Scoring a candidate scene against a reference by rendering both from the same cameras.

Per view: PSNR and SSIM over the whole frame, and foreground PSNR over the pixels where the
reference render's accumulated opacity exceeds 0.05 (docs/design.md, 'Measuring quality';
the headline figure, since objects often cover a small part of an orbit frame). Images are
clipped to [0, 1] before scoring, as they would be when saved.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from csgs_codec.metrics.image import foreground_mask, foreground_psnr, psnr, ssim
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene


@dataclass(frozen=True)
class ViewScore:
    """Scores of one view; PSNRs in dB (inf when equal, foreground nan when no foreground)."""

    name: str
    psnr: float
    ssim: float
    foreground_psnr: float
    foreground_fraction: float


@dataclass
class ComparisonReport:
    """Per-view scores, their means and (optionally) the per-attribute errors.

    Means are over views. Views rendered identically (infinite PSNR) are left out of a PSNR
    mean unless every view is, in which case the mean is inf; the foreground mean also skips
    views with no foreground.
    """

    views: list[ViewScore]
    attribute_errors: dict[str, dict[str, float]] | None = None
    matching: dict[str, object] | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def mean_psnr(self) -> float:
        """Mean of the per-view PSNRs, dB."""
        return _mean([v.psnr for v in self.views])

    @property
    def mean_ssim(self) -> float:
        """Mean of the per-view SSIMs."""
        return _mean([v.ssim for v in self.views])

    @property
    def mean_foreground_psnr(self) -> float:
        """Mean of the per-view foreground PSNRs over views that have foreground, dB."""
        return _mean([v.foreground_psnr for v in self.views if not math.isnan(v.foreground_psnr)])

    def to_dict(self) -> dict:
        """Plain-Python form; inf stays float('inf'), nan stays float('nan')."""
        return {
            "views": [asdict(v) for v in self.views],
            "mean": {"psnr": self.mean_psnr, "ssim": self.mean_ssim,
                     "foreground_psnr": self.mean_foreground_psnr},
            "attribute_errors": self.attribute_errors,
            "matching": self.matching,
            "notes": list(self.notes),
        }


def score_views(reference, candidate, cameras: Sequence[Camera], *, backend: str = "auto",
                progress: Callable[[Iterable], Iterable] | None = None) -> list[ViewScore]:
    """Render both scenes from every camera (black background) and score each view.

    Either scene may be a :class:`GaussianScene` or an anchor scene (``AnchorScene``, its
    neural Gaussians decoded for each camera)."""
    from csgs_codec.render.rasterizer import render

    reference, candidate = _views(reference), _views(candidate)
    scores = []
    for camera in (progress or iter)(list(cameras)):
        ref = render(reference.gaussians(camera), camera, backend=backend)
        scores.append(score_view(ref, candidate, camera, backend=backend))
    return scores


def render_references(reference, cameras: Sequence[Camera], *, backend: str = "auto") -> list:
    """The reference renders (RenderOutput) of every camera, to score many candidates
    (``reference``: a GaussianScene or an AnchorScene)."""
    from csgs_codec.render.rasterizer import render

    reference = _views(reference)
    return [render(reference.gaussians(camera), camera, backend=backend)
            for camera in cameras]


def score_view(reference_render, candidate, camera: Camera, *,
               backend: str = "auto") -> ViewScore:
    """Score ``candidate`` (a GaussianScene or AnchorScene) rendered from ``camera`` against
    an existing reference render."""
    from csgs_codec.render.rasterizer import render

    cand = render(_views(candidate).gaussians(camera), camera, backend=backend)
    ref_image, cand_image = to_unit_range(reference_render.image), to_unit_range(cand.image)
    mask = foreground_mask(reference_render.alpha)
    return ViewScore(
        name=camera.name,
        psnr=psnr(ref_image, cand_image),
        ssim=ssim(ref_image, cand_image),
        foreground_psnr=foreground_psnr(ref_image, cand_image, mask),
        foreground_fraction=float(mask.mean()),
    )


def compare_scenes(reference, candidate, cameras: Sequence[Camera], *,
                   attributes: bool = True, backend: str = "auto",
                   progress: Callable[[Iterable], Iterable] | None = None) -> ComparisonReport:
    """Render scores over ``cameras`` plus, if ``attributes``, per-attribute errors.

    Either scene may be a :class:`GaussianScene` or an anchor scene (rendered exactly, per
    view); attribute errors need two Gaussian scenes, and a note says when they were left
    out."""
    report = ComparisonReport(views=score_views(reference, candidate, cameras, backend=backend,
                                                progress=progress))
    if attributes and not (isinstance(reference, GaussianScene)
                           and isinstance(candidate, GaussianScene)):
        report.notes.append("attribute errors compare two Gaussian scenes; an anchor scene's "
                            "Gaussians depend on the view, so only renders were scored")
    elif attributes:
        from csgs_codec.metrics.attribute_errors import attribute_errors

        errors, matching = attribute_errors(reference, candidate)
        report.attribute_errors = errors
        report.matching = {"method": matching.method, "max_distance": matching.max_distance,
                           "unpicked_candidates": matching.unpicked_candidates,
                           "reference_gaussians": len(reference),
                           "candidate_gaussians": len(candidate)}
        if len(reference) != len(candidate):
            report.notes.append(f"Gaussian counts differ ({len(reference)} vs "
                                f"{len(candidate)}): attribute errors pair each reference "
                                "Gaussian with its nearest candidate")
    return report


def _views(scene):
    """``scene`` as per-camera Gaussians (:class:`~csgs_codec.model.anchor_views.SceneViews`);
    imported here so that comparing standard scenes never loads the anchor model."""
    from csgs_codec.model.anchor_views import scene_views

    return scene_views(scene)


def to_unit_range(image: np.ndarray) -> np.ndarray:
    """The image clipped to [0, 1], float32 (what a saved PNG holds, before 8-bit rounding)."""
    return np.clip(np.asarray(image, dtype=np.float32), 0.0, 1.0)


def _mean(values: list[float]) -> float:
    if not values:
        return float("nan")
    finite = [v for v in values if not math.isinf(v)]
    return float(np.mean(finite)) if finite else math.inf
