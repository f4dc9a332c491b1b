"""The Studio's segmentation editor: the bone-angle signal, the detector's cuts, Save and Export.

Everything is the library's: the signal ``Q`` is :func:`usdmotion.ops.segment.detect.bone_angles`
→ :func:`~usdmotion.ops.segment.detect.norm_signal` (the detector's own feature), the cuts come
from :func:`~usdmotion.ops.segment.detect.segment` with the CLI's detector options, Save writes
:func:`~usdmotion.ops.segment.files.write_segments_json` (the document of ``usdmotion segment
--out``, plus the person's segment labels, validated against ``schemas/segments.schema.json``)
and Export is a job running :func:`~usdmotion.ops.segment.files.export_clips` (the clips of
``usdmotion segment --export-clips``). The page only holds the cut frames and names it edits.

Files go to the output folder (:func:`usdmotion.studio.jobs.output_path`):
``<stem>.segments.json`` (``-2``, ``-3``... on later saves) and a folder ``<stem>.clips``
(``-2``...) per export. Opening a take shows its newest saved segments file there, else one
beside the take (``<stem>.segments.json`` or ``<stem>_segments.json``).
"""

from __future__ import annotations

import contextlib
import csv
import glob
import itertools
import json
import math
import os
import threading
from pathlib import Path

import numpy as np
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from usdmotion.errors import error_line
from usdmotion.schemas import json_or_none
from usdmotion.studio.errors import StudioError
from usdmotion.studio.jobs import json_body, library_name, output_path

#: A take longer than this is segmented as a job (progress, cancel) rather than in the request.
LONG_TAKE_FRAMES = 30_000
#: Most cuts the page may send (a 10-minute take cut every second).
MAX_CUTS = 1000
#: Label files read for the names offered (``*.segments*.json``, ``*_segments.json``, ``*segments*.csv``).
MAX_LABEL_FILES = 2000
MAX_LABEL_FILE_BYTES = 1 << 20
#: The detector options of ``usdmotion segment`` the panel offers, with the CLI's defaults.
DETECTOR_DEFAULTS = {"method": "kcpd", "penalty": None, "min_length": 1.0, "refine": True, "param": 0.5,
                     "cutoff": 2.0}
CLIP_FORMATS = ("bvh", "usda", "usdc")


def detector_options(given) -> dict:
    """The detector options of a request (missing ones: the CLI's defaults), checked.

    Raises:
        StudioError: 400 with one line naming the bad option.
    """
    if given is None:
        given = {}
    if not isinstance(given, dict) or set(given) - set(DETECTOR_DEFAULTS):
        raise StudioError(400, f"detector options are {', '.join(DETECTOR_DEFAULTS)}")
    options = {**DETECTOR_DEFAULTS, **{k: v for k, v in given.items() if v is not None or k == "penalty"}}
    if options["method"] not in ("kcpd", "heuristic"):
        raise StudioError(400, f"detector must be kcpd or heuristic, not {str(options['method'])[:40]!r}")
    for key, low, high in (("penalty", 0.0, math.inf), ("min_length", 0.0, math.inf), ("param", None, 1.0),
                           ("cutoff", 0.0, math.inf)):
        value = options[key]
        if value is None and key == "penalty":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise StudioError(400, f"{key.replace('_', ' ')} must be a number, not {str(value)[:40]!r}")
        if (low is None and value < 0) or (low is not None and value <= low) or value > high:
            bounds = "between 0 and 1" if key == "param" else "greater than 0"
            raise StudioError(400, f"{key.replace('_', ' ')} must be {bounds}, not {value:g}")
    if not isinstance(options["refine"], bool):
        raise StudioError(400, "refine must be true or false")
    return options


def detect(motion, options: dict, source: str):
    """The library's :func:`~usdmotion.ops.segment.detect.segment` with the CLI's options."""
    from usdmotion.ops.segment.detect import segment

    return segment(motion, method=options["method"], param=float(options["param"]),
                   cutoff_hz=float(options["cutoff"]),
                   penalty=None if options["penalty"] is None else float(options["penalty"]),
                   min_length_s=float(options["min_length"]), refine=options["refine"], source=source)


