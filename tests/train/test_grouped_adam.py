"""GroupedAdam / adam_step: torch's Adam rule over several groups and optimisers at once."""

from __future__ import annotations

import io

import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.train.grouped_adam import GroupedAdam, adam_step


def _starts():
    generator = torch.Generator().manual_seed(0)
    return [torch.randn(7, 3, generator=generator), torch.randn(5, generator=generator),
            torch.randn(2, 4, 3, generator=generator)]


def _loss(params):
    return sum((p ** 3 - 2 * p).sum() for p in params)


def test_stepping_two_optimisers_together_is_torchs_adam_bit_for_bit():
    ours = [s.clone().requires_grad_() for s in _starts()]
    theirs = [s.clone().requires_grad_() for s in _starts()]
    groups = lambda ps: [{"params": [ps[0]], "lr": 0.05}, {"params": [ps[1]], "lr": 0.01}]  # noqa: E731
    first, second = GroupedAdam(groups(ours), eps=1e-15), GroupedAdam([ours[2]], lr=0.02)
    reference = [torch.optim.Adam(groups(theirs), eps=1e-15, foreach=False),
                 torch.optim.Adam([theirs[2]], lr=0.02, foreach=False)]
    for _ in range(40):
        for params in (ours, theirs):
            for p in params:
                p.grad = None
            _loss(params).backward()
        adam_step(first, second)
        for optimizer in reference:
            optimizer.step()
    for mine, torchs in zip(ours, theirs):
        assert torch.equal(mine, torchs)
    assert first.state[ours[0]]["step"] == 40.0


def test_parameters_without_a_gradient_are_left_alone():
    a, b = (torch.ones(3, requires_grad=True) for _ in range(2))
    optimizer = GroupedAdam([a, b], lr=0.1)
    a.sum().backward()
    optimizer.step()
    assert not torch.equal(a, torch.ones(3)) and torch.equal(b, torch.ones(3))
    assert b not in optimizer.state


def test_a_reloaded_state_continues_as_the_original():
    params = [s.clone().requires_grad_() for s in _starts()]
    optimizer = GroupedAdam(params, lr=0.03)
    for _ in range(5):
        optimizer.zero_grad()
        _loss(params).backward()
        optimizer.step()
    copies = [p.detach().clone().requires_grad_() for p in params]
    reloaded = GroupedAdam(copies, lr=0.03)
    buffer = io.BytesIO()  # as a checkpoint keeps it: saved, then loaded without code
    torch.save(optimizer.state_dict(), buffer)
    buffer.seek(0)
    reloaded.load_state_dict(torch.load(buffer, weights_only=True))
    for group in (params, copies):
        for p in group:
            p.grad = None
        _loss(group).backward()
    optimizer.step()
    reloaded.step()
    for p, q in zip(params, copies):
        assert torch.equal(p, q)


def test_settings_out_of_range_are_refused():
    with pytest.raises(InputError, match="Adam"):
        GroupedAdam([torch.zeros(1, requires_grad=True)], lr=0.0)
    with pytest.raises(InputError, match="Adam"):
        GroupedAdam([torch.zeros(1, requires_grad=True)], betas=(1.0, 0.9))
