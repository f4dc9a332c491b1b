"""The studio's ASGI app (Starlette): the page, its local JavaScript packages, and a JSON/binary API.

Every endpoint takes ids from :class:`~usdmotion.studio.library.Library` and answers 404
for anything that does not resolve inside a root. Reading and analysis run in the
thread pool (sync endpoints); a take that fails answers 422 with its one-line error.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from usdmotion.studio import compare, takes
from usdmotion.studio.library import Entry, Library, ReadOptions, error_line

WEB = Path(__file__).with_name("web")
NODE_MODULES = WEB / "node_modules"
#: Largest request body accepted (the API is read-only: GET requests carry none).
MAX_BODY_BYTES = 64 * 1024
#: Most ids in one metadata request, joints in one series request.
MAX_IDS = 200


class StudioError(Exception):
    """An answer other than 200: ``status`` and a one-line message."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def missing_web_packages() -> list[str]:
    """The npm packages the page needs that are not installed (``npm ci`` in ``web/``)."""
    need = {"three": "build/three.module.js", "uplot": "dist/uPlot.esm.js"}
    return [name for name, file in need.items() if not (NODE_MODULES / name / file).is_file()]


def create_app(roots: list[Path], options: ReadOptions = ReadOptions(), out: Path | None = None) -> Starlette:
    """The studio over ``roots``; ``out`` is the only folder it may write to (created on first use)."""
    cache = takes.TakeCache(options)
    library = Library(roots, options, read=cache.motion)

    def take(request: Request, param: str = "take") -> Entry:
        entry = library.resolve(request.query_params.get(param, ""))
        if entry is None:
            raise StudioError(404, "not found")
        return entry

    def compute(entry: Entry, what: str, fn):
        try:
            return cache.get(entry, what, fn)
        except StudioError:
            raise
        except Exception as exc:  # noqa: BLE001 - one line to the page, the server keeps running
            raise StudioError(422, error_line(entry, exc)) from None

    def index(request: Request) -> Response:
        return FileResponse(WEB / "index.html", headers={"Cache-Control": "no-cache"})

    def take_list(request: Request) -> Response:
        entries = library.scan()
        return JSONResponse({"roots": [r.name for r in library.roots],
                             "takes": [{"id": e.id, "name": e.name, "size": e.size} for e in entries],
                             "quantities": {k: {"label": v[0], "unit": v[1]} for k, v in takes.QUANTITIES.items()},
                             "units": options.units, "up_axis": options.up_axis, "out": str(out) if out else None})

    def metadata(request: Request) -> Response:
        ids = request.query_params.getlist("id")
        if len(ids) > MAX_IDS:
            raise StudioError(413, f"at most {MAX_IDS} ids per request")
        meta = {}
        for take_id in ids:
            entry = library.resolve(take_id)
            meta[take_id] = library.metadata(entry) if entry else {"error": "not found"}
        return JSONResponse({"meta": meta})

    def skeleton(request: Request) -> Response:
        return JSONResponse(compute(take(request), "skeleton", takes.skeleton))

    def positions(request: Request) -> Response:
        return Response(compute(take(request), "positions", takes.view_positions).tobytes(),
                        media_type="application/octet-stream")

    def com(request: Request) -> Response:
        entry = take(request)
        kin = compute(entry, "analysis", takes.analysis)
        if kin.com is None:
            raise StudioError(404, "no centre of mass for this skeleton (its landmarks were not found)")
        motion = cache.motion(entry)
        p = takes.to_view(kin.com * (1.0 if kin.length_unit == "m" else motion.meters_per_unit), motion.up_axis)
        return Response(np.ascontiguousarray(p, dtype=np.float32).tobytes(), media_type="application/octet-stream")

    def series(request: Request) -> Response:
        entry = take(request)
        kin = compute(entry, "analysis", takes.analysis)
        joints = [j for j in request.query_params.get("joints", "").split(",") if j][:MAX_IDS]
        quantities = [q for q in request.query_params.get("q", "bend,speed,com_height,com_speed").split(",") if q]
        bad = [j for j in joints if j not in kin.joint_names] + [q for q in quantities if q not in takes.QUANTITIES]
        if bad:
            raise StudioError(400, f"unknown joint or quantity {bad[0]!r}")
        return JSONResponse(takes.series(kin, joints, quantities))

    def glb(request: Request) -> Response:
        entry = take(request)
        try:
            from usdmotion.io.gltf import glb_bytes
        except ImportError:
            raise StudioError(501, "this usdmotion has no GLB writer; showing the stick figure") from None
        data = compute(entry, "glb", lambda m: cached_glb(entry, options, out, lambda: glb_bytes(m, mesh=True)))
        return Response(data, media_type="model/gltf-binary")

    def compare_takes(request: Request) -> Response:
        a, b = take(request, "a"), take(request, "b")
        ma, mb = compute(a, "motion", None), compute(b, "motion", None)
        mode = request.query_params.get("mode", "dtw")
        try:
            offset = float(request.query_params.get("offset", "0"))
            frame = int(request.query_params.get("frame", "0"))
        except ValueError:
            raise StudioError(400, "offset must be seconds and frame a frame number") from None
        if mode not in ("dtw", "offset") or not np.isfinite(offset):
            raise StudioError(400, "mode must be dtw or offset, offset a finite number of seconds")
        frame = min(max(frame, 0), ma.n_frames - 1)
        try:
            frame_map = (compare.dtw_frame_map(ma, mb) if mode == "dtw" else compare.offset_frame_map(ma, mb, offset))
            align = compare.spatial_alignment(ma, frame, mb, int(round(frame_map[frame])))
        except Exception as exc:  # noqa: BLE001
            raise StudioError(422, str(exc).splitlines()[0] if str(exc) else type(exc).__name__) from None
        return JSONResponse({"map": np.round(frame_map, 3).tolist(), "frame": frame, "align": align.tolist()})

    api = [Route("/api/takes", take_list), Route("/api/meta", metadata), Route("/api/skeleton", skeleton),
           Route("/api/positions", positions), Route("/api/com", com), Route("/api/series", series),
           Route("/api/glb", glb), Route("/api/compare", compare_takes)]
    routes = [Route("/", index), *api,
              Mount("/app", StaticFiles(directory=WEB, check_dir=False), name="app"),
              Mount("/vendor/three", StaticFiles(directory=NODE_MODULES / "three", check_dir=False), name="three"),
              Mount("/vendor/uplot", StaticFiles(directory=NODE_MODULES / "uplot", check_dir=False), name="uplot")]
    app = Starlette(routes=routes, exception_handlers={StudioError: _error_response})
    app.add_middleware(_Guard)
    app.state.library = library
    return app


