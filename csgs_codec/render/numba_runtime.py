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
(or where NUMBA_CACHE_DIR says) so that later processes skip the compile. numba's cache is
not safe against several processes compiling and saving the same functions at once (numba
issues 4807 and 10128): a cache written that way can index machine code that crashes every
later process loading it (the test suite's parallel workers did, with a segmentation fault in
the first render). So a kernel's first call for each argument type in a process, when numba
loads it or compiles and saves it, holds an exclusive lock on one file shared by every
process of the user (:func:`cache_lock_path`); later calls take no lock.

On a read-only install with no writable home (a container with a read-only root file
system, say) numba has nowhere to cache and refuses the function outright; the kernels are
then compiled in every process instead, with one warning saying how to give them a cache.
"""

from __future__ import annotations

import functools
import os
import tempfile
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

import numba
import numpy as np

from csgs_codec.errors import CsgsWarning

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"

_LAUNCH = threading.Lock()
_COMPILE_IN_PROCESS = threading.RLock()
_held_depth = 0
_warned_no_cache = False
Kernel = TypeVar("Kernel", bound=Callable)


def _free_turn_in_child() -> None:
    global _LAUNCH, _COMPILE_IN_PROCESS, _held_depth
    _LAUNCH = threading.Lock()
    _COMPILE_IN_PROCESS = threading.RLock()
    _held_depth = 0


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


def cache_lock_path() -> str:
    """The file whose exclusive lock every process of this user holds while numba loads or
    compiles and caches one of the project's kernels (module notes)."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    return os.path.join(tempfile.gettempdir(), f"csgs-numba-cache-{uid}.lock")


@contextmanager
def cache_writers_take_turns() -> Iterator[None]:
    """Hold the user's numba cache lock (:func:`cache_lock_path`) for the block; threads of
    this process queue on a process lock first. Where no lock file can be opened, or the
    platform has no ``lockf``, the block runs unlocked (as numba itself would)."""
    global _held_depth
    with _COMPILE_IN_PROCESS:
        if _held_depth:  # nested in this thread: the lock is held already
            yield
            return
        try:
            import fcntl
            handle = open(cache_lock_path(), "a+b")  # noqa: SIM115 (closed below)
        except (ImportError, OSError):
            yield
            return
        # A POSIX record lock belongs to this process: a child forked inside the block does
        # not inherit it (an flock would be shared with the child and outlive our close).
        try:
            fcntl.lockf(handle, fcntl.LOCK_EX)
            _held_depth += 1
            try:
                yield
            finally:
                _held_depth -= 1
        finally:
            handle.close()  # closing the descriptor releases the lock


def _numba_type_key(value) -> tuple:
    # What numba dispatches on, cheaply (numba.typeof costs ~15 us an array): an array's
    # dtype, rank, layout and flags; other values by Python type.
    if isinstance(value, np.ndarray):
        flags = value.flags
        return (value.dtype.str, value.ndim, flags.c_contiguous, flags.f_contiguous,
                flags.writeable, flags.aligned)
    return (type(value),)


def _argument_types(args: tuple, kwargs: dict) -> tuple:
    return (tuple(_numba_type_key(a) for a in args),
            tuple((k, _numba_type_key(v)) for k, v in sorted(kwargs.items())))


def compile_safely(kernel: Kernel) -> Kernel:
    """``kernel`` (a numba dispatcher that Python calls) whose first call for each argument
    type holds :func:`cache_writers_take_turns` (module notes). The dispatcher stays
    reachable as ``.kernel``."""
    seen: set[tuple] = set()

    def call(*args, **kwargs):
        types = _argument_types(args, kwargs)
        if types in seen:
            return kernel(*args, **kwargs)
        with cache_writers_take_turns():
            result = kernel(*args, **kwargs)
        seen.add(types)
        return result

    functools.update_wrapper(call, kernel.py_func, updated=())
    call.kernel = kernel
    return call


def one_launch_at_a_time(kernel: Kernel) -> Kernel:
    """``kernel`` (a numba dispatcher that Python calls) behind the process's launch lock:
    calls from several threads run one after another instead of aborting the process; its
    first call for each argument type also holds the cache lock (:func:`compile_safely`).
    The dispatcher itself stays reachable as ``.kernel`` (for its signatures and cache)."""
    guarded = compile_safely(kernel)

    def launch(*args, **kwargs):
        with _LAUNCH:
            return guarded(*args, **kwargs)

    functools.update_wrapper(launch, kernel.py_func, updated=())
    launch.kernel = kernel
    return launch