def signal(motion, source: str) -> dict:
    """``Q = ‖θ‖`` per frame and its low-passed version (degrees) and the joints of each role."""
    from usdmotion.ops.segment.detect import (DEFAULT_CUTOFF_HZ, angles_from_positions, check_length, lowpass,
                                              norm_signal, role_positions)
    from usdmotion.ops.segment.roles import find_roles

    check_length(motion, source)
    roles = find_roles(motion, source=source)
    q = norm_signal(angles_from_positions(role_positions(motion, roles)))
    filtered = lowpass(q, motion.fps, min(DEFAULT_CUTOFF_HZ, 0.45 * motion.fps))
    return {"fps": motion.fps, "frames": motion.n_frames,
            "q": np.round(np.degrees(q), 3).tolist(), "filtered": np.round(np.degrees(filtered), 3).tolist(),
            "roles": {r: motion.joint_names[j] for r, j in roles.items()}, "job_frames": LONG_TAKE_FRAMES}


def detection_answer(seg) -> dict:
    """What the page gets of a detector run: the segments document and the paper's candidates."""
    return {"doc": seg.to_dict(), "candidates": [] if seg.candidates is None else seg.candidates.tolist()}


def read_labels(path: Path) -> list[str]:
    """Segment names in a saved segments JSON (``segments[].label``) or a label CSV (``label`` column)."""
    try:
        if path.stat().st_size > MAX_LABEL_FILE_BYTES:
            return []
        text = path.read_text(encoding="utf-8")
        if path.suffix.lower() == ".csv":
            rows = csv.DictReader(text.splitlines())
            return [r["label"] for r in rows if isinstance(r.get("label"), str)]
        doc = json_or_none(text)
        segments = doc.get("segments") if isinstance(doc, dict) else None
        return [s["label"] for s in segments or [] if isinstance(s, dict) and isinstance(s.get("label"), str)]
    except (OSError, ValueError, csv.Error):
        return []


def is_label_file(name: str) -> bool:
    low = name.lower()
    return (low.endswith(".json") and (".segments" in low or low.endswith("_segments.json"))) or (
        low.endswith(".csv") and "segments" in low)


