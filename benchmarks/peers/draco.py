"""Google Draco (PyPI ``DracoPy``) as a point-cloud peer for whole 3DGS scenes.

Draco has no Gaussian-splat mode, so this wrapper gives it the plainest mapping: positions
are Draco's own quantized point positions (``position_bits`` per axis over the bounding
cube, best compression level), and every other channel — f_dc, f_rest, opacity logit, log
scale, and the unit quaternion with w >= 0 — is quantized uniformly between its own min and
max to ``attribute_bits`` and stored as one integer generic attribute. Draco codes generic
integer attributes close to raw, so this is a baseline, not a tuned 3DGS codec.

File layout (little-endian), all of it counted in the size: ``b"DRGS"``, u8 layout version
(1), u8 attribute bits, u8 SH rest coefficients per color (0, 3, 8 or 15), u8 zero, u16
channel count C, C x (float32 low, float32 high), then the Draco point-cloud buffer. Draco
may reorder the points; decoded Gaussians are matched to originals by position.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply, write_ply
from csgs_codec.scene.gaussian_scene import SH_DEGREE_OF_REST, GaussianScene

from .base import DecodeResult, EncodeResult, PeerCodec, PeerToolError

MAGIC = b"DRGS"
LAYOUT_VERSION = 1
_HEADER = struct.Struct("<4sBBBBH")
_ATTRIBUTE_NAME = "gaussian"


def _draco():
    import DracoPy

    return DracoPy


class DracoCodec(PeerCodec):
    """Draco point cloud with uniformly quantized 3DGS attributes.

    Args:
        position_bits: Draco position quantization, bits per axis (1..30).
        attribute_bits: bits per attribute channel (1..16).
        compression_level: Draco's compression level (0..10).
    """

    extension = ".drc"

    def __init__(self, position_bits: int = 16, attribute_bits: int = 8,
                 compression_level: int = 10) -> None:
        if not (1 <= position_bits <= 30 and 1 <= attribute_bits <= 16
                and 0 <= compression_level <= 10):
            raise InputError(f"Draco settings out of range: position_bits={position_bits}, "
                             f"attribute_bits={attribute_bits}, level={compression_level}")
        self.position_bits = position_bits
        self.attribute_bits = attribute_bits
        self.compression_level = compression_level
        self.name = f"draco-p{position_bits}-a{attribute_bits}"
        self.description = (f"Google Draco point cloud, {position_bits}-bit positions, "
                            f"{attribute_bits}-bit min/max-quantized attributes")

    def why_unavailable(self) -> str:
        """``""`` when DracoPy imports."""
        try:
            _draco()
        except ImportError:
            return "PyPI package DracoPy is not installed (pip install DracoPy)"
        return ""

    def version(self) -> str:
        """DracoPy's installed version (``""`` if unknown)."""
        from importlib.metadata import PackageNotFoundError
        from importlib.metadata import version as package_version

        try:
            return package_version("DracoPy")
        except PackageNotFoundError:
            return ""

    def encode(self, ply_path: str | Path, out_dir: str | Path) -> EncodeResult:
        """Read the PLY, quantize, Draco-encode, write ``out_dir/<stem>.drc``; time it all."""
        self.require_available()
        output = self.output_path(ply_path, out_dir)
        start = time.perf_counter()
        scene = read_ply(ply_path)
        data = self.encode_scene(scene)
        output.write_bytes(data)
        return EncodeResult(bytes=len(data), seconds=time.perf_counter() - start, path=output)

    def encode_scene(self, scene: GaussianScene) -> bytes:
        """The whole compressed file for ``scene`` (layout in the module docstring)."""
        channels = gaussian_channels(scene)
        low = channels.min(axis=0) if len(scene) else np.zeros(channels.shape[1])
        high = channels.max(axis=0) if len(scene) else np.zeros(channels.shape[1])
        span = np.where(high > low, high - low, 1.0)
        levels = (1 << self.attribute_bits) - 1
        dtype = np.uint8 if self.attribute_bits <= 8 else np.uint16
        quantized = np.round((channels - low) / span * levels).astype(dtype)
        try:
            payload = _draco().encode(
                scene.positions.astype(np.float32), quantization_bits=self.position_bits,
                compression_level=self.compression_level,
                generic_attributes={_ATTRIBUTE_NAME: quantized})
        except Exception as error:  # DracoPy raises its own and generic exception types
            raise PeerToolError(f"Draco encode failed: {error}") from error
        header = _HEADER.pack(MAGIC, LAYOUT_VERSION, self.attribute_bits,
                              scene.sh_rest.shape[1], 0, channels.shape[1])
        ranges = np.stack([low, high], axis=1).astype("<f4").tobytes()
        return header + ranges + bytes(payload)

    def decode(self, encoded_path: str | Path, out_ply: str | Path) -> DecodeResult:
        """Decode the ``.drc`` file to a standard PLY at ``out_ply``; time includes writing."""
        self.require_available()
        encoded_path, out_ply = Path(encoded_path), Path(out_ply)
        if not encoded_path.is_file():
            raise InputError("no such compressed file", file=encoded_path)
        start = time.perf_counter()
        scene = decode_scene(encoded_path.read_bytes(), source=encoded_path)
        out_ply.parent.mkdir(parents=True, exist_ok=True)
        write_ply(scene, out_ply)
        return DecodeResult(seconds=time.perf_counter() - start, path=out_ply)


