"""Fit the INR hyperprior (and the CARM for the feature groups) of one anchor scene in torch.

The hyperprior is an MLP on the positional embedding of each anchor's integer cell. For each
attribute type (e.g. f, offsets, scaling; or the semantic feature) it predicts a per-channel
mean, a per-channel scale-table index and one step index per anchor. The CARM is one small
MLP per feature group g >= 1 over the decoded groups < g that adds to the group's mean and
scale index. Training minimises the estimated rate (Gaussian mass over the quantization bin
with the uniform-noise relaxation, in bits) + lambda * squared error, with lambda chosen so
that a step of ``base_step`` is the rate-distortion optimum at high rate
(lambda = 6 / (ln 2 * q^2)). The fitted networks are exported to exact integer networks;
the codec then codes with the integer networks only (decode == encoder reconstruction).

Fitting runs on the CPU with one torch thread and a fixed seed, so the same scene and
settings give the same networks (and bytes) on this machine whatever OMP_NUM_THREADS says.

Stability: gradients are clipped to a total norm of ``GRAD_CLIP_NORM``; a fit whose loss,
gradients or weights become non-finite, or whose networks cannot be exported, restarts once
with a lower learning rate and another seed, and if that fails too falls back to the
factorized prior (per-channel means and scales, no position dependence, CARM outputs 0),
which involves no training and always exports. Each restart or fallback emits a
:class:`~csgs_codec.errors.CsgsWarning` saying what happened.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np
import torch

from csgs_codec.entropy.anchor_attributes import (
    CARM_INPUT_BITS,
    CARM_INPUT_SHIFT,
    FRAC_BITS,
    MEAN_BITS,
    SCALE_MAX,
    group_bounds,
)
from csgs_codec.entropy.intnet import IntMLP
from csgs_codec.entropy.intnet_dense import IntDenseMLP
from csgs_codec.entropy.residual import STEP_COUNT, step_index
from csgs_codec.errors import CsgsWarning, ModelError
from csgs_codec.model.dense_export import export_dense_mlp, export_position_mlp
from csgs_codec.model.fit_tools import (
    GRAD_CLIP_NORM,
    INDEX_UNIT,
    Adam,
    clip_gradients,
    gaussian_bin_bits,
    mlp,
    num_freqs_for,
    scale_index_for_std,
    scaled_outputs,
)
from csgs_codec.model.intnet_export import float_embedding
from csgs_codec.model.seeded_init import seeded_global_rng

#: The step index may move this far from the base step's index (a factor 4 either way).
STEP_RANGE = 16
MEAN_LIMIT = 1 << 40
#: Signed weight bits per layer of the exported hyperprior and CARM networks.
HYPER_WEIGHT_BITS = (8, 8, 10)
CARM_WEIGHT_BITS = (8, 10)
CARM_DELTA_LIMIT = 1 << 30
#: A failed fit is retried once with the learning rate times this and the seed plus this.
RESTART_LR_FACTOR = 0.1
RESTART_SEED_OFFSET = 7919


@dataclass
class AttributeTarget:
    """One attribute type to model.

    Attributes:
        values: (M, C) float64 values in their coding units.
        weights: (M, C) float64 in {0, 1}: 0 for values that are not coded (masked offsets).
        base_step: the quantization step (value units) the quality asks for.
    """

    values: np.ndarray
    weights: np.ndarray
    base_step: float

    @property
    def channels(self) -> int:
        """C."""
        return int(self.values.shape[1])


@dataclass
class FitSettings:
    """Training settings (defaults: a few seconds for 10k anchors on one core)."""

    hidden: int = 32
    carm_hidden: int = 16
    steps: int = 300
    batch: int = 1024
    learning_rate: float = 5e-3
    seed: int = 0
    #: Size the exported networks' activation scales on at most this many anchors (every
    #: k-th; None: all). Values beyond the calibration clip exactly as the decoder does.
    calibration_rows: int | None = None


#: The ``fast`` encoder's settings: 80 steps instead of 300 at twice the learning rate, a
#: smaller batch and narrower networks (cheaper to fit and to evaluate when coding). On
#: synthetic scenes of 10k-100k anchors the file grows by about 0.5-2 %.
FAST_FIT = FitSettings(hidden=16, carm_hidden=8, steps=80, batch=256, learning_rate=1e-2,
                       calibration_rows=16384)


def step_for_lambda(lam: float) -> float:
    """The quantization step (value units) whose high-rate optimum is rate-distortion weight
    ``lam`` (squared value units per bit): sqrt(6 lam / ln 2), the inverse of the fit's
    lambda = 6 / (ln 2 q^2) (the fit then minimises bits + squared error / ``lam``)."""
    return math.sqrt(6.0 * lam / math.log(2.0))


def step_index_of(step: float) -> int:
    """Step index whose step is nearest to ``step`` value units (log scale)."""
    return int(step_index(np.array([step * 2.0 ** FRAC_BITS]))[0])


def _step_value(j: torch.Tensor) -> torch.Tensor:
    """Smooth step (value units) of a continuous step index (exact on the 1/8-octave grid)."""
    return torch.pow(2.0, (j + 17.0) / 8.0 - FRAC_BITS)


class _Prior(torch.nn.Module):
    def __init__(self, in_width: int, targets: list[AttributeTarget], groups: int,
                 settings: FitSettings, *, device: torch.device) -> None:
        super().__init__()
        self.targets = targets
        # Per target: (base step index, lowest and highest step index the fit may use).
        self.step_bounds = [_step_bounds(t) for t in targets]
        widths = [2 * t.channels + 1 for t in targets]
        self.hyper = mlp([in_width, settings.hidden, settings.hidden, sum(widths)],
                         device=device)
        self.bounds = group_bounds(targets[0].channels, groups) if groups > 1 else []
        self.carm = torch.nn.ModuleList(
            mlp([lo, settings.carm_hidden, 2 * (hi - lo)], device=device)
            for lo, hi in self.bounds[1:])
        last = self.hyper[-1]
        with torch.no_grad():
            last.weight.mul_(0.1)
            col = 0
            for t in targets:
                c, w = t.channels, t.weights
                count = np.maximum(w.sum(axis=0), 1.0)
                mean = (t.values * w).sum(axis=0) / count
                std = np.sqrt(((t.values - mean) ** 2 * w).sum(axis=0) / count) + 1e-6
                j0 = step_index_of(t.base_step)
                q0 = float(_step_value(torch.tensor(float(j0), device=device)))
                idx = scale_index_for_std(std / q0)
                last.bias[col:col + c] = torch.as_tensor(mean, device=device)
                last.bias[col + c:col + 2 * c] = torch.as_tensor(idx / INDEX_UNIT, device=device)
                last.bias[col + 2 * c] = j0 / INDEX_UNIT
                col += 2 * c + 1
            for net in self.carm:
                net[-1].weight.zero_()
                net[-1].bias.zero_()

    def loss(self, emb, values, weights, lams, gen) -> torch.Tensor:
        out = self.hyper(emb)
        total, col = 0.0, 0
        recon_f = None
        for i, t in enumerate(self.targets):
            c = t.channels
            mean = out[:, col:col + c]
            scale = out[:, col + c:col + 2 * c] * INDEX_UNIT
            _, j_lo, j_hi = self.step_bounds[i]
            j = torch.clamp(out[:, col + 2 * c] * INDEX_UNIT, j_lo, j_hi)
            q = _step_value(j)[:, None]
            noise = torch.rand(values[i].shape, generator=gen, device=values[i].device) - 0.5
            if i == 0 and self.carm:
                recon_f = values[i] + noise * q
                means, scales = [mean[:, :self.bounds[0][1]]], [scale[:, :self.bounds[0][1]]]
                for net, (lo, hi) in zip(self.carm, self.bounds[1:]):
                    delta = net(recon_f[:, :lo].detach())
                    means.append(mean[:, lo:hi] + delta[:, :hi - lo])
                    scales.append(scale[:, lo:hi] + delta[:, hi - lo:] * INDEX_UNIT)
                mean, scale = torch.cat(means, dim=1), torch.cat(scales, dim=1)
            bits = gaussian_bin_bits(values[i], mean, scale, q, noise)
            total = total + (weights[i] * (bits + lams[i] * q * q / 12.0)).sum()
            col += 2 * c + 1
        return total / emb.shape[0]

    def make_factorized(self) -> None:
        """Zero every weight and bias but the hyperprior's output biases (the per-channel
        statistics set at construction): outputs no longer depend on the position and the
        CARM adds 0, so the networks export whatever the scene."""
        with torch.no_grad():
            for p in self.parameters():
                if p is not self.hyper[-1].bias:
                    p.zero_()


def _step_bounds(target: AttributeTarget) -> tuple[int, int, int]:
    """(j0, lo, hi): the base step's index and the step index range around it."""
    j0 = step_index_of(target.base_step)
    return j0, max(0, j0 - STEP_RANGE), min(STEP_COUNT - 1, j0 + STEP_RANGE)


