"""A local HTTP server for the browser viewer: the page, the JavaScript receiver, the frozen
tables and one scene file, nothing else (no internet at run time: every script is in the
package).

Routes:

* ``/`` redirects to ``/v/TAG/web/index.html``;
* ``/v/TAG/web/...``, ``/v/TAG/js/...``, ``/v/TAG/entropy/data/...``: files of the installed
  ``csgs_codec`` package under those folders (the page, the receiver's modules, the frozen
  tables), cacheable for good: TAG (:func:`package_tag`) changes whenever a served file
  does, so the page and its decode workers load each module once;
* the same paths without ``/v/TAG`` answer the same files, never cached;
* ``/config.json``: the scene's URL, file name and the layers the page should read;
* ``/scene.csgs``: the scene file, answering single-range HTTP Range requests (206 with
  Content-Range, 416 past the end), so a page showing the color layer fetches only the
  header, TOC and base and color chunks.

Every request must name this server in its Host header (``127.0.0.1:PORT``,
``localhost:PORT``, ``[::1]:PORT`` or the address it listens on): any other name gets 403, so
a web page whose own name was rebound to this machine's address (DNS rebinding) cannot read
the scene; a request with two Host headers gets 400. A request the handler cannot answer
gets 400 or 500 with a one-line body, never a traceback. A connection silent for
:data:`CONNECTION_TIMEOUT` seconds is closed, and at most :data:`MAX_CONNECTIONS` are served
at once (a further one is closed unanswered), so idle or piled-up clients hold no threads.

The server counts the scene bytes it sends (:attr:`ViewerServer.scene_bytes_sent`), which is
how ``benchmarks/web_viewer.py`` measures what the page fetches, and logs the byte ranges of
the scene it was asked for (:attr:`ViewerServer.scene_ranges`: which frames a streaming page
read before its first frame). ``rate`` (bytes per second) paces the scene's bytes as a link
of that speed would (benchmarks simulate a network with it).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import sys
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

from csgs_codec.errors import InputError

#: Layers the page may be asked to read, in the order it reads them.
PAGE_LAYERS = ("color", "semantic")
#: Folders of the package the server exposes, and the file types it serves from them.
PACKAGE_ROOT = Path(__file__).resolve().parent.parent
SERVED_FOLDERS = ("web/", "js/", "entropy/data/")
CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8", ".mjs": "text/javascript; charset=utf-8",
    ".js": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8",
    ".bin": "application/octet-stream", ".png": "image/png", ".svg": "image/svg+xml",
}
SCENE_PATH = "/scene.csgs"
_BLOCK = 1 << 16
_RANGE = re.compile(r"bytes=([0-9]*)-([0-9]*)")
_VERSIONED = re.compile(r"/v/([0-9a-f]{16})(/.*)")
_FOREVER = "public, max-age=31536000, immutable"
_NEVER = "no-store"
#: Seconds a connection may stay silent (before or between requests, or mid-request) before
#: the server closes it: a client that connects and sends nothing holds no thread for good.
CONNECTION_TIMEOUT = 30.0
#: Connections served at once; more are closed at once (each holds a thread).
MAX_CONNECTIONS = 64


def package_tag(root: Path = PACKAGE_ROOT) -> str:
    """16 hex digits naming the current content of the served folders under ``root`` (a
    hash of each file's path, size and modification time): the ``/v/TAG/`` prefix of
    cacheable URLs."""
    digest = hashlib.sha256()
    for folder in SERVED_FOLDERS:
        for path in sorted((root / folder).rglob("*")):
            if path.is_file() and path.suffix in CONTENT_TYPES:
                stat = path.stat()
                digest.update(f"{path.relative_to(root)}|{stat.st_size}|"
                              f"{stat.st_mtime_ns}\n".encode())
    return digest.hexdigest()[:16]


def parse_layers(text: str | None) -> tuple[str, ...]:
    """The page layers of a ``--layers`` value: "color" or "color,semantic" (the default).

    Raises:
        InputError: an unknown layer name, or a list without "color".
    """
    if text is None:
        return PAGE_LAYERS
    names = tuple(dict.fromkeys(part.strip() for part in text.split(",") if part.strip()))
    unknown = [name for name in names if name not in PAGE_LAYERS]
    if unknown or "color" not in names:
        raise InputError(f"--layers must be 'color' or 'color,semantic', got {text!r}",
                         property="--layers")
    return tuple(name for name in PAGE_LAYERS if name in names)


def byte_range(header: str | None, size: int) -> tuple[int, int] | None | bool:
    """The inclusive (first, last) byte of a single-range Range header for a file of ``size``
    bytes; None when the header is absent, malformed or asks for several ranges (the whole
    file is sent); False when the range cannot be satisfied (416)."""
    if not header:
        return None
    match = _RANGE.fullmatch(header.strip())
    if not match or (not match[1] and not match[2]):
        return None
    if not match[1]:  # the last N bytes
        count = _byte_number(match[2], size)
        return (max(size - count, 0), size - 1) if count and size else False
    first = _byte_number(match[1], size)
    last = _byte_number(match[2], size) if match[2] else size - 1
    if first >= size or last < first:
        return False
    return first, min(last, size - 1)


def _byte_number(digits: str, size: int) -> int:
    """The value of a Range header's decimal ``digits``, or ``size + 1`` (past the end of the
    file) for a number too long for the file: never converts thousands of digits, which
    Python refuses (and which would take quadratic time)."""
    digits = digits.lstrip("0") or "0"
    if len(digits) > len(str(size)):
        return size + 1
    return int(digits)


def allowed_hosts(host: str, port: int) -> frozenset[str]:
    """The Host header values (lower case) a server listening on ``host``:``port`` answers:
    the loopback names and the address it listens on, each with the port."""
    names = {"127.0.0.1", "localhost", "[::1]", host.lower()}
    return frozenset(f"[{name}]:{port}" if ":" in name and not name.startswith("[")
                     else f"{name}:{port}" for name in names)


class ViewerServer(ThreadingHTTPServer):
    """The viewer's HTTP server for one scene (or none: the page then offers its file picker).

    Args:
        scene: path of the .csgs file to serve, or None.
        layers: page layers to read (see :func:`parse_layers`).
        host, port: where to listen; port 0 picks a free one.
        package_root: the folder holding ``web/``, ``js/`` and ``entropy/data/`` (default:
            the installed package's; benchmarks/web_viewer.py serves an older page too).
        connection_timeout: seconds a connection may stay silent before it is closed.
        max_connections: connections served at once; a further one is closed unanswered.
        rate: bytes per second the scene is sent at, all answers together (a simulated
            link), or None (as fast as the machine goes).
    """

    daemon_threads = True

    def __init__(self, scene: str | Path | None, *, layers: tuple[str, ...] = PAGE_LAYERS,
                 host: str = "127.0.0.1", port: int = 0, package_root: Path = PACKAGE_ROOT,
                 connection_timeout: float = CONNECTION_TIMEOUT,
                 max_connections: int = MAX_CONNECTIONS, rate: float | None = None):
        self.scene = None if scene is None else Path(scene)
        self.connection_timeout = connection_timeout
        self._slots = threading.BoundedSemaphore(max_connections)
        self.package_root = Path(package_root).resolve()
        self.layers = tuple(layers)
        self._lock = threading.Lock()
        self._sent = 0
        self._ranges: list[tuple[float, int, int]] = []
        self.rate = rate
        self._link_free_at = 0.0  # when the simulated link has sent what it was given
        self._thread: threading.Thread | None = None
        self.tag = package_tag(self.package_root)
        super().__init__((host, port), _Handler)
        bound_host, bound_port = self.server_address[:2]
        self.allowed_hosts = allowed_hosts(host, bound_port) | allowed_hosts(bound_host,
                                                                              bound_port)

    @property
    def url(self) -> str:
        """The page's address, e.g. ``http://127.0.0.1:8000/``."""
        host, port = self.server_address[:2]
        return f"http://{host}:{port}/"

    @property
    def scene_bytes_sent(self) -> int:
        """Bytes of the scene file sent so far (bodies of 200 and 206 answers)."""
        with self._lock:
            return self._sent

    @property
    def scene_ranges(self) -> list[tuple[float, int, int]]:
        """The scene byte ranges asked for so far, in arrival order: (``time.monotonic()``
        when the answer began, first byte, end byte (exclusive))."""
        with self._lock:
            return list(self._ranges)

    def reset_counter(self) -> None:
        """Set :attr:`scene_bytes_sent` back to 0 and forget the ranges asked for."""
        with self._lock:
            self._sent = 0
            self._ranges.clear()

    def log_range(self, first: int, end: int) -> None:
        """Note that scene bytes ``first`` .. ``end`` (exclusive) are being sent."""
        with self._lock:
            self._ranges.append((time.monotonic(), first, end))

    def pace(self, count: int) -> None:
        """With a ``rate``, wait until a link of that speed shared by every answer has sent
        ``count`` more bytes."""
        if not self.rate:
            return
        with self._lock:
            start = max(self._link_free_at, time.monotonic())
            self._link_free_at = start + count / self.rate
            until = self._link_free_at
        delay = until - time.monotonic()
        if delay > 0:
            time.sleep(delay)

    def count_sent(self, count: int) -> None:
        """Add ``count`` bytes to :attr:`scene_bytes_sent`."""
        with self._lock:
            self._sent += count

    def config(self) -> dict:
        """What ``/config.json`` answers: scene URL (or None), file name, layers."""
        return {"scene": None if self.scene is None else SCENE_PATH,
                "name": None if self.scene is None else self.scene.name,
                "layers": list(self.layers)}

    def handle_error(self, request, client_address) -> None:
        """One line on stderr, not socketserver's traceback, for an error the handler did not
        answer itself (a client that went away is no error)."""
        error = sys.exc_info()[1]
        if isinstance(error, (ConnectionError, TimeoutError)):
            return
        print(f"csgs view: request from {client_address[0]} failed: "
              f"{type(error).__name__}: {error}", file=sys.stderr)

    def process_request(self, request, client_address) -> None:
        """Serve the connection on its own thread when a slot is free, else close it."""
        if not self._slots.acquire(blocking=False):
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request, client_address) -> None:
        """As the base class, then give the connection's slot back."""
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def start(self) -> ViewerServer:
        """Serve on a background daemon thread; returns self."""
        self._thread = threading.Thread(target=self.serve_forever, name="csgs-web",
                                        daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and release the socket."""
        if self._thread is not None:
            self.shutdown()
            self._thread.join()
            self._thread = None
        self.server_close()

    def __enter__(self) -> ViewerServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()


def package_file(url_path: str, root: Path = PACKAGE_ROOT) -> Path | None:
    """The file under ``root`` a URL path names under :data:`SERVED_FOLDERS`, or None
    (anything else, ``..`` tricks and unknown file types included)."""
    relative = unquote(url_path).lstrip("/")
    if "\0" in relative:
        return None
    if not relative.startswith(SERVED_FOLDERS) or Path(relative).suffix not in CONTENT_TYPES:
        return None
    try:  # a name the system refuses (too long: ENAMETOOLONG) is a file that is not there
        path = (root / relative).resolve()
        if not path.is_relative_to(root) or not path.is_file():
            return None
    except OSError:
        return None
    return path


class _Handler(BaseHTTPRequestHandler):
    server: ViewerServer
    protocol_version = "HTTP/1.1"

    def setup(self) -> None:
        """As the base class, with the server's per-connection timeout on the socket."""
        self.timeout = self.server.connection_timeout
        super().setup()

    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        pass  # quiet: the command prints the address once

    def do_HEAD(self):  # noqa: N802 - http.server's naming
        self._answer(send_body=False)

    def do_GET(self):  # noqa: N802
        self._answer(send_body=True)

    def _answer(self, send_body: bool) -> None:
        """Answer one GET or HEAD; whatever goes wrong ends as a 400 or 500 answer."""
        self._started = False
        try:
            if self._host_refused(send_body):
                return
            self._route(send_body)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the page went away mid-answer
        except ValueError as exc:  # a request no route can read (odd bytes, bad numbers)
            self._fail(HTTPStatus.BAD_REQUEST, exc, send_body)
        except Exception as exc:  # noqa: BLE001 - a server answers, it does not crash
            self._fail(HTTPStatus.INTERNAL_SERVER_ERROR, exc, send_body)

    def _host_refused(self, send_body: bool) -> bool:
        """Answer 400 (no Host header, or two) or 403 (a name not this server's) and return
        True, or return False for a request that names this server."""
        hosts = self.headers.get_all("Host") or []
        if len(hosts) > 1:
            self._send_bytes(b"one Host header, please\n", "text/plain", send_body,
                             status=HTTPStatus.BAD_REQUEST)
            return True
        host = hosts[0] if hosts else None
        if host is None:
            self._send_bytes(b"a Host header is required\n", "text/plain", send_body,
                             status=HTTPStatus.BAD_REQUEST)
            return True
        if host.strip().lower() not in self.server.allowed_hosts:
            self._send_bytes(b"forbidden: unknown Host\n", "text/plain", send_body,
                             status=HTTPStatus.FORBIDDEN)
            return True
        return False

    def _fail(self, status: HTTPStatus, error: Exception, send_body: bool) -> None:
        """Answer ``status`` with a one-line body, unless an answer has already begun: then
        close the connection, since its headers are out."""
        self.close_connection = True
        if self._started:
            return
        line = f"{status.phrase.lower()}: {type(error).__name__}\n".encode()
        with contextlib.suppress(OSError):
            self._send_bytes(line, "text/plain", send_body, status=status)

    def send_response(self, code, message=None) -> None:
        """As the base class, and remember that an answer has begun."""
        self._started = True
        super().send_response(code, message)

    def _route(self, send_body: bool) -> None:
        """Send what the request's path names."""
        url = urlsplit(self.path)
        path, cache = url.path, _NEVER
        versioned = _VERSIONED.fullmatch(path)
        if versioned and versioned[1] == self.server.tag:
            path, cache = versioned[2], _FOREVER
        if path == "/":
            self._redirect(f"/v/{self.server.tag}/web/index.html"
                           + (f"?{url.query}" if url.query else ""))
        elif path == "/config.json":
            body = json.dumps(self.server.config()).encode()
            self._send_bytes(body, "application/json", send_body)
        elif path == SCENE_PATH and self.server.scene is not None:
            self._send_scene(send_body)
        else:
            found = package_file(path, self.server.package_root)
            if found is None:
                self._send_bytes(b"not found\n", "text/plain", send_body,
                                 status=HTTPStatus.NOT_FOUND)
            else:
                self._send_bytes(found.read_bytes(), CONTENT_TYPES[found.suffix],
                                 send_body, cache=cache)

    def _redirect(self, target: str) -> None:
        self.send_response(HTTPStatus.FOUND)
        self.send_header("Location", target)
        self.send_header("Content-Length", "0")
        self.end_headers()

    def _send_bytes(self, body: bytes, content_type: str, send_body: bool,
                    status: HTTPStatus = HTTPStatus.OK, cache: str = _NEVER) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", cache)
        self.end_headers()
        if send_body:
            self.wfile.write(body)

    def _send_scene(self, send_body: bool) -> None:
        try:
            fh = open(self.server.scene, "rb")  # noqa: SIM115 - closed below
        except OSError:
            self._send_bytes(b"scene file unreadable\n", "text/plain", send_body,
                             status=HTTPStatus.NOT_FOUND)
            return
        with fh:
            size = fh.seek(0, 2)
            wanted = byte_range(self.headers.get("Range"), size)
            if wanted is False:
                self.send_response(HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE)
                self.send_header("Content-Range", f"bytes */{size}")
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            first, last = (0, size - 1) if wanted is None else wanted
            count = max(last - first + 1, 0)
            self.send_response(HTTPStatus.OK if wanted is None else HTTPStatus.PARTIAL_CONTENT)
            self.send_header("Content-Type", "application/octet-stream")
            self.send_header("Accept-Ranges", "bytes")
            self.send_header("Content-Length", str(count))
            self.send_header("Cache-Control", "no-store")
            if wanted is not None:
                self.send_header("Content-Range", f"bytes {first}-{last}/{size}")
            self.end_headers()
            if not send_body:
                return
            self.server.log_range(first, first + count)
            fh.seek(first)
            left = count
            while left > 0:
                block = fh.read(min(_BLOCK, left))
                if not block:
                    break
                self.server.pace(len(block))
                self.wfile.write(block)
                self.server.count_sent(len(block))
                left -= len(block)
