"""Rate-distortion benchmark: csgs at every preset against the peer codecs, in one run.

For each scene: render the original from the scoring views (black background, the project's
own rasterizer), then for csgs at each quality and for every available peer
(benchmarks/peers): encode, decode, check the round trip, render and score. Rows give
whole-file bytes, bits per Gaussian (per chunk type too, for csgs), mean PSNR / SSIM /
foreground PSNR (the headline: pixels where the original's opacity > 0.05), encode and decode
wall time and the encode's CPU time.

Scoring views (``--scoring``): ``held-out`` (default) is 16 orbit views at 20 degrees plus
12 at 45 degrees, none of which any encoder setting renders (render-aware encodes allocate
on the default viewing distribution, a sphere of directions at three distances); ``orbit``
is the ``--views`` orbit views at 20 degrees alone (what results before 2026-11-24 used).

Variants (``--variants``): ``plain`` is ``Encoder(quality=q)`` at ``--qualities`` (the
default encoder: rotation steps by footprint, FORMAT §12.8 scored steps, and each scene's step
allocation, csgs_codec/decisions/step_allocation.py); ``preset`` keeps the preset's steps
(``--no-step-allocation``, the default before 2026-11-27, so ``plain`` of earlier results);
``allocated`` allocates on every scene (``--step-allocation``; the default skips SH-0 scenes);
``uniform`` is ``plain`` with one rotation step for all (``--rotation-steps uniform``); ``pruned``
is ``plain`` with view pruning on the default viewing distribution (``--view-prune``);
``refined`` is ``plain`` with ``--refine-steps`` refinement steps (``--refine``); ``stacked``
adds the opt-in distortion-side levers of issue 17
(view pruning on the default viewing distribution, ``--refine-steps`` refinement steps) at
``--stacked-qualities``. For each peer point and variant, ``csgs_size_ratio[variant]`` is the
size that variant needs for the peer's foreground PSNR (interpolated on its curve, log-size
linear; null outside it) divided by the peer's size.

Each csgs row of another variant, measured beside ``uniform`` or ``preset``, gets
``size_vs_uniform_at_same_psnr`` / ``size_vs_preset_at_same_psnr``: its bytes over what that
variant's curve needs for its foreground PSNR (null outside that curve).

    .venv/bin/python benchmarks/rd.py --scenes donut biker --out rd.json --plot rd.png
    .venv/bin/python benchmarks/rd.py --variants plain stacked --scenes donut --out a.json
    .venv/bin/python benchmarks/rd.py --combine a.json b.json --out rd.json --plot rd.png

``--combine`` joins documents measured the same way (e.g. scenes run in two processes) and
recomputes the ratios.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import FULL_PRECISION, SCENES, document, emit, held_out_views  # noqa: E402

from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import QUALITIES  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402
from csgs_codec.metrics.comparison import render_references, score_view  # noqa: E402
from csgs_codec.scene.orbit import orbit_cameras  # noqa: E402


def scores(refs, scene, cameras, backend) -> dict:
    """Mean PSNR, SSIM and foreground PSNR of ``scene`` over the cameras (dB, dB, 1)."""
    views = [score_view(ref, scene, cam, backend=backend) for ref, cam in zip(refs, cameras)]
    finite = lambda xs: [x for x in xs if not math.isnan(x)]  # noqa: E731
    mean = lambda xs: float(np.mean(finite(xs))) if finite(xs) else float("nan")  # noqa: E731
    return {"psnr": mean([v.psnr for v in views]), "ssim": mean([v.ssim for v in views]),
            "foreground_psnr": mean([v.foreground_psnr for v in views])}


#: Encoder options of each variant (the quality is added per row).
VARIANTS = {"plain": {}, "uniform": {"rotation_steps": "uniform"},
            "preset": {"step_allocation": False}, "allocated": {"step_allocation": True},
            "stacked": {"view_pruning": True}, "pruned": {"view_pruning": True},
            "refined": {}}
#: Variants the others are compared with at equal foreground PSNR
#: (``size_vs_<variant>_at_same_psnr``).
BASELINES = ("uniform", "preset")


def csgs_rows(name, original, refs, cameras, qualities, backend, variant: str = "plain",
              refine_steps: int = 0) -> list[dict]:
    """Encode, decode, check and score ``original`` at each quality with one variant."""
    options = dict(VARIANTS[variant])
    if variant in ("stacked", "refined"):
        options["refine"] = refine_steps
    rows = []
    for q in qualities:
        start, cpu_start = time.perf_counter(), time.process_time()
        result = Encoder(quality=q, **options).encode_with_report(original)
        encode_s = time.perf_counter() - start
        encode_cpu_s = time.process_time() - cpu_start
        start = time.perf_counter()
        decoded = Decoder().decode(result.data, layers="color")
        decode_s = time.perf_counter() - start
        if not decoded.equals(result.reconstruction):
            raise SystemExit(f"{name} q{q} {variant}: decode differs from the encoder's "
                             "reconstruction")
        rows.append({"scene": name, "codec": "csgs", "variant": variant,
                     "setting": f"quality {q}", "options": options,
                     "bytes": len(result.data),
                     "bits_per_gaussian": 8 * len(result.data) / len(original),
                     "chunk_bits_per_gaussian": {kind: 8 * size / len(original) for kind, size
                                                 in sorted(result.stream_bytes.items())},
                     "view_pruned": result.view_pruned,
                     "encode_s": encode_s, "encode_cpu_s": encode_cpu_s, "decode_s": decode_s,
                     **scores(refs, decoded, cameras, backend)})
        print(f"{name} q{q} {variant}: {rows[-1]['bits_per_gaussian']:.2f} bits/G, "
              f"{rows[-1]['foreground_psnr']:.2f} dB, {encode_s:.0f} s", file=sys.stderr)
    return rows


def for_scene(peer, scene):
    """The peer as run on ``scene``: SOG's SH k-means gets one iteration on SH scenes (its
    default takes over 30 minutes for playbot on 2 cores); the row's setting says so."""
    if peer.name == "playcanvas-sog" and scene.sh_degree_in_use() > 0:
        from peers import SplatTransformCodec

        return SplatTransformCodec("sog", extra_args=["--sh-iterations", "1"]), \
            " --sh-iterations 1"
    return peer, ""


