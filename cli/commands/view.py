"""``csgs view SCENE [--screenshot out.png] [--select X,Y | --select-mask M.npy]``: a pyvista
preview of the Gaussians, optionally with a selection highlighted.

``csgs view --web SCENE.csgs [--port P] [--no-browser] [--layers color]``: the browser viewer
(csgs_codec/web), served locally until Ctrl-C."""

from __future__ import annotations

from csgs_codec.errors import InputError

NAME = "view"
HELP = ("preview a scene with pyvista: Gaussians as oriented ellipsoids or points colored by "
        "DC color or semantic label; --screenshot renders offscreen to a PNG; --web opens a "
        ".csgs in the browser viewer (decoded in the page, click to select objects)")
#: Options of the pyvista preview that mean nothing to the browser viewer.
PYVISTA_ONLY = ("screenshot", "select", "select_mask")


def add_arguments(parser) -> None:
    """Arguments of ``csgs view``."""
    from csgs_codec.semantic.selection import DEFAULT_THRESHOLD

    parser.add_argument("scene", nargs="?",
                        help="a 3DGS .ply or .csgs scene (with --web: a .csgs, or none to "
                             "open files from the page)")
    parser.add_argument("--screenshot", metavar="PNG",
                        help="render offscreen to this PNG file instead of opening a window")
    parser.add_argument("--points", action="store_true",
                        help="draw points instead of oriented ellipsoids (faster)")
    parser.add_argument("--color", default="auto", choices=("auto", "dc", "label", "semantic"),
                        help="color by DC color, integer label or the first three semantic "
                             "channels (default: label when present, else DC color)")
    parser.add_argument("--size", metavar="WxH", default="800x600", help="window size")
    parser.add_argument("--up", metavar="AXIS",
                        help="up axis of the view: +x -x +y -y +z -z (default: guessed)")
    parser.add_argument("--max-gaussians", type=int, default=60_000, metavar="N",
                        help="draw at most N Gaussians, an even sample (default 60000)")
    chosen = parser.add_mutually_exclusive_group()
    chosen.add_argument("--select", metavar="X,Y",
                        help="highlight the object under pixel X,Y of this view (by semantic "
                             "feature, as 'csgs select'); the rest is drawn dim")
    chosen.add_argument("--select-mask", metavar="NPY",
                        help="highlight the Gaussians of a .npy bool mask from 'csgs select "
                             "--save-mask' (same scene file); the rest is drawn dim")
    parser.add_argument("--threshold", type=float, default=DEFAULT_THRESHOLD, metavar="T",
                        help=f"cosine threshold for --select (default {DEFAULT_THRESHOLD})")
    web = parser.add_argument_group("browser viewer")
    web.add_argument("--web", action="store_true",
                     help="serve the browser viewer for this .csgs on a local port and open it: "
                          "decoded in the page (color layer first, then the semantic layer), "
                          "click an object to select it; runs until Ctrl-C")
    web.add_argument("--port", type=int, default=0, metavar="P",
                     help="port of --web (default: any free port)")
    web.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                     help="address --web listens on (default 127.0.0.1, this machine only)")
    web.add_argument("--no-browser", action="store_true",
                     help="with --web: print the address instead of opening a browser")
    web.add_argument("--layers", metavar="LAYERS",
                     help="with --web: 'color' (the page fetches and decodes only the base and "
                          "color layers) or 'color,semantic' (default)")


def run(args) -> int:
    """Open the preview window, write the screenshot, or serve the browser viewer."""
    if args.web:
        return run_web(args)
    if args.layers or args.no_browser or args.port:
        raise InputError("--layers, --port and --no-browser go with --web", property="--web")
    if args.scene is None:
        raise InputError("give the scene to view (only --web opens without one)",
                         property="scene")
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_cli.scene_input import load_scene
    from csgs_cli.view_options import parse_size
    from csgs_codec.render.preview import save_screenshot, show_window
    from csgs_codec.scene.gaussian_scene import GaussianScene

    if args.max_gaussians < 1:
        raise InputError(f"--max-gaussians must be positive, got {args.max_gaussians}",
                         property="--max-gaussians")
    refuse_overwriting_inputs([("--screenshot", args.screenshot)],
                              [("the scene", args.scene), ("--select-mask", args.select_mask)])
    scene = load_scene(args.scene, command=NAME)
    if not isinstance(scene, GaussianScene):  # an anchor scene: shown as its bake
        from csgs_codec.bake.anchor_bake import bake_anchor_scene

        scene = bake_anchor_scene(scene)
    options = dict(mode="points" if args.points else "ellipsoids", color_by=args.color,
                   window_size=parse_size(args.size), up=args.up,
                   max_gaussians=args.max_gaussians, selection=selection_from_args(args, scene))
    if args.screenshot:
        save_screenshot(scene, args.screenshot, **options)
        if not args.quiet:
            print(f"wrote {args.screenshot}")
    else:
        show_window(scene, **options)
    return 0


