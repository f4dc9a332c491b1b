"""The studio's ASGI app (Starlette): the page, its local JavaScript packages, and a JSON/binary API.

Every endpoint takes ids from :class:`~usdmotion.studio.library.Library` and answers 404
for anything that does not resolve inside a root. Reading and analysis run in the
thread pool (sync endpoints); a take that fails answers 422 with its one-line error.
"""

from __future__ import annotations

import asyncio
import math
import stat
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from starlette.applications import Starlette
from starlette.background import BackgroundTask
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from usdmotion.studio import compare, takes
from usdmotion.studio.errors import StudioError
from usdmotion.studio.library import Entry, Library, read_options, take_error_line

WEB = Path(__file__).with_name("web")
NODE_MODULES = WEB / "node_modules"
#: Largest request body accepted (GET requests carry none; a job's parameters are small JSON).
MAX_BODY_BYTES = 64 * 1024
#: Most ids in one metadata request, joints in one series request.
MAX_IDS = 200
#: Host names always accepted (besides IP addresses): a page of another site that a DNS rebinding
#: points at this machine sends its own name in the ``Host`` header, and is refused.
LOCAL_HOSTS = ("localhost",)
#: Longest a linked page's render-blocking stylesheet is held (``/api/hold``), ms.
MAX_HOLD_MS = 10_000.0


def missing_web_packages() -> list[str]:
    """The npm packages the page needs that are not installed (``npm ci`` in ``web/``)."""
    need = {"three": "build/three.module.js", "uplot": "dist/uPlot.esm.js"}
    return [name for name, file in need.items() if not (NODE_MODULES / name / file).is_file()]


