"""Whether the optional numba kernels can be used, and loading them with a clear error."""

from __future__ import annotations

from types import ModuleType

from csgs_codec.errors import UnsupportedError


def numba_available() -> bool:
    """True when numba can be imported (the fast CPU paths are usable)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def rasterizer_kernels(purpose: str = "the numba backend") -> ModuleType:
    """:mod:`csgs_codec.render.numba_kernels`, compiled on first use.

    Raises:
        UnsupportedError: numba is not installed (the message names ``purpose``).
    """
    try:
        from csgs_codec.render import numba_kernels
    except ImportError as exc:
        raise UnsupportedError(f"{purpose} needs numba: pip install 'csgs[fast]' "
                               f"({exc})") from exc
    return numba_kernels
