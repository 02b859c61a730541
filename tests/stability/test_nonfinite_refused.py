"""NaN and Inf never pass: refused with an InputError naming the property, or a FormatError.

Rules: the encoder, the PLY writer, the PLY reader and the renderer refuse a scene with NaN or
+-Inf in any float attribute, naming its PLY property (issue #20: "f_dc_2", not "sh_dc") and
the Gaussian; the decoder refuses a
bitstream whose values would decode to NaN or Inf, naming the chunk, instead of outputting
them.
"""

from __future__ import annotations

import dataclasses
import struct

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.chunks.scene_header import SceneHeader
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.interchange.ply_io import parse_ply_bytes, ply_bytes, write_ply
from csgs_codec.interchange.ply_writer import vertex_ply_bytes
from csgs_codec.render.rasterizer import render
from csgs_codec.scene.orbit import orbit_cameras
from tests.stability.stress_scenes import (
    ATTRIBUTES,
    far_outlier,
    identical_gaussians,
    plain_scene,
    with_nonfinite,
)

BAD_VALUES = {"nan": np.nan, "+inf": np.inf, "-inf": -np.inf}
CASES = [(attr, label) for attr in ATTRIBUTES for label in BAD_VALUES]
IDS = [f"{attr}-{label}" for attr, label in CASES]
BAD_INDEX = 5
#: The PLY property of the last channel of each attribute (where with_nonfinite writes) in
#: the SH-degree-1 scene with semantic channels ins_feat_0..2.
LAST_PLY_PROPERTY = {"positions": "z", "sh_dc": "f_dc_2", "sh_rest": "f_rest_8",
                     "opacity": "opacity", "scales": "scale_2", "rotations": "rot_3",
                     "semantic": "ins_feat_2"}


@pytest.mark.parametrize(("attribute", "label"), CASES, ids=IDS)
def test_encoder_refuses_nonfinite_naming_property_and_gaussian(attribute, label):
    scene = with_nonfinite(attribute, BAD_VALUES[label], BAD_INDEX)
    with pytest.raises(InputError) as err:
        Encoder(quality=5).encode(scene)
    assert err.value.property == LAST_PLY_PROPERTY[attribute] and err.value.index == BAD_INDEX


@pytest.mark.parametrize(("attribute", "label"), CASES, ids=IDS)
def test_ply_writer_refuses_nonfinite_and_leaves_no_file(attribute, label, tmp_path):
    scene = with_nonfinite(attribute, BAD_VALUES[label], BAD_INDEX)
    target = tmp_path / "out.ply"
    with pytest.raises(InputError) as err:
        write_ply(scene, target)
    assert err.value.property == LAST_PLY_PROPERTY[attribute] and err.value.index == BAD_INDEX
    assert list(tmp_path.iterdir()) == []


def _ply_with_nonfinite(property_name: str, value: float) -> bytes:
    """A valid scene's PLY with ``value`` written into Gaussian BAD_INDEX of one property."""
    scene = plain_scene(16)
    n = len(scene)
    fields = [(name, np.zeros(n, np.float32)) for name in ("x", "y", "z")]
    fields += [(f"f_dc_{i}", scene.sh_dc[:, i]) for i in range(3)]
    fields += [("opacity", scene.opacity)]
    fields += [(f"scale_{i}", scene.scales[:, i]) for i in range(3)]
    fields += [(f"rot_{i}", scene.rotations[:, i]) for i in range(4)]
    fields += [("ins_feat_0", np.ones(n, np.float32))]
    for name, column in fields:
        if name == property_name:
            column[BAD_INDEX] = value
    return vertex_ply_bytes(n, fields)


PLY_PROPERTIES = ("x", "f_dc_1", "opacity", "scale_2", "rot_0", "ins_feat_0")


@pytest.mark.parametrize("label", list(BAD_VALUES))
@pytest.mark.parametrize("ply_property", list(PLY_PROPERTIES))
def test_ply_reader_refuses_nonfinite_naming_property_and_gaussian(ply_property, label):
    data = _ply_with_nonfinite(ply_property, BAD_VALUES[label])
    with pytest.raises(InputError) as err:
        parse_ply_bytes(data, source="bad.ply")
    assert err.value.property == ply_property
    assert err.value.index == BAD_INDEX and err.value.file == "bad.ply"


@pytest.mark.parametrize("backend", ["numba", "torch"])
@pytest.mark.parametrize("attribute", ATTRIBUTES[:-1])
def test_renderer_refuses_nonfinite_naming_the_property(attribute, backend):
    camera = orbit_cameras(plain_scene(), count=1, width=24, height=16)[0]
    scene = with_nonfinite(attribute, np.nan, BAD_INDEX)
    with pytest.raises(InputError) as err:
        render(scene, camera, backend=backend)
    assert err.value.property == LAST_PLY_PROPERTY[attribute]


def _replace_payload(data: bytes, chunk_type: str, payload: bytes) -> bytes:
    chunks = [Chunk(c.type, c.layer, payload if c.type == chunk_type else c.payload, c.tile)
              for c in read_layers(data, layers={"color", "semantic"}).chunks()]
    return write_container(chunks)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf], ids=["nan", "+inf", "-inf"])
def test_decoder_refuses_a_nonfinite_constant_channel(value):
    scene = identical_gaussians()
    data = Encoder(quality=5).encode(scene)
    payload = read_layers(data).payload("SCAL")
    constant = struct.pack("<f", float(scene.scales[0, 0]))
    at = payload.find(constant)
    assert at > 0, "the constant channel's float32 is in the payload"
    forged = payload[:at] + struct.pack("<f", value) + payload[at + 4:]
    with pytest.raises(FormatError) as err:
        Decoder().decode(_replace_payload(data, "SCAL", forged))
    assert err.value.chunk == "SCAL"


def test_decoder_refuses_a_nonfinite_far_outlier():
    scene = far_outlier()
    data = Encoder(quality=5).encode(scene)
    payload = read_layers(data).payload("OUTL")
    outlier = struct.pack("<f", 1e7)
    at = payload.find(outlier)
    assert at > 0
    forged = payload[:at] + struct.pack("<f", np.inf) + payload[at + 4:]
    with pytest.raises(FormatError) as err:
        Decoder().decode(_replace_payload(data, "OUTL", forged))
    assert err.value.chunk == "OUTL"


@pytest.mark.parametrize("field", ["grid_cell", "grid_origin"])
def test_decoder_refuses_a_grid_whose_positions_overflow_float32(field):
    data = Encoder(quality=5).encode(plain_scene())
    header = SceneHeader.from_bytes(read_layers(data).payload("SCNE"))
    if field == "grid_cell":
        header = dataclasses.replace(header, grid_cell=1e300)
    else:
        header = dataclasses.replace(header, grid_origin=(1e300, 0.0, 0.0))
    with pytest.raises(FormatError) as err:
        Decoder().decode(_replace_payload(data, "SCNE", header.to_bytes()))
    assert err.value.chunk == "GEOM"


def test_the_unforged_inputs_are_accepted():
    # The control for the forged cases above: the unmodified bytes read and decode.
    scene = plain_scene(16)
    parsed, _ = parse_ply_bytes(ply_bytes(scene))
    assert parsed.equals(scene)
    assert len(Decoder().decode(Encoder(quality=5).encode(scene))) == 16