class StudioApi:
    """The JSON/binary endpoints, one method each, over one library and its take cache."""

    def __init__(self, library: Library, cache: takes.TakeCache, options: dict, out: Path | None) -> None:
        self.library, self.cache, self.options, self.out = library, cache, options, out

    def routes(self) -> list[Route]:
        return [Route(f"/api/{name}", getattr(self, name.replace("-", "_")))
                for name in ("takes", "meta", "skeleton", "positions", "com", "series", "glb", "compare")]

    def take(self, request: Request, param: str = "take") -> Entry:
        return self.library.get(request.query_params.get(param, ""), f"?{param}")

    def compute(self, entry: Entry, what: str, fn):
        try:
            return self.cache.get(entry, what, fn)
        except Exception as exc:  # noqa: BLE001 - one line to the page, the server keeps running
            raise StudioError(422, take_error_line(entry, exc)) from None

    def prefetch(self, take_id: str | None) -> None:
        """Start computing a linked take's positions (reading the file first) on a thread, when its
        page is asked for: the page's own requests for them come after its HTML, and wait for this
        (the cache computes each value once). A failure is left for those requests to report."""
        entry = self.library.resolve(take_id) if take_id else None
        if entry is not None:
            threading.Thread(target=self.compute_quietly, args=(entry, "positions", takes.view_positions),
                             daemon=True).start()

    def compute_quietly(self, entry: Entry, what: str, fn) -> None:
        try:
            self.compute(entry, what, fn)
        except StudioError:
            pass

    def takes(self, request: Request) -> Response:
        entries = self.library.scan()
        return JSONResponse({"roots": [r.name for r in self.library.roots],
                             "takes": [{"id": e.id, "name": e.name, "size": e.size} for e in entries],
                             "quantities": {k: {"label": v[0], "unit": v[1]} for k, v in takes.QUANTITIES.items()},
                             "read_options": self.options,
                             "out": str(self.out) if self.out else None})

    def meta(self, request: Request) -> Response:
        ids = request.query_params.getlist("id")
        if len(ids) > MAX_IDS:
            raise StudioError(413, f"at most {MAX_IDS} ids per request")
        entries = {take_id: self.library.resolve(take_id) for take_id in ids}
        return JSONResponse({"meta": {take_id: self.library.metadata(e) if e
                                      else {"error": self.library.missing_line(take_id)}
                                      for take_id, e in entries.items()}})

    def skeleton(self, request: Request) -> Response:
        return JSONResponse(self.compute(self.take(request), "skeleton", takes.skeleton))

    def positions(self, request: Request) -> Response:
        return Response(self.compute(self.take(request), "positions", takes.view_positions).tobytes(),
                        media_type="application/octet-stream")

    def com(self, request: Request) -> Response:
        entry = self.take(request)
        kin = self.compute(entry, "analysis", takes.analysis)
        if kin.com is None:
            raise StudioError(404, "no centre of mass for this skeleton (its landmarks were not found)")
        motion = self.cache.motion(entry)
        p = takes.to_view(kin.com * (1.0 if kin.length_unit == "m" else motion.meters_per_unit), motion.up_axis)
        return Response(np.ascontiguousarray(p, dtype=np.float32).tobytes(), media_type="application/octet-stream")

    def series(self, request: Request) -> Response:
        kin = self.compute(self.take(request), "analysis", takes.analysis)
        return JSONResponse(takes.series_query(kin, request.query_params, MAX_IDS))

    def glb(self, request: Request) -> Response:
        from usdmotion.io.gltf import glb_bytes

        entry = self.take(request)
        data = self.compute(entry, "glb",
                            lambda m: cached_glb(entry, self.options, self.out, lambda: glb_bytes(m, mesh=True)))
        return Response(data, media_type="model/gltf-binary")

    def compare(self, request: Request) -> Response:
        """Frame of ``b`` for every frame of ``a`` (``mode`` dtw, or offset by ``offset`` s) and the
        4×4 matrix putting ``b`` on ``a`` at ``frame``."""
        a, b = self.take(request, "a"), self.take(request, "b")
        ma, mb = self.compute(a, "motion", None), self.compute(b, "motion", None)
        mode, offset, frame = _compare_params(request, ma.n_frames)
        try:
            frame_map = (compare.dtw_frame_map(ma, mb) if mode == "dtw" else compare.offset_frame_map(ma, mb, offset))
            align = compare.spatial_alignment(ma, frame, mb, int(round(frame_map[frame])))
        except Exception as exc:  # noqa: BLE001 - the CLI's line (usdmotion blend aligns the same way)
            raise StudioError(422, take_error_line(a, exc).replace(str(b.path), b.name)) from None
        return JSONResponse({"map": np.round(frame_map, 3).tolist(), "frame": frame, "align": align.tolist()})


def _compare_params(request: Request, n_frames: int) -> tuple[str, float, int]:
    mode = request.query_params.get("mode", "dtw")
    try:
        offset = float(request.query_params.get("offset", "0"))
        frame = int(request.query_params.get("frame", "0"))
    except ValueError:
        raise StudioError(400, "offset must be seconds and frame a frame number") from None
    if mode not in ("dtw", "offset") or not np.isfinite(offset):
        raise StudioError(400, "mode must be dtw or offset, offset a finite number of seconds")
    return mode, offset, min(max(frame, 0), n_frames - 1)


def hold_seconds(ms: str) -> float:
    """Seconds ``/api/hold?ms=`` waits: ``ms`` / 1000 within 0 and MAX_HOLD_MS (0 for what is not a number)."""
    try:
        value = float(ms)
    except ValueError:
        return 0.0
    return 0.0 if math.isnan(value) else min(max(value, 0.0), MAX_HOLD_MS) / 1000


