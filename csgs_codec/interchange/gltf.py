"""glTF 2.0 binary (``.glb``) with ``KHR_gaussian_splatting``: one ``POINTS`` primitive whose
attributes are the Gaussians.

Attributes (KhronosGroup/glTF ``extensions/2.0/Khronos/KHR_gaussian_splatting``): POSITION
(VEC3), ``KHR_gaussian_splatting:ROTATION`` (VEC4 unit quaternion, glTF's x, y, z, w order),
``:SCALE`` (VEC3, linear), ``:OPACITY`` (SCALAR, 0..1), ``:SH_DEGREE_0_COEF_0`` (VEC3, the DC
coefficients) and ``:SH_DEGREE_l_COEF_n`` (VEC3 RGB per coefficient, m from -l to l), plus
``COLOR_0`` (linear RGBA) for viewers that show the points only. The extension object says
``kernel`` "ellipse" and ``colorSpace`` "srgb_rec709_display" (3DGS is trained on sRGB
images).

Axes: glTF is +Y up with the asset facing +Z; 3DGS PLY scenes (COLMAP's convention) are +Y
down. The writer turns the scene 180 degrees about Z (x, y -> -x, -y, the quaternion
multiplied on the left by that turn, the SH coefficients odd in x and y negated), as
splat-transform does, and the reader turns it back.
"""

from __future__ import annotations

import json
import struct
import warnings

import numpy as np

from csgs_codec import __version__
from csgs_codec.errors import CsgsWarning, UnsupportedError
from csgs_codec.interchange.binary import (
    Bytes,
    alpha_to_logit,
    dc_to_color,
    linear_to_log_scale,
    logit_to_alpha,
)
from csgs_codec.interchange.source import SceneSource
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.untrusted import load_json

GLB_MAGIC = b"glTF"
JSON_CHUNK = 0x4E4F534A
BIN_CHUNK = 0x004E4942
EXTENSION = "KHR_gaussian_splatting"
PREFIX = EXTENSION + ":"
FLOAT, BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT = 5126, 5120, 5121, 5122, 5123
COMPONENTS = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}
DTYPES = {FLOAT: "<f4", BYTE: "i1", UNSIGNED_BYTE: "u1", SHORT: "<i2", UNSIGNED_SHORT: "<u2"}
#: Sign of each of the 15 SH rest coefficients (degree 1: y, z, x; then degrees 2 and 3 in
#: m order) under the 180-degree turn about Z: -1 where the basis function is odd in x, y.
SH_TURN_SIGNS = np.array([-1, 1, -1, 1, -1, 1, -1, 1, -1, 1, -1, 1, -1, 1, -1], np.float32)
MAX_JSON_BYTES = 64 << 20


