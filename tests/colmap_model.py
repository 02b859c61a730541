"""The tests' one COLMAP model writer: cameras.{txt,bin} and images.{txt,bin} as COLMAP
writes them (binary: little-endian records; text: one line per camera, two per image)."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

#: COLMAP camera model ids by name (the ones the tests use).
MODEL_IDS = {"SIMPLE_PINHOLE": 0, "PINHOLE": 1, "SIMPLE_RADIAL": 2}


@dataclass
class ColmapCamera:
    """One camera: id, model (name, or any integer id for the binary form), size in pixels
    and the model's parameters (PINHOLE: fx, fy, cx, cy)."""

    camera_id: int
    model: str | int
    width: int
    height: int
    params: tuple[float, ...]


@dataclass
class ColmapImage:
    """One image: id, world-to-camera rotation quaternion (w, x, y, z) and translation, its
    camera's id, file name and 2D points (x, y, point3D id; -1: none)."""

    image_id: int
    qvec: tuple[float, float, float, float]
    tvec: tuple[float, float, float]
    camera_id: int
    name: str
    points2d: list[tuple[float, float, int]] = field(default_factory=list)


def write_colmap_model(folder: Path, cameras: list[ColmapCamera], images: list[ColmapImage],
                       *, binary: bool, truncate: int = 0) -> Path:
    """Write the model into ``folder`` (created); ``truncate`` cuts that many bytes off the
    end of images.bin (binary only). Returns ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    if binary:
        cams = struct.pack("<Q", len(cameras))
        for c in cameras:
            model = MODEL_IDS[c.model] if isinstance(c.model, str) else c.model
            cams += struct.pack(f"<iiQQ{len(c.params)}d", c.camera_id, model, c.width,
                                c.height, *c.params)
        imgs = struct.pack("<Q", len(images))
        for i in images:
            imgs += struct.pack("<i7di", i.image_id, *i.qvec, *i.tvec, i.camera_id)
            imgs += i.name.encode() + b"\0" + struct.pack("<Q", len(i.points2d))
            imgs += b"".join(struct.pack("<ddq", *p) for p in i.points2d)
        (folder / "cameras.bin").write_bytes(cams)
        (folder / "images.bin").write_bytes(imgs[:len(imgs) - truncate])
        return folder
    cam_lines = [" ".join([str(c.camera_id), str(c.model), str(c.width), str(c.height),
                           *map(repr, map(float, c.params))]) for c in cameras]
    img_lines = []
    for i in images:
        img_lines.append(" ".join([str(i.image_id), *map(repr, map(float, i.qvec)),
                                   *map(repr, map(float, i.tvec)), str(i.camera_id), i.name]))
        img_lines.append(" ".join(f"{x!r} {y!r} {p}" for x, y, p in i.points2d))
    (folder / "cameras.txt").write_text("\n".join(cam_lines) + "\n")
    (folder / "images.txt").write_text("\n".join(img_lines) + "\n")
    return folder
