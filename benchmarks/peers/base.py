"""The interface every peer codec wrapper offers, and the subprocess runner they share."""

from __future__ import annotations

import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

from csgs_codec.errors import CsgsError, InputError, UnsupportedError

#: Default for how long a peer tool may run on one file before it is stopped, in seconds
#: (SOG's SH palette k-means on a CPU takes minutes on a 250k-Gaussian SH2 scene).
TOOL_TIMEOUT_S = 1800.0


class PeerToolError(CsgsError):
    """A peer's tool exited with an error, timed out, or wrote no output."""


@dataclass(frozen=True)
class EncodeResult:
    """One compressed file written by a peer.

    Attributes:
        bytes: size of the whole compressed file on disk, in bytes.
        seconds: wall time of the encode, in seconds (tool start-up included).
        path: the compressed file.
    """

    bytes: int
    seconds: float
    path: Path


@dataclass(frozen=True)
class DecodeResult:
    """One standard 3DGS PLY decoded back from a peer's file.

    Attributes:
        seconds: wall time of the peer's decode, in seconds (tool start-up included; the
            fix-ups below are not timed).
        path: the decoded PLY, readable by ``csgs_codec.interchange.ply_io.read_ply``.
        fixups: what the wrapper changed in the tool's PLY so the reader takes it, as
            ``{what: count}`` (e.g. ``{"opacity_inf_clamped": 930}``); empty when nothing.
    """

    seconds: float
    path: Path
    fixups: dict[str, int] = field(default_factory=dict)


class PeerCodec:
    """A compressor from another project, wrapped to take and give standard 3DGS PLY files.

    Subclasses set :attr:`name` (stable, used as a JSON key), :attr:`extension` (of the
    compressed file, e.g. ``".sog"``) and :attr:`description`, and implement
    :meth:`why_unavailable`, :meth:`encode` and :meth:`decode`.
    """

    name: str = ""
    extension: str = ""
    description: str = ""

    def why_unavailable(self) -> str:
        """Why this peer cannot run on this machine, or ``""`` when it can."""
        raise UnsupportedError(f"peer {type(self).__name__} does not say if it is available")

    def available(self) -> bool:
        """Whether the peer's tool is installed and runs here (see :meth:`why_unavailable`)."""
        return self.why_unavailable() == ""

    def version(self) -> str:
        """The peer tool's version string, or ``""`` when unknown."""
        return ""

    def encode(self, ply_path: str | Path, out_dir: str | Path) -> EncodeResult:
        """Compress the PLY at ``ply_path`` into ``out_dir/<stem><extension>``."""
        raise UnsupportedError(f"peer {self.name} cannot encode")

    def decode(self, encoded_path: str | Path, out_ply: str | Path) -> DecodeResult:
        """Decode ``encoded_path`` back to a standard 3DGS PLY at ``out_ply``."""
        raise UnsupportedError(f"peer {self.name} cannot decode")

    def require_available(self) -> None:
        """Raise :class:`UnsupportedError` naming the reason when the peer cannot run."""
        reason = self.why_unavailable()
        if reason:
            raise UnsupportedError(f"peer {self.name} is not available: {reason}")

    def output_path(self, ply_path: str | Path, out_dir: str | Path) -> Path:
        """Where :meth:`encode` writes: ``out_dir/<stem of ply_path><extension>``."""
        ply_path = Path(ply_path)
        if not ply_path.is_file():
            raise InputError("no such PLY file", file=ply_path)
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        stem = ply_path.name[: -len(".ply")] if ply_path.name.endswith(".ply") else ply_path.stem
        return out_dir / f"{stem}{self.extension}"


def run_tool(command: list[str], *, output: Path, cwd: Path | None = None,
             timeout_s: float = TOOL_TIMEOUT_S) -> float:
    """Run a peer tool's command line and return its wall time in seconds.

    The command must write ``output``; a stale file there is removed first, so a tool that
    exits 0 without writing is caught.

    Raises:
        PeerToolError: non-zero exit (with its first error line), a run past ``timeout_s``
            seconds, a missing executable, or no output file.
    """
    output.unlink(missing_ok=True)
    start = time.perf_counter()
    try:
        done = subprocess.run(command, cwd=cwd, capture_output=True, text=True,
                              timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired as error:
        raise PeerToolError(f"{command[0]} ran past {timeout_s:.0f} s",
                            file=output) from error
    except OSError as error:
        raise PeerToolError(f"cannot run {command[0]}: {error}", file=output) from error
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise PeerToolError(f"{Path(command[1] if len(command) > 1 else command[0]).name} "
                            f"exited {done.returncode}: {_error_line(done.stderr or done.stdout)}",
                            file=output)
    if not output.is_file():
        raise PeerToolError("the tool exited 0 but wrote no file", file=output)
    return seconds


def _error_line(text: str) -> str:
    """The first line of a tool's output that mentions an error, else its last line."""
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    for line in lines:
        if "error" in line.lower():
            return line
    return lines[-1] if lines else "(no output)"