def _turn_about_z(positions, wxyz, sh_rest):
    """The 180-degree turn about Z (its own inverse up to the quaternion's sign)."""
    p = positions * np.array([-1.0, -1.0, 1.0], np.float32)
    w, x, y, z = (wxyz[:, i] for i in range(4))
    q = np.stack([-z, -y, x, w], axis=1)
    sh = sh_rest * SH_TURN_SIGNS[: sh_rest.shape[1], None]
    return p.astype(np.float32), q.astype(np.float32), sh.astype(np.float32)


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def glb_bytes(scene: GaussianScene) -> bytes:
    """The scene as a GLB with one ``KHR_gaussian_splatting`` point primitive (float
    attributes; semantic channels and labels are not carried)."""
    scene.validate()
    n = len(scene)
    if n == 0:
        raise UnsupportedError("glTF accessors cannot be empty: the scene has no Gaussians")
    positions, rotations, sh_rest = _turn_about_z(scene.positions, scene.rotations,
                                                  scene.sh_rest)
    norm = np.linalg.norm(rotations.astype(np.float64), axis=1, keepdims=True)
    rotations = np.where(norm > 0, rotations / np.where(norm > 0, norm, 1), [0, 0, 0, 1])
    alpha = logit_to_alpha(scene.opacity)
    color = _srgb_to_linear(np.clip(dc_to_color(scene.sh_dc), 0.0, 1.0))
    color_0 = np.clip(np.rint(np.column_stack([color, alpha]) * 255), 0, 255)
    attributes = [
        ("POSITION", positions, FLOAT, "VEC3"),
        ("COLOR_0", color_0.astype(np.uint8), UNSIGNED_BYTE, "VEC4"),
        (PREFIX + "ROTATION", rotations[:, [1, 2, 3, 0]].astype(np.float32), FLOAT, "VEC4"),
        (PREFIX + "SCALE", np.exp(scene.scales.astype(np.float64)).astype(np.float32), FLOAT,
         "VEC3"),
        (PREFIX + "OPACITY", alpha.astype(np.float32), FLOAT, "SCALAR"),
        (PREFIX + "SH_DEGREE_0_COEF_0", scene.sh_dc, FLOAT, "VEC3"),
    ]
    k = 0
    for degree in range(1, scene.sh_degree_stored + 1):
        for coef in range(2 * degree + 1):
            attributes.append((f"{PREFIX}SH_DEGREE_{degree}_COEF_{coef}",
                               np.ascontiguousarray(sh_rest[:, k, :]), FLOAT, "VEC3"))
            k += 1
    blob, views, accessors, names = bytearray(), [], [], {}
    for i, (name, values, component, kind) in enumerate(attributes):
        data = np.ascontiguousarray(values).tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data),
                      "target": 34962})
        accessor = {"bufferView": i, "componentType": component, "count": n, "type": kind}
        if component != FLOAT:
            accessor["normalized"] = True
        if name == "POSITION":
            accessor["min"] = [float(v) for v in positions.min(axis=0)]
            accessor["max"] = [float(v) for v in positions.max(axis=0)]
        accessors.append(accessor)
        names[name] = i
        blob += data + b"\0" * (-len(data) % 4)
    document = {
        "asset": {"version": "2.0", "generator": f"csgs {__version__}"},
        "extensionsUsed": [EXTENSION],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": names, "mode": 0,
            "extensions": {EXTENSION: {"kernel": "ellipse", "colorSpace": "srgb_rec709_display",
                                       "projection": "perspective",
                                       "sortingMethod": "cameraDistance"}}}]}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    text = json.dumps(document, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    return (struct.pack("<4sII", GLB_MAGIC, 2, total) + struct.pack("<II", len(text), JSON_CHUNK)
            + text + struct.pack("<II", len(blob), BIN_CHUNK) + bytes(blob))


# --------------------------------------------------------------------------- reading
def parse_glb(data: bytes, source: str = "<bytes>") -> tuple[GaussianScene, SceneSource]:
    """Decode the first ``KHR_gaussian_splatting`` primitive of a GLB (node transforms are
    not applied: the Gaussians come in the primitive's own space, turned back to PLY axes).

    Raises:
        InputError: bad magic or chunk lengths, missing attributes, accessors outside the
            binary chunk, counts that differ (file, byte offset or property named).
        UnsupportedError: external buffers, sparse accessors, compression extensions,
            a ``.gltf`` without its binary chunk.
    """
    raw = Bytes(data, source)
    raw.need(0, 20, "the GLB header")
    magic, version, length = struct.unpack_from("<4sII", data)
    if magic != GLB_MAGIC or version != 2:
        raise raw.error("not a glTF 2.0 binary (magic 'glTF', version 2)", offset=0)
    if length != len(data):
        raise raw.error(f"the header declares {length} bytes, the file has {len(data)}",
                        offset=8)
    json_length, kind = struct.unpack_from("<II", data, 12)
    if kind != JSON_CHUNK or json_length > MAX_JSON_BYTES:
        raise raw.error("the first chunk is not a JSON chunk of a sane size", offset=12)
    raw.need(20, json_length, "the JSON chunk")
    document = load_json(data[20:20 + json_length], file=source, what="the JSON chunk",
                         offset=20)
    at = 20 + json_length
    binary, binary_offset = b"", at + 8
    if at < len(data):
        raw.need(at, 8, "the BIN chunk header")
        bin_length, kind = struct.unpack_from("<II", data, at)
        if kind != BIN_CHUNK:
            raise raw.error("the second chunk is not a BIN chunk", offset=at + 4)
        raw.need(at + 8, bin_length, "the BIN chunk")
        binary = data[at + 8:at + 8 + bin_length]
    reader = _Document(document, binary, binary_offset, raw)
    scene = reader.scene()
    return scene, SceneSource("glb", "glTF binary (KHR_gaussian_splatting)", "2.0",
                              lossy=reader.lossy)


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


class _Document:
    """The parsed glTF JSON with the GLB's binary chunk: every field is checked for its JSON
    type before use, so a malformed document is an InputError naming the field."""

    def __init__(self, document, binary: bytes, binary_offset: int, raw: Bytes) -> None:
        if not isinstance(document, dict):
            raise raw.error("the JSON chunk is not an object", offset=20)
        self.doc, self.binary, self.binary_offset, self.raw = document, binary, binary_offset, raw
        self.lossy = False
        required = document.get("extensionsRequired", []) or []
        if not isinstance(required, list) or not all(isinstance(e, str) for e in required):
            raise raw.error("expected a list of extension names", property="extensionsRequired")
        unknown = set(required) - {EXTENSION}
        if unknown:
            raise UnsupportedError(f"required glTF extensions {sorted(unknown)}",
                                   file=raw.source, property="extensionsRequired")

    def _list(self, key: str, node: dict | None = None, name: str | None = None) -> list:
        """``node[key]`` (default: the document's), [] when absent; InputError unless a list."""
        value = (self.doc if node is None else node).get(key, [])
        if not isinstance(value, list):
            raise self.raw.error("expected a list", property=name or key)
        return value

    def _item(self, key: str, index, name: str) -> dict:
        """Object ``index`` of the document's list ``key``; InputError naming ``name``."""
        items = self._list(key)
        if not _is_int(index) or not 0 <= index < len(items):
            raise self.raw.error(f"{key}[{index!r}] does not exist", property=name)
        if not isinstance(items[index], dict):
            raise self.raw.error(f"{key}[{index}] is not an object", property=name)
        return items[index]

    def _size(self, node: dict, key: str, name: str, default: int | None = 0) -> int:
        """The non-negative integer ``node[key]`` (``default`` when absent)."""
        value = node.get(key, default)
        if not _is_int(value) or value < 0:
            raise self.raw.error(f"{key} {value!r} is not a non-negative integer", property=name)
        return value

    def primitive(self) -> dict:
        for m, mesh in enumerate(self._list("meshes")):
            if not isinstance(mesh, dict):
                continue
            for p, primitive in enumerate(self._list("primitives", mesh, f"meshes[{m}]")):
                extensions = primitive.get("extensions") if isinstance(primitive, dict) else None
                if isinstance(extensions, dict) and EXTENSION in extensions:
                    if primitive.get("mode", 4) != 0:
                        raise self.raw.error("a KHR_gaussian_splatting primitive must have mode "
                                             "POINTS (0)", property=f"meshes[{m}].primitives[{p}]")
                    return primitive
        raise self.raw.error(f"no mesh primitive uses {EXTENSION}", property="meshes")

    def accessor(self, index, name: str, kind: str) -> np.ndarray:
        a = self._item("accessors", index, name)
        if "sparse" in a:
            raise UnsupportedError("sparse accessors", file=self.raw.source, property=name)
        component = a.get("componentType")
        if a.get("type") != kind or not _is_int(component) or component not in DTYPES:
            raise self.raw.error(f"expected a {kind} accessor of float or (normalized) "
                                 "integers", property=name)
        dtype = np.dtype(DTYPES[component])
        count, width = a.get("count"), COMPONENTS[kind]
        if not _is_int(count) or count <= 0:
            raise self.raw.error(f"accessor count {count!r}", property=name)
        view = self._item("bufferViews", a.get("bufferView"), name)
        buffers = self._list("buffers")
        if buffers and not isinstance(buffers[0], dict):
            raise self.raw.error("buffers[0] is not an object", property=name)
        if view.get("buffer", 0) != 0 or (buffers and "uri" in buffers[0]):
            raise UnsupportedError("buffers outside the GLB's binary chunk", file=self.raw.source,
                                   property=name)
        if "extensions" in view:
            extensions = view["extensions"]
            names = sorted(extensions) if isinstance(extensions, dict) else extensions
            raise UnsupportedError(f"compressed buffer views ({names!r:.80})",
                                   file=self.raw.source, property=name)
        element = dtype.itemsize * width
        stride = self._size(view, "byteStride", name, None) if view.get("byteStride") else element
        start = self._size(view, "byteOffset", name) + self._size(a, "byteOffset", name)
        end_view = self._size(view, "byteOffset", name) + self._size(view, "byteLength", name)
        end = start + stride * (count - 1) + element
        if stride < element or end > end_view or end_view > len(self.binary):
            raise self.raw.error(f"accessor {index} reaches byte {end} of a {len(self.binary)}"
                                 "-byte binary chunk", offset=self.binary_offset + start,
                                 property=name)
        rows = np.lib.stride_tricks.as_strided(
            np.frombuffer(self.binary, np.uint8, count=end - start, offset=start),
            shape=(count, element), strides=(stride, 1))
        values = np.ascontiguousarray(rows).view(dtype).reshape(count, width).astype(np.float64)
        if component != FLOAT:
            self.lossy = True
            if a.get("normalized"):
                values = np.maximum(values / np.iinfo(dtype).max, -1.0)
        return values

    def scene(self) -> GaussianScene:
        attributes = self.primitive().get("attributes", {})
        if not isinstance(attributes, dict):
            raise self.raw.error("expected an object", property="attributes")
        for node in self._list("nodes"):
            if isinstance(node, dict) and any(k in node for k in ("matrix", "translation",
                                                                  "rotation", "scale")):
                warnings.warn(f"{self.raw.source}: node transforms are not applied; the "
                              "Gaussians are read in their mesh's own space", CsgsWarning,
                              stacklevel=4)
                break

        def get(name, kind, required=True):
            if name not in attributes:
                if required:
                    raise self.raw.error("missing attribute", property=name)
                return None
            return self.accessor(attributes[name], name, kind)

        positions = get("POSITION", "VEC3")
        n = len(positions)
        xyzw = get(PREFIX + "ROTATION", "VEC4")
        scale = get(PREFIX + "SCALE", "VEC3")
        opacity = get(PREFIX + "OPACITY", "SCALAR")
        dc = get(PREFIX + "SH_DEGREE_0_COEF_0", "VEC3")
        rest = []
        for degree in (1, 2, 3):
            coefs = [get(f"{PREFIX}SH_DEGREE_{degree}_COEF_{c}", "VEC3", required=False)
                     for c in range(2 * degree + 1)]
            if all(c is None for c in coefs):
                break
            if any(c is None for c in coefs):
                raise self.raw.error(f"SH degree {degree} is partly defined",
                                     property=f"{PREFIX}SH_DEGREE_{degree}_COEF_*")
            rest += coefs
        for name, values in (("rotation", xyzw), ("scale", scale), ("opacity", opacity),
                             ("SH degree 0", dc), *(("SH", c) for c in rest)):
            if len(values) != n:
                raise self.raw.error(f"{len(values)} values of {name}, {n} positions",
                                     property=name)
        sh_rest = (np.stack(rest, axis=1) if rest else np.zeros((n, 0, 3))).astype(np.float32)
        wxyz = xyzw[:, [3, 0, 1, 2]]
        p, q, sh = _turn_about_z(positions.astype(np.float32), wxyz, sh_rest)
        # Turning twice gives -q: negate so a file written by the turn reads back as q.
        return GaussianScene(positions=p, sh_dc=dc.astype(np.float32), sh_rest=sh,
                             opacity=alpha_to_logit(opacity[:, 0]),
                             scales=linear_to_log_scale(scale), rotations=-q)
