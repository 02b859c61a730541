"""Options shared by the commands that render views: cameras, orbit, size, progress bars."""

from __future__ import annotations

import re

from csgs_codec.errors import InputError

DEFAULT_ORBIT_VIEWS = 16
DEFAULT_ORBIT_SIZE = (800, 600)
#: Most views an orbit may have (each is a camera made up front; 10^8 ran for minutes).
MAX_ORBIT_VIEWS = 10_000


def add_view_arguments(parser, *, default_orbit: int = DEFAULT_ORBIT_VIEWS) -> None:
    """--cameras / --orbit (exclusive), --size, --up and --backend."""
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--cameras", metavar="FILE",
                       help="cameras to render from: INRIA cameras.json, transforms.json, or a "
                            "COLMAP model (folder or cameras/images .txt/.bin)")
    which.add_argument("--orbit", type=int, metavar="N",
                       help=f"N views on an orbit around the scene (default {default_orbit} "
                            "when --cameras is not given)")
    parser.add_argument("--size", metavar="WxH",
                        help="image size; default: the cameras' own size, or "
                             f"{DEFAULT_ORBIT_SIZE[0]}x{DEFAULT_ORBIT_SIZE[1]} for an orbit")
    parser.add_argument("--up", metavar="AXIS",
                        help="orbit up axis: +x -x +y -y +z -z (default: guessed)")
    parser.add_argument("--backend", default="auto", choices=("auto", "torch", "numba", "gsplat"),
                        help="rasterizer backend (default: the fastest available)")
    parser.set_defaults(_default_orbit=default_orbit)


def parse_size(text: str) -> tuple[int, int]:
    """(width, height) from 'WxH'."""
    match = re.fullmatch(r"\s*(\d{1,5})\s*[xX]\s*(\d{1,5})\s*", text or "")
    if not match or int(match[1]) == 0 or int(match[2]) == 0:
        raise InputError(f"size must look like 800x600 with positive numbers, got {text!r}",
                         property="--size")
    return int(match[1]), int(match[2])


def cameras_from_args(args, scene) -> list:
    """The cameras ``args`` ask for: loaded from --cameras, else an orbit around ``scene``."""
    from csgs_codec.scene.cameras_io import load_cameras, resize_camera
    from csgs_codec.scene.orbit import orbit_cameras

    size = parse_size(args.size) if args.size else None
    if args.cameras:
        cameras = load_cameras(args.cameras)
        return [resize_camera(c, *size) for c in cameras] if size else cameras
    count = args._default_orbit if args.orbit is None else args.orbit
    check_orbit_views(count)
    width, height = size or DEFAULT_ORBIT_SIZE
    return orbit_cameras(scene, count, width=width, height=height, up=args.up)


def check_orbit_views(count: int) -> None:
    """InputError naming --orbit unless ``count`` is 1..MAX_ORBIT_VIEWS."""
    if not 1 <= count <= MAX_ORBIT_VIEWS:
        raise InputError(f"--orbit must be 1..{MAX_ORBIT_VIEWS:,} views, got {count:,}",
                         property="--orbit")


def progress(args, items, description: str):
    """``items`` wrapped in a tqdm bar on stderr, or bare when --quiet."""
    if args.quiet:
        return items
    from tqdm import tqdm

    return tqdm(items, desc=description, unit="view", leave=False)
