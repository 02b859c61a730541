"""Which optional install extra provides a module that could not be imported.

``pip install csgs`` brings the decoder alone (numpy, constriction, tqdm); encoding, training,
the viewer and the numba kernels come with extras (pyproject.toml). Code needing an extra
imports it where it is used, so a core install fails only there, with a ModuleNotFoundError
that :func:`missing_extra_message` turns into an instruction.
"""

from __future__ import annotations

#: Top-level module -> (PyPI name, extra that installs it).
EXTRA_OF_MODULE = {
    "torch": ("torch", "encode"),
    "PIL": ("pillow", "encode"),
    "pyvista": ("pyvista", "view"),
    "vtk": ("pyvista", "view"),
    "numba": ("numba", "fast"),
    "zstandard": ("zstandard", "formats"),
}


def missing_extra_message(error: ModuleNotFoundError, command: str | None = None) -> str | None:
    """A one-line instruction for an optional module that is not installed, else None.

    ``command`` (e.g. ``"train"``) names the extra when the command has its own (training
    needs torch through the ``train`` extra rather than ``encode``).
    """
    top = (error.name or "").split(".")[0]
    if top not in EXTRA_OF_MODULE:
        return None
    package, extra = EXTRA_OF_MODULE[top]
    if command == "train" and extra == "encode":
        extra = "train"
    what = f"`csgs {command}`" if command else "this"
    return (f"{what} needs the Python package '{package}', which is not installed: "
            f"pip install 'csgs[{extra}]'")
