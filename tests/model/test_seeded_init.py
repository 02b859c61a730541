"""Seeded initial weights are the same when several threads draw them at once."""

from __future__ import annotations

import numpy as np
import torch

from csgs_codec.model.seeded_init import seeded_global_rng
from tests.threads import on_threads


def test_seeded_draws_on_threads_are_those_of_one_thread_and_leave_the_callers_state():
    def init() -> torch.Tensor:
        with seeded_global_rng(7):
            return torch.nn.Linear(128, 128).weight.detach().clone()

    reference = init()
    torch.manual_seed(123)
    expected_next = torch.rand(4)
    torch.manual_seed(123)
    results = on_threads(lambda _: init(), range(400), threads=4)
    assert len(results) == 400 and all(torch.equal(w, reference) for w in results)
    assert torch.equal(torch.rand(4), expected_next), "the caller's generator moved"


def test_color_prior_fits_built_on_threads_start_from_the_same_weights():
    from csgs_codec.chunks.color_prior import MEAN_BITS, MEAN_LIMIT
    from csgs_codec.model.color_hyperprior import ColorFitSettings, ColorPriorFit

    rng = np.random.default_rng(4)
    cells = rng.integers(0, 1 << 10, (256, 3))
    residuals = rng.integers(-5, 6, (256, 3))
    settings = ColorFitSettings(steps=1, batch=64, hidden=64)

    def initial_weights() -> list[torch.Tensor]:
        fit = ColorPriorFit(cells, 10, residuals, settings, mean_bits=MEAN_BITS,
                            mean_limit=MEAN_LIMIT)
        return [p.detach().clone() for p in fit.net.parameters()]

    reference = initial_weights()
    results = on_threads(lambda _: initial_weights(), range(100), threads=4)
    assert all(len(got) == len(reference) and all(torch.equal(a, b)
                                                  for a, b in zip(got, reference))
               for got in results)


def _one_seeded_init() -> None:
    with seeded_global_rng(3):
        torch.nn.Linear(4, 4)


def test_a_child_forked_while_a_thread_holds_the_lock_can_seed():
    from csgs_codec.model import seeded_init
    from tests.fork_while_held import child_finishes_while_a_thread_holds

    code = child_finishes_while_a_thread_holds(lambda: seeded_init._GLOBAL_GENERATOR,
                                               _one_seeded_init)
    assert code == 0, "the child waited for a lock no thread of its own held"