def create_app(roots: list[Path], options: dict | None = None, out: Path | None = None,
               hosts: Sequence[str] = ()) -> Starlette:
    """The studio over ``roots``, reading with ``options`` (:func:`usdmotion.io.read_motion`
    keywords); ``out`` is the only folder it may write to (created on first use). It answers only
    requests whose ``Host`` header is an IP address, ``localhost`` or one of ``hosts`` (names, without
    port); any other gets 400 (see :class:`_Guard`)."""
    from usdmotion.studio import edit_panel, jobs, retarget_panel, segment_panel, video_panel

    options = read_options(**(options or {}))
    cache = takes.TakeCache(options)
    out = None if out is None else Path(out).absolute()
    listed = [*roots, out] if out is not None and not _inside_any(out, roots) else roots  # what the studio writes
    api = StudioApi(Library(listed, options, read=cache.motion, skip=[] if out is None else [out / "cache"]),
                    cache, options, out)
    api.jobs = jobs.Jobs(out)

    async def index(request: Request) -> Response:
        # sent from the event loop at once, and only then the linked take's read started: a thread
        # reading a take holds the GIL most of the time, and each hop of a file response to a worker
        # thread waited for it (the page came 30-260 ms after its request, at load 5)
        return Response((WEB / "index.html").read_bytes(), media_type="text/html",
                        headers={"Cache-Control": "no-cache"},
                        background=BackgroundTask(api.prefetch, request.query_params.get("take")))

    async def hold(request: Request) -> Response:
        # a linked page's render-blocking stylesheet (index.html): answered empty after ?ms (at most
        # MAX_HOLD_MS), unless the page removed it first, once its take's first frame was drawn
        await asyncio.sleep(hold_seconds(request.query_params.get("ms", "0")))
        return Response("", media_type="text/css", headers={"Cache-Control": "no-store"})

    routes = [Route("/", index), Route("/api/hold", hold), *api.routes(), *jobs.routes(api.jobs),
              *edit_panel.routes(api), *retarget_panel.routes(api), *video_panel.routes(api),
              *segment_panel.routes(api),
              Mount("/app", _Static(directory=WEB, check_dir=False), name="app"),
              Mount("/vendor/three", _Static(directory=NODE_MODULES / "three", check_dir=False), name="three"),
              Mount("/vendor/uplot", _Static(directory=NODE_MODULES / "uplot", check_dir=False), name="uplot")]
    app = Starlette(routes=routes, exception_handlers={StudioError: _error_response}, lifespan=_stops_jobs(api.jobs))
    app.add_middleware(_Guard, hosts=[*LOCAL_HOSTS, *hosts])
    app.state.api = api
    return app


def _stops_jobs(jobs):
    """The app's lifespan: when the server stops, running jobs are cancelled and waited for."""
    import contextlib

    from starlette.concurrency import run_in_threadpool

    @contextlib.asynccontextmanager
    async def lifespan(app):
        yield
        await run_in_threadpool(jobs.shutdown)

    return lifespan


def _inside_any(path: Path, roots: list[Path]) -> bool:
    path = path.resolve()
    return any(path.is_relative_to(Path(r).resolve()) for r in roots if Path(r).is_dir())


def cached_glb(entry: Entry, options: dict, out: Path | None, make) -> bytes:
    """The take's GLB from ``out/cache/glb`` (keyed by path, size, mtime and reading options), or
    ``make()`` written there atomically. Building the skinned body takes seconds; reopening must not."""
    import hashlib

    from usdmotion.io.atomic import atomic_output

    if out is None:
        return make()
    key = f"{entry.path}|{entry.size}|{entry.mtime_ns}|{sorted(options.items())}|v1"
    path = out / "cache" / "glb" / f"{hashlib.sha1(key.encode()).hexdigest()}.glb"
    if path.is_file():
        return path.read_bytes()
    data = make()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_output(path) as tmp:
            tmp.write_bytes(data)
    except OSError:
        pass  # a read-only or full output folder only loses the cache
    return data


