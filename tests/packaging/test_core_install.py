"""A core install (``pip install csgs``, no extras) decodes everything and names the extras.

The fast tests run a subprocess in which the optional packages cannot be imported (a finder
at the front of ``sys.meta_path`` refuses them), which is what a core install looks like to
the code; the slow test makes a real virtual environment without extras.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
VECTORS = REPO / "spec" / "vectors"
#: What the core install lacks: every optional dependency of pyproject.toml's extras.
OPTIONAL = ("torch", "PIL", "pyvista", "vtk", "numba", "plyfile", "trimesh", "scipy",
            "zstandard")

_BLOCKER = textwrap.dedent(f"""
    import importlib.abc, sys
    class _CoreInstall(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {OPTIONAL!r}:
                raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
            return None
    sys.meta_path.insert(0, _CoreInstall())
""")


def _run_core(code: str, cwd: Path = REPO) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _BLOCKER + textwrap.dedent(code)],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


def test_every_conformance_vector_decodes_without_optional_packages():
    out = _run_core(f"""
        from pathlib import Path
        from tests.determinism.vector_cases import vector_cases
        cases = vector_cases(Path({str(VECTORS)!r}))
        wrong = [c.id for c in cases if c.compute() != c.expected]
        import json
        print(json.dumps({{"cases": len(cases), "wrong": wrong,
                          "loaded": sorted(set(sys.modules) & set({OPTIONAL!r}))}}))
    """)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report["cases"] > 50
    assert report["wrong"] == [] and report["loaded"] == [], report


def test_the_cli_decodes_and_describes_without_optional_packages(tmp_path):
    vector = VECTORS / "scenes" / "donut_q3.csgs"
    out = _run_core(f"""
        from csgs_cli.main import main
        codes = [main(["-q", "decode", {str(vector)!r}, "-o", {str(tmp_path / "d.ply")!r}]),
                 main(["-q", "info", {str(vector)!r}]),
                 main(["-q", "info", {str(tmp_path / "d.ply")!r}])]
        print("codes", codes, "torch" in sys.modules)
    """)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "codes [0, 0, 0] False"
    assert (tmp_path / "d.ply").stat().st_size > 1000


@pytest.mark.parametrize(("command", "extra"), [("encode", "encode"), ("view", "view")])
def test_commands_needing_an_extra_name_it(tmp_path, command, extra):
    sample = REPO / "samples" / "donut.ply"
    argv = (["encode", str(sample), "-o", str(tmp_path / "x.csgs")] if command == "encode"
            else ["view", str(sample), "--screenshot", str(tmp_path / "x.png")])
    out = _run_core(f"""
        from csgs_cli.main import main
        print("code", main(["-q", *{argv!r}]))
    """)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "code 2"
    assert f"pip install 'csgs[{extra}]'" in out.stderr
    assert "Traceback" not in out.stderr
    assert not (tmp_path / "x.csgs").exists() and not (tmp_path / "x.png").exists()


@pytest.mark.slow
def test_pip_install_without_extras_decodes_and_imports_no_torch(tmp_path):
    env_dir = tmp_path / "core"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", str(REPO)], check=True,
                   timeout=900)
    code = ("import sys, hashlib, json; from csgs_codec import Decoder; "
            "from csgs_codec.interchange.ply_io import ply_bytes; "
            f"d = open({str(VECTORS / 'scenes' / 'donut_q3.csgs')!r}, 'rb').read(); "
            "h = hashlib.sha256(ply_bytes(Decoder().decode(d))).hexdigest(); "
            "print(h, 'torch' in sys.modules)")
    out = subprocess.run([str(python), "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, check=True)
    expected = json.loads((VECTORS / "scenes" / "donut_q3.json").read_text())
    digest, torch_loaded = out.stdout.split()
    assert torch_loaded == "False"
    assert digest in json.dumps(expected)
    freeze = subprocess.run([str(python), "-m", "pip", "freeze"], capture_output=True,
                            text=True, check=True).stdout.lower()
    assert "torch" not in freeze and "pyvista" not in freeze
