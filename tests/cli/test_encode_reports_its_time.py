"""The encode summary gives the encode's wall time (issue #29, item 14).

Rule: the time printed is the time the encode took, streamed tile by tile from a PLY or not;
a tiled encode never reports "0.00 s". The clock is faked, so nothing here is timed.
"""

from __future__ import annotations

import pytest

from csgs_cli.commands import encode as encode_command
from csgs_cli.main import main
from csgs_codec.interchange.ply_io import write_ply
from tests.codec.helpers import random_scene


@pytest.mark.parametrize("extra", [["--tile-size", "1000"], []], ids=["tiled", "one-tile"])
def test_the_summary_prints_the_measured_encode_time(tmp_path, capsys, monkeypatch, extra):
    ply = tmp_path / "scene.ply"
    write_ply(random_scene(2_400, sh_degree=0), ply)
    ticks = iter([100.0, 103.25])
    monkeypatch.setattr(encode_command, "perf_counter", lambda: next(ticks), raising=False)
    out = tmp_path / "out.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--no-hyperprior", "--quiet", *extra]) == 0
    captured = capsys.readouterr()
    summary = captured.out.splitlines()[0]
    assert summary.endswith(", 3.25 s"), summary
    assert "Traceback" not in captured.err
    if extra:
        assert "spatial tiles" in captured.out
