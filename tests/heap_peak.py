"""Heap-peak measurement for the fuzz and damaged-input tests, switching tracemalloc rarely.

Python 3.11's ``tracemalloc.stop()`` races with allocations in other threads (CPython
gh-128679, fixed in 3.12 and 3.13 only; pytest-xdist's workers run an I/O thread), so a loop
that switched tracing on and off around each of thousands of inputs could end in a segfault
in libpython. Loops hold tracing on with :func:`heap_tracing`; each input is measured with
:func:`heap_peak`, which then only resets the peak. The hypothesis tests measure each example
alone (tracing hypothesis's own work as well made the 20,000-example PLY test 334 s instead
of 40), and the long decoder campaign runs in a child process (tests/fuzz/campaign_process.py).
"""

from __future__ import annotations

import tracemalloc
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass


@dataclass
class HeapPeak:
    """The peak of traced Python heap (numpy buffers included) during a block, in bytes above
    what was allocated when the block began; set when the block ends."""

    bytes: int = 0


@contextmanager
def heap_tracing() -> Iterator[None]:
    """Keep tracemalloc tracing for the block; switch it on (and off after) only when it was
    off, so nested blocks and per-input :func:`heap_peak` calls never switch it."""
    started = not tracemalloc.is_tracing()
    if started:
        tracemalloc.start()
    try:
        yield
    finally:
        if started:
            tracemalloc.stop()


@contextmanager
def heap_peak() -> Iterator[HeapPeak]:
    """Measure the heap peak of the block (see :class:`HeapPeak`), tracing for it alone when
    no enclosing :func:`heap_tracing` holds tracing on."""
    peak = HeapPeak()
    with heap_tracing():
        tracemalloc.reset_peak()
        before = tracemalloc.get_traced_memory()[0]
        try:
            yield peak
        finally:
            peak.bytes = tracemalloc.get_traced_memory()[1] - before
