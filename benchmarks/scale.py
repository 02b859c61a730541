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
from csgs_codec.interchange.ply_io import write_ply  # noqa: E402

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


def measure(size: int, work: Path, source: Path, untiled: bool = True,
            engines: tuple = ENGINES, tile: int | None = None) -> dict:
    """The cases for one scene size: the untiled encode (unless ``untiled`` is False: its
    whole-scene read needs about 4 GB per million SH-3 Gaussians) and the tiled ``engines``,
    with tiles of ``tile`` Gaussians (default: an eighth of the scene)."""
    ply = work / f"scene_{size}.ply"
    if not ply.exists():
        write_ply(upsampled_to(read_ply(source), size, seed=0), ply)
    tile = tile or size // 8
    row = {"scene": f"{source.name} upsampled to {size:,} (jittered copies, seed 0)",
           "gaussians": size, "sh_degree": 3, "quality": 5, "tile_size": tile,
           "ply_mb": ply.stat().st_size / 2**20, "encodes": []}
    untiled_out = str(work / f"untiled_{size}.csgs")
    if untiled:
        whole = _run(["encode", str(ply), untiled_out, "--tile-size", str(size), "--whole"])
        row["encodes"].append({"case": "untiled (read whole)", **whole})
        print(f"{size}: untiled {whole}", file=sys.stderr, flush=True)
    files = []
    for label, extra in engines:
        out = str(work / f"tiled_{size}_{len(files)}.csgs")
        got = _run(["encode", str(ply), out, "--tile-size", str(tile), *extra])
        row["encodes"].append({"case": f"tiled, {label}", **got})
        files.append(Path(out).read_bytes())
        print(f"{size}: {label} {got}", file=sys.stderr, flush=True)
    row["identical_across_engines"] = all(f == files[0] for f in files)
    tiled_bytes = len(files[0])
    row["bits_per_gaussian_tiled"] = 8 * tiled_bytes / size
    enc = {e["case"]: e["encode_s"] for e in row["encodes"]}
    for key, one, two in (("speedup_2_workers_local", "local, 1 worker", "local, 2 workers"),
                          ("speedup_2_workers_ray", "ray local, 1 CPU", "ray local, 2 CPUs")):
        if f"tiled, {one}" in enc and f"tiled, {two}" in enc:
            row[key] = enc[f"tiled, {one}"] / enc[f"tiled, {two}"]
    tiled_decode = _run(["decode", str(work / f"tiled_{size}_0.csgs"), str(ply)])
    row["tiled_decode"] = tiled_decode
    if untiled:
        row["bits_per_gaussian_untiled"] = 8 * whole["bytes"] / size
        row["tiled_size_ratio"] = tiled_bytes / whole["bytes"]
        untiled_decode = _run(["decode", untiled_out, str(ply)])
        row["untiled_decode"] = {k: v for k, v in untiled_decode.items()
                                 if k.endswith("_rmse") or k == "full_decode_s"}
    row["region_bytes_fraction"] = tiled_decode["region_bytes_read"] / tiled_decode["file_bytes"]
    row["region_time_fraction"] = (tiled_decode["region_decode_s"]
                                   / tiled_decode["full_decode_s"])
    print(f"{size}: decode {tiled_decode}", file=sys.stderr, flush=True)
    return row


def plot(rows: list[dict], path: str) -> None:
    """Encode time and peak memory against size per case; the tiling cost."""
    from benchmarks._png_plot import MARKERS, PALETTE, Chart, Series, save_charts

    cases = list(dict.fromkeys(e["case"] for r in rows for e in r["encodes"]))
    time_chart = Chart("encode wall time (shared 2-core machine)", "Gaussians", "seconds",
                       log_x=True, log_y=True)
    memory_chart = Chart("peak memory (process tree, summed RSS)", "Gaussians", "MB",
                         log_x=True, log_y=True)
    for i, case in enumerate(cases):

        def pick(key: str, case: str = case) -> tuple[list[int], list[float]]:
            found = [(r["gaussians"], e[key]) for r in rows for e in r["encodes"]
                     if e["case"] == case]
            return [x for x, _ in found], [y for _, y in found]

        style = {"color": PALETTE[i % len(PALETTE)], "marker": MARKERS[i % len(MARKERS)],
                 "line": True}
        time_chart.add(Series(case, *pick("encode_s"), **style))
        memory_chart.add(Series(case, *pick("peak_tree_mb"), **style))
    cost = Chart("tiled / untiled file size; region decode fractions", "Gaussians", "ratio",
                 log_x=True)
    for i, (key, label) in enumerate((("tiled_size_ratio", "tiled / untiled bytes"),
                                      ("region_bytes_fraction", "region bytes read / file"),
                                      ("region_time_fraction", "region / full decode time"))):
        have = [r for r in rows if key in r]
        cost.add(Series(label, [r["gaussians"] for r in have], [r[key] for r in have],
                        PALETTE[i], MARKERS[i], line=True))
    save_charts([time_chart, memory_chart, cost], path, columns=3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="1000000,5000000")
    parser.add_argument("--out", default=None)
    parser.add_argument("--plot", default=None)
    parser.add_argument("--work", default="/tmp/csgs_scale")
    parser.add_argument("--source", default=str(SOURCE))
    parser.add_argument("--no-untiled-above", type=int, default=None, metavar="N",
                        help="skip the untiled encode for sizes above N")
    parser.add_argument("--engines", default=None, metavar="I,J",
                        help="only these tiled cases (indices into 0 local 1 worker, 1 local "
                             "2 workers, 2 ray 1 CPU, 3 ray 2 CPUs)")
    parser.add_argument("--tile-size", type=int, default=None, metavar="N",
                        help="Gaussians per tile (default: an eighth of each scene)")
    parser.add_argument("--note", default="", help="a line about the machine's state")
    parser.add_argument("--append", default=None, metavar="JSON",
                        help="rows of an earlier run to keep before this run's")
    args = parser.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    rows = json.loads(Path(args.append).read_text())["results"] if args.append else []
    engines = (ENGINES if args.engines is None
               else tuple(ENGINES[int(i)] for i in args.engines.split(",")))
    for size in (int(s) for s in args.sizes.split(",")):
        untiled = args.no_untiled_above is None or size <= args.no_untiled_above
        rows.append(measure(size, work, Path(args.source), untiled, engines, args.tile_size))
        emit(document("scale", rows, note=args.note), args.out)  # after each size: partial
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()