def cached_glb(entry: Entry, options: ReadOptions, out: Path | None, make) -> bytes:
    """The take's GLB from ``out/cache/glb`` (keyed by path, size, mtime and reading options), or
    ``make()`` written there atomically. Building the skinned body takes seconds; reopening must not."""
    import hashlib

    from usdmotion.io.atomic import atomic_output

    if out is None:
        return make()
    key = f"{entry.path}|{entry.size}|{entry.mtime_ns}|{options.units}|{options.up_axis}|v1"
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


async def _error_response(request: Request, exc: StudioError) -> Response:
    return JSONResponse({"error": str(exc)}, status_code=exc.status)


class _Guard:
    """Read-only, bounded requests (GET/HEAD, no body over ``MAX_BODY_BYTES``); adds a
    ``Server-Timing`` header with the time the server spent on the request."""

    def __init__(self, app) -> None:
        self.app = app

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length", b"0")
        if scope["method"] not in ("GET", "HEAD"):
            return await JSONResponse({"error": "read-only"}, status_code=405)(scope, receive, send)
        if not length.isdigit() or int(length) > MAX_BODY_BYTES:
            return await JSONResponse({"error": "request too large"}, status_code=413)(scope, receive, send)
        start = time.perf_counter()

        async def timed_send(message) -> None:
            if message["type"] == "http.response.start":
                ms = (time.perf_counter() - start) * 1000.0
                message["headers"] = [*message.get("headers", []), (b"server-timing", f"app;dur={ms:.1f}".encode())]
            await send(message)

        await self.app(scope, receive, timed_send)