def peer_rows(name, path, original, refs, cameras, peers, backend, workdir) -> list[dict]:
    rows = []
    for listed in peers:
        peer, note = for_scene(listed, original)
        enc = peer.encode(path, workdir / peer.name)
        dec = peer.decode(enc.path, workdir / peer.name / f"{name}.decoded.ply")
        decoded = read_ply(dec.path)
        rows.append({"scene": name, "codec": peer.name, "setting": (peer.version() or "") + note,
                     "bytes": enc.bytes, "bits_per_gaussian": 8 * enc.bytes / len(original),
                     "gaussians_decoded": len(decoded), "encode_s": enc.seconds,
                     "decode_s": dec.seconds, "fixups": dec.fixups,
                     **scores(refs, decoded, cameras, backend)})
    return rows


def size_at(curve: list[dict], psnr: float) -> float | None:
    """csgs bytes at foreground PSNR ``psnr`` on its curve (log-linear), None if outside."""
    pts = sorted((r["foreground_psnr"], math.log(r["bytes"])) for r in curve)
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    if not xs or psnr < xs[0] or psnr > xs[-1]:
        return None
    return float(math.exp(np.interp(psnr, xs, ys)))


def add_ratios(rows: list[dict]) -> None:
    """Give each peer row, per csgs variant, the csgs/peer size ratio at the peer's
    foreground PSNR (``csgs_size_ratio`` and ``csgs_bytes_at_same_psnr``, keyed by variant)."""
    for row in rows:
        if row["codec"] == "csgs":
            continue
        ratios, sizes = {}, {}
        for variant in sorted({r.get("variant", "plain") for r in rows if r["codec"] == "csgs"
                               and r["scene"] == row["scene"]}):
            curve = [r for r in rows if r["codec"] == "csgs" and r["scene"] == row["scene"]
                     and r.get("variant", "plain") == variant]
            size = size_at(curve, row["foreground_psnr"])
            sizes[variant] = size
            ratios[variant] = None if size is None else size / row["bytes"]
        row["csgs_bytes_at_same_psnr"] = sizes
        row["csgs_size_ratio"] = ratios
    for base in BASELINES:  # each csgs variant against each baseline variant measured
        for row in rows:
            if row["codec"] != "csgs" or row.get("variant", "plain") == base:
                continue
            curve = [r for r in rows if r["codec"] == "csgs" and r["scene"] == row["scene"]
                     and r.get("variant") == base]
            if not curve:
                continue
            size = size_at(curve, row["foreground_psnr"])
            row[f"size_vs_{base}_at_same_psnr"] = None if size is None else row["bytes"] / size


