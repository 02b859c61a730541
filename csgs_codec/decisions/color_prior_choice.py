"""Encoder side of the color hyperprior: fit it on the planned streams and keep it only for
the channels, and only when, it makes the file smaller (the network's bytes counted)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from csgs_codec.attributes.float_stream import (
    ChannelPrior,
    StreamPlan,
    prior_stream,
)
from csgs_codec.chunks.color_prior import (
    MEAN_BITS,
    MEAN_LIMIT,
    ColorPrior,
    channel_priors,
    color_prior_payload,
    keep_outputs,
    stream_layout,
)
from csgs_codec.errors import CsgsWarning, ModelError

#: Scenes with fewer Gaussians skip the fit: its network (about 3 KB) would cost more than
#: the 1-3 bits per Gaussian it saves on the scenes measured (benchmarks/rd.py).
MIN_GAUSSIANS = 8192
#: The prior must save at least this share of the color layer's bits: below it, the network
#: evaluation at decode (about 0.3-0.5 s per 250k Gaussians on one core) is not worth it.
MIN_SAVING_SHARE = 0.02
#: Steps of the trial fit, and the share of the required saving the trial must show for the
#: fit to go on.
TRIAL_STEPS = 300
TRIAL_SHARE = 0.5


@dataclass(frozen=True)
class PriorFitPolicy:
    """How the encoder fits the color hyperprior and when it keeps it.

    Attributes:
        settings: the fit's training settings (a
            :class:`~csgs_codec.model.color_hyperprior.ColorFitSettings`); None: its
            defaults (1,500 steps, about 10 s on one core).
        min_gaussians: scenes (tiles) with fewer Gaussians skip the fit.
        keep_when_larger: keep the prior for every channel it codes smaller even when the
            network costs more than it saves, and skip the trial (conformance vectors and
            tests that need the CHYP path on small scenes).
    """

    settings: object = None
    min_gaussians: int = MIN_GAUSSIANS
    keep_when_larger: bool = False


#: What encoders do unless told otherwise.
DEFAULT_PRIOR_FIT = PriorFitPolicy()


@dataclass
class PriorChoice:
    """What the encoder writes: the CHYP payload (None: no hyperprior) and, per stream, the
    channels coded with it (channel -> (prior, residual stream))."""

    payload: bytes | None = None
    channels: dict[str, dict[int, tuple[ChannelPrior, bytes]]] = field(default_factory=dict)


def choose_prior(plans: dict[str, StreamPlan], cells: np.ndarray, pos_bits: int,
                 on_step=None, policy: PriorFitPolicy = DEFAULT_PRIOR_FIT) -> PriorChoice:
    """Fit the color hyperprior on ``plans`` (stream -> plan, in stream order) and keep it
    where it pays.

    The fit first runs ``TRIAL_STEPS`` steps; when the exported trial network saves less
    than ``TRIAL_SHARE`` of what the prior must save, the rest of the fit is skipped (on the
    15 scene/quality cases of benchmarks/prior_gain.py it stopped only fits that would then
    have been left out).

    Args:
        cells: (N, 3) int64 network inputs (:func:`~csgs_codec.chunks.color_prior.prior_cells`).
        pos_bits: the grid's bits per axis.
        on_step: optional ``on_step(done, total)`` told of the fit's training steps.
        policy: the fit's settings and when the prior is kept.
    """
    names = list(plans)
    layout = stream_layout(names)
    # Channels with scored steps keep their own per-class tables.
    coded = np.array([not plans[s].channels[c].is_constant and plans[s].scored is None
                      for s, c in layout], bool)
    if len(cells) < policy.min_gaussians or not coded.any():
        return PriorChoice()
    from csgs_codec.model.color_hyperprior import ColorPriorFit

    bases = np.column_stack([plans[s].channels[c].base
                             for (s, c), on in zip(layout, coded) if on])
    needed = MIN_SAVING_SHARE * sum(plans[s].channels[c].cost for s, c in layout)
    try:
        fit = ColorPriorFit(cells, pos_bits, bases, policy.settings, mean_bits=MEAN_BITS,
                             mean_limit=MEAN_LIMIT)
        total = fit.settings.steps
        if total > TRIAL_STEPS and not policy.keep_when_larger:
            fit.train(TRIAL_STEPS, on_step)
            trial_saving, _ = _evaluate(ColorPrior(coded, fit.export()), plans, cells)
            if trial_saving < TRIAL_SHARE * needed:
                return PriorChoice()
        fit.train(total, on_step)
        prior = ColorPrior(coded, fit.export())
    except ModelError as err:
        warnings.warn(f"the color hyperprior was not used ({err.message}); the file decodes "
                      "exactly but is larger", CsgsWarning, stacklevel=3)
        return PriorChoice()
    saving, choice = _evaluate(prior, plans, cells)
    if saving <= needed and not policy.keep_when_larger:
        return PriorChoice()
    return choice


def _evaluate(prior: ColorPrior, plans: dict[str, StreamPlan], cells: np.ndarray
              ) -> tuple[float, PriorChoice]:
    """(bits saved net of the CHYP payload, the choice) when ``prior`` codes the channels
    where it codes smaller; the saving is -inf when it codes none smaller."""
    names = list(plans)
    priors = channel_priors(prior, cells, names)
    modelled = [lc for lc, on in zip(stream_layout(names), prior.mask) if on]
    keep, saved, streams = [], 0.0, {}
    for s, c in modelled:
        plan = plans[s].channels[c]
        stream = prior_stream(plan, priors[s][c])
        overhead = 8 * (3 * c + 6) if plan.coefs is not None else 0
        gain = plan.cost - (8 * len(stream) + overhead)
        keep.append(gain > 0)
        if gain > 0:
            saved += gain
            streams.setdefault(s, {})[c] = (priors[s][c], stream)
    if not any(keep):
        return -np.inf, PriorChoice()
    payload = color_prior_payload(keep_outputs(prior, np.array(keep)))
    return saved - 8 * len(payload), PriorChoice(payload, streams)
