"""Adam that updates every parameter group of one or more optimisers in one pass.

``torch.optim.Adam`` runs its update once per parameter group, fused or not. Stage 1 has six
groups (four per-anchor tensors with their own step sizes, the Scaffold-GS MLPs, the rate
model), and on a GPU its step is bound by the host: the two ``Adam.step`` calls took about
0.9 ms of each 19 ms step on an H100 (gpu_check_2026-11-27d). :func:`adam_step` gathers the
parameters of every group of the optimisers it is given and updates them with seven
multi-tensor operations per device and dtype, whatever the number of groups, each tensor with
its own group's step size. The rule is torch's (no weight decay, no AMSGrad), written as its
single-tensor implementation writes it:

    m = b1 m + (1 - b1) g;  v = b2 v + (1 - b2) g^2
    p -= (lr / (1 - b1^t)) * m / (sqrt(v) / sqrt(1 - b2^t) + eps)

The state per parameter is torch's ("step", "exp_avg", "exp_avg_sq") with the step count a
Python float, so reading it costs no device synchronisation.
"""

from __future__ import annotations

from collections.abc import Iterable

import torch

from csgs_codec.errors import InputError


class GroupedAdam(torch.optim.Optimizer):
    """Adam over parameter groups (torch's group syntax and ``lr``, ``betas``, ``eps``), whose
    :meth:`step` updates all groups together (see :func:`adam_step` to step several
    optimisers in one pass)."""

    def __init__(self, params: Iterable, lr: float = 1e-3,
                 betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8) -> None:
        if not (lr > 0 and 0 <= betas[0] < 1 and 0 <= betas[1] < 1 and eps >= 0):
            raise InputError(f"Adam settings out of range: lr {lr}, betas {betas}, eps {eps}",
                             property="optimizer")
        super().__init__(params, {"lr": lr, "betas": tuple(betas), "eps": eps})

    @torch.no_grad()
    def step(self, closure=None) -> None:  # noqa: ARG002 (torch's signature)
        """One update of every parameter that has a gradient."""
        adam_step(self)


@torch.no_grad()
def adam_step(*optimizers: GroupedAdam) -> None:
    """One Adam update of every parameter with a gradient in every group of ``optimizers``
    (module notes); parameters without one, and their state, are left as they are."""
    buckets: dict[tuple, tuple[list, ...]] = {}
    for optimizer in optimizers:
        for group in optimizer.param_groups:
            beta1, beta2 = group["betas"]
            for param in group["params"]:
                if param.grad is None:
                    continue
                state = optimizer.state[param]
                if not state:
                    state["step"] = 0.0
                    state["exp_avg"] = torch.zeros_like(param)
                    state["exp_avg_sq"] = torch.zeros_like(param)
                state["step"] = float(state["step"]) + 1.0
                step = state["step"]
                key = (param.device, param.dtype, beta1, beta2, group["eps"])
                bucket = buckets.setdefault(key, ([], [], [], [], [], []))
                for items, value in zip(bucket, (
                        param, param.grad, state["exp_avg"], state["exp_avg_sq"],
                        -group["lr"] / (1.0 - beta1 ** step), (1.0 - beta2 ** step) ** 0.5)):
                    items.append(value)
    for (_device, _dtype, beta1, beta2, eps), bucket in buckets.items():
        params, grads, first, second, step_sizes, roots = bucket
        torch._foreach_lerp_(first, grads, 1.0 - beta1)
        torch._foreach_mul_(second, beta2)
        torch._foreach_addcmul_(second, grads, grads, 1.0 - beta2)
        denominators = torch._foreach_sqrt(second)
        torch._foreach_div_(denominators, roots)
        torch._foreach_add_(denominators, eps)
        torch._foreach_addcdiv_(params, first, denominators, step_sizes)
