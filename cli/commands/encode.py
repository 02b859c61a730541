"""``csgs encode SCENE.ply -o SCENE.csgs``: compress a 3DGS scene."""

from __future__ import annotations

import os

from tqdm import tqdm

from csgs_codec.codec.presets import DEFAULT_QUALITY

NAME = "encode"
HELP = "compress a 3DGS .ply scene into a .csgs bitstream"
STAGES = ("geometry", "colour", "semantic", "container")


def add_arguments(parser) -> None:
    """Arguments of ``csgs encode``."""
    parser.add_argument("scene", help="input 3DGS .ply")
    parser.add_argument("-o", "--output", required=True, help="output .csgs file")
    parser.add_argument("--quality", type=int, default=DEFAULT_QUALITY, choices=range(1, 10),
                        metavar="1-9", help=f"1 smallest .. 9 near-lossless "
                                            f"(default {DEFAULT_QUALITY})")
    parser.add_argument("--semantic", choices=("auto", "none"), default="auto",
                        help="write the semantic layer when the scene has semantic channels "
                             "(auto) or never (none)")
    parser.add_argument("--prune-opacity", type=float, default=None, metavar="T",
                        help="drop Gaussians with opacity below T (lossy, opt-in)")
    parser.add_argument("--sanitize", action="store_true",
                        help="drop Gaussians with NaN/Inf values instead of failing")


def run(args) -> int:
    """Read, encode and write atomically; print the sizes."""
    from csgs_codec.atomic_write import write_atomically
    from csgs_codec.codec.encoder import Encoder
    from csgs_codec.scene.ply_io import read_ply

    scene = read_ply(args.scene, sanitize=args.sanitize)
    bar = tqdm(total=len(STAGES), desc="encode", unit="stage", disable=args.quiet,
               leave=False)

    def progress(stage: str) -> None:
        bar.set_postfix_str(stage)
        bar.update(1)

    try:
        result = Encoder(quality=args.quality, semantic=args.semantic,
                         prune_opacity=args.prune_opacity, progress=progress
                         ).encode_with_report(scene)
    finally:
        bar.close()
    write_atomically(args.output, result.data)
    n = len(result.reconstruction)
    in_bytes = os.path.getsize(args.scene)
    bits = 8 * len(result.data) / max(n, 1)
    print(f"{args.output}: {len(result.data):,} bytes, {n:,} Gaussians, {bits:.2f} bits/Gaussian"
          f", {in_bytes / max(len(result.data), 1):.1f}x smaller than the input, "
          f"{result.seconds:.2f} s")
    if result.pruned:
        print(f"pruned {result.pruned:,} Gaussians with opacity below {args.prune_opacity}")
    return 0
