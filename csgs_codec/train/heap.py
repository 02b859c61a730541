"""Handing freed heap memory back to the system between the large phases of a run.

glibc keeps memory that large numpy and torch buffers released in its heap (the threshold
above which it maps buffers separately grows after the first large frees), so a phase that
frees a gigabyte of per-view matrices and then builds their stacked form peaks at both.
:func:`release_freed_memory` asks the allocator to return what is free (``malloc_trim``);
elsewhere (other C libraries, other systems) it does nothing. It never changes a result.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.cache
def _trim():
    """glibc's ``malloc_trim``, or None where the C library has none."""
    name = ctypes.util.find_library("c")
    try:
        library = ctypes.CDLL(name)
        function = library.malloc_trim
    except (OSError, AttributeError, TypeError):
        return None
    function.argtypes = [ctypes.c_size_t]
    function.restype = ctypes.c_int
    return function


def release_freed_memory() -> bool:
    """Return the heap's free memory to the system; True when the C library could."""
    trim = _trim()
    return bool(trim is not None and trim(0))
