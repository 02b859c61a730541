"""One phase of one speed-benchmark point, run in a fresh process by benchmarks/speed.py.

    python benchmarks/_speed_worker.py encode FOLDER QUALITY BUDGET_S MAX_RUNS
    python benchmarks/_speed_worker.py decode FOLDER QUALITY BUDGET_S MAX_RUNS

FOLDER holds the scene as .npy arrays (``scene/``, see _scaling.save_arrays). ``encode`` writes
``q{Q}.csgs`` and the encoder's reconstruction (``q{Q}.reconstruction/``); ``decode`` reads
them and checks the decoded scene equals that reconstruction bit for bit. Each phase prints one
JSON line with: the wall and CPU times of every timed run (s); the process's peak resident size
over the first run minus its resident size just before it (bytes; the kernel's peak count is
reset first where Linux allows, else a higher peak from earlier in the process can mask it);
and tracemalloc's peak over one more run (bytes; numpy registers its buffers with tracemalloc,
constriction's own buffers are not seen). Memory freed earlier in the process and reused stays
resident, so the RSS growth of a small phase can read near 0; tracemalloc's peak does not have
that blind spot. A fresh process per phase keeps one point's high-water mark out of the next
one's. CPU time (all threads) is the steadier figure on a machine shared with other work.
"""

from __future__ import annotations

import json
import resource
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
from _scaling import load_arrays, save_arrays

from csgs_codec import Decoder, Encoder

#: Gaussians encoded and decoded once before measuring, so one-off costs (imports, table
#: loading, compilation) are not counted in the first timed run.
WARMUP_GAUSSIANS = 2000


def resident_bytes() -> int:
    """Resident set size of this process now (Linux /proc), else its peak so far."""
    status = _proc_status()
    return status["VmRSS"] if status else peak_resident_bytes()


def reset_peak_resident() -> bool:
    """Restart the kernel's peak-RSS count at the current size (Linux); False if unable.

    Without it a peak reached earlier in the process (imports, warm-up) would hide a
    smaller peak of the phase measured next.
    """
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return bool(_proc_status())


def peak_resident_bytes() -> int:
    """Peak resident set size: since the last reset on Linux, else since process start."""
    status = _proc_status()
    if status and "VmHWM" in status:
        return status["VmHWM"]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak) if sys.platform == "darwin" else int(peak) * 1024


def _proc_status() -> dict[str, int]:
    """VmRSS and VmHWM of /proc/self/status in bytes, or {} where there is no /proc."""
    try:
        lines = Path("/proc/self/status").read_text().splitlines()
    except OSError:
        return {}
    out = {}
    for line in lines:
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            out[key] = int(value.split()[0]) * 1024
    return out


def measure(run, budget_s: float, max_runs: int):
    """Call ``run()`` at least once and report its cost.

    Returns:
        (first result, figures) with figures ``seconds`` (wall, one per timed run),
        ``cpu_seconds`` (this process's user + system time, all threads, per run),
        ``peak_rss_delta_bytes`` (first run), ``tracemalloc_peak_bytes`` (an extra run) and
        ``peak_was_reset`` (whether the peak count started at this phase).
    """
    peak_was_reset = reset_peak_resident()
    before = resident_bytes()
    result, wall, cpu = _timed(run)
    rss_delta = max(0, peak_resident_bytes() - before)
    seconds, cpu_seconds = [wall], [cpu]
    while sum(seconds) < budget_s and len(seconds) < max_runs:
        _, wall, cpu = _timed(run)
        seconds.append(wall)
        cpu_seconds.append(cpu)
    tracemalloc.start()
    try:
        run()
        traced_peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return result, {"seconds": seconds, "cpu_seconds": cpu_seconds,
                    "peak_rss_delta_bytes": rss_delta,
                    "tracemalloc_peak_bytes": int(traced_peak),
                    "peak_was_reset": peak_was_reset}


def _timed(run):
    """(result, wall seconds, CPU seconds of this process) of one call of ``run``."""
    start, cpu_start = time.perf_counter(), time.process_time()
    result = run()
    return result, time.perf_counter() - start, time.process_time() - cpu_start


def encode_phase(folder: Path, quality: int, budget_s: float, max_runs: int) -> dict:
    """Encode ``folder/scene`` at ``quality``; write the file and the reconstruction."""
    scene = load_arrays(folder / "scene")
    warm = scene.subset(np.arange(min(WARMUP_GAUSSIANS, len(scene))))
    (folder / f"warmup_q{quality}.csgs").write_bytes(Encoder(quality=quality).encode(warm))
    result, figures = measure(lambda: Encoder(quality=quality).encode_with_report(scene),
                              budget_s, max_runs)
    (folder / f"q{quality}.csgs").write_bytes(result.data)
    save_arrays(result.reconstruction, folder / f"q{quality}.reconstruction")
    return {"bytes": len(result.data), "gaussians": len(scene), **figures}


def decode_phase(folder: Path, quality: int, budget_s: float, max_runs: int) -> dict:
    """Decode ``folder/q{quality}.csgs`` (color layer) and check it against the encoder."""
    Decoder().decode((folder / f"warmup_q{quality}.csgs").read_bytes(), layers="color")
    data = (folder / f"q{quality}.csgs").read_bytes()
    decoded, figures = measure(lambda: Decoder().decode(data, layers="color"), budget_s,
                               max_runs)
    expected = load_arrays(folder / f"q{quality}.reconstruction")
    return {"gaussians": len(decoded), "roundtrip_ok": bool(expected.equals(decoded)),
            **figures}


def main(argv: list[str]) -> int:
    """Run the phase named on the command line; see the module docstring."""
    phase, folder, quality, budget_s, max_runs = argv
    run = {"encode": encode_phase, "decode": decode_phase}[phase]
    print(json.dumps(run(Path(folder), int(quality), float(budget_s), int(max_runs))))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
