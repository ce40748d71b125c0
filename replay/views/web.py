"""The web viewer, fed over HTTP: the recording is served on 127.0.0.1 and the viewer opens it by URL.

Given a local file, `rerun --web-viewer` streams it to the page through its gRPC proxy, and the page
shows Rerun's welcome screen until the data arrive (about 30 s for the sample trial, with no sign of
progress). Given an HTTP URL instead, Rerun hosts only the viewer, and the page loads the file by its
``?url=`` parameter, saying so with a progress indicator from its first frame. So `view --web` serves
the one file itself, bound to 127.0.0.1, under an unguessable path, readable only by the viewer's own
origin (CORS), and hands its URL to `rerun --web-viewer --bind 127.0.0.1`.
"""

from __future__ import annotations

import os
import secrets
import socket
import threading
import urllib.parse
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

WEB_BIND = "127.0.0.1"
CHUNK = 1 << 20


def free_port(host: str = WEB_BIND) -> int:
    """A TCP port free on `host` now (the OS picks it)."""
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


@dataclass(frozen=True)
class Served:
    """A file being served: its URL and the origin allowed to read it."""

    url: str
    origin: str


def _handler(path: Path, route: str, origin: str) -> type[BaseHTTPRequestHandler]:
    """A request handler that answers GET/HEAD of `route` with the file and 404 for anything else."""

    class Handler(BaseHTTPRequestHandler):
        def _head(self) -> int | None:
            if urllib.parse.urlsplit(self.path).path != route:
                self.send_error(404)
                return None
            size = path.stat().st_size
            self.send_response(200)
            self.send_header("Content-Type", "application/octet-stream")
            self.send_header("Content-Length", str(size))
            self.send_header("Access-Control-Allow-Origin", origin)
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            return size

        def do_HEAD(self) -> None:
            self._head()

        def do_GET(self) -> None:
            if self._head() is None:
                return
            with path.open("rb") as f:
                while block := f.read(CHUNK):
                    try:
                        self.wfile.write(block)
                    except (BrokenPipeError, ConnectionResetError):     # the page was closed
                        return

        def log_message(self, format: str, *args: object) -> None:
            """Quiet: the viewer's own log says what it loads."""

    return Handler


@contextmanager
def serve_file(path: str | os.PathLike[str], viewer_port: int, host: str = WEB_BIND) -> Iterator[Served]:
    """Serve one file over HTTP on `host` (a free port) while the block runs; readable by the web viewer on
    `viewer_port` only."""
    file = Path(path).resolve()
    if not file.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    route = f"/{secrets.token_urlsafe(16)}/{urllib.parse.quote(file.name)}"
    origin = f"http://{host}:{viewer_port}"
    server = ThreadingHTTPServer((host, 0), _handler(file, route, origin))
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, name="rrd-http", daemon=True)
    thread.start()
    try:
        yield Served(f"http://{host}:{server.server_address[1]}{route}", origin)
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5.0)


def web_viewer_command(rerun: str, url: str, viewer_port: int, host: str = WEB_BIND) -> list[str]:
    """The command hosting the web viewer on `host`:`viewer_port` that opens the file at `url`."""
    return [rerun, url, "--web-viewer", "--bind", host, "--web-viewer-port", str(viewer_port)]


def viewer_url(url: str, viewer_port: int, host: str = WEB_BIND) -> str:
    """The page to open: the web viewer with the file's URL as its ``url`` parameter."""
    return f"http://{host}:{viewer_port}/?url={urllib.parse.quote(url, safe='')}"
