"""A temporary studio library and a real uvicorn server on a free port (for the studio tests)."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from pathlib import Path

from usdmotion.io import read_motion, write_motion

REPO = Path(__file__).resolve().parents[1]
#: Where the browser tests write their screenshots (the best are committed under docs/studio/).
SHOTS = REPO / "out" / "studio-screenshots"
WALK = REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
#: The second take is the walk from this frame on, turned and moved: DTW must find the
#: shift and the spatial alignment must undo the turn.
SHIFT = 60
TURN_DEG = 90.0
MOVE = (40.0, 0.0, -25.0)  # asf units


def make_library(folder: Path) -> Path:
    """``folder/lib`` with the walk, a second take (walk[SHIFT:] turned and moved, USD),
    one malformed BVH, a sub-folder and a symlink that points out of the library."""
    from usdmotion.ops.edit.trajectory import reorient

    lib = folder / "lib"
    (lib / "session2").mkdir(parents=True)
    walk = read_motion(WALK, units="asf")
    write_motion(walk, lib / "walk.bvh")
    second = reorient(walk.sliced(SHIFT, None), rotate=TURN_DEG, translate=MOVE)
    write_motion(second, lib / "session2" / "walk_turned.usda")
    (lib / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    outside = folder / "outside.bvh"
    outside.write_bytes(WALK.read_bytes())
    (lib / "escape.bvh").symlink_to(outside)
    return lib


def cli_error_line(folder: Path, name: str, units: str = "asf") -> str:
    """What ``usdmotion info NAME --units UNITS``, run in ``folder``, prints for a file it cannot read:
    the one error line the Studio must show for the same take (exit 2, nothing on stdout)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-m", "usdmotion", "info", name, "--units", units], cwd=folder,
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and not proc.stdout, (proc.returncode, proc.stdout, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("usdmotion: error: "), proc.stderr
    return lines[0]


@contextlib.contextmanager
def running_studio(roots: list[Path], units: str | None = "asf", out: Path | None = None):
    """Serve the studio on 127.0.0.1 and a free port; yields the base URL; always stops it."""
    from usdmotion.studio.app import create_app

    with serving(create_app(roots, {"units": units}, out)) as base:
        yield base


@contextlib.contextmanager
def serving(app):
    """Serve ``app`` (uvicorn) on 127.0.0.1 and a free port; yields the base URL; always stops it."""
    import uvicorn

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.02)
    try:
        yield f"http://127.0.0.1:{sock.getsockname()[1]}"
    finally:
        server.should_exit = True
        thread.join(10)
        sock.close()


def raw_get(base: str, target: str, host_header: str | None = None) -> tuple[int, bytes]:
    """GET ``target`` exactly as written (no client-side normalisation of ``..``), with the
    ``Host`` header of ``base`` or ``host_header``."""
    import http.client
    from urllib.parse import urlsplit

    host = urlsplit(base)
    conn = http.client.HTTPConnection(host.hostname, host.port, timeout=60)
    try:
        conn.putrequest("GET", target, skip_accept_encoding=True, skip_host=host_header is not None)
        if host_header is not None:
            conn.putheader("Host", host_header)
        conn.endheaders()
        response = conn.getresponse()
        return response.status, response.read()
    finally:
        conn.close()


def shoot(page, name: str, frame: int | None = None) -> None:
    """A screenshot of the view with the open tool panel (a taller window, so both show)."""
    page.set_viewport_size({"width": 1400, "height": 1350})
    if frame is not None:
        page.evaluate(f"() => window.studio.player.setFrame({frame})")
    page.wait_for_timeout(300)
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / name)
    page.set_viewport_size({"width": 1400, "height": 900})


@contextlib.contextmanager
def studio_with_output(folder: Path, prepare=None):
    """A studio over :func:`make_library` in ``folder`` writing to ``folder/out`` (the tools'
    tests); ``prepare(lib)`` adds takes first. Yields ``(base URL, lib, out)``; skips when the
    web packages are not installed."""
    import pytest

    from usdmotion.studio.app import missing_web_packages

    if missing_web_packages():
        pytest.skip(f"studio web packages missing ({missing_web_packages()}): run scripts/setup.sh")
    lib = make_library(folder)
    if prepare is not None:
        prepare(lib)
    with running_studio([lib], out=folder / "out") as base:
        yield base, lib, folder / "out"
