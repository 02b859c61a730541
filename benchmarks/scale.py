"""Large scenes: tiled encoding with 1 and 2 workers, locally and on a local Ray cluster;
the cost of tiling in bits; region decode of an eighth of the scene.

    .venv/bin/python benchmarks/scale.py [--sizes 1000000,5000000] [--out FILE.json]
        [--plot FILE.png] [--work DIR] [--source PLY]

Scenes: the shared SH-3 scene (``../shared/data/real_sh3/leica_sofort_top8192.ply``,
8,192 Gaussians) upsampled deterministically with jittered copies
(benchmarks/_scaling.py, seed 0) to each size and written as binary PLY into ``--work``.
Each case runs in a fresh process (benchmarks/_scale_worker.py):

- untiled: the scene read whole and encoded as one tile (``--tile-size`` = its size);
- tiled: tiles of size/8 (8 tiles), encoded from the memory-mapped PLY as ``csgs encode``
  does, with 1 and 2 local workers and on a local Ray cluster with 1 and 2 CPUs. Every
  tiled file must be byte-identical (``identical_across_engines``).

Per size: encode wall time and peak memory per case, bits per Gaussian tiled and untiled
(same preset, quality 5; RMSE of each attribute against the input shows the quality is the
same), and a region decode of the tiles meeting the lower octant of the scene's 1-99
percentile box: bytes read and time as fractions of a full decode. The machine is shared
(2 cores, other jobs running), so times are noisy.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._scaling import upsampled_to  # noqa: E402
from benchmarks.bench_common import REPO, document, emit  # noqa: E402
from csgs_codec import read_ply  # noqa: E402
from csgs_codec.scene.ply_io import write_ply  # noqa: E402

SOURCE = REPO.parent / "shared" / "data" / "real_sh3" / "leica_sofort_top8192.ply"
#: (label, worker arguments) of the tiled encodes.
ENGINES = (("local, 1 worker", ["--workers", "1"]), ("local, 2 workers", ["--workers", "2"]),
           ("ray local, 1 CPU", ["--ray", "local", "--workers", "1"]),
           ("ray local, 2 CPUs", ["--ray", "local", "--workers", "2"]))


def _run(args: list[str]) -> dict:
    """One worker process; its JSON line."""
    done = subprocess.run([sys.executable, "-m", "benchmarks._scale_worker", *args],
                          cwd=REPO, capture_output=True, text=True, check=False)
    if done.returncode:
        raise RuntimeError(f"worker {args} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def measure(size: int, work: Path, source: Path) -> dict:
    """Every case for one scene size."""
    ply = work / f"scene_{size}.ply"
    if not ply.exists():
        write_ply(upsampled_to(read_ply(source), size, seed=0), ply)
    tile = size // 8
    row = {"scene": f"{source.name} upsampled to {size:,} (jittered copies, seed 0)",
           "gaussians": size, "sh_degree": 3, "quality": 5, "tile_size": tile,
           "ply_mb": ply.stat().st_size / 2**20, "encodes": []}
    untiled_out = str(work / f"untiled_{size}.csgs")
    untiled = _run(["encode", str(ply), untiled_out, "--tile-size", str(size), "--whole"])
    row["encodes"].append({"case": "untiled (read whole)", **untiled})
    print(f"{size}: untiled {untiled}", file=sys.stderr, flush=True)
    files = []
    for label, extra in ENGINES:
        out = str(work / f"tiled_{size}_{len(files)}.csgs")
        got = _run(["encode", str(ply), out, "--tile-size", str(tile), *extra])
        row["encodes"].append({"case": f"tiled, {label}", **got})
        files.append(Path(out).read_bytes())
        print(f"{size}: {label} {got}", file=sys.stderr, flush=True)
    row["identical_across_engines"] = all(f == files[0] for f in files)
    tiled_bytes = len(files[0])
    row["bits_per_gaussian_untiled"] = 8 * untiled["bytes"] / size
    row["bits_per_gaussian_tiled"] = 8 * tiled_bytes / size
    row["tiled_size_ratio"] = tiled_bytes / untiled["bytes"]
    enc = {e["case"]: e["encode_s"] for e in row["encodes"]}
    row["speedup_2_workers_local"] = enc["tiled, local, 1 worker"] / enc["tiled, local, 2 workers"]
    row["speedup_2_workers_ray"] = enc["tiled, ray local, 1 CPU"] / enc["tiled, ray local, 2 CPUs"]
    tiled_decode = _run(["decode", str(work / f"tiled_{size}_0.csgs"), str(ply)])
    untiled_decode = _run(["decode", untiled_out, str(ply)])
    row["tiled_decode"] = tiled_decode
    row["untiled_decode"] = {k: v for k, v in untiled_decode.items() if k.endswith("_rmse")
                             or k == "full_decode_s"}
    row["region_bytes_fraction"] = tiled_decode["region_bytes_read"] / tiled_decode["file_bytes"]
    row["region_time_fraction"] = (tiled_decode["region_decode_s"]
                                   / tiled_decode["full_decode_s"])
    print(f"{size}: decode {tiled_decode}", file=sys.stderr, flush=True)
    return row


def plot(rows: list[dict], path: str) -> None:
    """Encode time and peak memory against size per case; the tiling cost."""
    from benchmarks._png_plot import MARKERS, PALETTE, Chart, Series, save_charts

    cases = [e["case"] for e in rows[0]["encodes"]]
    time_chart = Chart("encode wall time (shared 2-core machine)", "Gaussians", "seconds",
                       log_x=True, log_y=True)
    memory_chart = Chart("peak memory (process tree, summed RSS)", "Gaussians", "MB",
                         log_x=True, log_y=True)
    for i, case in enumerate(cases):
        xs = [r["gaussians"] for r in rows]

        def pick(key: str, case: str = case) -> list[float]:
            return [next(e[key] for e in r["encodes"] if e["case"] == case) for r in rows]

        style = {"color": PALETTE[i % len(PALETTE)], "marker": MARKERS[i % len(MARKERS)],
                 "line": True}
        time_chart.add(Series(case, xs, pick("encode_s"), **style))
        memory_chart.add(Series(case, xs, pick("peak_tree_mb"), **style))
    cost = Chart("tiled / untiled file size; region decode fractions", "Gaussians", "ratio",
                 log_x=True)
    xs = [r["gaussians"] for r in rows]
    for i, (key, label) in enumerate((("tiled_size_ratio", "tiled / untiled bytes"),
                                      ("region_bytes_fraction", "region bytes read / file"),
                                      ("region_time_fraction", "region / full decode time"))):
        cost.add(Series(label, xs, [r[key] for r in rows], PALETTE[i], MARKERS[i], line=True))
    save_charts([time_chart, memory_chart, cost], path, columns=3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="1000000,5000000")
    parser.add_argument("--out", default=None)
    parser.add_argument("--plot", default=None)
    parser.add_argument("--work", default="/tmp/csgs_scale")
    parser.add_argument("--source", default=str(SOURCE))
    args = parser.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    for size in (int(s) for s in args.sizes.split(",")):
        rows.append(measure(size, work, Path(args.source)))
        emit(document("scale", rows, note="shared 2-core machine under load from other "
                      "jobs: times are noisy"), args.out)  # after every size: partial results
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()
