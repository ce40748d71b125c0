"""`auvreplay view --web`: Rerun's web viewer really serves the file, and only on 127.0.0.1."""

from __future__ import annotations

import os
import re
import socket
import subprocess
import time
import urllib.request
from pathlib import Path

from replay.views import recording as views
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
