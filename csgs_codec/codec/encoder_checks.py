"""What the encoder refuses up front, and the padding that keeps its files decodable.

Rule (issue #20): whatever the encoder writes, the default :class:`Decoder` reads, and what
the format cannot carry is refused before any coding starts, with an error naming the PLY
property and row.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.chunks.semantic_names import (
    MAX_FLOAT_STREAM_CHANNELS,
    MAX_NAME_BYTES,
    semantic_name_problem,
)
from csgs_codec.codec.decoder import MAX_GAUSSIANS, MAX_GAUSSIANS_PER_BYTE
from csgs_codec.errors import InputError
from csgs_codec.format import Chunk, write_container
from csgs_codec.format.layout import Layer
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Largest |value| of an attribute coded as a float stream without a clamp or normalisation
#: before it: grid values and their reconstructions then stay within 2^53 (FORMAT §12.8).
MAX_CODED_MAGNITUDE = 2.0**52
LIMITED_ATTRIBUTES = ("sh_dc", "sh_rest", "scales", "semantic")
#: Largest |log-scale| taken: exp(88) = 1.65e38 is near float32's largest value, so a scale
#: beyond it (or below exp(-88), under float32's smallest normal) has no physical meaning.
#: Refusing them also keeps every scale's precision: FORMAT §12.8 picks one value grid per
#: stream from its largest |value|, and one value of 2^28 or more (say 1e15) would coarsen
#: the grid of every scale in the scene.
MAX_LOG_SCALE = 88.0


def check_encodable(scene: GaussianScene, *, semantic: bool = True) -> None:
    """InputError, before any coding, when ``scene`` holds something the format or the
    default decoder cannot carry: too many or too long semantic channel names, a log-scale
    outside +-88, or a value beyond 2^52 (the count is :func:`check_count`'s, after pruning).

    Errors name the PLY property (``scale_1``, ``f_dc_0``, a semantic name) and the row.
    ``semantic``: the semantic layer will be written (its names are checked only then).
    """
    if semantic and scene.semantic is not None:
        check_semantic_names(scene.semantic_names, MAX_FLOAT_STREAM_CHANNELS)
    _check_log_scales(scene)
    _check_magnitudes(scene)


def check_count(count: int) -> None:
    """InputError when a scene of ``count`` Gaussians (after pruning) is more than the
    default decoder takes (2^24, FORMAT §10.1)."""
    if count > MAX_GAUSSIANS:
        raise InputError(f"{count:,} Gaussians; the format's decoders take at most "
                         f"{MAX_GAUSSIANS:,} (2^24)")


def check_semantic_names(names: tuple[str, ...], max_channels: int) -> None:
    """InputError when the semantic layer cannot carry ``names``: more than
    ``max_channels`` of them, one that is not UTF-8 text or over 256 UTF-8 bytes, or one that
    breaks the name rule (payloads.SEMANTIC_NAME_RULE: a PLY-safe ``sem_*``/``ins_feat_*``
    identifier, each name once)."""
    if len(names) > max_channels:
        raise InputError(f"{len(names)} semantic channels; the semantic layer carries at most "
                         f"{max_channels}", property=names[max_channels])
    for name in names:
        try:
            size = len(name.encode("utf-8"))
        except UnicodeEncodeError:
            raise InputError("semantic property name is not valid UTF-8 text",
                             property=repr(name)) from None
        if size > MAX_NAME_BYTES:
            raise InputError(f"semantic property name is {size} bytes long; the semantic "
                             f"layer carries names of at most {MAX_NAME_BYTES} bytes",
                             property=name[:40] + "...")
    for i, name in enumerate(names):
        problem = semantic_name_problem(name, names[:i])
        if problem:
            raise InputError(problem, property=name if name.isprintable() else repr(name))


def _check_log_scales(scene: GaussianScene) -> None:
    scales = scene.scales
    bad = ~(np.abs(scales) <= MAX_LOG_SCALE)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise InputError(f"log-scale {float(scales[row, col]):.6g} is outside "
                         f"[-{MAX_LOG_SCALE:g}, {MAX_LOG_SCALE:g}] (exp of it is not a float32 "
                         "size)", property=scene.ply_property("scales", int(col)),
                         index=int(row))


def _check_magnitudes(scene: GaussianScene) -> None:
    attributes = scene.attributes()
    for name in LIMITED_ATTRIBUTES:
        values = attributes.get(name)
        if values is None or not values.size:
            continue
        too_big = ~(np.abs(values) <= MAX_CODED_MAGNITUDE)
        if too_big.any():
            row, col = np.argwhere(too_big)[0]
            raise InputError(f"|value| {abs(float(values[row, col])):.6g} exceeds 2^52, the "
                             "largest the codec can code", index=int(row),
                             property=scene.ply_property(name, int(col)))


def decodable_container(chunks: list[Chunk], count: int) -> bytes:
    """The container of ``chunks``, padded so that the default decoder takes its ``count``
    Gaussians: at least ceil(count / 64) bytes (FORMAT §10.1). Where the coded scene is
    smaller (many identical Gaussians), a ``fill`` chunk is inserted into ``chunks`` at the
    end of the base layer, so every prefix that holds the base layer is large enough."""
    return padded_container(chunks, -(-count // MAX_GAUSSIANS_PER_BYTE))


def padded_container(chunks: list[Chunk], needed: int, through: Layer = Layer.BASE) -> bytes:
    """The container of ``chunks``, whose every prefix holding the layers up to ``through``
    is at least ``needed`` bytes long: a ``fill`` chunk is inserted into ``chunks`` at the end
    of the base layer where it is shorter (FORMAT §10.1)."""
    from csgs_codec.format.source import open_source
    from csgs_codec.format.toc import read_toc

    data = write_container(chunks)
    toc = read_toc(open_source(data))
    prefix = max([toc.header_and_toc_size] + [e.end for e in toc.entries if e.layer <= through])
    if through == Layer.BASE:
        prefix = len(data)  # the Gaussian scenes' rule: the whole file (FORMAT §10.1)
    if prefix >= needed:
        return data
    at = sum(1 for c in chunks if c.layer == Layer.BASE)
    chunks.insert(at, Chunk("fill", Layer.BASE, bytes(needed - prefix)))
    return write_container(chunks)  # the fill's frame and TOC entry only add bytes
