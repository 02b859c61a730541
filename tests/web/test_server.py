"""The viewer's HTTP server without a browser: Range answers, what it serves and refuses, the
page configuration, and `csgs view --web`'s argument checks."""

from __future__ import annotations

import json
import urllib.error
import urllib.request

import pytest

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.web.server import PACKAGE_ROOT, ViewerServer, byte_range, parse_layers

CONTENT = bytes(range(256)) * 40  # 10,240 bytes


@pytest.fixture()
def server(tmp_path):
    path = tmp_path / "scene.csgs"
    path.write_bytes(CONTENT)
    with ViewerServer(path, layers=("color",)) as running:
        yield running


def _get(url: str, headers: dict | None = None):
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, dict(response.headers), response.read()
    except urllib.error.HTTPError as err:
        return err.code, dict(err.headers), err.read()


@pytest.mark.parametrize(("header", "expected"), [
    (None, None), ("bytes=0-15", (0, 15)), ("bytes=100-", (100, 10239)),
    ("bytes=-10", (10230, 10239)), ("bytes=10000-99999", (10000, 10239)),
    ("bytes=10240-", False), ("bytes=20-10", False), ("bytes=-0", False),
    ("bytes=0-1,5-6", None), ("items=0-1", None), ("bytes=-", None),
])
def test_byte_range(header, expected):
    assert byte_range(header, len(CONTENT)) == expected


def _counter_reaches(server, count: int, timeout: float = 10.0) -> bool:
    """Whether the server's byte counter reaches ``count`` (exactly) within ``timeout`` s:
    the handler thread counts a body after writing it, so the client can read the answer
    before the count is updated."""
    import time

    deadline = time.monotonic() + timeout
    while server.scene_bytes_sent < count and time.monotonic() < deadline:
        time.sleep(0.01)
    return server.scene_bytes_sent == count


def test_range_requests_get_206_with_the_asked_bytes(server):
    status, headers, body = _get(server.url + "scene.csgs", {"Range": "bytes=16-1039"})
    assert status == 206 and body == CONTENT[16:1040]
    assert headers["Content-Range"] == f"bytes 16-1039/{len(CONTENT)}"
    assert _counter_reaches(server, 1024)
    status, headers, body = _get(server.url + "scene.csgs", {"Range": "bytes=20000-"})
    assert status == 416 and body == b"" and headers["Content-Range"] == f"bytes */{len(CONTENT)}"
    status, headers, body = _get(server.url + "scene.csgs")
    assert status == 200 and body == CONTENT and headers["Accept-Ranges"] == "bytes"
    assert _counter_reaches(server, 1024 + len(CONTENT))


def test_serves_the_page_receiver_and_tables_from_the_package(server):
    status, headers, body = _get(server.url)  # redirected to the page
    assert status == 200 and b'src="viewer.mjs"' in body
    for path, kind in [("web/viewer.mjs", "text/javascript"), ("js/scene.mjs", "text/javascript"),
                       ("web/vendor/playcanvas/playcanvas.min.mjs", "text/javascript"),
                       ("entropy/data/sine_v1.bin", "application/octet-stream")]:
        status, headers, body = _get(server.url + path)
        assert status == 200 and headers["Content-Type"].startswith(kind), path
        assert body == (PACKAGE_ROOT / path).read_bytes()
    status, _, body = _get(server.url + "config.json")
    assert status == 200
    assert json.loads(body) == {"scene": "/scene.csgs", "name": "scene.csgs", "layers": ["color"]}


@pytest.mark.parametrize("path", [
    "web/../web/server.py", "web/%2e%2e/codec/decoder.py", "codec/decoder.py", "web/server.py",
    "web/missing.mjs", "js/../../setup.py", "entropy/data/../__init__.py",
])
def test_refuses_everything_else(server, path):
    status, _, _ = _get(server.url + path)
    assert status == 404


def test_without_a_scene_the_page_offers_the_file_picker(tmp_path):
    with ViewerServer(None) as running:
        status, _, body = _get(running.url + "config.json")
        assert json.loads(body)["scene"] is None
        assert _get(running.url + "scene.csgs")[0] == 404


def test_parse_layers():
    assert parse_layers(None) == ("color", "semantic")
    assert parse_layers("color") == ("color",)
    assert parse_layers("semantic, color") == ("color", "semantic")
    for bad in ("semantic", "colour", "color,base", ""):
        with pytest.raises(InputError):
            parse_layers(bad)


