"""``csgs decode SCENE.csgs -o OUT.ply|.splat|.spz|.glb [--layers color|color,semantic]``."""

from __future__ import annotations

import time

NAME = "decode"
HELP = ("decode a .csgs bitstream into a 3DGS .ply, an antimatter15 .splat, a Niantic .spz "
        "(v4) or a glTF .glb (KHR_gaussian_splatting), picked by the output's extension")


def add_arguments(parser) -> None:
    """Arguments of ``csgs decode``."""
    parser.add_argument("bitstream", help="input .csgs")
    parser.add_argument("-o", "--output", required=True,
                        help="output .ply, .splat, .spz or .glb, picked by extension (an anchor "
                             "scene: an anchor .ply, or a Scaffold-GS checkpoint folder when the "
                             "name has no .ply suffix)")
    parser.add_argument("--layers", default="color", type=layers_option,
                        metavar="color|color,semantic",
                        help="layers to decode, comma-separated in any order (default color; "
                             "'color' never reads the semantic bytes)")


def layers_option(text: str) -> str:
    """The ``--layers`` value normalised to "color" or "color,semantic" (argparse type)."""
    import argparse

    from csgs_codec.codec.container_access import parse_layers
    from csgs_codec.errors import InputError

    try:
        names = parse_layers(text)
    except InputError as err:
        raise argparse.ArgumentTypeError(err.message) from None
    return "color,semantic" if "semantic" in names else "color"


def run(args) -> int:
    """Decode the layers asked for and write the output atomically, in the format its
    extension names."""
    from csgs_codec.atomic_write import check_output
    from csgs_codec.codec.anchor_decoder import is_anchor_file
    from csgs_codec.codec.decoder import Decoder
    from csgs_codec.interchange.writers import write_scene, writer_for

    if is_anchor_file(args.bitstream):
        return _decode_anchors(args)
    check_output(args.output, [args.bitstream])
    writer_for(args.output)  # an unknown extension fails before the decode
    start = time.perf_counter()
    scene = Decoder().decode(args.bitstream, layers=args.layers)
    seconds = time.perf_counter() - start
    write_scene(scene, args.output, [args.bitstream])
    extra = ""
    if scene.semantic is not None:
        extra += f", {scene.semantic.shape[1]} semantic channels"
    if scene.labels is not None:
        extra += ", labels"
    print(f"{args.output}: {len(scene):,} Gaussians, SH degree {scene.sh_degree_stored}"
          f"{extra} (decoded in {seconds:.2f} s)")
    return 0


def _decode_anchors(args) -> int:
    """Decode an anchor-scene bitstream to an anchor PLY or a checkpoint folder."""
    from pathlib import Path

    from csgs_codec.codec.anchor_decoder import AnchorDecoder
    from csgs_codec.scene.anchor_ply import write_anchor_ply
    from csgs_codec.scene.scaffold_io import write_scaffold

    start = time.perf_counter()
    scene = AnchorDecoder().decode(args.bitstream, layers=args.layers)
    seconds = time.perf_counter() - start
    if Path(args.output).suffix.lower() == ".ply":
        write_anchor_ply(scene, args.output, [args.bitstream])
        kind = "anchor PLY"
    else:
        write_scaffold(scene, args.output)
        kind = "checkpoint folder"
    print(f"{args.output}: {len(scene):,} anchors ({kind}; decoded in {seconds:.2f} s)")
    return 0
