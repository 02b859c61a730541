"""Forking while another thread holds a lock, for the tests of the locks' fork handling."""

from __future__ import annotations

import multiprocessing
import threading
from collections.abc import Callable


def child_finishes_while_a_thread_holds(lock_of: Callable, work: Callable,
                                        seconds: float = 60.0) -> int | None:
    """Exit code of a child forked while a parent thread holds ``lock_of()`` and running
    ``work()`` (0: it returned), or None when it did not finish within ``seconds`` (it is
    killed)."""
    held, release = threading.Event(), threading.Event()

    def hold() -> None:
        with lock_of():
            held.set()
            release.wait()

    holder = threading.Thread(target=hold)
    holder.start()
    held.wait()
    try:
        child = multiprocessing.get_context("fork").Process(target=work)
        child.start()
        child.join(seconds)
        if child.is_alive():
            child.kill()
            child.join()
            return None
        return child.exitcode
    finally:
        release.set()
        holder.join()