def test_view_web_refuses_bad_input_with_exit_code_2(tmp_path, capsys):
    ply = tmp_path / "scene.ply"
    ply.write_bytes(b"ply\nformat ascii 1.0\nend_header\n")
    csgs = tmp_path / "scene.csgs"
    csgs.write_bytes(b"\x89CSG\r\n\x1a\n" + bytes(8))
    cases = [
        ([str(ply), "--web"], ".csgs files"),
        ([str(tmp_path / "missing.csgs"), "--web"], "file not found"),
        ([str(csgs), "--web", "--layers", "semantic"], "--layers"),
        ([str(csgs), "--web", "--screenshot", str(tmp_path / "x.png")], "--screenshot"),
        ([str(csgs), "--web", "--port", "70000"], "--port"),
        ([str(csgs), "--layers", "color"], "go with --web"),
        ([], "give the scene"),
    ]
    for argv, words in cases:
        assert main(["view", *argv]) == 2, argv
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err, argv


def test_every_page_file_is_package_data():
    """`pip install` must bring every file the page loads (pyproject's package-data globs)."""
    tomllib = pytest.importorskip("tomllib", reason="tomllib needs Python 3.11")
    config = tomllib.loads((PACKAGE_ROOT.parent / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["csgs_codec"]
    shipped = {path for pattern in patterns for path in PACKAGE_ROOT.glob(pattern)}
    page_files = [path for path in (PACKAGE_ROOT / "web").rglob("*") if path.is_file()
                  and path.suffix not in (".py", ".pyc") and "__pycache__" not in path.parts]
    assert len(page_files) >= 10
    assert [path for path in page_files if path not in shipped] == []


def test_view_web_serves_until_interrupted(tmp_path):
    """The command as a user runs it: prints the address, serves the scene, stops on Ctrl-C."""
    import os
    import re
    import signal
    import subprocess
    import sys

    from tests.conftest import REPO

    scene = tmp_path / "scene.csgs"
    scene.write_bytes(b"\x89CSG\r\n\x1a\n" + bytes(8))
    def ctrl_c_as_in_a_terminal() -> None:
        # A shell starts background jobs with SIGINT ignored, and an ignored signal stays
        # ignored across exec (Python then never raises KeyboardInterrupt): give the
        # command the default disposition a terminal gives it, wherever the tests run.
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    process = subprocess.Popen(
        [sys.executable, "-m", "cli.main", "view", "--web", str(scene), "--no-browser",
         "--layers", "color"], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, env={**os.environ, "PYTHONPATH": str(REPO)},
        preexec_fn=ctrl_c_as_in_a_terminal)
    try:
        line = process.stdout.readline()
        url = re.search(r"at (http://127\.0\.0\.1:\d+/)", line)[1]
        status, _, body = _get(url + "config.json")
        assert status == 200 and json.loads(body)["layers"] == ["color"]
        assert _get(url + "scene.csgs", {"Range": "bytes=0-7"})[2] == b"\x89CSG\r\n\x1a\n"
    finally:
        process.send_signal(signal.SIGINT)
        try:
            out, err = process.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()  # leave no server behind
            process.communicate()
            raise
    assert process.returncode == 0 and "Traceback" not in err


def _imports(path) -> set:
    """The files a module imports (static ``import ... from './x.mjs'`` / ``import './x.mjs'``)."""
    import re

    names = re.findall(r"""import[^'"]*['"](\.{1,2}/[^'"]+\.mjs)['"]""", path.read_text())
    return {(path.parent / name).resolve() for name in names}


def test_the_workers_name_every_receiver_module_up_front():
    """receiver_modules.mjs lists every module the decode workers reach, so the browser
    requests them all at once (a module left out still loads, one import level later)."""
    web = PACKAGE_ROOT / "web"
    listed = _imports(web / "receiver_modules.mjs")
    for worker in ("decode_worker.mjs", "lane_worker.mjs"):
        assert (web / "receiver_modules.mjs").resolve() in _imports(web / worker), worker
        reached, todo = set(), [web / worker]
        while todo:
            for module in _imports(todo.pop()):
                if module not in reached:
                    reached.add(module)
                    todo.append(module)
        receiver = {m for m in reached if m.parent == (PACKAGE_ROOT / "js").resolve()}
        assert receiver and receiver <= listed, sorted(m.name for m in receiver - listed)


def test_package_files_have_cacheable_versioned_urls(server):
    status, headers, _ = _get(server.url)
    assert status == 200
    tag = server.tag
    status, headers, body = _get(f"{server.url}v/{tag}/js/scene.mjs")
    assert status == 200 and body == (PACKAGE_ROOT / "js" / "scene.mjs").read_bytes()
    assert "immutable" in headers["Cache-Control"]
    assert _get(f"{server.url}v/{'0' * 16}/js/scene.mjs")[0] == 404  # another version's
    assert _get(server.url + "js/scene.mjs")[1]["Cache-Control"] == "no-store"


def _raw(server, path: str, headers: dict, host: str | None = "default"):
    """GET ``path`` with exactly these headers (``host=None`` sends no Host header at all):
    the status and body."""
    import http.client

    address, port = server.server_address[:2]
    connection = http.client.HTTPConnection(address, port, timeout=30)
    try:
        connection.putrequest("GET", path, skip_host=True, skip_accept_encoding=True)
        if host == "default":
            host = f"127.0.0.1:{port}"
        if host is not None:
            connection.putheader("Host", host)
        for name, value in headers.items():
            connection.putheader(name, value)
        connection.endheaders()
        response = connection.getresponse()
        return response.status, response.read()
    finally:
        connection.close()


@pytest.mark.parametrize("host", ["attacker.example", "attacker.example:{port}",
                                  "127.0.0.1:1", "127.0.0.1", "localhost.attacker.example:{port}"])
def test_a_foreign_host_header_gets_403(server, host, capsys):
    """DNS rebinding: a page whose name now points at 127.0.0.1 must not read the scene."""
    port = server.server_address[1]
    status, body = _raw(server, "/scene.csgs", {}, host=host.format(port=port))
    assert status == 403 and CONTENT[:16] not in body and body.count(b"\n") == 1
    assert _raw(server, "/config.json", {}, host=host.format(port=port))[0] == 403
    assert server.scene_bytes_sent == 0
    assert "Traceback" not in capsys.readouterr().err


def test_a_request_without_a_host_header_is_refused(server):
    status, body = _raw(server, "/scene.csgs", {}, host=None)
    assert status in (400, 403) and CONTENT[:16] not in body


@pytest.mark.parametrize("host", ["127.0.0.1:{port}", "localhost:{port}", "LocalHost:{port}",
                                  "[::1]:{port}"])
def test_loopback_host_headers_are_answered(server, host):
    status, body = _raw(server, "/scene.csgs", {"Range": "bytes=0-7"},
                        host=host.format(port=server.server_address[1]))
    assert status == 206 and body == CONTENT[:8]


def test_the_address_it_listens_on_is_an_accepted_host(tmp_path):
    path = tmp_path / "scene.csgs"
    path.write_bytes(CONTENT)
    with ViewerServer(path, host="0.0.0.0") as running:
        port = running.server_address[1]
        assert f"0.0.0.0:{port}" in running.allowed_hosts
        assert _raw(running, "/config.json", {}, host=f"0.0.0.0:{port}")[0] == 200
        assert _raw(running, "/config.json", {}, host=f"127.0.0.1:{port}")[0] == 200
        assert _raw(running, "/config.json", {}, host=f"192.0.2.1:{port}")[0] == 403


@pytest.mark.parametrize(("header", "expected"), [
    ("bytes=" + "9" * 5000 + "-", False), ("bytes=0-" + "9" * 5000, (0, 10239)),
    ("bytes=-" + "9" * 5000, (0, 10239)), ("bytes=" + "0" * 5000 + "5-9", (5, 9)),
    ("bytes=99999999999999999999-", False), ("bytes=\u0661-\u0662", None),
])
def test_byte_range_of_absurd_numbers(header, expected):
    assert byte_range(header, len(CONTENT)) == expected


def test_an_absurdly_long_range_gets_416_not_a_traceback(server, capsys):
    status, body = _raw(server, "/scene.csgs", {"Range": "bytes=" + "9" * 5000 + "-"})
    assert status == 416 and body == b""
    assert _raw(server, "/scene.csgs", {"Range": "bytes=0-7"}) == (206, CONTENT[:8])
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize("path", ["/web/index.html%00.png", "/js/%00", "/web/%00/../index.html",
                                  "/%00", "/scene.csgs%00", "//[::1/x"])
def test_odd_paths_get_a_short_4xx_not_a_traceback(server, path, capsys):
    status, body = _raw(server, path, {})
    assert status in (400, 404) and body.count(b"\n") == 1
    assert _raw(server, "/config.json", {})[0] == 200  # still serving
    assert "Traceback" not in capsys.readouterr().err


def test_an_unexpected_error_in_a_route_gets_500_and_one_line(server, capsys, monkeypatch):
    from csgs_codec.web import server as module

    def broken(url_path, root):
        raise RuntimeError("boom")

    monkeypatch.setattr(module, "package_file", broken)
    status, body = _raw(server, "/web/index.html", {})
    assert status == 500 and body.count(b"\n") == 1 and b"Traceback" not in body
    assert "Traceback" not in capsys.readouterr().err
