"""A saved recording rendered by Rerun's real viewer, headless (software Vulkan), and the picture checked.

Needs Debian's mesa-vulkan-drivers (lavapipe) and libvulkan1; `.ci/run` installs
them. Without a working graphics stack this test FAILS with the reason: it is
never skipped. The viewer listens on 127.0.0.1 only, on a free port, in its own
process group, which the test ends.
"""

from __future__ import annotations

import os
import socket
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from tests.processes import end_group
from tests.review_fixtures import synthetic_review

HINT = ("the headless Rerun viewer needs a Vulkan driver: apt-get install -y mesa-vulkan-drivers libvulkan1 "
        "(software rasterizer lavapipe), and WGPU_BACKEND=vulkan")
WINDOW = (1280, 800)
START_TIMEOUT_S = 60.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _tail(path: Path, n: int = 15) -> str:
    lines = path.read_text(errors="replace").splitlines() if path.exists() else []
    return "\n".join(lines[-n:])


def _connect(proc: subprocess.Popen, port: int, log: Path):
    from rerun.experimental import ViewerClient

    deadline = time.monotonic() + START_TIMEOUT_S
    last: Exception | None = None
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"the headless viewer exited with {proc.returncode}; {HINT}\n{_tail(log)}")
        try:
            client = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy")
            client.get_state()
            return client
        except (ConnectionError, RuntimeError, OSError) as exc:
            last = exc
            time.sleep(0.3)
    pytest.fail(f"no answer from the headless viewer in {START_TIMEOUT_S:.0f} s ({last}); {HINT}\n{_tail(log)}")


def _wait_loaded(client, store_id: str) -> None:
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        state = client.get_state()
        if not state.loading and any(r.store_id == store_id and r.timelines for r in state.recordings):
            return
        time.sleep(0.3)
    pytest.fail(f"the viewer did not finish loading the recording: {client.get_state()}")


@pytest.fixture
def viewer(tmp_path: Path, venv_bin: Path):
    """A headless viewer bound to 127.0.0.1, ended with its process group after the test."""
    exe = venv_bin / "rerun"
    if not exe.exists():
        pytest.fail("the rerun CLI that rerun-sdk installs is missing")
    port, log = _free_port(), tmp_path / "viewer.log"
    env = dict(os.environ, WGPU_BACKEND=os.environ.get("WGPU_BACKEND", "vulkan"))
    with log.open("w") as out:
        proc = subprocess.Popen([str(exe), "--headless", "--bind", "127.0.0.1", "--port", str(port),
                                 "--hide-welcome-screen", "--window-size", f"{WINDOW[0]}x{WINDOW[1]}"],
                                env=env, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=True)
    try:
        yield _connect(proc, port, log), log
    finally:
        end_group(proc)



def _image(path: Path) -> np.ndarray:
    try:
        from PIL import Image
    except ImportError:
        pytest.fail("Pillow is needed to read the screenshot (it comes with matplotlib)")
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), dtype=np.int16)


def test_viewer_renders_the_recording(viewer, tmp_path: Path) -> None:
    from replay.views.recording import save_rrd

    client, log = viewer
    review = synthetic_review(5, n_epochs=50, anfis_epochs=4)
    rrd = save_rrd([review], tmp_path / "shot.rrd", application_id="auvreplay_screenshot_test")
    opened = client.open(str(rrd))
    store = next((s for s in opened.store_ids if s.endswith(":auvreplay:run-a")), None)
    assert store is not None, opened
    _wait_loaded(client, store)
    client.set_time("time", timestamp=(review.trial_start_ns + 90 * 10**9) / 1e9, play_state="paused")
    state = client.get_state()
    names = {v.name for v in state.views}
    assert {"Local east/north (m), range circles, scale bar", "Events"} <= names
    assert any(n.startswith("Map: GPS truth and the focus tracks") for n in names)
    assert [(v.name, v.reports) for v in state.views if v.reports] == []
    shot = tmp_path / "viewer.png"
    client.save_screenshot(str(shot))
    assert shot.exists(), _tail(log)
    img = _image(shot)
    assert img.shape[0] >= WINDOW[1] // 2 and img.shape[1] >= WINDOW[0] // 2
    luminance = img.mean(axis=2)
    assert luminance.std() > 8.0, "the screenshot is blank"
    coloured = (img.max(axis=2) - img.min(axis=2)) > 60
    # tracks, range circles and labels in the method colours, not just the viewer's grey chrome
    assert coloured.mean() > 0.002, f"only {coloured.mean():.4%} coloured pixels"
    assert len(np.unique(img.reshape(-1, 3)[::7], axis=0)) > 200
