"""Running a test's work on several threads that start together."""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence


def on_threads(work: Callable, jobs: Sequence, threads: int) -> list:
    """``work(job)`` for every job, in order, on ``threads`` threads released together
    (thread i takes jobs i, i + threads, ...); an exception is returned in its job's place."""
    results: list = [None] * len(jobs)
    start = threading.Barrier(threads)

    def run(first: int) -> None:
        start.wait()
        for k in range(first, len(jobs), threads):
            try:
                results[k] = work(jobs[k])
            except BaseException as exc:  # noqa: BLE001 - handed to the test
                results[k] = exc
    pool = [threading.Thread(target=run, args=(i,)) for i in range(threads)]
    for thread in pool:
        thread.start()
    for thread in pool:
        thread.join()
    return results
