"""The JavaScript CLI refuses bad files and bad arguments in one line (issue #29, item 13).

Rules: a FILE that is missing, a folder or not a regular file gives its JSON line
{"file", "ok": false, "error": "InputError", "chunk": null, "offset": null, "message"} and exit
status 2, and the other files are still decoded; a bad command line (an unknown layer, an
unknown option, a missing or bad number, no file) gives one usage line on stderr and exit
status 2. Never a Node stack trace. Skipped when ``node`` is not on PATH.
"""

from __future__ import annotations

import json
import os
import subprocess

import pytest

from benchmarks._js_receiver import CLI, REPO, node_executable

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

SCENE = REPO / "spec" / "vectors" / "scenes" / "color_prior_q3.csgs"


def _run(*args) -> subprocess.CompletedProcess:
    return subprocess.run([node_executable(), str(CLI), *map(str, args)], capture_output=True,
                          text=True, timeout=300, check=False)


def _no_stack_trace(err: str) -> None:
    assert "\n    at " not in err and "node:internal" not in err, err
    assert len(err.splitlines()) <= 1, err


def _lines(out: str) -> list[dict]:
    return [json.loads(line) for line in out.splitlines() if line.strip()]


@pytest.mark.parametrize(("kind", "message"), [("missing", "file not found"),
                                               ("folder", "folder"),
                                               ("fifo", "not a regular file")])
def test_an_unreadable_file_is_an_input_error_line(tmp_path, kind, message):
    path = tmp_path / "scene.csgs"
    if kind == "folder":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    done = _run(path, "--threads", "1")
    assert done.returncode == 2
    _no_stack_trace(done.stderr)
    [line] = _lines(done.stdout)
    assert line == {"file": str(path), "ok": False, "error": "InputError", "chunk": None,
                    "offset": None, "message": line["message"]}
    assert message in line["message"]


def test_the_other_files_are_still_decoded(tmp_path):
    done = _run(tmp_path / "missing.csgs", SCENE, "--threads", "1")
    assert done.returncode == 2
    first, second = _lines(done.stdout)
    assert first["error"] == "InputError" and second["ok"] is True and second["count"] > 0


@pytest.mark.parametrize("args", [
    [SCENE, "--layers", "bogus"], [SCENE, "--layers", "color,bogus"], [SCENE, "--layers"],
    [SCENE, "--frob"], [SCENE, "--repeat", "x"], [SCENE, "--threads", "0"],
    [SCENE, "--range-coder", "fortran"], [],
])
def test_a_bad_command_line_is_one_usage_line_and_exit_2(args):
    done = _run(*args)
    assert done.returncode == 2
    assert done.stdout == ""
    _no_stack_trace(done.stderr)
    assert done.stderr.startswith("decode_cli.mjs: error: ") and "usage:" in done.stderr


@pytest.mark.parametrize("layers", ["color", "color,semantic", "semantic, color"])
def test_known_layers_are_accepted(layers):
    done = _run(SCENE, "--layers", layers, "--threads", "1")
    assert done.returncode == 0, done.stderr
    [line] = _lines(done.stdout)
    assert line["ok"] is True and line["file"] == str(SCENE)
