"""``csgs encode SCENE.ply -o SCENE.csgs``: compress a 3DGS scene."""

from __future__ import annotations

import os

from tqdm import tqdm

from csgs_codec.codec.presets import DEFAULT_QUALITY

NAME = "encode"
HELP = "compress a 3DGS .ply scene (or a Scaffold-GS anchor scene) into a .csgs bitstream"
STAGES = ("geometry", "colour", "semantic", "container")


def add_arguments(parser) -> None:
    """Arguments of ``csgs encode``."""
    parser.add_argument("scene", help="input 3DGS .ply, or a Scaffold-GS checkpoint folder / "
                                      "anchor .ply (coded as an anchor scene)")
    parser.add_argument("-o", "--output", required=True, help="output .csgs file")
    parser.add_argument("--quality", type=int, default=DEFAULT_QUALITY, choices=range(1, 10),
                        metavar="1-9", help=f"1 smallest .. 9 near-lossless "
                                            f"(default {DEFAULT_QUALITY})")
    parser.add_argument("--target-psnr", type=float, default=None, metavar="DB",
                        help="instead of --quality: the smallest file whose renders reach this "
                             "foreground PSNR on the encoder's probe views (several encodes)")
    parser.add_argument("--semantic", choices=("auto", "none"), default="auto",
                        help="write the semantic layer when the scene has semantic channels "
                             "(auto) or never (none)")
    parser.add_argument("--prune-opacity", type=float, default=None, metavar="T",
                        help="drop Gaussians with opacity below T (lossy, opt-in)")
    parser.add_argument("--sanitize", action="store_true",
                        help="drop Gaussians with NaN/Inf values instead of failing")


def run(args) -> int:
    """Read, encode and write atomically; print the sizes."""
    from csgs_cli.scene_input import is_anchor_input
    from csgs_codec.atomic_write import write_atomically
    from csgs_codec.codec.encoder import Encoder
    from csgs_codec.scene.ply_io import read_ply

    if is_anchor_input(args.scene):
        return _encode_anchors(args, write_atomically)
    scene = read_ply(args.scene, sanitize=args.sanitize)
    bar = tqdm(total=None if args.target_psnr else len(STAGES), desc="encode", unit="stage",
               disable=args.quiet, leave=False)

    def progress(stage: str) -> None:
        bar.set_postfix_str(stage)
        bar.update(1)

    try:
        result = Encoder(quality=args.quality, target_psnr=args.target_psnr,
                         semantic=args.semantic,
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
    if result.rate_control is not None:
        rc = result.rate_control
        print(f"rate control: {rc.psnr:.2f} dB on the probe views (target {rc.target:.2f} dB), "
              f"steps x{rc.multiplier:.3g} of quality 8's, {len(rc.trials)} trial encodes")
    if result.pruned:
        print(f"pruned {result.pruned:,} Gaussians with opacity below {args.prune_opacity}")
    return 0


def _encode_anchors(args, write_atomically) -> int:
    """Encode a Scaffold-GS anchor scene (checkpoint folder or anchor PLY)."""
    from csgs_cli.scene_input import load_anchor_scene
    from csgs_codec.codec.anchor_encoder import AnchorEncoder

    if args.prune_opacity is not None or args.sanitize:
        from csgs_codec.errors import InputError

        raise InputError("--prune-opacity and --sanitize apply to 3DGS PLY input, not to "
                         "anchor scenes", file=args.scene)
    scene = load_anchor_scene(args.scene)
    with tqdm(total=1, desc="encode anchors (fit + code)", disable=args.quiet, leave=False):
        result = AnchorEncoder(quality=args.quality, semantic=args.semantic
                               ).encode_with_report(scene)
    write_atomically(args.output, result.data)
    m = len(result.reconstruction)
    print(f"{args.output}: {len(result.data):,} bytes, {m:,} anchors, "
          f"{8 * len(result.data) / max(m, 1):.1f} bits/anchor, {result.seconds:.2f} s")
    return 0
