"""The subprocess runner every tool-based peer uses: failures become PeerToolError."""

from __future__ import annotations

import sys

import pytest

from benchmarks.peers import PeerToolError
from benchmarks.peers.base import run_tool


def test_successful_run_returns_its_wall_time(tmp_path):
    output = tmp_path / "out.bin"
    seconds = run_tool([sys.executable, "-c", f"open({str(output)!r}, 'wb').write(b'x')"],
                       output=output)
    assert seconds > 0
    assert output.read_bytes() == b"x"


def test_nonzero_exit_names_the_error_line(tmp_path):
    code = "import sys; print('at frame 1', file=sys.stderr); sys.exit('Error: bad splat')"
    with pytest.raises(PeerToolError, match="Error: bad splat"):
        run_tool([sys.executable, "-c", code], output=tmp_path / "out.bin")


def test_exit_zero_without_output_is_an_error(tmp_path):
    output = tmp_path / "out.bin"
    output.write_bytes(b"stale")
    with pytest.raises(PeerToolError, match="wrote no file"):
        run_tool([sys.executable, "-c", "pass"], output=output)


def test_run_past_the_time_limit_is_stopped(tmp_path):
    with pytest.raises(PeerToolError, match="ran past"):
        run_tool([sys.executable, "-c", "import time; time.sleep(30)"],
                 output=tmp_path / "out.bin", timeout_s=0.5)


def test_missing_executable_is_an_error(tmp_path):
    with pytest.raises(PeerToolError, match="cannot run"):
        run_tool([str(tmp_path / "no-such-tool")], output=tmp_path / "out.bin")
