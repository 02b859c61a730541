"""``csgs decode SCENE.csgs -o OUT.ply [--layers color|color,semantic]``."""

from __future__ import annotations

import time

NAME = "decode"
HELP = "decode a .csgs bitstream into a standard 3DGS .ply"


def add_arguments(parser) -> None:
    """Arguments of ``csgs decode``."""
    parser.add_argument("bitstream", help="input .csgs")
    parser.add_argument("-o", "--output", required=True, help="output .ply")
    parser.add_argument("--layers", default="color", choices=("color", "color,semantic"),
                        help="layers to decode; 'color' never reads the semantic bytes")


def run(args) -> int:
    """Decode the layers asked for and write the PLY atomically."""
    from csgs_codec.codec.decoder import Decoder
    from csgs_codec.scene.ply_io import write_ply

    start = time.perf_counter()
    scene = Decoder().decode(args.bitstream, layers=args.layers)
    seconds = time.perf_counter() - start
    write_ply(scene, args.output)
    extra = ""
    if scene.semantic is not None:
        extra += f", {scene.semantic.shape[1]} semantic channels"
    if scene.labels is not None:
        extra += ", labels"
    print(f"{args.output}: {len(scene):,} Gaussians, SH degree {scene.sh_degree_stored}"
          f"{extra} (decoded in {seconds:.2f} s)")
    return 0
