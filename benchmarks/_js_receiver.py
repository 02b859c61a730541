"""Running the JavaScript receiver (csgs_codec/js/decode_cli.mjs) under Node, and the same
per-array hashes computed from the Python decoder's output, for tests and benchmarks."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CLI = REPO / "csgs_codec" / "js" / "decode_cli.mjs"


def node_executable() -> str | None:
    """The ``node`` on PATH, or None."""
    return shutil.which("node")


def run_js(files: list[Path], *, layers: str = "color", container: bool = False,
           repeat: int = 1, threads: int = 2, range_coder: str = "wasm",
           timeout: float = 600, lod: int | None = None) -> list[dict]:
    """Decode ``files`` with the JavaScript CLI (on ``threads`` threads, 1 or 2, with the
    'wasm' or 'js' range decoder loop; level of detail ``lod``, default the scene); one
    result dict per file, in order."""
    args = [node_executable(), str(CLI), *map(str, files), "--layers", layers,
            "--threads", str(threads), "--range-coder", range_coder]
    if lod is not None:
        args += ["--lod", str(lod)]
    if container:
        args.append("--container")
    if repeat > 1:
        args += ["--repeat", str(repeat)]
    done = subprocess.run(args, capture_output=True, text=True, timeout=timeout, check=False)
    if done.returncode < 0:
        # Killed by a signal: the engine itself aborted (seen once in many runs: SIGABRT in
        # V8's optimizing compiler, Node 20.20). The receiver's own failures exit 1-3 and
        # are never retried; a second engine abort fails below with both reports.
        first = done.stderr
        done = subprocess.run(args, capture_output=True, text=True, timeout=timeout,
                              check=False)
        if done.returncode < 0:
            raise RuntimeError(f"node was killed by signal {-done.returncode} twice: "
                               f"{_both_ends(first)} / {_both_ends(done.stderr)}")
    if done.returncode not in (0, 2, 3):
        raise RuntimeError(f"node failed ({done.returncode}): {_both_ends(done.stderr)}")
    results = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
    if len(results) != len(files):
        raise RuntimeError(f"node printed {len(results)} results for {len(files)} files: "
                           f"{done.stderr[-2000:]}")
    return results


def _both_ends(text: str, size: int = 1500) -> str:
    """The start and end of ``text`` (where V8 prints its fatal message, and the stack)."""
    return text if len(text) <= 2 * size else f"{text[:size]} [...] {text[-size:]}"


def _digest(values: np.ndarray, dtype: str) -> str:
    return hashlib.sha256(np.ascontiguousarray(values, dtype=dtype).tobytes()).hexdigest()


def scene_hashes(scene) -> dict[str, dict]:
    """{name: {"shape", "sha256"}} of a decoded GaussianScene in the CLI's canonical layout:
    little-endian row-major float32 arrays (int32 labels)."""
    arrays = {
        "positions": scene.positions, "sh_dc": scene.sh_dc, "sh_rest": scene.sh_rest,
        "opacity": scene.opacity, "scales": scene.scales, "rotations": scene.rotations,
    }
    if scene.semantic is not None:
        arrays["semantic"] = scene.semantic
    if getattr(scene, "instances", None) is not None:
        arrays["instance_prototypes"] = scene.instances.prototypes
        arrays["instance_embeddings"] = scene.instances.embeddings
    out = {name: {"shape": list(v.shape), "sha256": _digest(v, "<f4")}
           for name, v in arrays.items()}
    if scene.labels is not None:
        out["labels"] = {"shape": list(scene.labels.shape),
                         "sha256": _digest(scene.labels, "<i4")}
    return out


def anchor_hashes(scene) -> dict[str, dict]:
    """{name: {"shape", "sha256"}} of a decoded AnchorScene in the CLI's layout (see
    csgs_codec/js/anchor_scene.mjs anchorArrays): float32 arrays, the offset mask one byte
    (0/1) per slot, int32 labels; the MLP arrays as ``mlp.<head>.<w1|b1|w2|b2>`` and
    ``mlp.appearance``; view_origins, semantic and labels only when present."""
    arrays = {"positions": scene.positions, "features": scene.features,
              "offsets": scene.offsets, "scaling": scene.scaling}
    if scene.mlps is not None:
        for name, head in scene.mlps.heads().items():
            arrays.update({f"mlp.{name}.{key}": arr for key, arr in head.arrays().items()})
        if scene.mlps.appearance is not None:
            arrays["mlp.appearance"] = scene.mlps.appearance
    if scene.view_origins is not None:
        arrays["view_origins"] = scene.view_origins
    if scene.semantic is not None:
        arrays["semantic"] = scene.semantic
    out = {name: {"shape": list(v.shape), "sha256": _digest(v, "<f4")}
           for name, v in arrays.items()}
    out["offset_mask"] = {"shape": list(scene.offset_mask.shape),
                          "sha256": _digest(scene.offset_mask, "?")}
    if scene.labels is not None:
        out["labels"] = {"shape": list(scene.labels.shape),
                         "sha256": _digest(scene.labels, "<i4")}
    return out
