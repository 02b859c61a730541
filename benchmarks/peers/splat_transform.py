"""PlayCanvas splat-transform as a peer: SOG, compressed PLY and (through it) Niantic SPZ.

The npm package ``@playcanvas/splat-transform`` is installed into ``benchmarks/node_modules``
by ``npm ci`` in ``benchmarks/`` (version pinned in ``benchmarks/package.json``). It picks the
format from the output file's extension. Its SPZ writer is Niantic's own spz library compiled
to WebAssembly (npm ``@adobe/spz``), so the ``spz`` peer stands for Niantic SPZ.

Every run passes ``-g cpu``: SOG's k-means (SH palette) then runs on the CPU, with no GPU or
WebGPU adapter needed; the other formats ignore it. That k-means is slow on scenes with SH
bands: on a shared 2-core machine, 25k SH2 Gaussians took 91 s (25 s with
``extra_args=["--sh-iterations", "1"]``) and the 248k-Gaussian playbot did not finish in
30 minutes. Decoding writes a plain ``.ply`` with the same tool.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import time
from pathlib import Path

from csgs_codec.errors import InputError

from .base import TOOL_TIMEOUT_S, DecodeResult, EncodeResult, PeerCodec, run_tool
from .ply_fixup import clamp_infinite_opacity

#: Where ``npm ci`` in benchmarks/ puts the package.
DEFAULT_NODE_MODULES = Path(__file__).resolve().parents[1] / "node_modules"
PACKAGE = "@playcanvas/splat-transform"

#: format key -> (peer name, compressed file extension, what it is)
FORMATS = {
    "sog": ("playcanvas-sog", ".sog",
            "PlayCanvas SOG: WebP-packed quantized attributes, k-means codebooks for "
            "scale/color and an SH palette"),
    "compressed-ply": ("playcanvas-compressed-ply", ".compressed.ply",
                       "PlayCanvas compressed PLY: 256-Gaussian chunks, 11/10/11-bit "
                       "positions and scales, 8-bit color and opacity, 2-10-10-10 rotations"),
    "spz": ("niantic-spz", ".spz",
            "Niantic SPZ v4 written by Niantic's spz library (WebAssembly, @adobe/spz) "
            "inside splat-transform"),
}


class SplatTransformCodec(PeerCodec):
    """One output format of ``splat-transform`` (``"sog"``, ``"compressed-ply"``, ``"spz"``).

    Args:
        format: which of :data:`FORMATS`.
        node_modules: the ``node_modules`` folder holding the package.
        extra_args: more global options for the encode (e.g. ``["--max-workers", "2"]``).
        timeout_s: longest one tool run may take, in seconds.
    """

    def __init__(self, format: str, node_modules: str | Path = DEFAULT_NODE_MODULES,
                 extra_args: list[str] | None = None,
                 timeout_s: float = TOOL_TIMEOUT_S) -> None:
        if format not in FORMATS:
            raise InputError(f"unknown splat-transform format {format!r}; "
                             f"one of {sorted(FORMATS)}")
        self.format = format
        self.name, self.extension, self.description = FORMATS[format]
        self.package_dir = Path(node_modules) / PACKAGE
        self.extra_args = list(extra_args or [])
        self.timeout_s = timeout_s

    def _cli(self) -> Path:
        return self.package_dir / "bin" / "cli.mjs"

    def why_unavailable(self) -> str:
        """``""`` when node and the installed package's CLI are both present."""
        if shutil.which("node") is None:
            return "node (Node.js) is not on PATH"
        if not self._cli().is_file():
            return (f"{PACKAGE} is not installed in {self.package_dir.parent} "
                    "(run `npm ci` in benchmarks/)")
        return ""

    def version(self) -> str:
        """The installed package's version, from its package.json (``""`` if absent)."""
        try:
            return str(json.loads((self.package_dir / "package.json").read_text())["version"])
        except (OSError, ValueError, KeyError):
            return ""

    def _command(self, *args: str) -> list[str]:
        return [shutil.which("node") or "node", str(self._cli()), "--quiet", "--overwrite",
                *args]

    def encode(self, ply_path: str | Path, out_dir: str | Path) -> EncodeResult:
        """Compress ``ply_path`` to ``out_dir/<stem><extension>``; wall time includes node."""
        self.require_available()
        output = self.output_path(ply_path, out_dir)
        seconds = run_tool(self._command("--gpu", "cpu", *self.extra_args, str(ply_path),
                                         str(output)), output=output, timeout_s=self.timeout_s)
        return EncodeResult(bytes=output.stat().st_size, seconds=seconds, path=output)

    def decode(self, encoded_path: str | Path, out_ply: str | Path) -> DecodeResult:
        """Decode to a standard PLY at ``out_ply`` (which must end in ``.ply``, not
        ``.compressed.ply``), clamping infinite opacity logits (see :mod:`.ply_fixup`)."""
        self.require_available()
        encoded_path, out_ply = Path(encoded_path), Path(out_ply)
        if not encoded_path.is_file():
            raise InputError("no such compressed file", file=encoded_path)
        if out_ply.suffix != ".ply" or out_ply.name.endswith(".compressed.ply"):
            raise InputError("decoded output must be a plain .ply path", file=out_ply)
        out_ply.parent.mkdir(parents=True, exist_ok=True)
        seconds = run_tool(self._command(str(encoded_path), str(out_ply)), output=out_ply,
                           timeout_s=self.timeout_s)
        clamped = clamp_infinite_opacity(out_ply)
        fixups = {"opacity_inf_clamped": clamped} if clamped else {}
        return DecodeResult(seconds=seconds, path=out_ply, fixups=fixups)

    def startup_seconds(self) -> float:
        """Wall time of ``splat-transform --version``: node plus module load, no work."""
        self.require_available()
        start = time.perf_counter()
        subprocess.run([shutil.which("node") or "node", str(self._cli()), "--version"],
                       capture_output=True, check=False, timeout=60)
        return time.perf_counter() - start
