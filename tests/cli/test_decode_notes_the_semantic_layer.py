"""``csgs decode`` says when it leaves a semantic layer out (issue #29, item 11).

Rules: decoding a file that has a semantic layer with the default ``--layers color`` prints one
warning line on stderr naming the file and ``--layers color,semantic``; ``--quiet`` hides it
(an informational line, not dropped input); nothing is said when the semantic layer is decoded
or the file has none. The output is written either way.
"""

from __future__ import annotations

import pytest

from csgs_cli.main import main
from csgs_codec.codec.encoder import Encoder
from tests.anchors.helpers import encoded
from tests.codec.helpers import random_scene


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("semantic_note")
    with_semantic = folder / "with.csgs"
    with_semantic.write_bytes(Encoder(quality=4, hyperprior=False).encode(
        random_scene(300, sh_degree=0, semantic=2, labels=True)))
    without = folder / "without.csgs"
    without.write_bytes(Encoder(quality=4, hyperprior=False).encode(
        random_scene(300, sh_degree=0)))
    anchors = folder / "anchors.csgs"
    anchors.write_bytes(encoded().data)
    return {"with": with_semantic, "without": without, "anchors": anchors}


def _decode(source, out, *extra) -> tuple[int, str]:
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["decode", str(source), "-o", str(out), *extra])
    return code, err.getvalue()


@pytest.mark.parametrize("name", ["with", "anchors"])
def test_a_left_out_semantic_layer_is_noted_once(files, tmp_path, name):
    out = tmp_path / "out.ply"
    code, err = _decode(files[name], out)
    assert code == 0 and out.exists()
    notes = [line for line in err.splitlines() if "semantic layer" in line]
    assert len(notes) == 1, err
    assert str(files[name]) in notes[0] and "--layers color,semantic" in notes[0]
    assert "Traceback" not in err


@pytest.mark.parametrize("name", ["with", "anchors"])
def test_quiet_hides_the_note(files, tmp_path, name):
    code, err = _decode(files[name], tmp_path / "out.ply", "--quiet")
    assert code == 0 and "semantic layer" not in err


@pytest.mark.parametrize(("name", "extra"), [("with", ["--layers", "color,semantic"]),
                                             ("anchors", ["--layers", "semantic,color"]),
                                             ("without", [])])
def test_no_note_when_nothing_is_left_out(files, tmp_path, name, extra):
    code, err = _decode(files[name], tmp_path / "out.ply", *extra)
    assert code == 0 and "semantic layer" not in err