def run_web(args) -> int:
    """Serve the browser viewer for ``args.scene`` until interrupted.

    Raises:
        InputError: the scene is not a readable .csgs file, a pyvista-only option was given,
            or the address cannot be listened on.
    """
    import contextlib
    import threading
    import webbrowser

    from csgs_codec.web.server import ViewerServer, parse_layers

    given = [f"--{name.replace('_', '-')}" for name in PYVISTA_ONLY if getattr(args, name)]
    if given:
        raise InputError(f"{', '.join(given)}: for the pyvista preview, not --web (the page "
                         "selects by click)", property="--web")
    if args.scene is not None:
        check_csgs_file(args.scene)
    layers = parse_layers(args.layers)
    if not 0 <= args.port <= 65535:
        raise InputError(f"--port must be 0..65535, got {args.port}", property="--port")
    try:
        server = ViewerServer(args.scene, layers=layers, host=args.host, port=args.port)
    except OSError as exc:
        raise InputError(f"cannot listen on {args.host}:{args.port}: {exc.strerror or exc}",
                         property="--port") from None
    # Ctrl-C (or SIGTERM) is the way to stop, from the moment the address is printed: the
    # suppression starts before the print, so an interrupt that lands between the print and
    # the wait (a loaded machine, a quick user) still stops the server cleanly.
    with server, contextlib.suppress(KeyboardInterrupt):
        what = args.scene if args.scene is not None else "the viewer (open a file there)"
        print(f"serving {what} at {server.url} (Ctrl-C to stop)", flush=True)
        if not args.no_browser:
            webbrowser.open(server.url)
        threading.Event().wait()
    return 0


def check_csgs_file(path: str) -> None:
    """Raise InputError unless ``path`` is a readable file starting with the .csgs magic."""
    from pathlib import Path

    from csgs_codec.format import MAGIC as CSGS_MAGIC

    file = Path(path)
    if not file.is_file():
        raise InputError("file not found" if not file.exists() else "not a file", file=path)
    try:
        with open(file, "rb") as fh:
            head = fh.read(len(CSGS_MAGIC))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", file=path) from None
    if head != CSGS_MAGIC:
        raise InputError("--web shows .csgs files (the page decodes them); encode this scene "
                         "first: csgs encode SCENE.ply -o SCENE.csgs", file=path)


def selection_from_args(args, scene):
    """The (N,) bool mask --select or --select-mask asks for, or None.

    Raises:
        InputError: a bad click, a click on nothing, or a mask file that is unreadable or does
            not fit the scene.
    """
    from csgs_cli.commands.select import parse_click
    from csgs_cli.view_options import parse_size
    from csgs_codec.render.preview import preview_camera
    from csgs_codec.semantic.selection import select_at_click

    if args.select:
        x, y = parse_click(args.select)
        camera = preview_camera(scene, parse_size(args.size), args.up)
        return select_at_click(scene, camera, x, y, threshold=args.threshold)
    if args.select_mask:
        return load_mask(args.select_mask, len(scene))
    return None


def load_mask(path: str, count: int):
    """The (count,) bool mask stored in the .npy file ``path``.

    Raises:
        InputError: the file is missing, not a .npy array, or not (count,) bool.
    """
    import numpy as np

    from csgs_codec.untrusted import read_npy

    limit = count + (1 << 16)  # one byte per Gaussian and a header
    mask = read_npy(path, limit, what="a selection mask", kinds="b")
    if mask.dtype != np.bool_ or mask.shape != (count,):
        raise InputError(f"selection mask must be a ({count},) bool array for this scene, got "
                         f"{mask.shape} {mask.dtype}", file=path)
    return mask
