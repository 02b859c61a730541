"""Progress callbacks: the no-op the library uses when the caller gives none.

A leaf module: library code several layers down calls it without calling back up into the
orchestration that passed it.
"""

from __future__ import annotations


def ignore_progress(*_told) -> None:
    """A progress callback that ignores what it is told (any arguments)."""


def announce(progress, stage: str) -> None:
    """Tell ``progress(stage, done, total)`` that ``stage`` starts (``done == total == 0``);
    ``partial(announce, progress)`` is a ``progress(message)`` callback for code that only
    announces."""
    progress(stage, 0, 0)