class SegmentPanel:
    """Routes of the segmentation editor over the Studio's API object (library, take cache, jobs)."""

    def __init__(self, api) -> None:
        """``api``: the app's :class:`~usdmotion.studio.app.StudioApi` (library, take cache, jobs, out)."""
        self.api = api
        self._labels: dict[tuple[str, int], list[str]] = {}
        self._lock = threading.Lock()

    def routes(self) -> list[Route]:
        return [Route("/api/segment/signal", self.signal), Route("/api/segment/saved", self.saved),
                Route("/api/segment/labels", self.labels),
                Route("/api/segment/detect", self.detect, methods=["POST"]),
                Route("/api/segment/save", self.save, methods=["POST"]),
                Route("/api/segment/export", self.export, methods=["POST"])]

    def entry(self, take_id):
        return self.api.library.get(take_id)

    def compute(self, entry, what: str, fn):
        """``fn(motion)`` cached with the take; a library error is one line naming the take (422)."""
        return self.api.compute(entry, what, fn)

    def signal(self, request: Request) -> Response:
        entry = self.api.take(request)
        return JSONResponse(self.compute(entry, "segment_signal", lambda m: signal(m, entry.name)))

    def segmentation(self, entry, options: dict, in_job: bool = False):
        """The detector run with ``options``, cached with the take. In a job the library's own
        exception propagates (the job prints it as the CLI would); in a request it is a 422 line."""
        key = "segment:" + json.dumps(options, sort_keys=True)
        if in_job:
            return self.api.cache.get(entry, key, lambda m: detect(m, options, entry.name))
        return self.compute(entry, key, lambda m: detect(m, options, entry.name))

    async def detect(self, request: Request) -> Response:
        """The detector's cuts: answered at once, or ``{job}`` for a long take."""
        body = await json_body(request)
        entry = self.entry(body.get("take"))
        options = detector_options(body.get("detector"))
        motion = await run_in_threadpool(self.compute, entry, "motion", None)
        if motion.n_frames <= LONG_TAKE_FRAMES:
            return JSONResponse(detection_answer(await run_in_threadpool(self.segmentation, entry, options)))

        def work(progress, outputs):
            progress(0, None, f"segmenting {entry.name}")
            return detection_answer(self.segmentation(entry, options, in_job=True))

        job = self.api.jobs.submit("segment", [], work, names={str(entry.path): entry.name})
        return JSONResponse({"job": job.id})

    def edited(self, entry, body: dict):
        """The detector run of ``body["detector"]`` with the page's cuts and labels."""
        from usdmotion.ops.segment.files import edited

        cuts, labels = body.get("cuts"), body.get("labels")
        if not isinstance(cuts, list) or len(cuts) > MAX_CUTS:
            raise StudioError(400, f"cuts must be a list of at most {MAX_CUTS} frames")
        if labels is not None and not isinstance(labels, list):
            raise StudioError(400, "labels must be a list of texts, one per segment")
        seg = self.segmentation(entry, detector_options(body.get("detector")))
        try:
            return edited(seg, cuts), labels
        except ValueError as exc:
            raise StudioError(400, f"{entry.name}: {exc}") from None

    async def save(self, request: Request) -> Response:
        """Write the segments JSON of ``usdmotion segment --out`` with the page's cuts and labels."""
        body = await json_body(request)
        entry = self.entry(body.get("take"))
        return JSONResponse(await run_in_threadpool(self._save, entry, body))

    def _save(self, entry, body: dict) -> dict:
        from usdmotion.ops.segment.files import segments_document, write_segments_json
        from usdmotion.schemas import validate

        seg, labels = self.edited(entry, body)
        jobs = self.api.jobs
        path = jobs.output_path(library_name(self.api.library, self.api.out, entry), "segments", "json")
        try:
            doc = validate(segments_document(seg, entry.name, labels=labels), "segments", path.name)
            write_segments_json(seg, path, entry.name, labels=labels)
        except Exception as exc:  # noqa: BLE001 - one line to the page
            raise StudioError(422, error_line(exc).replace(str(path.parent), jobs.shown(path.parent))) from None
        return {"output": jobs.shown(path), "doc": doc}

    async def export(self, request: Request) -> Response:
        """A job writing one clip per segment (the CLI's ``--export-clips``) into a new folder."""
        from usdmotion.ops.segment.files import clip_paths, export_clips

        body = await json_body(request)
        entry = self.entry(body.get("take"))
        fmt = body.get("format", "bvh")
        if fmt not in CLIP_FORMATS:
            raise StudioError(400, f"clip format must be one of {', '.join(CLIP_FORMATS)}")
        seg, _ = await run_in_threadpool(self.edited, entry, body)
        jobs = self.api.jobs
        folder = self.clips_folder(entry)
        stem = Path(entry.name).stem
        paths = clip_paths(seg, folder, stem, fmt, range(len(seg.bounds())))

        def work(progress, outputs):
            motion = self.api.cache.motion(entry)  # read already (the cuts were checked against it)
            try:
                written = export_clips(motion, seg, folder, fmt, stem, progress=progress)
            except BaseException:  # failed or cancelled: no clip and no folder is left
                for path in outputs:
                    path.unlink(missing_ok=True)
                with contextlib.suppress(OSError):
                    folder.rmdir()
                raise
            return {"folder": jobs.shown(folder), "clips": [jobs.shown(p) for p in written],
                    "ids": [self.library_id(p) for p in written]}

        try:
            job = jobs.submit("segment-export", paths, work, names={str(entry.path): entry.name,
                                                                    str(folder): jobs.shown(folder)})
        except BaseException:
            folder.rmdir()
            raise
        return JSONResponse({"job": job.id, "output": jobs.shown(folder)})

    def clips_folder(self, entry) -> Path:
        """A new, empty folder ``<stem>.clips`` (``-2``, ``-3``... if taken) where the take's files go
        (:func:`~usdmotion.studio.jobs.output_path`'s rule), created now so two exports never share it."""
        if self.api.out is None:
            raise StudioError(403, "this studio was started without an output folder (--out): it writes nothing")
        first = output_path(self.api.out, library_name(self.api.library, self.api.out, entry), "clips", "x")
        for n in itertools.count(1):
            folder = first.with_name(f"{Path(entry.name).stem}.clips{'' if n == 1 else f'-{n}'}")
            try:
                folder.mkdir()
                return folder
            except FileExistsError:
                continue
            except OSError as exc:
                raise StudioError(507, f"cannot write in the output folder: {exc.strerror or exc}") from None
        raise AssertionError("unreachable")

    def library_id(self, path: Path) -> str | None:
        path = path.resolve()
        for index, root in enumerate(self.api.library.roots):
            if root.is_dir() and path.is_relative_to(root):
                return f"{index}/{path.relative_to(root).as_posix()}"
        return None

    def saved(self, request: Request) -> Response:
        """The take's newest saved segments file, checked against the schema and the take."""
        entry = self.api.take(request)
        motion = self.compute(entry, "motion", None)
        path = self.saved_path(entry)
        if path is None:
            return JSONResponse({"doc": None, "output": None})
        shown = self.shown(path, entry)
        try:
            doc = load_saved(path, motion, shown)
        except Exception as exc:  # noqa: BLE001 - one line to the page
            raise StudioError(422, error_line(exc).replace(str(path), shown)) from None
        return JSONResponse({"doc": doc, "output": shown})

    def saved_path(self, entry) -> Path | None:
        """The newest ``<stem>.segments*.json`` saved for this take (its ``file`` names it: takes
        ``jump.bvh`` and ``jump.usda`` share a stem), else one beside the take."""
        stem = Path(entry.name).stem
        if self.api.out is not None:
            name = library_name(self.api.library, self.api.out, entry)
            folder = Path(self.api.out).joinpath(*Path(name).parent.parts)
            found = sorted(folder.glob(f"{glob.escape(stem)}.segments*.json"), key=lambda p: p.stat().st_mtime_ns)
            for path in reversed(found):
                if saved_for(path) in (None, entry.name):
                    return path
        for name in (f"{stem}.segments.json", f"{stem}_segments.json"):
            beside = entry.path.with_name(name)
            if beside.is_file():
                return beside
        return None

    def shown(self, path: Path, entry) -> str:
        if self.api.out is not None and path.resolve().is_relative_to(Path(self.api.out).resolve()):
            return self.api.jobs.shown(path.resolve())
        return str(Path(entry.name).with_name(path.name))

    def labels(self, request: Request) -> Response:
        """Segment names already used in the library's saved segments and label files, most used first."""
        counts: dict[str, int] = {}
        for path in self.label_files():
            try:
                key = (str(path), path.stat().st_mtime_ns)
            except OSError:
                continue
            with self._lock:
                names = self._labels.get(key)
            if names is None:
                names = read_labels(path)
                with self._lock:
                    self._labels[key] = names
            for name in names:
                name = " ".join(name.split())
                if name:
                    counts[name] = counts.get(name, 0) + 1
        return JSONResponse({"labels": sorted(counts, key=lambda n: (-counts[n], n.lower()))})

    def label_files(self) -> list[Path]:
        files = []
        for root in self.api.library.roots:
            if root.is_file():
                continue
            for folder, dirs, names in os.walk(root):
                dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d != "cache")
                files += [Path(folder, n) for n in sorted(names) if is_label_file(n)]
                if len(files) >= MAX_LABEL_FILES:
                    return files[:MAX_LABEL_FILES]
        return files


def saved_for(path: Path) -> str | None:
    """The ``file`` a saved segments document names (``None`` if it names none or cannot be read)."""
    try:
        doc = json_or_none(path.read_bytes()) if path.stat().st_size <= MAX_LABEL_FILE_BYTES else None
    except OSError:
        return None
    return doc.get("file") if isinstance(doc, dict) and isinstance(doc.get("file"), str) else None


def load_saved(path: Path, motion, shown: str) -> dict:
    """A saved segments file, valid for ``motion`` (schema, frame count, cuts inside the take)."""
    from usdmotion.errors import InputError
    from usdmotion.schemas import load_document

    doc = load_document(path, "segments")
    if doc["frames"] != motion.n_frames:
        raise InputError(shown, f"segments of a {doc['frames']}-frame take; this take has {motion.n_frames} frames")
    cuts = doc["cuts"]
    if any(b <= a for a, b in zip(cuts, cuts[1:])) or (cuts and cuts[-1] >= motion.n_frames):
        raise InputError(shown, f"/cuts: must increase and stay below {motion.n_frames} frames")
    return doc


def routes(api) -> list[Route]:
    return SegmentPanel(api).routes()
