"""numba's thread pool for the project's parallel kernels: which threading layer, and one
kernel launch at a time; importing this module needs numba.

Unless the user chose a threading layer (NUMBA_THREADING_LAYER), importing this module
selects numba's own "workqueue" pool: the OpenMP layer's workers keep spinning after a
kernel and measurably slow the torch operations that run next in the same process. The
workqueue pool aborts the whole process when two Python threads launch parallel kernels at
the same time, so every kernel Python calls goes through :func:`one_launch_at_a_time`:
callers on several threads (a service rendering previews, a pool scoring views) take turns,
and each kernel is parallel inside already.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Callable
from typing import TypeVar

import numba

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"

_LAUNCH = threading.Lock()
Kernel = TypeVar("Kernel", bound=Callable)


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