def gaussian_channels(scene: GaussianScene) -> np.ndarray:
    """(N, C) float64 attribute channels in file order: f_dc (3), f_rest (3B, PLY order),
    opacity (1), log scales (3), unit quaternion w x y z with w >= 0 (4)."""
    n = len(scene)
    rest = scene.sh_rest.transpose(0, 2, 1).reshape(n, -1)
    rotations = scene.rotations.astype(np.float64)
    norms = np.linalg.norm(rotations, axis=1, keepdims=True)
    rotations = np.where(norms > 0, rotations / np.where(norms > 0, norms, 1), [1, 0, 0, 0])
    rotations *= np.where(rotations[:, :1] < 0, -1.0, 1.0)
    return np.concatenate([scene.sh_dc, rest, scene.opacity[:, None], scene.scales,
                           rotations], axis=1).astype(np.float64)


def decode_scene(data: bytes, source: str | Path | None = None) -> GaussianScene:
    """The :class:`GaussianScene` in a ``.drc`` file's bytes.

    Raises:
        InputError: wrong magic, version, sizes or attribute shape.
        PeerToolError: Draco cannot decode the buffer.
    """
    if len(data) < _HEADER.size:
        raise InputError("file too short for the Draco 3DGS header", file=source, offset=0)
    magic, version, bits, bands, _, count = _HEADER.unpack_from(data)
    if magic != MAGIC or version != LAYOUT_VERSION:
        raise InputError("not a Draco 3DGS file of layout version 1", file=source, offset=0)
    if bands not in SH_DEGREE_OF_REST or count != 11 + 3 * bands or not 1 <= bits <= 16:
        raise InputError(f"inconsistent header: bits={bits} bands={bands} channels={count}",
                         file=source, offset=4)
    ranges_end = _HEADER.size + 8 * count
    if len(data) < ranges_end:
        raise InputError("file too short for the channel ranges", file=source,
                         offset=_HEADER.size)
    ranges = np.frombuffer(data, "<f4", 2 * count, _HEADER.size).reshape(count, 2)
    try:
        cloud = _draco().decode(data[ranges_end:])
        attribute = cloud.get_attribute_by_name(_ATTRIBUTE_NAME)
    except Exception as error:  # DracoPy raises its own and generic exception types
        raise PeerToolError(f"Draco decode failed: {error}", file=source,
                            offset=ranges_end) from error
    points = np.asarray(cloud.points, np.float32).reshape(-1, 3)
    quantized = None if attribute is None else np.asarray(attribute["data"])
    if quantized is None or quantized.shape != (len(points), count):
        raise InputError("Draco buffer lacks the Gaussian attribute of the header's shape",
                         file=source, offset=ranges_end)
    low, high = ranges[:, 0].astype(np.float64), ranges[:, 1].astype(np.float64)
    channels = low + quantized.astype(np.float64) / ((1 << bits) - 1) * (high - low)
    n, cut = len(points), np.cumsum([3, 3 * bands, 1, 3])
    return GaussianScene(
        positions=points,
        sh_dc=channels[:, : cut[0]].astype(np.float32),
        sh_rest=channels[:, cut[0]: cut[1]].reshape(n, 3, bands).transpose(0, 2, 1)
        .astype(np.float32),
        opacity=channels[:, cut[1]].astype(np.float32),
        scales=channels[:, cut[2]: cut[3]].astype(np.float32),
        rotations=channels[:, cut[3]:].astype(np.float32),
    )