class _Static(StaticFiles):
    """Scripts and styles the browser keeps but checks again on every load (ETag → 304 Not
    Modified): a reload reuses them (and the compiled code) yet never runs a stale app.

    A GET is answered from the event loop in one piece (a stat and a read of a local file of at most
    a few MB): Starlette's file responses hop to a worker thread for the look-up and for every 64 KiB,
    and while the server reads a take (a thread holding the GIL) each hop waited its turn, which made
    three.js (2 MB) arrive late for a linked take's first frame."""

    async def get_response(self, path: str, scope) -> Response:
        if scope["method"] == "GET":
            try:
                full_path, stat_result = self.lookup_path(path)
            except (OSError, ValueError):
                full_path, stat_result = "", None  # Starlette's own answer below (401, 404...)
            if stat_result is not None and stat.S_ISREG(stat_result.st_mode):
                return self.file_response(full_path, stat_result, scope)
        return await super().get_response(path, scope)

    def file_response(self, full_path, stat_result, scope, status_code: int = 200) -> Response:
        response = super().file_response(full_path, stat_result, scope, status_code)
        if scope["method"] == "GET" and isinstance(response, FileResponse):
            try:
                response = Response(Path(full_path).read_bytes(), status_code, headers=dict(response.headers))
            except OSError:
                pass  # gone meanwhile: the file response reports it
        response.headers["cache-control"] = "no-cache"
        return response


async def _error_response(request: Request, exc: StudioError) -> Response:
    return JSONResponse({"error": str(exc)}, status_code=exc.status)


class _Guard:
    """Only requests for this studio by name: a ``Host`` header that is an IP address or one of
    ``hosts`` (else 400: a DNS rebinding cannot read the library through another site's name);
    bounded requests (no body over ``MAX_BODY_BYTES``); only GET/HEAD, except POST (JSON)
    and DELETE on ``/api/`` from the studio's own page (a cross-site ``Origin`` is refused, so
    another web site cannot start jobs); adds a ``Server-Timing`` header with the time the
    server spent on the request."""

    def __init__(self, app, hosts: Sequence[str]) -> None:
        self.app = app
        self.hosts = {h.lower() for h in hosts}

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length", b"0")
        host = _host_name(headers.get(b"host", b""))
        if host not in self.hosts and not _is_ip_address(host):
            return await JSONResponse({"error": f"this studio does not answer for the host {host!r} (see --allow-host)"},
                                      status_code=400)(scope, receive, send)
        if scope["method"] not in ("GET", "HEAD") and not _same_site_api_call(scope, headers):
            return await JSONResponse({"error": "read-only"}, status_code=405)(scope, receive, send)
        if not length.isdigit() or int(length) > MAX_BODY_BYTES:
            return await JSONResponse({"error": "request too large"}, status_code=413)(scope, receive, send)
        if scope["path"].startswith(("/app/node_modules", "/app/package")):  # packages: under /vendor only
            return await JSONResponse({"error": "not found"}, status_code=404)(scope, receive, send)
        start = time.perf_counter()

        async def timed_send(message) -> None:
            if message["type"] == "http.response.start":
                ms = (time.perf_counter() - start) * 1000.0
                message["headers"] = [*message.get("headers", []), (b"server-timing", f"app;dur={ms:.1f}".encode())]
            await send(message)

        await self.app(scope, receive, timed_send)


def _host_name(header: bytes) -> str:
    """The name in a ``Host`` header, lower case, without port or IPv6 brackets."""
    text = header.decode("latin-1").strip().lower()
    if text.startswith("["):
        return text[1:].split("]", 1)[0]
    return text.rsplit(":", 1)[0] if text.count(":") == 1 else text


def _is_ip_address(host: str) -> bool:
    import ipaddress

    try:
        ipaddress.ip_address(host)
    except ValueError:
        return False
    return True


def _same_site_api_call(scope, headers: dict) -> bool:
    """A POST with a JSON body or a DELETE, to ``/api/``, sent by a page of this server (or no browser)."""
    if scope["method"] not in ("POST", "DELETE") or not scope["path"].startswith("/api/"):
        return False
    if scope["method"] == "POST" and not headers.get(b"content-type", b"").startswith(b"application/json"):
        return False
    origin = headers.get(b"origin")
    if origin is None:
        return True
    host = headers.get(b"host", b"")
    return origin.split(b"://", 1)[-1] == host
