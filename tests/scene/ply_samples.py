"""Builders of small PLY files in any layout, for reader tests."""

from __future__ import annotations

import numpy as np

STANDARD = (["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"],
            ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"])


def property_names(sh_rest: int = 0, extra: tuple[str, ...] = ()) -> list[str]:
    """INRIA property order with ``sh_rest`` f_rest properties and ``extra`` names appended."""
    head, tail = STANDARD
    return head + [f"f_rest_{i}" for i in range(sh_rest)] + tail + list(extra)


def make_ply(values: np.ndarray, names: list[str], *, fmt: str = "binary_little_endian",
             types: dict[str, str] | None = None, count: int | None = None) -> bytes:
    """A PLY file with one vertex element holding ``values`` (N, len(names)).

    ``types`` maps property names to PLY type names (default float); ``count`` overrides the
    declared element count (to build lying headers).
    """
    types = types or {}
    n = values.shape[0]
    ply_to_np = {"float": "f4", "double": "f8", "half": "f2", "uchar": "u1", "int": "i4",
                 "short": "i2", "uint": "u4"}
    lines = ["ply", f"format {fmt} 1.0", f"element vertex {n if count is None else count}"]
    lines += [f"property {types.get(name, 'float')} {name}" for name in names]
    lines.append("end_header\n")
    header = "\n".join(lines).encode()
    if fmt == "ascii":
        body = "".join(" ".join(repr(float(v)) if types.get(nm, "float") in
                                ("float", "double", "half") else str(int(v))
                                for v, nm in zip(row, names)) + "\n" for row in values)
        return header + body.encode()
    order = "<" if fmt == "binary_little_endian" else ">"
    dtype = np.dtype([(name, order + ply_to_np[types.get(name, "float")]) for name in names])
    rows = np.empty(n, dtype=dtype)
    for i, name in enumerate(names):
        rows[name] = values[:, i]
    return header + rows.tobytes()


def random_values(n: int, names: list[str], seed: int = 0) -> np.ndarray:
    """(n, len(names)) float32 values that are exact in float16 too (small dyadic numbers)."""
    rng = np.random.default_rng(seed)
    return (rng.integers(-64, 64, size=(n, len(names))) / 8).astype(np.float32)
