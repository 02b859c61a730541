"""Rate control: the smallest encode whose renders reach a target foreground PSNR.

The encoder renders the original scene from a few low-resolution orbit views once, then
searches the step multiplier (all steps and the grid bits scale together, as between the
quality presets; :func:`csgs_codec.codec.presets.scaled_preset`): it encodes, renders the
encoder's own reconstruction (which equals what the decoder will output) and searches the
multiplier's logarithm, along which PSNR falls almost linearly (about 6 dB per octave), by
interpolation inside a bracket that always holds the target (the Illinois variant of
regula falsi), keeping the coarsest encode that meets the target.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from csgs_codec.codec.presets import scaled_preset
from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Probe views: few and small, so a search step costs about one encode.
PROBE_VIEWS = 4
PROBE_SIZE = (256, 192)
#: The multiplier is searched in [2^LOG2_LO, 2^LOG2_HI] (finer than quality 9 .. coarser
#: than quality 1).
LOG2_LO = -4.0
LOG2_HI = 5.0
SEARCH_STEPS = 6
#: The search stops once an encode meets the target by less than this, dB.
TOLERANCE = 0.3
#: ... or once the bracket is narrower than this (octaves of the multiplier): the grid bits
#: change in whole steps, so PSNR can jump across the target there.
MIN_BRACKET = 0.1
MIN_TARGET, MAX_TARGET = 10.0, 90.0


class RenderProbe:
    """Foreground PSNR of candidate scenes against the original, on fixed orbit views.

    Args:
        original: the scene as given to the encoder.
        views, size: number of orbit views and their (width, height) in pixels.
        backend: renderer backend (see :func:`csgs_codec.render.rasterizer.render`).
    """

    def __init__(self, original: GaussianScene, *, views: int = PROBE_VIEWS,
                 size: tuple[int, int] = PROBE_SIZE, backend: str = "auto") -> None:
        from csgs_codec.render.comparison import render_references
        from csgs_codec.render.orbit import orbit_cameras

        self.backend = backend
        self.cameras = orbit_cameras(original, views, width=size[0], height=size[1])
        self.references = render_references(original, self.cameras, backend=backend)

    def psnr(self, candidate: GaussianScene) -> float:
        """Mean foreground PSNR (dB) of ``candidate`` over the views that have foreground;
        inf when every view renders identically."""
        from csgs_codec.render.comparison import score_view

        scores = [score_view(ref, candidate, cam, backend=self.backend).foreground_psnr
                  for ref, cam in zip(self.references, self.cameras)]
        finite = [s for s in scores if not math.isnan(s)]
        return float(np.mean(finite)) if finite else math.inf


@dataclass(frozen=True)
class RateControlReport:
    """What the search did: the multiplier kept, its probe PSNR and every trial.

    Attributes:
        multiplier: step multiplier of the kept encode.
        psnr: its mean foreground PSNR on the probe views, dB.
        target: the PSNR asked for, dB.
        trials: (multiplier, bytes, psnr) of every encode tried, in order.
    """

    multiplier: float
    psnr: float
    target: float
    trials: tuple[tuple[float, int, float], ...]


def check_target(target_psnr: float) -> None:
    """InputError unless ``target_psnr`` is a finite dB value in [10, 90]."""
    if not math.isfinite(target_psnr) or not MIN_TARGET <= target_psnr <= MAX_TARGET:
        raise InputError(f"target PSNR must be between {MIN_TARGET:g} and {MAX_TARGET:g} dB, "
                         f"got {target_psnr}", property="target_psnr")


def encode_to_target(encode: Callable, scene: GaussianScene, target_psnr: float, *,
                     probe: RenderProbe | None = None, progress=None):
    """The coarsest encode of ``scene`` whose probe PSNR is at least ``target_psnr``.

    Args:
        encode: ``encode(preset) -> EncodeResult`` for a :class:`Preset`.
        probe: the views to score on (made from ``scene`` when None).
        progress: ``progress(message)`` told of each trial, or None.

    Returns:
        (EncodeResult, RateControlReport). When even the finest multiplier misses the
        target, that encode is returned with a CsgsWarning saying what it reached.
    """
    check_target(target_psnr)
    probe = probe or RenderProbe(scene)
    trials = []

    def trial(log2_multiplier: float):
        multiplier = 2.0 ** log2_multiplier
        result = encode(scaled_preset(multiplier))
        psnr = probe.psnr(result.reconstruction)
        trials.append((multiplier, len(result.data), psnr))
        if progress:
            progress(f"rate control: x{multiplier:.3g} steps -> {psnr:.2f} dB")
        return result, psnr

    lo, hi = LOG2_LO, LOG2_HI
    result, psnr_hi = trial(hi)
    if psnr_hi >= target_psnr:
        best = (result, psnr_hi, hi)
    else:
        result, psnr_lo = trial(lo)
        best = (result, psnr_lo, lo)
        if psnr_lo < target_psnr:
            warnings.warn(f"target {target_psnr:.2f} dB not reached: the finest steps give "
                          f"{psnr_lo:.2f} dB on the probe views", CsgsWarning, stacklevel=2)
        # Invariant: psnr(lo) >= target > psnr(hi); f = psnr - target.
        f_lo, f_hi, side = psnr_lo - target_psnr, psnr_hi - target_psnr, 0
        for _ in range(SEARCH_STEPS if psnr_lo >= target_psnr else 0):
            if (best[1] - target_psnr < TOLERANCE or not math.isfinite(f_lo)
                    or hi - lo < MIN_BRACKET):
                break
            mid = lo + (hi - lo) * f_lo / (f_lo - f_hi)
            mid = min(max(mid, lo + 0.02 * (hi - lo)), hi - 0.02 * (hi - lo))
            result, psnr = trial(mid)
            if psnr >= target_psnr:
                best, lo, f_lo = (result, psnr, mid), mid, psnr - target_psnr
                f_hi = f_hi / 2 if side == 1 else f_hi
                side = 1
            else:
                hi, f_hi = mid, psnr - target_psnr
                f_lo = f_lo / 2 if side == -1 else f_lo
                side = -1
    result, psnr, log2_multiplier = best
    report = RateControlReport(2.0 ** log2_multiplier, psnr, target_psnr, tuple(trials))
    return result, report