def _hyper_export(prior: _Prior, cells: np.ndarray, pos_bits: int, num_freqs: int) -> IntMLP:
    scales, lo, hi = [], [], []
    for t, (_, j_lo, j_hi) in zip(prior.targets, prior.step_bounds):
        c = t.channels
        scales += [2.0 ** MEAN_BITS] * c + [INDEX_UNIT] * (c + 1)
        lo += [-MEAN_LIMIT] * c + [0] * c + [j_lo]
        hi += [MEAN_LIMIT] * c + [SCALE_MAX] * c + [j_hi]
    return export_position_mlp(scaled_outputs(prior.hyper, np.array(scales)), pos_bits=pos_bits,
                               num_freqs=num_freqs, calibration_positions=cells,
                               out_lo=np.array(lo), out_hi=np.array(hi),
                               weight_bits=HYPER_WEIGHT_BITS)


def _carm_export(prior: _Prior, feature_grid: np.ndarray) -> list[IntDenseMLP]:
    nets = []
    for net, (lo, hi) in zip(prior.carm, prior.bounds[1:]):
        c = hi - lo
        scales = np.array([2.0 ** MEAN_BITS] * c + [INDEX_UNIT] * c)
        limits = np.array([CARM_DELTA_LIMIT] * c + [SCALE_MAX] * c)
        nets.append(export_dense_mlp(
            scaled_outputs(net, scales), input_shift=CARM_INPUT_SHIFT, input_bits=CARM_INPUT_BITS,
            input_frac_bits=MEAN_BITS, calibration_inputs=feature_grid[:, :lo],
            out_lo=-limits, out_hi=limits, weight_bits=CARM_WEIGHT_BITS))
    return nets