def plot(rows: list[dict], path: str) -> None:
    """One panel per scene: foreground PSNR against bits per Gaussian."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = sorted({r["scene"] for r in rows})
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.5 * len(scenes), 4), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        for variant in sorted({r.get("variant", "plain") for r in rows}):
            mine = sorted((r for r in rows if r["scene"] == scene and r["codec"] == "csgs"
                           and r.get("variant", "plain") == variant),
                          key=lambda r: r["bits_per_gaussian"])
            if mine:
                ax.plot([r["bits_per_gaussian"] for r in mine],
                        [r["foreground_psnr"] for r in mine], "o-", label=f"csgs {variant}")
        peers = sorted({r["codec"] for r in rows if r["codec"] != "csgs"})
        for r in rows:
            if r["scene"] == scene and r["codec"] != "csgs":
                ax.plot(r["bits_per_gaussian"], r["foreground_psnr"], "s", label=r["codec"],
                        color=f"C{2 + peers.index(r['codec'])}")  # the same color per peer
        ax.set_title(scene + ("" if scene in FULL_PRECISION else " (re-decoded)"))
        ax.set_xlabel("bits per Gaussian")
        ax.set_ylabel("foreground PSNR (dB)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _emit_rows(rows: list[dict], args, peers) -> None:
    """Write the document of ``rows`` (ratios recomputed) to ``args.out`` or stdout."""
    add_ratios(rows)
    for row in rows:
        row["full_precision_scene"] = row["scene"] in FULL_PRECISION
    scoring = ("16 orbit views @20deg + 12 @45deg" if args.scoring == "held-out"
               else f"{args.views} orbit views @20deg")
    emit(document("rd", rows, scoring=scoring, size=args.size, refine_steps=args.refine_steps,
                  peers=[p.name for p in peers]), args.out)


def combine(paths: list[str]) -> tuple[list[dict], dict]:
    """Rows and shared settings of several rd documents measured the same way."""
    rows, settings = [], None
    for path in paths:
        doc = json.loads(Path(path).read_text())
        these = {k: doc.get(k) for k in ("scoring", "size", "refine_steps")}
        if settings is not None and these != settings:
            raise SystemExit(f"{path}: measured differently ({these} vs {settings})")
        settings = these
        derived = ("csgs_size_ratio", "csgs_bytes_at_same_psnr",
                   *(f"size_vs_{base}_at_same_psnr" for base in BASELINES))
        rows += [{k: v for k, v in r.items() if k not in derived}
                 for r in doc["results"]]
    return rows, {**settings, "combined_from": [Path(p).name for p in paths]}


def main() -> int:
    """Run the benchmark; see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="*", default=None,
                        help="scene names in ../shared/data/scenes or paths to .ply files "
                             "(default: every scene there)")
    parser.add_argument("--qualities", nargs="*", type=int, default=list(QUALITIES))
    parser.add_argument("--variants", nargs="+", default=["plain"], choices=sorted(VARIANTS))
    parser.add_argument("--stacked-qualities", nargs="*", type=int, default=[5, 7, 8, 9])
    parser.add_argument("--refine-steps", type=int, default=20)
    parser.add_argument("--scoring", choices=["held-out", "orbit"], default="held-out")
    parser.add_argument("--views", type=int, default=16, help="orbit views (--scoring orbit)")
    parser.add_argument("--size", default="800x600")
    parser.add_argument("--peers", nargs="*", default=None,
                        help="peer names (default: every available one); none: --peers")
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--combine", nargs="+", default=None, metavar="JSON",
                        help="join these rd documents instead of measuring")
    parser.add_argument("--out", default=None, help="JSON file (default: stdout)")
    parser.add_argument("--plot", default=None, help="PNG of the RD curves")
    args = parser.parse_args()
    if args.combine:
        rows, settings = combine(args.combine)
        add_ratios(rows)
        emit(document("rd", rows, **settings), args.out)
        if args.plot:
            plot(rows, args.plot)
        return 0
    width, height = (int(v) for v in args.size.lower().split("x"))
    names = args.scenes or sorted(p.stem for p in SCENES.glob("*.ply"))

    from peers import all_peers

    peers = [p for p in all_peers() if p.available()]
    if args.peers is not None:
        peers = [p for p in peers if p.name in args.peers]
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            path = Path(name) if name.endswith(".ply") else SCENES / f"{name}.ply"
            name = path.stem
            original = read_ply(path)
            if args.scoring == "held-out":
                cameras = held_out_views(original, width, height)
            else:
                cameras = orbit_cameras(original, args.views, width=width, height=height)
            refs = render_references(original, cameras, backend=args.backend)
            for variant in args.variants:
                qualities = args.stacked_qualities if variant == "stacked" else args.qualities
                rows += csgs_rows(name, original, refs, cameras, qualities, args.backend,
                                  variant, args.refine_steps)
            rows += peer_rows(name, path, original, refs, cameras, peers, args.backend,
                              Path(tmp))
            print(f"{name}: done", file=sys.stderr)
            if args.out:  # a run stopped later still leaves the scenes it finished
                _emit_rows(rows, args, peers)
    _emit_rows(rows, args, peers)
    if args.plot:
        plot(rows, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
