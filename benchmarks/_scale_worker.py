"""One measured case of benchmarks/scale.py, run in a fresh process.

    python -m benchmarks._scale_worker encode PLY OUT.csgs --tile-size N [--workers W]
        [--ray local] [--whole]
    python -m benchmarks._scale_worker decode FILE.csgs PLY [--region-eighth]

Prints one JSON line. Peak memory is sampled from /proc (Linux) every 0.1 s over this
process and all its descendants (worker processes, a local Ray cluster) by a forked helper
process: ``peak_tree_mb`` sums their resident sets (shared pages such as the mapped PLY
counted once per process, so an upper bound), ``peak_tree_anon_mb`` sums their anonymous
memory only (what the processes allocate; the mapped input, ``input_mb``, is page cache on
top of it, at most once), ``peak_process_anon_mb`` is the largest anonymous memory of one
process (with workers: one tile's work, or this process), ``peak_self_mb`` is this process's
own high-water mark. ``cpu_s`` is the CPU time of this process and its finished children (local
workers; a Ray cluster's workers are not counted).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time
from pathlib import Path

import numpy as np


def _memory_tree_kb(root: int, skip: int) -> tuple[int, int, int]:
    """(summed VmRSS, summed RssAnon, largest RssAnon of one process), kB, over ``root`` and
    its descendants except ``skip``, from /proc. RssAnon leaves out file pages such as the
    memory-mapped input, which every process that touches them counts in its VmRSS."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    rss = anon = largest = 0
    stack = [root]
    while stack:
        pid = stack.pop()
        if pid == skip:
            continue
        stack += children.get(pid, [])
        try:
            with open(f"/proc/{pid}/status") as fh:
                for line in fh:
                    if line.startswith("VmRSS:"):
                        rss += int(line.split()[1])
                    elif line.startswith("RssAnon:"):
                        own = int(line.split()[1])
                        anon += own
                        largest = max(largest, own)
        except OSError:
            pass
    return rss, anon, largest


class PeakSampler:
    """Samples this process's tree from a forked helper process (so the sampling takes no
    time from this process's threads); ``stop`` returns the peaks in MB of the summed RSS,
    the summed anonymous RSS and the largest anonymous RSS of one process. The helper leaves
    itself out."""

    def __init__(self) -> None:
        import multiprocessing

        context = multiprocessing.get_context("fork")
        self._parent, child = context.Pipe()
        self._process = context.Process(target=_sample, args=(os.getpid(), child),
                                        daemon=True)
        self._process.start()

    def stop(self) -> tuple[float, float, float]:
        self._parent.send("stop")
        peaks = self._parent.recv()
        self._process.join()
        return tuple(kb / 1024 for kb in peaks)


def _sample(root: int, pipe) -> None:
    """The helper: sample every 0.1 s until told to stop, then send the peaks (kB)."""
    me, peaks = os.getpid(), (0, 0, 0)
    while not pipe.poll(0.1):
        peaks = tuple(map(max, peaks, _memory_tree_kb(root, me)))
    pipe.recv()
    pipe.send(peaks)


def _high_water_mb() -> float:
    """This process's peak RSS (VmHWM, MB). Not ru_maxrss: that survives exec, so it would
    report the peak of the process that started this one when that was larger."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def encode(args) -> dict:
    """Encode the PLY as csgs encode would (streamed when tiled) and time it."""
    from csgs_codec import Encoder, read_ply
    from csgs_codec.codec.tile_encoder import encode_ply_tiled

    encoder = Encoder(quality=args.quality, tile_size=args.tile_size, workers=args.workers,
                      ray=args.ray)
    sampler = PeakSampler()
    start = time.perf_counter()
    if args.whole:
        result = encoder.encode_with_report(read_ply(args.ply))
    else:
        result = encode_ply_tiled(encoder, args.ply)
    seconds = time.perf_counter() - start
    used = [resource.getrusage(who) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    cpu = sum(u.ru_utime + u.ru_stime for u in used)  # before the sampler ends: not its share
    peak, anon, largest_anon = sampler.stop()
    Path(args.out).write_bytes(result.data)
    np.save(args.out + ".order.npy", result.order)
    return {"encode_s": seconds, "cpu_s": cpu, "peak_tree_mb": peak,
            "peak_tree_anon_mb": anon, "peak_process_anon_mb": largest_anon,
            "input_mb": Path(args.ply).stat().st_size / 2**20,
            "peak_self_mb": _high_water_mb(),
            "bytes": len(result.data), "tiles": result.tiles, "gaussians": len(result.order)}


def decode(args) -> dict:
    """Full decode and the decode of the tiles meeting the lower octant of the robust box;
    attribute errors against the input in encoder order."""
    from csgs_codec import Decoder, read_ply

    decoder = Decoder()
    start = time.perf_counter()
    full = decoder.decode_with_report(args.csgs)
    full_s = time.perf_counter() - start
    scene = read_ply(args.ply)
    order = np.load(args.csgs + ".order.npy")
    errors = {}
    for name in ("positions", "sh_dc", "sh_rest", "opacity", "scales"):
        decoded, original = getattr(full.scene, name), getattr(scene, name)
        total = 0.0
        for start in range(0, len(order), 1 << 20):  # in slices: 20M SH-3 rows at once
            part = order[start:start + (1 << 20)]  # would need tens of GB in float64
            diff = decoded[start:start + len(part)].astype(np.float64) - original[part]
            total += float(np.sum(diff**2))
        errors[f"{name}_rmse"] = float(np.sqrt(total / max(decoded.size, 1)))
    lo = np.percentile(scene.positions, 1, axis=0)
    hi = np.percentile(scene.positions, 99, axis=0)
    mid = (lo + hi) / 2
    region = [*map(float, lo), *map(float, mid)]
    del scene, full
    start = time.perf_counter()
    part = decoder.decode_with_report(args.csgs, region=region)
    part_s = time.perf_counter() - start
    return {"full_decode_s": full_s, "region": region, "region_decode_s": part_s,
            "region_tiles": part.tiles, "tile_count": part.tile_count,
            "region_bytes_read": part.bytes_read, "file_bytes": part.file_bytes,
            "region_gaussians": len(part.scene) if part.scene is not None else 0, **errors}


def main() -> None:
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="what", required=True)
    e = sub.add_parser("encode")
    e.add_argument("ply")
    e.add_argument("out")
    e.add_argument("--tile-size", type=int, required=True)
    e.add_argument("--workers", type=int, default=1)
    e.add_argument("--ray", default=None)
    e.add_argument("--quality", type=int, default=5)
    e.add_argument("--whole", action="store_true", help="read the PLY whole (untiled case)")
    d = sub.add_parser("decode")
    d.add_argument("csgs")
    d.add_argument("ply")
    args = parser.parse_args()
    print(json.dumps(encode(args) if args.what == "encode" else decode(args)), flush=True)


if __name__ == "__main__":
    main()
