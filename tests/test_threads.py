"""The thread helper of the concurrency tests (tests/threads.py)."""

from __future__ import annotations

import threading

from tests.threads import on_threads


def test_results_come_back_in_job_order_with_exceptions_in_place():
    seen = set()

    def work(job):
        seen.add(threading.get_ident())
        if job == 2:
            raise ValueError("two")
        return job * 10

    results = on_threads(work, [0, 1, 2, 3, 4], threads=2)
    assert results[:2] == [0, 10] and results[3:] == [30, 40]
    assert isinstance(results[2], ValueError)
    assert len(seen) == 2
