"""`auvreplay view --web`: Rerun's web viewer really serves the file, and only on 127.0.0.1; the recording is
served over HTTP on 127.0.0.1 and the page opens it by URL."""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

from replay.views import recording as views
from replay.views import web
from tests.processes import end_group
from tests.review_fixtures import synthetic_review

LISTEN = "0A"   # TCP state in /proc/net/tcp


def _group_socket_inodes(pgid: int) -> set[str]:
    """Socket inodes open in any process of a process group (the rerun script runs the viewer binary)."""
    out = set()
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            stat = (proc / "stat").read_text()
            if int(stat.rsplit(")", 1)[1].split()[2]) != pgid:
                continue
            fds = list((proc / "fd").iterdir())
        except (OSError, ValueError, IndexError):
            continue
        for fd in fds:
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith("socket:["):
                out.add(target[8:-1])
    return out


def _listening(pgid: int) -> list[str]:
    """Addresses (ip:port) a process group listens on, over IPv4 and IPv6."""
    inodes, found = _group_socket_inodes(pgid), []
    for table, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[3] != LISTEN or cols[9] not in inodes:
                continue
            hex_ip, hex_port = cols[1].split(":")
            raw = bytes.fromhex(hex_ip)
            if width == 8:
                ip = socket.inet_ntop(socket.AF_INET, raw[::-1])
            else:   # four little-endian 32-bit words
                ip = socket.inet_ntop(socket.AF_INET6, b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4)))
            found.append(f"{ip}:{int(hex_port, 16)}")
    return found


def test_web_viewer_serves_on_loopback_only(tmp_path: Path) -> None:
    rrd = views.save_rrd([synthetic_review(3, n_epochs=20, anfis_epochs=2)], tmp_path / "w.rrd",
                         application_id="auvreplay_web_test")
    cmd = views.viewer_command(rrd, web=True) + ["--port", "0", "--web-viewer-port", "0"]
    log = tmp_path / "web.log"
    env = dict(os.environ, BROWSER="true")      # no browser to open here
    with log.open("w") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env=env, start_new_session=True)
    try:
        url = None
        deadline = time.monotonic() + 60.0
        while url is None and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.3)
            found = re.search(r"Hosting a web-viewer at (http://[^\s]+)", log.read_text(errors="replace"))
            url = found.group(1) if found else None
        assert url is not None, f"the web viewer did not start: {log.read_text(errors='replace')[-2000:]}"
        addresses = _listening(proc.pid)
        assert len(addresses) >= 2, addresses            # the HTTP server and the gRPC proxy
        assert all(a.startswith("127.0.0.1:") for a in addresses), addresses
        assert url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200 and b"<html" in page.read(4096).lower()
    finally:
        end_group(proc)


def test_serve_file_answers_the_viewer_only_on_loopback(tmp_path: Path) -> None:
    data = os.urandom(3 * 1024 * 1024 + 17)          # more than one block of the server's copy loop
    (tmp_path / "r.rrd").write_bytes(data)
    with web.serve_file(tmp_path / "r.rrd", viewer_port=9999) as served:
        assert served.url.startswith("http://127.0.0.1:") and served.url.endswith("/r.rrd")
        with urllib.request.urlopen(served.url, timeout=10) as got:
            assert got.read() == data
            assert got.headers["Access-Control-Allow-Origin"] == "http://127.0.0.1:9999" == served.origin
        base = served.url.rsplit("/", 2)[0]
        for other in ("/r.rrd", "/", served.url.rsplit("/", 1)[0].replace(base, "") + "/other.rrd"):
            try:
                urllib.request.urlopen(base + other, timeout=10)
                raise AssertionError(f"{other} was served")
            except urllib.error.HTTPError as exc:
                assert exc.code == 404
    try:                                              # closed with the block
        urllib.request.urlopen(served.url, timeout=2)
        raise AssertionError("still served")
    except urllib.error.URLError:
        pass


def test_view_web_serves_the_recording_by_url_on_loopback(tmp_path: Path) -> None:
    """`view --web`: the page opens with the recording's URL (it shows its loading at once), both servers on
    127.0.0.1 only, and the URL answers with the file."""
    rrd = views.save_rrd([synthetic_review(3, n_epochs=20, anfis_epochs=2)], tmp_path / "w.rrd",
                         application_id="auvreplay_web_test")
    log = tmp_path / "view.log"
    env = dict(os.environ, BROWSER="true", PYTHONPATH=str(Path(__file__).resolve().parent.parent))
    with log.open("w") as out:
        proc = subprocess.Popen([sys.executable, "-m", "replay.cli", "view", str(rrd), "--web"], stdout=out,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env, start_new_session=True)
    try:
        page = None
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and proc.poll() is None:
            text = log.read_text(errors="replace")
            found = re.search(r"web viewer: (http://127\.0\.0\.1:\d+/\?url=\S+)", text)
            if found and "Hosting a web-viewer" in text:
                page = found.group(1)
                break
            time.sleep(0.3)
        assert page is not None, f"view --web did not start: {log.read_text(errors='replace')[-2000:]}"
        file_url = urllib.parse.unquote(page.split("?url=", 1)[1])
        assert file_url.startswith("http://127.0.0.1:") and file_url.endswith("/w.rrd")
        with urllib.request.urlopen(file_url, timeout=10) as got:
            assert got.read() == rrd.read_bytes()
        with urllib.request.urlopen(page, timeout=10) as got:
            assert got.status == 200 and b"<html" in got.read(4096).lower()
        addresses = _listening(proc.pid)
        assert len(addresses) >= 2, addresses            # our file server and Rerun's web viewer
        assert all(a.startswith("127.0.0.1:") for a in addresses), addresses
    finally:
        end_group(proc)