def fit_prior(cells: np.ndarray, pos_bits: int, targets: list[AttributeTarget], *,
              carm_groups: int = 1, settings: FitSettings | None = None,
              name: str = "hyperprior") -> tuple[IntMLP, list[IntDenseMLP]]:
    """Fit and export the hyperprior (and CARM over ``targets[0]`` when carm_groups > 1).

    A fit that diverges (non-finite loss, gradients or weights) or cannot be exported is
    restarted once with the learning rate times ``RESTART_LR_FACTOR`` and the seed plus
    ``RESTART_SEED_OFFSET``; if that fails too, the factorized prior is exported instead
    (see :meth:`_Prior.make_factorized`). Each of these emits a CsgsWarning.

    Args:
        cells: (M, 3) integer anchor cells in [0, 2^pos_bits).
        pos_bits: bits per cell coordinate.
        targets: the attribute types in layout order.
        carm_groups: channel groups of targets[0]; 1 = no CARM.
        settings: training settings.
        name: what the warnings call this fit.

    Returns:
        (hyperprior IntMLP with sum(2C + 1) outputs, carm_groups - 1 CARM networks).

    Raises:
        ModelError: even the factorized prior cannot be exported (values beyond the limits
            the encoders check).
    """
    settings = settings or FitSettings()
    num_freqs = num_freqs_for(pos_bits)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with seeded_global_rng():  # _train seeds it
            emb = float_embedding(cells, pos_bits, num_freqs)
            rows = slice(None, None, -(-len(cells) // settings.calibration_rows)
                         if settings.calibration_rows else 1)
            calib_cells = cells[rows]
            grid = np.rint(np.ldexp(targets[0].values[rows], FRAC_BITS)).astype(np.int64)
            retry = replace(settings, learning_rate=settings.learning_rate * RESTART_LR_FACTOR,
                            seed=settings.seed + RESTART_SEED_OFFSET)
            for attempt, run in enumerate((settings, retry)):
                try:
                    prior = _train(emb, targets, carm_groups, run)
                    return (_hyper_export(prior, calib_cells, pos_bits, num_freqs),
                            _carm_export(prior, grid))
                except (_DivergedError, ModelError) as exc:
                    problem = str(exc)
                if attempt == 0:
                    _warn(f"the {name} fit failed ({problem}); restarting with learning "
                          f"rate {retry.learning_rate:.3g} and seed {retry.seed}")
            _warn(f"the {name} fit failed again ({problem}); falling back to the "
                  "factorized prior (per-channel means and scales, no position dependence, "
                  "no CARM prediction): the file decodes exactly but is larger")
            prior = _Prior(emb.shape[1], targets, carm_groups, settings, device=emb.device)
            prior.make_factorized()
            return (_hyper_export(prior, calib_cells, pos_bits, num_freqs),
                    _carm_export(prior, grid))
    finally:
        torch.set_num_threads(threads)


class _DivergedError(Exception):
    """A fit produced a non-finite loss, gradient or weight."""


def _warn(message: str) -> None:
    warnings.warn(message, CsgsWarning, stacklevel=3)


def _train(emb: torch.Tensor, targets: list[AttributeTarget], carm_groups: int,
           settings: FitSettings) -> _Prior:
    """Train a :class:`_Prior` on embeddings ``emb`` (M, 6L), on their device; _DivergedError
    if it blows up."""
    device = emb.device
    torch.manual_seed(settings.seed)
    gen = torch.Generator(device=device).manual_seed(settings.seed)
    prior = _Prior(emb.shape[1], targets, carm_groups, settings, device=device)
    values = [torch.as_tensor(t.values, device=device).float() for t in targets]
    weights = [torch.as_tensor(t.weights, device=device).float() for t in targets]
    lams = [6.0 / (math.log(2.0) * t.base_step ** 2) for t in targets]
    optimizer = Adam(prior.parameters(), lr=settings.learning_rate)
    m = emb.shape[0]
    for step in range(settings.steps):
        if step == settings.steps * 3 // 4:
            optimizer.lr = settings.learning_rate / 4
        rows = torch.randint(0, m, (min(settings.batch, m),), generator=gen, device=device)
        optimizer.zero_grad()
        # index_select: the rows of emb[rows], several times faster on the CPU
        loss = prior.loss(torch.index_select(emb, 0, rows),
                          [torch.index_select(v, 0, rows) for v in values],
                          [torch.index_select(w, 0, rows) for w in weights], lams, gen)
        if not torch.isfinite(loss):
            raise _DivergedError(f"non-finite loss at step {step}")
        loss.backward()
        if not math.isfinite(clip_gradients(optimizer.params, GRAD_CLIP_NORM)):
            raise _DivergedError(f"non-finite gradient at step {step}")
        optimizer.step()
    if not all(torch.isfinite(p).all() for p in prior.parameters()):
        raise _DivergedError("non-finite weights after the fit")
    return prior
