"""Byte layouts of the anchor-scene chunks that are not entropy-coded attributes: the
``ANCH`` header and the ``AMLP`` Scaffold-GS MLP weights (spec/FORMAT.md §17.3, §17.7).
Numpy only. The other anchor chunks: :mod:`~csgs_codec.chunks.anchor_networks` (AHYP, ACRM),
:mod:`~csgs_codec.chunks.anchor_streams` (AMSK, AFEA, AOFF, ASCL) and
:mod:`~csgs_codec.chunks.anchor_semantic` (SHYP, ASEM)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from csgs_codec.attributes.float_stream import read_float_stream, write_float_stream
from csgs_codec.entropy.anchor_attributes import FRAC_BITS, MEAN_BITS
from csgs_codec.entropy.morton import MAX_BITS
from csgs_codec.entropy.residual import coded_value_limit
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.primitives import ByteReader, ByteWriter
from csgs_codec.scene.anchor_scene import MLPWeights, ScaffoldMLPWeights

ANCHOR_VERSION = 1
#: AMLP payload versions: 1 stores float16 weights; 2 codes each weight array as a float
#: stream (spec/FORMAT.md §17.7). Encoders write 2; decoders read both.
MLP_VERSION_F16 = 1
MLP_VERSION = 2
#: Version 2's quantization step of a weight array, relative to the array's standard
#: deviation, at step multiplier 1 (quality 8; the quality's multiplier scales it). Measured
#: on a trained 1,850-anchor scene (F 32, K 10): std/64 costs 0.008 dB of held-out PSNR and
#: std/32 0.035 dB, against float16's 14.4 KB the weights take 7.4 and 6.5 KB.
MLP_RELATIVE_STEP = 1.0 / 128
#: Smallest step used (arrays of equal values are coded as constants whatever the step).
MLP_MIN_STEP = 2.0**-20
#: Decoder limits.
MAX_ANCHORS = 1 << 26
#: Most coded values (anchors x (F + 3K + 6)) a decoder accepts.
MAX_VALUES = 1 << 31
MAX_FEATURES = 4096
MAX_OFFSETS = 64
MAX_MLP_WIDTH = 4096
MAX_APPEARANCE_CAMERAS = 1 << 20
FLAG_MLPS = 0x01


@dataclass(frozen=True)
class AnchorHeader:
    """The ``ANCH`` payload: what every other anchor chunk is read against.

    Attributes:
        count: anchors M (0..2^26).
        feat_dim: F (1..4096); n_offsets: K (1..64).
        grid_bits: bits per axis of the anchor cells (0..21).
        voxel_size: cell edge, world units (finite, > 0); origin: (3,) world position of
            cell (0, 0, 0) (finite). Anchor i is at origin + cell_i * voxel_size (float64,
            then rounded to float32).
        carm_groups: feature channel groups (1 = no CARM, else 2..min(F, 64)).
        quality: the encoder's quality preset (1..9; informative).
        has_mlps: an ``AMLP`` chunk follows in the base layer.
    """

    count: int
    feat_dim: int
    n_offsets: int
    grid_bits: int
    voxel_size: float
    origin: tuple[float, float, float]
    carm_groups: int
    quality: int
    has_mlps: bool

    def to_bytes(self) -> bytes:
        """The ``ANCH`` payload bytes."""
        out = ByteWriter()
        out.fixed("u8", ANCHOR_VERSION)
        out.varint(self.count)
        out.varint(self.feat_dim)
        out.fixed("u8", self.n_offsets)
        out.fixed("u8", self.grid_bits)
        out.fixed("f64", self.voxel_size)
        for v in self.origin:
            out.fixed("f64", v)
        out.fixed("u8", FRAC_BITS)
        out.fixed("u8", MEAN_BITS)
        out.fixed("u8", self.carm_groups)
        out.fixed("u8", self.quality)
        out.fixed("u8", FLAG_MLPS if self.has_mlps else 0)
        return out.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, base_offset: int = 0) -> AnchorHeader:
        """Parse and check an ``ANCH`` payload; FormatError naming the field and offset."""
        r = ByteReader(data, base_offset=base_offset, chunk="ANCH")

        def u8(name: str, low: int, high: int) -> int:
            at = r.offset
            value = r.fixed("u8", name)
            if not low <= value <= high:
                raise r.error(f"field '{name}' = {value} outside [{low}, {high}]", at=at)
            return value

        u8("version", ANCHOR_VERSION, ANCHOR_VERSION)
        count = r.varint("anchor_count", maximum=MAX_ANCHORS)
        at = r.offset
        feat_dim = r.varint("feat_dim", maximum=MAX_FEATURES)
        if feat_dim == 0:
            raise r.error("feat_dim is 0", at=at)
        n_offsets = u8("n_offsets", 1, MAX_OFFSETS)
        grid_bits = u8("grid_bits", 0, MAX_BITS)
        at = r.offset
        voxel = r.fixed("f64", "voxel_size")
        origin = tuple(r.fixed("f64", "origin") for _ in range(3))
        if not (math.isfinite(voxel) and voxel > 0 and all(map(math.isfinite, origin))):
            raise r.error("voxel_size must be finite and > 0, origin finite", at=at)
        u8("frac_bits", FRAC_BITS, FRAC_BITS)
        u8("mean_bits", MEAN_BITS, MEAN_BITS)
        carm_groups = u8("carm_groups", 1, min(feat_dim, 64))
        quality = u8("quality", 1, 9)
        flags = u8("flags", 0, FLAG_MLPS)
        r.expect_end("the anchor header")
        if count * (feat_dim + 3 * n_offsets + 6) > MAX_VALUES:
            raise r.error(f"{count} anchors x {feat_dim + 3 * n_offsets + 6} values exceed "
                          f"the limit {MAX_VALUES}", at=base_offset)
        return cls(count, feat_dim, n_offsets, grid_bits, voxel, origin, carm_groups,
                   quality, bool(flags & FLAG_MLPS))


def _f16(values: np.ndarray, name: str) -> np.ndarray:
    half = values.astype(np.float16)
    if not np.all(np.isfinite(half)):
        raise InputError("weight does not fit float16 (|w| > 65504)", property=name)
    return half


def mlps_to_bytes(mlps: ScaffoldMLPWeights, multiplier: float = 1.0, *,
                  version: int = MLP_VERSION) -> tuple[bytes, ScaffoldMLPWeights]:
    """The ``AMLP`` payload and the weights the decoder will return.

    Args:
        mlps: the weights; each |w| must fit float16 (<= 65504) and be finite.
        multiplier: the quality's step multiplier (version 2: each array is quantized with
            step ``MLP_RELATIVE_STEP * multiplier * std(array)``).
        version: 2 (float streams) or 1 (float16, as files written before version 2).
    """
    if version not in (MLP_VERSION_F16, MLP_VERSION):
        raise InputError(f"unknown MLP payload version {version}", property="mlps")
    starts: list[tuple[int, int]] = []  # (payload offset, value count) of each array
    out = ByteWriter()
    out.fixed("u8", version)
    out.fixed("u8", 0 if mlps.appearance is None else 1)

    def coded(values: np.ndarray, name: str) -> np.ndarray:
        half = _f16(values, name)
        if version == MLP_VERSION_F16:
            out.array(half, "<f2")
            return half.astype(np.float32)
        flat = values.astype(np.float32).reshape(-1, 1)
        starts.append((len(out.getvalue()), flat.shape[0]))
        step = max(float(np.std(flat)) * MLP_RELATIVE_STEP * multiplier, MLP_MIN_STEP)
        return write_float_stream(out, flat, step).reshape(values.shape)

    rounded = {}
    for name, head in mlps.heads().items():
        out.varint(head.w1.shape[0])
        out.varint(head.w1.shape[1])
        out.varint(head.w2.shape[0])
        rounded[name] = MLPWeights(**{key: coded(arr, f"{name}.{key}")
                                      for key, arr in head.arrays().items()})
    appearance = None
    if mlps.appearance is not None:
        out.varint(mlps.appearance.shape[0])
        out.varint(mlps.appearance.shape[1])
        appearance = coded(mlps.appearance, "appearance")
    payload = out.getvalue()
    if any(count > coded_value_limit(len(payload) - start) for start, count in starts):
        # Huge arrays of nearly equal values code in fewer bytes than a decoder may trust.
        return mlps_to_bytes(mlps, multiplier, version=MLP_VERSION_F16)
    return payload, ScaffoldMLPWeights(appearance=appearance, **rounded)


def _weights(r: ByteReader, version: int, count: int, name: str) -> np.ndarray:
    """``count`` weights as (count,) float32: float16 (version 1) or a float stream."""
    if version == MLP_VERSION_F16:
        return r.array(count, "<f2", name).astype(np.float32)
    if count > coded_value_limit(r.remaining):  # refuse before allocating
        raise r.error(f"{name}: {count} weights exceed the {coded_value_limit(r.remaining)} "
                      f"allowed with {r.remaining} payload bytes left")
    return read_float_stream(r, count, 1)[:, 0]


def read_mlps(container, header: AnchorHeader) -> ScaffoldMLPWeights | None:
    """The Scaffold-GS MLPs of ``container``'s AMLP, checked against ``header``'s F and K;
    None when the header declares none (``has_mlps`` unset).

    Raises:
        FormatError: naming AMLP and the byte offset (missing, malformed, or heads that do
            not fit the anchors).
    """
    if not header.has_mlps:
        return None
    data, offset = container.single_payload("AMLP")
    return mlps_from_bytes(data, header.feat_dim, header.n_offsets, offset)


def mlps_from_bytes(data: bytes, feat_dim: int, n_offsets: int,
                    base_offset: int = 0) -> ScaffoldMLPWeights:
    """Parse an ``AMLP`` payload and check the heads against F and K (FormatError if not)."""
    r = ByteReader(data, base_offset=base_offset, chunk="AMLP")
    at = r.offset
    version = r.fixed("u8", "version")
    if version not in (MLP_VERSION_F16, MLP_VERSION):
        raise r.error(f"MLP payload version {version} is not {MLP_VERSION_F16} or "
                      f"{MLP_VERSION}", at=at)
    at = r.offset
    flags = r.fixed("u8", "flags")
    if flags > 1:
        raise r.error(f"reserved flag bits set ({flags})", at=at)
    heads = {}
    for name in ("opacity", "cov", "color"):
        hidden, inputs, outputs = (r.varint(f"{name} {f}", maximum=MAX_MLP_WIDTH)
                                   for f in ("hidden", "inputs", "outputs"))

        def arr(count: int, key: str, shape: tuple[int, ...], name: str = name) -> np.ndarray:
            return _weights(r, version, count, f"{name}.{key}").reshape(shape)

        heads[name] = MLPWeights(arr(hidden * inputs, "w1", (hidden, inputs)),
                                 arr(hidden, "b1", (hidden,)),
                                 arr(outputs * hidden, "w2", (outputs, hidden)),
                                 arr(outputs, "b2", (outputs,)))
    appearance = None
    if flags:
        cams = r.varint("appearance cameras", maximum=MAX_APPEARANCE_CAMERAS)
        width = r.varint("appearance width", maximum=MAX_MLP_WIDTH)
        appearance = _weights(r, version, cams * width, "appearance").reshape(cams, width)
    r.expect_end("the MLP weights")
    mlps = ScaffoldMLPWeights(appearance=appearance, **heads)
    try:
        mlps.validate(feat_dim, n_offsets)
    except InputError as err:
        raise FormatError(f"MLP weights do not fit the anchors: {err}", chunk="AMLP",
                          offset=base_offset) from None
    return mlps
