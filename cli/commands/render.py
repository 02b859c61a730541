"""``csgs render SCENE [--cameras FILE | --orbit N] [--size WxH] -o DIR``: views to PNG files."""

from __future__ import annotations

import re
from pathlib import Path

from csgs_codec.errors import InputError

NAME = "render"
HELP = "render a scene to PNG images from its cameras or from an orbit around it"


def add_arguments(parser) -> None:
    """Arguments of ``csgs render``."""
    from csgs_cli.view_options import add_view_arguments

    parser.add_argument("scene", help="a scene file, a .csgs, or an anchor scene (rendered "
                                      "exactly, per view)")
    add_view_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="folder for the PNG images (created if missing)")


def run(args) -> int:
    """Render every requested view of ``args.scene`` into ``args.output``."""
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_cli.scene_input import load_scene
    from csgs_cli.view_options import cameras_from_args, progress
    from csgs_codec.model.anchor_views import SceneViews
    from csgs_codec.render.image_io import save_png
    from csgs_codec.render.rasterizer import render

    views = SceneViews(load_scene(args.scene, command=NAME))
    cameras = cameras_from_args(args, views.framing())
    output = Path(args.output)
    if output.exists() and not output.is_dir():
        raise InputError("output exists and is not a folder", file=output)
    names = image_file_names(cameras)
    refuse_overwriting_inputs([("-o", output / name) for name in names],
                              [("the scene", args.scene), ("--cameras", args.cameras)])
    try:
        output.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output folder: {exc.strerror or exc}",
                         file=output) from None
    for camera, name in progress(args, list(zip(cameras, names)), "rendering"):
        save_png(render(views.gaussians(camera), camera, backend=args.backend).image,
                 output / name)
    if not args.quiet:
        print(f"wrote {len(cameras)} image(s) of {cameras[0].width}x{cameras[0].height} "
              f"to {output}")
    return 0


def image_file_names(cameras) -> list[str]:
    """One distinct, file-system-safe PNG name per camera: ``NNN_<camera name>.png``."""
    names = []
    for i, camera in enumerate(cameras):
        stem = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(camera.name).stem).strip("._")
        if camera.name.startswith("orbit_"):
            names.append(f"{camera.name}.png")
        else:
            names.append(f"{i:03d}_{stem}.png" if stem else f"{i:03d}.png")
    return names
