"""How the project's numba kernels run: the threading layer, one kernel launch at a time,
and where compiled kernels are cached; importing this module needs numba.

Unless the user chose a threading layer (NUMBA_THREADING_LAYER), importing this module
selects numba's own "workqueue" pool: the OpenMP layer's workers keep spinning after a
kernel and measurably slow the torch operations that run next in the same process. The
workqueue pool aborts the whole process when two Python threads launch parallel kernels at
the same time, so the rasterizer's and SSIM's kernels that Python calls go through
:func:`one_launch_at_a_time`: callers on several threads (a service rendering previews, a
pool scoring views) take turns, and each kernel is parallel inside already. A child process
forked while another thread held the turn starts with the turn free.

Kernels are compiled by :func:`jit_kernel`, which caches the machine code beside the package
(or where NUMBA_CACHE_DIR says) so that later processes skip the compile. On a read-only
install with no writable home (a container with a read-only root file system, say) numba
has nowhere to cache and refuses the function outright; the kernels are then compiled in
every process instead, with one warning saying how to give them a cache.
"""

from __future__ import annotations

import functools
import os
import threading
import warnings
from collections.abc import Callable
from typing import TypeVar

import numba

from csgs_codec.errors import CsgsWarning

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"

_LAUNCH = threading.Lock()
_warned_no_cache = False
Kernel = TypeVar("Kernel", bound=Callable)


def _free_turn_in_child() -> None:
    global _LAUNCH
    _LAUNCH = threading.Lock()


os.register_at_fork(after_in_child=_free_turn_in_child)


def jit_kernel(**options) -> Callable[[Callable], Callable]:
    """``numba.njit(cache=True, **options)``, or without the cache where numba finds no
    writable place for one (module notes)."""

    def compile_(fn: Callable) -> Callable:
        global _warned_no_cache
        try:
            return numba.njit(cache=True, **options)(fn)
        except RuntimeError as exc:
            if "no locator available" not in str(exc):
                raise
        if not _warned_no_cache:
            _warned_no_cache = True
            warnings.warn(f"numba finds no writable folder to cache compiled kernels beside "
                          f"{fn.__code__.co_filename} or in the home folder, so every process "
                          f"compiles them again; set NUMBA_CACHE_DIR to a writable folder to "
                          f"keep them", CsgsWarning, stacklevel=2)
        return numba.njit(cache=False, **options)(fn)

    return compile_


def one_launch_at_a_time(kernel: Kernel) -> Kernel:
    """``kernel`` (a numba dispatcher that Python calls) behind the process's launch lock:
    calls from several threads run one after another instead of aborting the process. The
    dispatcher itself stays reachable as ``.kernel`` (for its signatures and cache)."""

    def launch(*args, **kwargs):
        with _LAUNCH:
            return kernel(*args, **kwargs)

    functools.update_wrapper(launch, kernel.py_func, updated=())
    launch.kernel = kernel
    return launch
