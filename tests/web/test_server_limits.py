"""The viewer's server holds no thread for a client that says nothing, serves a bounded
number of connections at once, and wants exactly one Host header (issue #52, item 13)."""

from __future__ import annotations

import socket
import time

from csgs_codec.web.server import ViewerServer


def _connect(server) -> socket.socket:
    host, port = server.server_address[:2]
    sock = socket.create_connection((host, port), timeout=10)
    return sock


def _closed_within(sock: socket.socket, seconds: float) -> bool:
    """Whether the server closes ``sock`` (recv gives b'') within ``seconds``."""
    sock.settimeout(seconds)
    try:
        return sock.recv(1) == b""
    except TimeoutError:
        return False
    except ConnectionResetError:
        return True


def test_a_silent_connection_is_closed_after_the_timeout():
    with ViewerServer(None, connection_timeout=0.3) as server, _connect(server) as sock:
        start = time.monotonic()
        assert _closed_within(sock, 10)
        assert time.monotonic() - start < 5


def test_a_connection_over_the_limit_is_closed_and_a_freed_slot_serves_again():
    with ViewerServer(None, connection_timeout=10, max_connections=1) as server:
        first = _connect(server)
        time.sleep(0.2)  # the first is accepted and holds the only slot
        with _connect(server) as second:
            assert _closed_within(second, 5)
        first.close()
        deadline = time.monotonic() + 5
        answer = b""
        while time.monotonic() < deadline and not answer.startswith(b"HTTP/1.1 200"):
            with _connect(server) as third:
                host, port = server.server_address[:2]
                third.sendall(f"GET /config.json HTTP/1.1\r\nHost: {host}:{port}\r\n"
                              "Connection: close\r\n\r\n".encode())
                third.settimeout(5)
                try:
                    answer = third.recv(64)
                except (TimeoutError, ConnectionResetError):
                    answer = b""
            time.sleep(0.05)
        assert answer.startswith(b"HTTP/1.1 200")


def test_two_host_headers_get_400():
    with ViewerServer(None) as server:
        host, port = server.server_address[:2]
        with _connect(server) as sock:
            sock.sendall(f"GET /config.json HTTP/1.1\r\nHost: {host}:{port}\r\n"
                         f"Host: evil.example:{port}\r\nConnection: close\r\n\r\n".encode())
            assert sock.recv(64).startswith(b"HTTP/1.1 400")
