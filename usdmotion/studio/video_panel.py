"""The Studio's feedback-video panel: the current view rendered to MP4 by the offscreen
renderer (:func:`usdmotion.render.render_motion`, what ``usdmotion render`` runs) as a
job with progress, and the finished file served for download from the output folder.

The page sends its view: camera preset, compare take and time alignment (the ghost: DTW, or
a manual offset in seconds as the renderer's ``frame:N,M``),
joint and centre-of-mass traces, loop range and playback speed; they become
:class:`usdmotion.render.RenderOptions` exactly as the CLI's options do.
"""

from __future__ import annotations

import os
from pathlib import Path

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Route

from usdmotion.studio.errors import StudioError
from usdmotion.studio.jobs import json_body, library_name, saved

#: The Studio's camera modes → the renderer's presets (the user's own orbit has no preset: side).
CAMERAS = {"side": "side", "front": "front", "top": "top", "follow": "follow", "orbit": "side"}
#: Sizes offered (width, height).
SIZES = {"640x360": (640, 360), "1280x720": (1280, 720), "1920x1080": (1920, 1080), "320x180": (320, 180)}
STYLES = ("body", "stick", "both")


def render_options(body: dict, motion, other) -> tuple:
    """``RenderOptions`` of the page's view (400 with one line for a value the page cannot send)."""
    from usdmotion.render import RenderOptions, check_options

    size = body.get("size", "1280x720")
    if not isinstance(size, str) or size not in SIZES:
        raise StudioError(400, f"size must be one of {', '.join(SIZES)}")
    camera = body.get("camera", "side")
    if not isinstance(camera, str) or camera not in CAMERAS:
        raise StudioError(400, f"camera must be one of {', '.join(CAMERAS)}")
    style = body.get("style", "body")
    if style not in STYLES:
        raise StudioError(400, f"style must be one of {', '.join(STYLES)}")
    start, end = body.get("start"), body.get("end")
    for name, value in (("start", start), ("end", end)):
        if value is not None and not (isinstance(value, int) and 0 <= value <= motion.n_frames):
            raise StudioError(400, f"{name} must be a frame in 0..{motion.n_frames}, got {value!r}")
    speed = body.get("speed", 1.0)
    if not isinstance(speed, (int, float)) or not 0.05 <= speed <= 4:
        raise StudioError(400, f"speed must be a number in 0.05..4, got {speed!r}")
    traces = body.get("traces") or []
    if not isinstance(traces, list) or not all(isinstance(t, str) for t in traces) or len(traces) > 8:
        raise StudioError(400, "traces must be a list of at most 8 joint names (or 'com')")
    align = "start"
    if other is not None and body.get("align") == "dtw":
        align = "time"
    elif other is not None:  # the ghost starts ``offset`` s later (earlier when negative), in real time
        offset = body.get("offset", 0)
        if not isinstance(offset, (int, float)) or not abs(offset) < 1e6:
            raise StudioError(400, f"offset must be a number of seconds, got {offset!r}")
        if round(offset * motion.fps) >= motion.n_frames:  # the ghost would start after the take ends
            raise StudioError(400, f"offset must be under the take's {motion.n_frames / motion.fps:.3g} s, got {offset!r}")
        align = (f"frame:{round(offset * motion.fps)},0" if offset >= 0 else
                 f"frame:0,{min(round(-offset * other.fps), other.n_frames - 1)}")
    width, height = SIZES[size]
    options = RenderOptions(width=width, height=height, start=start, end=end, speed=float(speed),
                            camera=CAMERAS[camera], style=style, grid=bool(body.get("grid", True)),
                            traces=tuple(traces), align=align, labels=(body.get("label", ""), body.get("label2", "")))
    from usdmotion.render import output_frames
    from usdmotion.render.traces import check_traces

    try:
        check_options(options)
        check_traces(motion, traces)  # the page's names: refused at once, not as a job that fails
        output_frames(motion, options)  # a start at or after the end
    except Exception as exc:  # noqa: BLE001
        raise StudioError(400, str(exc).splitlines()[0].replace("--trace: ", "traces: ")) from None
    return options


class VideoPanel:
    def __init__(self, api) -> None:
        self.api = api

    def routes(self) -> list[Route]:
        return [Route("/api/video", self.start, methods=["POST"]), Route("/api/video/file", self.file)]

    async def start(self, request: Request) -> Response:
        """Render the view as a job writing ``<stem>.video.mp4``; its result names the file and its download URL."""
        from urllib.parse import quote

        from usdmotion.render import render_motion

        body = await json_body(request)
        entry = self.api.library.get(body.get("take", ""))
        other_entry = self.api.library.get(body["compare"]) if body.get("compare") else None

        def read() -> tuple:  # off the event loop: a long take's first read takes seconds
            motion = self.api.compute(entry, "motion", None)
            other = None if other_entry is None else self.api.compute(other_entry, "motion", None)
            return motion, other, render_options(
                {**body, "label": entry.name, "label2": other_entry.name if other_entry else ""}, motion, other)

        motion, other, options = await run_in_threadpool(read)
        jobs = self.api.jobs
        path = jobs.output_path(library_name(self.api.library, self.api.out, entry), "video", "mp4")

        def work(progress, outputs):
            progress(0, None, "building the body")
            result = render_motion(motion, outputs[0], options, other, progress=progress)
            rel = outputs[0].resolve().relative_to(self.api.out.resolve()).as_posix()
            return {**saved(self.api, outputs[0]), "frames": result.frames,
                    "url": f"/api/video/file?name={quote(rel)}", "size": [options.width, options.height]}

        names = {str(entry.path): entry.name, **({str(other_entry.path): other_entry.name} if other_entry else {})}
        job = jobs.submit("video", [path], work, names=names)
        return JSONResponse({"job": job.id, "output": jobs.shown(path)})

    def file(self, request: Request) -> Response:
        """A video in the output folder, as a download (404 for anything else)."""
        out = self.api.out
        name = request.query_params.get("name", "")
        if out is None or not name or "\0" in name or name.startswith("/") or ".." in name.split("/") \
                or not name.lower().endswith(".mp4"):
            raise StudioError(404, "not found")
        root = out.resolve()
        path = Path(os.path.realpath(root / name))
        if not path.is_relative_to(root) or not path.is_file():
            raise StudioError(404, "not found")
        return FileResponse(path, media_type="video/mp4", filename=path.name)


def routes(api) -> list[Route]:
    """The feedback-video panel's routes over ``api``, the app's :class:`usdmotion.studio.app.StudioApi`
    (library, take cache, reading options, output folder, ``jobs``)."""
    return VideoPanel(api).routes()
