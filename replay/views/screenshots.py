"""Screenshots of every tab of the workstation, shot in Rerun's native viewer run headless (`make screenshots`).

    python -m replay.views.screenshots ARCHIVE.mcap OUT_DIR [--times 620,1140,1700] [--size 1400x875]

The archive (a trial, or a replay's results) is replayed in memory with the
default methods (or `--set methods=...`), one recording per tab is saved
with that tab active, and the viewer (software Vulkan, bound to 127.0.0.1)
shoots each at each mission time: `OUT_DIR/<tab>-<time>s.png`. It needs
Debian's mesa-vulkan-drivers and libvulkan1, as `make test` installs.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from replay.errors import UserError
from replay.review.data import ReviewData

START_TIMEOUT_S = 60.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _connect(port: int, proc: subprocess.Popen[bytes]) -> Any:
    """A client of the headless viewer, once it answers; UserError if it exits or stays silent."""
    from rerun.experimental import ViewerClient

    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise UserError(f"the headless viewer exited with {proc.returncode} (does the machine have "
                            "mesa-vulkan-drivers and libvulkan1?)")
        try:
            client = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy")
            client.get_state()
            return client
        except (ConnectionError, RuntimeError, OSError):
            time.sleep(0.3)
    raise UserError(f"no answer from the headless viewer in {START_TIMEOUT_S:.0f} s")


def _wait_loaded(client: Any, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        state = client.get_state()
        if not state.loading and state.recordings:
            return
        time.sleep(0.3)


def tab_names(review: ReviewData) -> list[str]:
    """The names of the workstation's tabs for this run, in screen order."""
    from replay.views.recording import prepare

    _, _, _, blueprint = prepare([review])
    main = list(blueprint.root_container.contents)[0]
    return [str(getattr(tab, "name", "") or i) for i, tab in enumerate(getattr(main, "contents", []))]


def shoot(review: ReviewData, out_dir: Path, times_s: list[float], size: tuple[int, int],
          tabs: set[str] | None = None) -> list[Path]:
    """Every tab of `review` (or those named in `tabs`, lower case) at every mission time, as PNG files in
    `out_dir`; the files written."""
    from replay.views.recording import save_rrd

    out_dir.mkdir(parents=True, exist_ok=True)
    rerun = Path(sys.executable).with_name("rerun")
    port = _free_port()
    env = dict(os.environ, WGPU_BACKEND=os.environ.get("WGPU_BACKEND", "vulkan"))
    with (out_dir / "viewer.log").open("wb") as log:
        proc = subprocess.Popen([str(rerun), "--headless", "--bind", "127.0.0.1", "--port", str(port),
                                 "--hide-welcome-screen", "--window-size", f"{size[0]}x{size[1]}"],
                                env=env, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=True)
    written: list[Path] = []
    try:
        client = _connect(port, proc)
        for i, name in enumerate(tab_names(review)):
            if tabs and name.lower() not in tabs:
                continue
            rrd = save_rrd([review], out_dir / f".tab{i}.rrd", application_id=f"screenshot_{i}", active_tab=i)
            client.open(str(rrd))
            _wait_loaded(client)
            for t in times_s:
                client.set_time("mission_s", sequence=round(t), play_state="paused")
                time.sleep(1.5)      # the viewer draws a few frames before the picture settles
                path = out_dir / f"{i}-{name.lower().replace(' ', '-')}-{t:.0f}s.png"
                client.save_screenshot(str(path))
                written.append(path)
            rrd.unlink()
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    return written


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, replay the archive in memory, shoot every tab."""
    from replay.run.config import load_config
    from replay.run.pipeline import replay_archive

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("archive")
    parser.add_argument("out_dir")
    parser.add_argument("--times", default="620,1140,1700", help="mission seconds, comma-separated")
    parser.add_argument("--size", default="1400x875", help="window size WxH")
    parser.add_argument("--set", action="append", default=[], help="replay configuration key=value")
    parser.add_argument("--tabs", default="", help="only these tabs, comma-separated (default: every tab)")
    args = parser.parse_args(argv)
    try:
        times = [float(t) for t in args.times.split(",") if t.strip()]
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        print("screenshots: --times takes numbers, --size WxH", file=sys.stderr)
        return 2
    try:
        review = replay_archive(args.archive, load_config(overrides=args.set), write_output=False, review=True).review
        tabs = {t.strip().lower() for t in args.tabs.split(",") if t.strip()} or None
        for path in shoot(review, Path(args.out_dir), times, (w, h), tabs):
            print(path)
    except UserError as exc:
        print(f"screenshots: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
