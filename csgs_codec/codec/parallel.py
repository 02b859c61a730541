"""Running independent jobs (one per tile) in this process, in local processes, or on Ray.

Results always come back in job order, and a job's result depends only on the job, so what
is built from them is the same for any worker count and engine.

Engines:

- ``workers=1``, no ``ray``: one job after the other in this process.
- ``workers=N``: N local processes (started with ``spawn``: no thread state is copied from
  this process). Each runs its numeric libraries on one thread (``OMP_NUM_THREADS`` and
  the like, unless already set): the parallelism is across jobs, and BLAS threads of N
  processes spinning on the same cores cost more than they bring (1M Gaussians in 8
  tiles on 2 cores: 68 s with two BLAS threads per worker, 50 s with one).
- ``ray=ADDRESS``: tasks on the Ray cluster at ADDRESS (``"local"`` starts one on this
  machine with ``workers`` CPUs and stops it afterwards). Needs the ``ray`` package
  (``pip install 'csgs[scale]'``). Workers import this package from the same folder as
  this process (its path is passed as ``PYTHONPATH``), so a cluster's machines must see the
  package (and any input file a job names) at the same path.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from pathlib import Path

from csgs_codec.errors import InputError

#: The folder that holds the ``csgs_codec`` package (what workers need on their path).
PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])


def run_jobs(fn: Callable, jobs: Sequence, *, workers: int = 1, ray: str | None = None,
             progress: Callable[[int, int], None] | None = None) -> list:
    """``[fn(job) for job in jobs]``, spread over ``workers`` processes or a Ray cluster.

    Args:
        fn: a module-level function (it is pickled by name).
        jobs: picklable arguments, one per call.
        workers: local processes (1: run here), or the CPUs of a ``ray="local"`` cluster.
        ray: a Ray cluster address, ``"local"``, or None for local processes.
        progress: called as ``progress(done, total)`` after each job finishes.

    Raises:
        InputError: ``ray`` is asked for but not installed, or its cluster cannot be reached.
        Whatever ``fn`` raises (the first failing job's error, in job order).
    """
    total = len(jobs)
    report = progress or (lambda done, total: None)
    if ray is not None:
        return _run_ray(fn, jobs, workers, ray, report)
    if workers <= 1 or total <= 1:
        out = []
        for job in jobs:
            out.append(fn(job))
            report(len(out), total)
        return out
    context = multiprocessing.get_context("spawn")
    with _one_thread_children(), \
            ProcessPoolExecutor(min(workers, total), mp_context=context) as pool:
        futures = [pool.submit(fn, job) for job in jobs]
        pending, done = set(futures), 0
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            done += len(finished)
            report(done, total)
        return [f.result() for f in futures]  # in job order: the first error in order wins


#: Environment variables that size the thread pools of numpy's BLAS, OpenMP and torch.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "BLIS_NUM_THREADS", "NUMEXPR_NUM_THREADS")


@contextmanager
def _one_thread_children():
    """Within the block, processes started from this one see one thread per numeric library
    (variables the user set are kept); the environment is restored afterwards."""
    added = [name for name in THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


def _run_ray(fn: Callable, jobs: Sequence, workers: int, address: str, report) -> list:
    """The jobs as Ray tasks of one CPU each, results in job order."""
    try:
        import ray
    except ImportError:
        raise InputError("--ray needs the 'ray' package: pip install 'csgs[scale]' (or "
                         "pip install ray)", property="ray") from None
    variables = {name: os.environ.get(name, "1") for name in THREAD_VARIABLES}
    variables["PYTHONPATH"] = os.pathsep.join(
        [PACKAGE_ROOT] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
    env = {"env_vars": variables}
    local = address == "local"
    started = False
    if not ray.is_initialized():
        try:
            if local:
                ray.init(num_cpus=max(workers, 1), include_dashboard=False,
                         runtime_env=env, log_to_driver=False, configure_logging=False)
            else:
                ray.init(address=address, runtime_env=env, log_to_driver=False,
                         configure_logging=False)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise InputError(f"cannot reach the Ray cluster at {address!r}: {exc}",
                             property="ray") from None
        started = True
    try:
        task = ray.remote(num_cpus=1)(fn)
        refs = [task.remote(job) for job in jobs]
        pending, done = list(refs), 0
        while pending:
            finished, pending = ray.wait(pending, num_returns=1)
            done += len(finished)
            report(done, len(jobs))
        return ray.get(refs)
    finally:
        if started:
            ray.shutdown()
