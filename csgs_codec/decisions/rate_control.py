"""Rate control: the smallest encode whose renders reach a target foreground PSNR, or the
encode that minimises a rate-distortion cost J = D + lambda * R.

The encoder renders the original scene from a few low-resolution orbit views once, then
searches the step multiplier (all steps and the grid bits scale together, as between the
quality presets; :func:`csgs_codec.decisions.presets.scaled_preset`): it encodes, renders the
encoder's own reconstruction (which equals what the decoder will output) and searches the
multiplier's logarithm, along which PSNR falls almost linearly (about 6 dB per octave), by
interpolation inside a bracket that always holds the target (the Illinois variant of
regula falsi), keeping the coarsest encode that meets the target.

With a Lagrange weight instead (:func:`encode_for_lambda`), it minimises
J = D + lambda * R over the same multiplier by golden-section search, D the probe's
foreground mean squared error in squared 8-bit levels and R the file's bits per Gaussian, so
lambda is in squared 8-bit levels per bit per Gaussian (about 0.25 lands near quality 5 on
samples/donut.ply). Fast mode searches with fewer encodes (``FAST_*``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from csgs_codec.decisions.presets import scaled_preset
from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Probe views: few and small, so a search step costs about one encode.
PROBE_VIEWS = 4
PROBE_SIZE = (256, 192)
#: The multiplier is searched in [2^LOG2_LO, 2^LOG2_HI] (about quality 12's steps .. coarser
#: than quality 1).
LOG2_LO = -5.0
LOG2_HI = 5.0
SEARCH_STEPS = 6
#: The search stops once an encode meets the target by less than this, dB.
TOLERANCE = 0.3
#: ... or once the bracket is narrower than this (octaves of the multiplier): the grid bits
#: change in whole steps, so PSNR can jump across the target there.
MIN_BRACKET = 0.1
MIN_TARGET, MAX_TARGET = 10.0, 90.0
#: Encodes of the lambda search (golden section: the bracket shrinks by 0.618 per encode
#: after the first two; 10 leave about 0.2 octave of the 9-octave range).
LAMBDA_STEPS = 10
#: Fast mode: fewer encodes, a looser PSNR tolerance (dB); the lambda search also scores on
#: half the probe views (rendering them costs more than an encode).
FAST_PROBE_VIEWS = 2
FAST_SEARCH_STEPS = 3
FAST_TOLERANCE = 1.0
FAST_LAMBDA_STEPS = 6
#: Accepted lambda range, squared 8-bit levels per bit per Gaussian.
MIN_LAMBDA, MAX_LAMBDA = 1e-6, 1e6
_INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0


class RenderProbe:
    """Foreground PSNR of candidate scenes against the original, on fixed orbit views.

    Args:
        original: the scene as given to the encoder.
        views, size: number of orbit views and their (width, height) in pixels.
        backend: renderer backend (see :func:`csgs_codec.render.rasterizer.render`).
    """

    def __init__(self, original: GaussianScene, *, views: int = PROBE_VIEWS,
                 size: tuple[int, int] = PROBE_SIZE, backend: str = "auto") -> None:
        from csgs_codec.metrics.comparison import render_references
        from csgs_codec.scene.orbit import orbit_cameras

        self.backend = backend
        self.cameras = orbit_cameras(original, views, width=size[0], height=size[1])
        self.references = render_references(original, self.cameras, backend=backend)

    def psnr(self, candidate: GaussianScene) -> float:
        """Mean foreground PSNR (dB) of ``candidate`` over the views that have foreground;
        inf when every view renders identically."""
        from csgs_codec.metrics.comparison import score_view

        scores = [score_view(ref, candidate, cam, backend=self.backend).foreground_psnr
                  for ref, cam in zip(self.references, self.cameras)]
        finite = [s for s in scores if not math.isnan(s)]
        return float(np.mean(finite)) if finite else math.inf

    def mse(self, candidate: GaussianScene) -> float:
        """Mean over the views with foreground of ``candidate``'s foreground mean squared
        error against the original, in squared 8-bit levels ((255 x error)^2); 0 when no
        view has foreground."""
        from csgs_codec.metrics.comparison import to_unit_range
        from csgs_codec.metrics.image import foreground_mask
        from csgs_codec.render.rasterizer import render

        errors = []
        for ref, cam in zip(self.references, self.cameras):
            mask = foreground_mask(ref.alpha)
            if mask.any():
                image = to_unit_range(render(candidate, cam, backend=self.backend).image)
                diff = image[mask].astype(np.float64) - to_unit_range(ref.image)[mask]
                errors.append(float(np.mean(diff ** 2)) * 255.0 ** 2)
        return float(np.mean(errors)) if errors else 0.0


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

    def summary(self) -> str:
        """One line for a user: what was reached and how."""
        return (f"{self.psnr:.2f} dB on the probe views (target {self.target:.2f} dB), steps "
                f"x{self.multiplier:.3g} of quality 8's, {len(self.trials)} trial encodes")


@dataclass(frozen=True)
class LambdaReport:
    """What the lambda search kept: the multiplier minimising J = D + lambda * R.

    Attributes:
        lambda_: the Lagrange weight, squared 8-bit levels per bit per Gaussian.
        multiplier: step multiplier of the kept encode.
        distortion: its D, the probe's foreground MSE in squared 8-bit levels.
        rate: its R, file bits per Gaussian.
        cost: its J = D + lambda * R.
        trials: (multiplier, bytes, D, J) of every encode tried, in order.
    """

    lambda_: float
    multiplier: float
    distortion: float
    rate: float
    cost: float
    trials: tuple[tuple[float, int, float, float], ...]

    def summary(self) -> str:
        """One line for a user: the kept multiplier and its cost."""
        return (f"lambda {self.lambda_:g}: steps x{self.multiplier:.3g} of quality 8's, "
                f"D {self.distortion:.4g} (8-bit levels^2), R {self.rate:.2f} bits/Gaussian, "
                f"J {self.cost:.4g}, {len(self.trials)} trial encodes")


def check_target(target_psnr: float) -> None:
    """InputError unless ``target_psnr`` is a finite dB value in [10, 90]."""
    if not math.isfinite(target_psnr) or not MIN_TARGET <= target_psnr <= MAX_TARGET:
        raise InputError(f"target PSNR must be between {MIN_TARGET:g} and {MAX_TARGET:g} dB, "
                         f"got {target_psnr}", property="target_psnr")


def check_render_lambda(lam: float) -> None:
    """InputError (property ``lambda``) unless ``lam`` is a finite weight in
    [MIN_LAMBDA, MAX_LAMBDA] squared 8-bit levels per bit per Gaussian."""
    try:
        value = float(lam)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value) or not MIN_LAMBDA <= value <= MAX_LAMBDA:
        raise InputError(f"lambda must be a finite number in [{MIN_LAMBDA:g}, {MAX_LAMBDA:g}]"
                         f" (squared 8-bit levels per bit per Gaussian), got {lam!r}",
                         property="lambda")


def target_search(scene: GaussianScene, target_psnr: float, *,
                  probe: RenderProbe | None = None, progress=None,
                  search_steps: int = SEARCH_STEPS, tolerance: float = TOLERANCE):
    """The search for the coarsest encode of ``scene`` whose probe PSNR is at least
    ``target_psnr``, as a generator the encoder drives: it yields the :class:`Preset` to
    encode next and is sent that encode's EncodeReport, so the search never calls back into
    the encoder (``Encoder._search`` drives it).

    Args:
        probe: the views to score on (made from ``scene`` when None).
        progress: ``progress(message)`` told of each trial, or None.
        search_steps, tolerance: at most this many encodes inside the bracket; stop once
            one meets the target by less than ``tolerance`` dB.

    Returns (as the generator's value):
        (EncodeReport, RateControlReport). When even the finest multiplier misses the
        target, that encode is returned with a CsgsWarning saying what it reached.
    """
    check_target(target_psnr)
    probe = probe or RenderProbe(scene)
    trials = []

    def score(log2_multiplier: float, result) -> float:
        psnr = probe.psnr(result.reconstruction)
        trials.append((2.0 ** log2_multiplier, len(result.data), psnr))
        if progress:
            progress(f"rate control: x{2.0 ** log2_multiplier:.3g} steps -> {psnr:.2f} dB")
        return psnr

    lo, hi = LOG2_LO, LOG2_HI
    result = yield scaled_preset(2.0 ** hi)
    psnr_hi = score(hi, result)
    if psnr_hi >= target_psnr:
        best = (result, psnr_hi, hi)
    else:
        result = yield scaled_preset(2.0 ** lo)
        psnr_lo = score(lo, result)
        best = (result, psnr_lo, lo)
        if psnr_lo < target_psnr:
            warnings.warn(f"target {target_psnr:.2f} dB not reached: the finest steps give "
                          f"{psnr_lo:.2f} dB on the probe views", CsgsWarning, stacklevel=2)
        # Invariant: psnr(lo) >= target > psnr(hi); f = psnr - target.
        f_lo, f_hi, side = psnr_lo - target_psnr, psnr_hi - target_psnr, 0
        for _ in range(search_steps if psnr_lo >= target_psnr else 0):
            if (best[1] - target_psnr < tolerance or not math.isfinite(f_lo)
                    or hi - lo < MIN_BRACKET):
                break
            mid = lo + (hi - lo) * f_lo / (f_lo - f_hi)
            mid = min(max(mid, lo + 0.02 * (hi - lo)), hi - 0.02 * (hi - lo))
            result = yield scaled_preset(2.0 ** mid)
            psnr = score(mid, result)
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


def lambda_search(scene: GaussianScene, lam: float, *, probe: RenderProbe | None = None,
                  progress=None, steps: int = LAMBDA_STEPS):
    """The search for the encode of ``scene`` minimising J = D + ``lam`` * R over the step
    multiplier, as a generator the encoder drives (see :func:`target_search`).

    Golden-section search over log2(multiplier) in [LOG2_LO, LOG2_HI] (J is close to convex
    there: D grows about 4x per octave, R falls about linearly); the trial with the least J
    is kept. Deterministic for a given scene and machine.

    Args:
        lam: squared 8-bit levels per bit per Gaussian (see the module docstring).
        probe: the views to score on (made from ``scene`` when None).
        progress: ``progress(message)`` told of each trial, or None.
        steps: encodes in all (>= 2).

    Returns (as the generator's value):
        (EncodeReport, LambdaReport).
    """
    check_render_lambda(lam)
    probe = probe or RenderProbe(scene)
    count = max(1, len(scene))
    trials, best = [], None

    def cost(log2_multiplier: float, result) -> float:
        nonlocal best
        multiplier = 2.0 ** log2_multiplier
        distortion = probe.mse(result.reconstruction)
        rate = 8.0 * len(result.data) / count
        total = distortion + lam * rate
        trials.append((multiplier, len(result.data), distortion, total))
        if best is None or total < best[0]:
            best = (total, result, multiplier, distortion, rate)
        if progress:
            progress(f"lambda search: x{multiplier:.3g} steps -> J {total:.4g}")
        return total

    lo, hi = LOG2_LO, LOG2_HI
    left, right = hi - _INV_PHI * (hi - lo), lo + _INV_PHI * (hi - lo)
    f_left = cost(left, (yield scaled_preset(2.0 ** left)))
    f_right = cost(right, (yield scaled_preset(2.0 ** right)))
    for _ in range(max(0, steps - 2)):
        if f_left <= f_right:
            hi, right, f_right = right, left, f_left
            left = hi - _INV_PHI * (hi - lo)
            f_left = cost(left, (yield scaled_preset(2.0 ** left)))
        else:
            lo, left, f_left = left, right, f_right
            right = lo + _INV_PHI * (hi - lo)
            f_right = cost(right, (yield scaled_preset(2.0 ** right)))
    total, result, multiplier, distortion, rate = best
    return result, LambdaReport(float(lam), multiplier, distortion, rate, total, tuple(trials))
