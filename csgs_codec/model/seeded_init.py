"""Seeded draws from torch's global random generator, one thread at a time.

torch's module initialisers draw from its process-wide generator. The encoders and the
training stages seed it inside a fork (the caller's random state is restored afterwards) to
start from the same weights on every run; two threads doing that at once interleave their
draws, and each gets weights of neither seed (so the files differ from run to run). Every
such section runs under one lock (free again in a child process forked while another
thread held it).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import torch

_GLOBAL_GENERATOR = threading.RLock()


def _free_lock_in_child() -> None:
    global _GLOBAL_GENERATOR
    _GLOBAL_GENERATOR = threading.RLock()


os.register_at_fork(after_in_child=_free_lock_in_child)


@contextmanager
def seeded_global_rng(seed: int | None = None) -> Iterator[None]:
    """Hold the process's lock on torch's global CPU generator, fork its state (restored on
    exit) and, given ``seed``, seed it, for the block's draws."""
    with _GLOBAL_GENERATOR, torch.random.fork_rng(devices=[]):
        if seed is not None:
            torch.manual_seed(seed)
        yield
