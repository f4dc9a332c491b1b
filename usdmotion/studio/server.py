"""Run the studio: check the roots and the web packages, then serve with uvicorn."""

from __future__ import annotations

import socket
from collections.abc import Sequence
from pathlib import Path

from usdmotion.errors import InputError, UsdMotionError


def check_roots(paths: list[Path]) -> list[Path]:
    """The roots as given, each an existing folder or motion file (``InputError`` otherwise)."""
    from usdmotion.studio.library import MOTION_EXTENSIONS

    for path in paths:
        if not path.exists():
            raise InputError(path, "no such file or folder")
        if path.is_file() and not path.name.lower().endswith(MOTION_EXTENSIONS):
            raise InputError(path, f"not a motion file (use a folder or {', '.join(MOTION_EXTENSIONS)})")
    return paths


def host_names(host: str, extra: Sequence[str] = ()) -> list[str]:
    """The names (``Host`` header, besides IP addresses and ``localhost``) the studio listening on
    ``host`` answers for: that name, or for every address (``0.0.0.0``, ``::``) this machine's name;
    then ``extra`` (``--allow-host``)."""
    names = [socket.gethostname() if host in ("0.0.0.0", "::", "") else host, *extra]
    return list(dict.fromkeys(n.lower().strip("[]") for n in names if n))


def serve(paths: list[Path], host: str, port: int, out: Path, options: dict, open_browser: bool,
          ready=None, allow_hosts: Sequence[str] = ()) -> None:
    """Serve the studio until interrupted; ``options`` are :func:`usdmotion.io.read_motion`
    keywords for every take; ``ready(url)`` is called once it listens; requests naming another host
    than this machine, ``host`` or ``allow_hosts`` are refused (:func:`host_names`)."""
    import uvicorn

    from usdmotion.studio.app import create_app, missing_web_packages

    missing = missing_web_packages()
    if missing:
        raise UsdMotionError(f"the studio's web packages are missing ({', '.join(missing)}): run scripts/setup.sh "
                             "(npm ci in usdmotion/studio/web)")
    app = create_app(check_roots(paths), options, out, hosts=host_names(host, allow_hosts))
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
    try:
        sock.bind((host, port))
    except OSError as exc:
        raise UsdMotionError(f"cannot listen on {host}:{port}: {exc.strerror or exc} (try --port)") from None
    url = f"http://{host if ':' not in host else f'[{host}]'}:{sock.getsockname()[1]}/"
    if ready is not None:
        ready(url)
    if open_browser:
        import webbrowser

        webbrowser.open(url)
    config = uvicorn.Config(app, log_level="warning", limit_concurrency=64, timeout_keep_alive=5,
                            h11_max_incomplete_event_size=16 * 1024)
    uvicorn.Server(config).run(sockets=[sock])
