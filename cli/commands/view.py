"""``csgs view SCENE [--screenshot out.png]``: a pyvista preview of the Gaussians."""

from __future__ import annotations

NAME = "view"
HELP = ("preview a scene with pyvista: Gaussians as oriented ellipsoids or points coloured by "
        "DC colour or semantic label; --screenshot renders offscreen to a PNG")


def add_arguments(parser) -> None:
    """Arguments of ``csgs view``."""
    parser.add_argument("scene", help="a 3DGS .ply scene")
    parser.add_argument("--screenshot", metavar="PNG",
                        help="render offscreen to this PNG file instead of opening a window")
    parser.add_argument("--points", action="store_true",
                        help="draw points instead of oriented ellipsoids (faster)")
    parser.add_argument("--color", default="auto", choices=("auto", "dc", "label", "semantic"),
                        help="colour by DC colour, integer label or the first three semantic "
                             "channels (default: label when present, else DC colour)")
    parser.add_argument("--size", metavar="WxH", default="800x600", help="window size")
    parser.add_argument("--up", metavar="AXIS",
                        help="up axis of the view: +x -x +y -y +z -z (default: guessed)")
    parser.add_argument("--max-gaussians", type=int, default=60_000, metavar="N",
                        help="draw at most N Gaussians, an even sample (default 60000)")


def run(args) -> int:
    """Open the preview window, or write the screenshot."""
    from csgs_cli.scene_input import load_scene
    from csgs_cli.view_options import parse_size
    from csgs_codec.errors import InputError
    from csgs_codec.render.preview import save_screenshot, show_window

    if args.max_gaussians < 1:
        raise InputError(f"--max-gaussians must be positive, got {args.max_gaussians}",
                         property="--max-gaussians")
    scene = load_scene(args.scene, command=NAME)
    options = dict(mode="points" if args.points else "ellipsoids", color_by=args.color,
                   window_size=parse_size(args.size), up=args.up,
                   max_gaussians=args.max_gaussians)
    if args.screenshot:
        save_screenshot(scene, args.screenshot, **options)
        if not args.quiet:
            print(f"wrote {args.screenshot}")
    else:
        show_window(scene, **options)
    return 0
