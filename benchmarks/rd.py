"""Rate-distortion benchmark: csgs at every preset against the peer codecs, in one run.

For each scene: render the original from N orbit views (black background, the project's own
rasterizer), then for csgs at each quality and for every available peer (benchmarks/peers):
encode, decode, check the round trip, render and score. Rows give whole-file bytes, bits per
Gaussian, mean PSNR / SSIM / foreground PSNR (the headline: pixels where the original's opacity
> 0.05), encode and decode wall time. For each peer point, ``csgs_size_ratio`` is the size
csgs needs for the same foreground PSNR (interpolated on its curve, log-size linear) divided
by the peer's size.

    .venv/bin/python benchmarks/rd.py --scenes donut biker --out rd.json --plot rd.png
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import FULL_PRECISION, SCENES, document, emit  # noqa: E402

from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.metrics.comparison import render_references, score_view  # noqa: E402
from csgs_codec.scene.orbit import orbit_cameras  # noqa: E402
from csgs_codec.scene.ply_io import read_ply  # noqa: E402


def scores(refs, scene, cameras, backend) -> dict:
    """Mean PSNR, SSIM and foreground PSNR of ``scene`` over the cameras (dB, dB, 1)."""
    views = [score_view(ref, scene, cam, backend=backend) for ref, cam in zip(refs, cameras)]
    finite = lambda xs: [x for x in xs if not math.isnan(x)]  # noqa: E731
    mean = lambda xs: float(np.mean(finite(xs))) if finite(xs) else float("nan")  # noqa: E731
    return {"psnr": mean([v.psnr for v in views]), "ssim": mean([v.ssim for v in views]),
            "foreground_psnr": mean([v.foreground_psnr for v in views])}


def csgs_rows(name, original, refs, cameras, qualities, backend) -> list[dict]:
    rows = []
    for q in qualities:
        start = time.perf_counter()
        result = Encoder(quality=q).encode_with_report(original)
        encode_s = time.perf_counter() - start
        start = time.perf_counter()
        decoded = Decoder().decode(result.data, layers="color")
        decode_s = time.perf_counter() - start
        if not decoded.equals(result.reconstruction):
            raise SystemExit(f"{name} q{q}: decode differs from the encoder's reconstruction")
        rows.append({"scene": name, "codec": "csgs", "setting": f"quality {q}",
                     "bytes": len(result.data),
                     "bits_per_gaussian": 8 * len(result.data) / len(original),
                     "encode_s": encode_s, "decode_s": decode_s,
                     **scores(refs, decoded, cameras, backend)})
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
    """Give each peer row the csgs/peer size ratio at the peer's foreground PSNR."""
    for row in rows:
        if row["codec"] == "csgs":
            continue
        curve = [r for r in rows if r["codec"] == "csgs" and r["scene"] == row["scene"]]
        size = size_at(curve, row["foreground_psnr"])
        row["csgs_bytes_at_same_psnr"] = size
        row["csgs_size_ratio"] = None if size is None else size / row["bytes"]


def plot(rows: list[dict], path: str) -> None:
    """One panel per scene: foreground PSNR against bits per Gaussian."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = sorted({r["scene"] for r in rows})
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.5 * len(scenes), 4), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        mine = sorted((r for r in rows if r["scene"] == scene and r["codec"] == "csgs"),
                      key=lambda r: r["bits_per_gaussian"])
        ax.plot([r["bits_per_gaussian"] for r in mine], [r["foreground_psnr"] for r in mine],
                "o-", label="csgs")
        for r in rows:
            if r["scene"] == scene and r["codec"] != "csgs":
                ax.plot(r["bits_per_gaussian"], r["foreground_psnr"], "s", label=r["codec"])
        ax.set_title(scene + ("" if scene in FULL_PRECISION else " (re-decoded)"))
        ax.set_xlabel("bits per Gaussian")
        ax.set_ylabel("foreground PSNR (dB)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> int:
    """Run the benchmark; see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="*", default=None,
                        help="scene names in ../shared/data/scenes (default: all)")
    parser.add_argument("--qualities", nargs="*", type=int, default=list(range(1, 10)))
    parser.add_argument("--views", type=int, default=16)
    parser.add_argument("--size", default="800x600")
    parser.add_argument("--peers", nargs="*", default=None,
                        help="peer names (default: every available one); none: --peers")
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--out", default=None, help="JSON file (default: stdout)")
    parser.add_argument("--plot", default=None, help="PNG of the RD curves")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    names = args.scenes or sorted(p.stem for p in SCENES.glob("*.ply"))

    from peers import all_peers

    peers = [p for p in all_peers() if p.available()]
    if args.peers is not None:
        peers = [p for p in peers if p.name in args.peers]
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            path = SCENES / f"{name}.ply"
            original = read_ply(path)
            cameras = orbit_cameras(original, args.views, width=width, height=height)
            refs = render_references(original, cameras, backend=args.backend)
            rows += csgs_rows(name, original, refs, cameras, args.qualities, args.backend)
            rows += peer_rows(name, path, original, refs, cameras, peers, args.backend,
                              Path(tmp))
            print(f"{name}: done", file=sys.stderr)
    add_ratios(rows)
    for row in rows:
        row["full_precision_scene"] = row["scene"] in FULL_PRECISION
    emit(document("rd", rows, views=args.views, size=args.size,
                  peers=[p.name for p in peers]), args.out)
    if args.plot:
        plot(rows, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
