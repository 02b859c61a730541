"""Peer codecs' round trips on shared scenes: size, bits per Gaussian, time and errors.

Every available peer (see ``benchmarks/peers``) compresses each scene, decodes it back to a
standard PLY, and that PLY is read with csgs's own reader and compared with the original
(:func:`roundtrip_report`: dropped Gaussians, matching, per-attribute errors). Peers that are
not installed are listed with the reason. Rows say whether the scene is full precision or
was decoded from a compressed format (re-encoding those in the same format flatters it).
Times are single wall-clock runs of the tool (node start-up included; ``tool_startup_s`` in
``machine`` gives that cost alone) unless ``--repeat`` asks for the best of several.

    .venv/bin/python benchmarks/peers_check.py [--scenes donut.ply guitar.ply]
        [--peers playcanvas-sog niantic-spz] [--repeat 1] [--keep DIR] [--out FILE]

Exit status: 0 when every round trip ran and was read back, 1 when a peer failed (the row
has ``error``) or its PLY was rejected (``reader_rejects_decoded_ply``), 2 when a scene
cannot be read.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.peers import (  # noqa: E402
    PeerCodec,
    SplatTransformCodec,
    all_peers,
    peer_by_name,
    roundtrip_report,
)
from csgs_codec.errors import CsgsError  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402
from csgs_codec.scene.gaussian_scene import GaussianScene  # noqa: E402

SCENES = REPO.parent / "shared" / "data" / "scenes"
DEFAULT_SCENES = ["donut.ply", "guitar.ply"]

#: How each shared scene was made (docs/design.md, 'Measuring quality': name each figure's kind).
SCENE_KINDS = {
    "donut.ply": "full-precision",
    "biker.ply": "decoded-from:playcanvas-compressed-ply",
    "guitar.ply": "decoded-from:playcanvas-compressed-ply",
    "plant.ply": "decoded-from:splat",
    "playbot.ply": "decoded-from:playcanvas-sog",
}


def machine_info() -> dict:
    """CPU count, platform, Python and Node versions, and the splat-transform start-up cost."""
    info = {"cpus": os.cpu_count(), "platform": platform.platform(),
            "python": platform.python_version(), "node": ""}
    node = shutil.which("node")
    if node:
        done = subprocess.run([node, "--version"], capture_output=True, text=True, check=False)
        info["node"] = done.stdout.strip()
    splat = SplatTransformCodec("sog")
    if splat.available():
        info["tool_startup_s"] = {"splat-transform": splat.startup_seconds()}
    return info


def check_peer(peer: PeerCodec, scene_path: Path, original: GaussianScene, work: Path,
               repeat: int) -> dict:
    """One peer on one scene (``original`` is its PLY as read by csgs): encode, decode, read
    back, compare; times are the best of ``repeat`` runs."""
    row: dict = {"peer": peer.name, "peer_version": peer.version(), "scene": scene_path.name,
                 "scene_kind": SCENE_KINDS.get(scene_path.name, "unknown")}
    out_dir = work / peer.name
    try:
        encoded = min((peer.encode(scene_path, out_dir) for _ in range(repeat)),
                      key=lambda result: result.seconds)
        decoded_ply = out_dir / f"{scene_path.stem}.decoded.ply"
        decoded = min((peer.decode(encoded.path, decoded_ply) for _ in range(repeat)),
                      key=lambda result: result.seconds)
    except CsgsError as error:
        row["error"] = str(error)
        return row
    n = len(original)
    row.update({"bytes": encoded.bytes, "bits_per_gaussian": 8 * encoded.bytes / max(n, 1),
                "input_ply_bytes": scene_path.stat().st_size,
                "compression_ratio_vs_input_ply": scene_path.stat().st_size / encoded.bytes,
                "encode_s": encoded.seconds, "decode_s": decoded.seconds,
                "decode_fixups": decoded.fixups})
    try:
        row["roundtrip"] = roundtrip_report(original, read_ply(decoded.path))
    except CsgsError as error:
        row["reader_rejects_decoded_ply"] = str(error)
    return row


def main(argv: list[str] | None = None) -> int:
    """Run the check and print (or write) one csgs-bench/1 JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=DEFAULT_SCENES,
                        help="file names under ../shared/data/scenes, or paths")
    parser.add_argument("--peers", nargs="+", help="peer names (default: every available one)")
    parser.add_argument("--repeat", type=int, default=1, help="best of N runs per timing")
    parser.add_argument("--keep", type=Path, help="keep the compressed and decoded files here")
    parser.add_argument("--out", type=Path, help="write the JSON here instead of stdout")
    args = parser.parse_args(argv)

    peers = [peer_by_name(name) for name in args.peers] if args.peers else all_peers()
    skipped = [{"peer": p.name, "reason": p.why_unavailable()} for p in peers
               if not p.available()]
    runnable = [p for p in peers if p.available()]
    scene_paths = [Path(s) if Path(s).is_file() else SCENES / s for s in args.scenes]

    results = []
    with tempfile.TemporaryDirectory(prefix="csgs-peers-") as tmp:
        work = args.keep or Path(tmp)
        for scene_path in scene_paths:
            try:
                original = read_ply(scene_path)
            except CsgsError as error:
                print(f"error: {error}", file=sys.stderr)
                return 2
            for peer in runnable:
                print(f"{peer.name} on {scene_path.name} ...", file=sys.stderr, flush=True)
                results.append(check_peer(peer, scene_path, original, work / scene_path.stem,
                                          max(args.repeat, 1)))
    document = {"schema": "csgs-bench/1", "benchmark": "peers_check",
                "machine": machine_info(), "skipped_peers": skipped, "results": results}
    text = json.dumps(document, indent=2)
    if args.out:
        args.out.write_text(text + "\n")
    else:
        print(text)
    return 1 if any("error" in r or "reader_rejects_decoded_ply" in r for r in results) else 0


if __name__ == "__main__":
    raise SystemExit(main())
