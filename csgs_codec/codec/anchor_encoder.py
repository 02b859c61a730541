"""AnchorEncoder: a Scaffold-GS AnchorScene -> a layered .csgs bitstream (orchestration).

Base layer: ``ANCH`` header, ``GEOM`` anchor cells (lossless, canonical order), ``AHYP``
hyperprior, ``ACRM`` CARM networks, ``AMSK`` offset masks, ``AMLP`` Scaffold MLPs (float streams).
Color layer: ``AFEA`` features (one residual stream per CARM group), ``AOFF`` kept offsets,
``ASCL`` scaling. Semantic layer: ``SHYP`` semantic hyperprior, ``ASEM`` semantic features,
``SEML`` or ``SEMR`` labels (whichever is smaller). Everything after the cells is in the
decoded (canonical) order, and the encoder reconstructs with the integer networks the decoder
runs, so ``AnchorDecoder().decode(data, "color,semantic")`` equals ``reconstruction`` bit for bit.
The payloads are laid out by :mod:`csgs_codec.chunks` (``anchor_payloads``,
``anchor_networks``, ``anchor_streams``, ``anchor_semantic``, ``semantic``); this module fits
the networks, picks the candidate and orders the chunks.

Error bounds: anchor positions are exact cells (within float32 rounding of origin + cell *
voxel) when the anchors lie on a voxel grid, else within half a cell of a 2^16-cell grid;
every other coded value is within q / 2 + 2^-13 of its input, q the anchor's step for that
attribute type (``AnchorEncodeReport.steps``, at most 4x the quality's base step); masked
offsets decode as 0; MLP weights are rounded to float16.

Settings: a quality preset, or an expert rate-distortion weight ``lambda_`` (squared value
units per bit, the same for every attribute type); ``fast`` fits the networks with
:data:`~csgs_codec.model.anchor_hyperprior.FAST_FIT` (several times less fitting, a slightly
larger file). Every value the encoder codes must be finite and within 2^24 value units.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from csgs_codec.attributes.anchor_grid import anchor_grid
from csgs_codec.chunks.anchor_networks import carm_payload, color_channels, hyperprior_payload
from csgs_codec.chunks.anchor_payloads import AnchorHeader, mlps_to_bytes
from csgs_codec.chunks.anchor_semantic import anchor_semantic_payload, semantic_stream
from csgs_codec.chunks.anchor_streams import (
    anchor_feature_payload,
    anchor_offset_payload,
    anchor_scaling_payload,
    offset_mask_payload,
)
from csgs_codec.chunks.semantic import smallest_label_chunk
from csgs_codec.chunks.semantic_names import MAX_SEMANTIC_CHANNELS
from csgs_codec.chunks.view_origins import even_sample, view_origins_payload
from csgs_codec.codec.anchor_decoder import MAX_ANCHOR_VALUES_PER_BYTE, anchor_values
from csgs_codec.codec.encoder_checks import check_semantic_names, padded_container
from csgs_codec.codec.encoder_config import SEMANTIC_MODES
from csgs_codec.decisions.presets import (
    ANCHOR_BASE_STEPS,
    ANCHOR_QUALITIES,
    DEFAULT_QUALITY,
    MULTIPLIERS,
)
from csgs_codec.entropy.anchor_attributes import hyper_params, step_values
from csgs_codec.entropy.geometry import canonical_order, encode_positions
from csgs_codec.errors import InputError
from csgs_codec.format import Chunk
from csgs_codec.format.layout import Layer
from csgs_codec.model.anchor_hyperprior import (
    FAST_FIT,
    AttributeTarget,
    FitSettings,
    fit_prior,
    step_for_lambda,
)
from csgs_codec.scene.anchor_scene import AnchorScene

DEFAULT_CARM_GROUPS = 5
#: Scenes with fewer anchors also try hyperprior networks NARROW_WIDTHS wide and keep the
#: smallest file (measured on a 148-anchor trained scene: the 32-wide hyperprior's 13 KB were
#: most of the file; on a 1,850-anchor trained scene the semantic layer took 2,909 bytes with
#: width 4, 1,661 with 6, 1,793 with 8 and 4,529 with 32).
NARROW_FIT_ANCHORS = 50_000
NARROW_WIDTHS = (6, 4)
#: Largest |value| coded (value units): far above any trained scene's, and low enough that
#: every grid value, mean and residual stays in its exact integer range, even under the
#: factorized fallback prior.
MAX_VALUE = 2.0**24
#: ``lambda`` (rate-distortion weight, squared value units per bit) accepted from a user:
#: the steps it implies, sqrt(6 lambda / ln 2), stay inside the step table (2^-12..2^12).
MIN_LAMBDA = math.log(2.0) / 6.0 * 2.0 ** -24
MAX_LAMBDA = math.log(2.0) / 6.0 * 2.0 ** 24


@dataclass
class AnchorEncodeReport:
    """What :meth:`AnchorEncoder.encode_with_report` returns.

    Attributes:
        data: the .csgs bytes.
        reconstruction: the scene the decoder returns for layers "color,semantic" (masked
            offsets are zero), anchors in decoded order.
        order: (M,) int64 input index of each decoded anchor.
        steps: attribute type -> (M,) float64 quantization step of each anchor, value units.
        chunk_bytes: chunk type -> payload bytes.
        seconds: encode wall time; fit_seconds: of which fitting the networks.
    """

    data: bytes
    reconstruction: AnchorScene
    order: np.ndarray
    steps: dict[str, np.ndarray] = field(default_factory=dict)
    chunk_bytes: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    fit_seconds: float = 0.0


class AnchorEncoder:
    """Encodes Scaffold-GS anchor scenes to .csgs.

    Args:
        quality: 1 (smallest) .. 9 (finest): the base steps are ``ANCHOR_BASE_STEPS`` times
            ``MULTIPLIERS[quality]`` (default 5; not with ``lambda_``).
        lambda_: instead of a quality, the rate-distortion weight L of the fit, in squared
            value units per bit: the networks minimise bits + squared error / L for every
            attribute type alike, around the base step sqrt(6 L / ln 2) (e.g. L = 4.2e-4
            for quality 5's feature step of 0.06).
        fast: fit with ``FAST_FIT`` (fitting about 5x faster; a file about 0.5-2 % larger).
        carm_groups: feature channel groups for the CARM (1 disables it).
        semantic: "auto" writes the semantic layer when the scene has semantic features or
            labels, "none" never does.
        voxel_size: anchor grid cell (None: inferred, see :func:`anchor_grid`).
        fit: training settings of the hyperprior networks (overrides ``fast``).
    """

    def __init__(self, quality: int | None = None, *, lambda_: float | None = None,
                 fast: bool = False, carm_groups: int = DEFAULT_CARM_GROUPS,
                 semantic: str = "auto", voxel_size: float | None = None,
                 fit: FitSettings | None = None) -> None:
        if lambda_ is not None:
            if quality is not None:
                raise InputError("give a quality or a lambda, not both", property="lambda")
            check_lambda(lambda_)
            lambda_ = float(lambda_)
        if quality is None:
            quality = DEFAULT_QUALITY if lambda_ is None else _nearest_quality(lambda_)
        if quality not in ANCHOR_QUALITIES:
            raise InputError(f"anchor scenes take quality 1..{ANCHOR_QUALITIES[-1]}, got "
                             f"{quality}", property="quality")
        if not isinstance(carm_groups, int) or not 1 <= carm_groups <= 64:
            raise InputError(f"carm_groups must be 1..64, got {carm_groups}")
        if semantic not in SEMANTIC_MODES:
            raise InputError(f"semantic must be one of {SEMANTIC_MODES}, got {semantic!r}")
        self.quality = quality
        self.lambda_ = lambda_
        self.fast = bool(fast)
        self.carm_groups = carm_groups
        self.semantic = semantic
        self.voxel_size = voxel_size
        self.fit = fit or (FAST_FIT if fast else FitSettings())

    def _candidate_fits(self, anchors: int) -> list[FitSettings]:
        """The fit settings tried, smallest file kept: the configured fit, and for scenes of
        fewer than :data:`NARROW_FIT_ANCHORS` anchors also narrower ones
        (:data:`NARROW_WIDTHS`), whose smaller networks can outweigh their weaker prediction
        when there are few anchors to code."""
        fits = [self.fit]
        if anchors < NARROW_FIT_ANCHORS:
            fits += [replace(self.fit, hidden=width,
                             carm_hidden=min(self.fit.carm_hidden, width))
                     for width in NARROW_WIDTHS if width < self.fit.hidden]
        return fits

    def step(self, kind: str) -> float:
        """Base step of attribute type ``kind`` at this quality (or lambda), value units."""
        if self.lambda_ is not None:
            return step_for_lambda(self.lambda_)
        return ANCHOR_BASE_STEPS[kind] * MULTIPLIERS[self.quality]

    def encode(self, scene: AnchorScene) -> bytes:
        """The .csgs bytes of ``scene``."""
        return self.encode_with_report(scene).data

    def encode_with_report(self, scene: AnchorScene) -> AnchorEncodeReport:
        """Encode ``scene``; report the reconstruction, order, steps and bytes per chunk."""
        start = time.perf_counter()
        scene.validate()
        if len(scene) == 0:
            raise InputError("an anchor scene needs at least one anchor", property="positions")
        if scene.n_offsets > 64:
            raise InputError(f"{scene.n_offsets} offsets per anchor exceed 64",
                             property="offsets")
        _check_magnitudes(scene)
        if self.semantic == "auto" and scene.semantic is not None:
            check_semantic_names(scene.semantic_names, MAX_SEMANTIC_CHANNELS)  # before the fit
        grid = anchor_grid(scene.positions, self.voxel_size)
        order = canonical_order(grid.cells, grid.bits)
        cells = grid.cells[order]
        s = scene.subset(order)
        m, f, k = len(s), s.feat_dim, s.n_offsets
        groups = min(self.carm_groups, f)
        pos_bits = max(grid.bits, 1)
        mask = s.offset_mask
        header = AnchorHeader(m, f, k, grid.bits, grid.voxel_size,
                              tuple(float(v) for v in grid.origin), groups, self.quality,
                              s.mlps is not None)
        chunks = [Chunk("ANCH", "base", header.to_bytes()),
                  Chunk("GEOM", "base", encode_positions(cells, grid.bits))]

        fit_start = time.perf_counter()
        targets = [
            AttributeTarget(s.features.astype(np.float64), np.ones((m, f)), self.step("f")),
            AttributeTarget(np.where(mask[:, :, None], s.offsets, 0).reshape(m, 3 * k)
                            .astype(np.float64),
                            np.repeat(mask, 3, axis=1).astype(np.float64),
                            self.step("offsets")),
            AttributeTarget(s.scaling.astype(np.float64), np.ones((m, 6)),
                            self.step("scaling")),
        ]
        best = None
        for settings in self._candidate_fits(m):
            hyper, carm = fit_prior(cells, pos_bits, targets, carm_groups=groups,
                                    settings=settings)
            coded = _code_color(s, cells, hyper, carm)
            if best is None or coded.size < best.size:
                best = coded
        fit_seconds = time.perf_counter() - fit_start
        chunks.append(Chunk("AHYP", "base", best.hyper))
        chunks.append(Chunk("ACRM", "base", best.carm))
        chunks.append(Chunk("AMSK", "base", offset_mask_payload(mask)))
        mlps = None
        if s.mlps is not None:
            payload, mlps = mlps_to_bytes(s.mlps, self.step("f") / ANCHOR_BASE_STEPS["f"])
            chunks.append(Chunk("AMLP", "base", payload))
        origins = None
        if s.view_origins is not None:
            origins = even_sample(s.view_origins)
            chunks.append(Chunk("vorg", "base", view_origins_payload(origins)))
        chunks += [Chunk(name, "color", payload) for name, payload in best.layer.items()]
        recon = AnchorScene(grid.positions(cells), best.features, best.offsets, best.scaling,
                            mask.copy(), mlps=mlps, view_origins=origins)
        steps = dict(best.steps)
        if self.semantic == "auto" and (s.semantic is not None or s.labels is not None):
            fit_start = time.perf_counter()
            steps.update(self._semantic(s, cells, pos_bits, recon, chunks))
            fit_seconds += time.perf_counter() - fit_start
        data = padded_container(chunks, -(-anchor_values(header) // MAX_ANCHOR_VALUES_PER_BYTE),
                                through=Layer.COLOR)
        return AnchorEncodeReport(data, recon, order.astype(np.int64), steps,
                                  {c.type: len(c.payload) for c in chunks},
                                  time.perf_counter() - start, fit_seconds)

    def _semantic(self, s: AnchorScene, cells: np.ndarray, pos_bits: int,
                  recon: AnchorScene, chunks: list[Chunk]) -> dict[str, np.ndarray]:
        steps = {}
        if s.semantic is not None and s.semantic.shape[1]:
            m, width = s.semantic.shape
            target = AttributeTarget(s.semantic.astype(np.float64), np.ones((m, width)),
                                     self.step("semantic"))
            best = None
            for settings in self._candidate_fits(m):
                hyper, _ = fit_prior(cells, pos_bits, [target], settings=settings,
                                     name="semantic hyperprior")
                network = hyperprior_payload(hyper)
                (params,) = hyper_params(hyper, cells, [width])
                stream, decoded = semantic_stream(s.semantic, params)
                if best is None or len(network) + len(stream) < best[0]:
                    best = (len(network) + len(stream), network, params, stream, decoded)
            _, network, params, stream, decoded = best
            chunks.append(Chunk("SHYP", "semantic", network))
            chunks.append(Chunk("ASEM", "semantic",
                                anchor_semantic_payload(s.semantic_names, stream)))
            recon.semantic, recon.semantic_names = decoded, s.semantic_names
            steps["semantic"] = step_values(params.step)
        if s.labels is not None:
            code, payload = smallest_label_chunk(s.labels)
            chunks.append(Chunk(code, "semantic", payload))
            recon.labels = s.labels.copy()
        return steps


def check_lambda(lam: float) -> None:
    """InputError (property ``lambda``) unless ``lam`` is a finite rate-distortion weight in
    [MIN_LAMBDA, MAX_LAMBDA] squared value units per bit."""
    try:
        value = float(lam)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"lambda must be a positive finite number, got {lam!r}",
                         property="lambda")
    if not MIN_LAMBDA <= value <= MAX_LAMBDA:
        raise InputError(f"lambda must be in [{MIN_LAMBDA:.3g}, {MAX_LAMBDA:.3g}] squared "
                         f"value units per bit, got {value:g}", property="lambda")


def _nearest_quality(lam: float) -> int:
    """The quality whose feature step is nearest (log scale) to ``lam``'s (informative)."""
    ratio = step_for_lambda(lam) / ANCHOR_BASE_STEPS["f"]
    return min(ANCHOR_QUALITIES, key=lambda q: abs(math.log(MULTIPLIERS[q] / ratio)))


def _check_magnitudes(scene: AnchorScene) -> None:
    """InputError naming the attribute and anchor when a coded value exceeds MAX_VALUE
    (masked offsets are not coded and not checked)."""
    kept = np.where(scene.offset_mask[:, :, None], scene.offsets, 0)
    arrays = {"features": scene.features, "offsets": kept, "scaling": scene.scaling}
    if scene.semantic is not None:
        arrays["semantic"] = scene.semantic
    for name, values in arrays.items():
        flat = values.reshape(len(scene), -1)
        too_big = ~(np.abs(flat) <= MAX_VALUE)
        if too_big.any():
            row, col = np.argwhere(too_big)[0]
            raise InputError(f"|value| {abs(float(flat[row, col])):.6g} (channel {col}) "
                             f"exceeds 2^24, the largest the anchor codec codes",
                             property=name, index=int(row))


@dataclass
class _ColorCoding:
    """One candidate coding of the color layer: network payloads, layer chunks and the
    reconstruction (anchors in decoded order)."""

    hyper: bytes
    carm: bytes
    layer: dict[str, bytes]
    features: np.ndarray
    offsets: np.ndarray
    scaling: np.ndarray
    steps: dict[str, np.ndarray]

    @property
    def size(self) -> int:
        """Bytes this candidate adds to the file."""
        return len(self.hyper) + len(self.carm) + sum(len(v) for v in self.layer.values())


def _code_color(s: AnchorScene, cells: np.ndarray, hyper, carm) -> _ColorCoding:
    """Code features, kept offsets and scaling of ``s`` with the given networks."""
    p_f, p_off, p_scl = hyper_params(hyper, cells, color_channels(s.feat_dim, s.n_offsets))
    layer = {}
    layer["AFEA"], features = anchor_feature_payload(s.features, p_f, carm)
    layer["AOFF"], offsets = anchor_offset_payload(s.offsets, s.offset_mask, p_off)
    layer["ASCL"], scaling = anchor_scaling_payload(s.scaling, p_scl)
    steps = {"f": step_values(p_f.step), "offsets": step_values(p_off.step),
             "scaling": step_values(p_scl.step)}
    return _ColorCoding(hyperprior_payload(hyper), carm_payload(carm), layer, features,
                        offsets, scaling, steps)
