"""The Studio's edits panel: MotionLab edits with a live preview, and Save as.

The page sends a list of operations in the schema of ``usdmotion edit --pipeline``
(``schemas/edit-pipeline.schema.json``; a blend's ``with`` is a library id); the server
validates it with :func:`usdmotion.ops.edit.pipeline.validate_pipeline` and applies it with
:func:`~usdmotion.ops.edit.pipeline.run_pipeline`, the CLI's own code. The edited motion is
kept (a few, by take and operations) and served like a take: skeleton, positions, series.
Save as is a job writing :func:`usdmotion.studio.jobs.output_path` (``<stem>.edit.<ext>``).
"""

from __future__ import annotations

import hashlib
import json

import numpy as np
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from usdmotion.errors import error_line
from usdmotion.studio import takes
from usdmotion.studio.errors import StudioError
from usdmotion.studio.jobs import Kept, json_body, saved, submit_save

#: Edited motions kept for the page (positions and plots are fetched after the preview).
KEEP_PREVIEWS = 6
#: Most equaliser bands offered (band 0: the highest frequencies).
MAX_BANDS = 7
#: Formats Save as writes (the CLI's writers).
SAVE_FORMATS = ("bvh", "usda", "usdc")


def joint_groups(motion) -> list[dict]:
    """Equaliser groups: the whole body, the trunk and each limb (:func:`usdmotion.body_parts.body_groups`),
    each as the pipeline's joint selections ``[{"joint", "subtree"}]`` (whole body: ``[{}]``)."""
    from usdmotion.body_parts import TRUNK, body_groups

    groups = body_groups(motion)
    names = motion.joint_names
    out = [{"name": "body", "label": "whole body", "select": [{}], "joints": [n for n in names]}]
    trunk = [j for j in range(motion.n_joints) if groups[j] == TRUNK and not motion.end_sites[j]]
    if trunk:
        out.append({"name": "trunk", "label": "trunk (pelvis, spine, neck, head)",
                    "select": [{"joint": names[j], "subtree": False} for j in trunk],
                    "joints": [names[j] for j in trunk]})
    for g in sorted(set(groups.tolist()) - {TRUNK, -1}):
        members = np.flatnonzero(groups == g)
        top = int(min(members, key=lambda j: _depth(motion.parents, j)))
        subtree = [names[j] for j in members]
        out.append({"name": names[top], "label": f"{names[top]} (limb)",
                    "select": [{"joint": names[top], "subtree": True}], "joints": subtree})
    return out


def _depth(parents, j: int) -> int:
    d = 0
    while parents[j] >= 0:
        j, d = int(parents[j]), d + 1
    return d


def time_map(original, edited, operations: list[dict]) -> list[float]:
    """Frame of the original shown with each edited frame (the ghost): same time from the
    start, shifted by a trim's start."""
    from usdmotion.ops.edit.pipeline import _frame

    start = 0
    for op in operations:
        if op.get("op") == "trim" and op.get("start") is not None:
            start += _frame(op["start"], original, "start") % max(original.n_frames, 1)
    t = np.arange(edited.n_frames) / edited.fps
    return np.round((t * original.fps + start).clip(0, original.n_frames - 1), 3).tolist()


class EditPanel:
    """Routes of the edits panel over the Studio's API object (library, take cache, jobs)."""

    def __init__(self, api) -> None:
        self.api = api
        self._previews = Kept(KEEP_PREVIEWS)

    def routes(self) -> list[Route]:
        return [Route("/api/edit/groups", self.groups), Route("/api/edit/preview", self.preview, methods=["POST"]),
                Route("/api/edit/positions", self.positions), Route("/api/edit/series", self.series),
                Route("/api/edit/save", self.save, methods=["POST"])]

    def groups(self, request: Request) -> Response:
        from usdmotion.ops.edit.equalize import band_frequencies, max_bands

        entry = self.api.take(request)
        motion = self.api.compute(entry, "motion", None)
        n = min(MAX_BANDS, max_bands(motion.n_frames))
        return JSONResponse({"groups": self.api.compute(entry, "edit_groups", joint_groups),
                             "bands_hz": np.round(band_frequencies(motion.fps, n), 3).tolist()})

    def operations(self, body: dict):
        """The take, its motion and the pipeline of ``body`` (blend ``with``: library id → file)."""
        entry = self.api.library.get(body.get("take", ""))
        ops = body.get("ops")
        if not isinstance(ops, list) or len(ops) > 50:
            raise StudioError(400, "ops must be a list of at most 50 edit operations")
        ops = json.loads(json.dumps(ops))  # a private copy
        others = {}
        for op in ops:
            if isinstance(op, dict) and op.get("op") == "blend" and isinstance(op.get("with"), str):
                other = self.api.library.resolve(op["with"])
                if other is None:
                    raise StudioError(404, f"blend: no take {op['with']!r} in the library")
                others[str(other.path)] = other
                op["with"] = str(other.path)
        return entry, ops, others

    def run(self, entry, ops: list[dict], others: dict):
        """The edited motion (the CLI's pipeline); 422 with the CLI's one line on bad parameters."""
        from pathlib import Path

        from usdmotion.ops.edit.pipeline import run_pipeline, validate_pipeline

        motion = self.api.compute(entry, "motion", None)
        read = lambda path: self.api.compute(others[str(path)], "motion", None)  # noqa: E731
        try:
            validate_pipeline(ops, entry.name)
            return motion, run_pipeline(motion, ops, Path("."), entry.name, read=read)
        except StudioError:
            raise
        except Exception as exc:  # noqa: BLE001 - one line to the page, the server keeps running
            line = error_line(exc)
            for other in [entry, *others.values()]:
                line = line.replace(str(other.path), other.name)
            raise StudioError(422, line) from None

    async def preview(self, request: Request) -> Response:
        body = await json_body(request)
        entry, ops, others = self.operations(body)
        key = hashlib.sha1(json.dumps([entry.id, entry.mtime_ns, ops], sort_keys=True).encode()).hexdigest()[:16]

        def compute() -> dict:
            original, edited = self.run(entry, ops, others)
            self._previews.put(key, (edited, {"entry": entry}))
            return {"key": key, **takes.skeleton(edited), "map": time_map(original, edited, ops)}

        return JSONResponse(await run_in_threadpool(compute))

    def edited(self, request: Request):
        found = self._previews.get(request.query_params.get("key", ""))
        if found is None:
            raise StudioError(404, "this preview is no longer kept: edit again")
        return found

    def cached(self, request: Request, what: str, compute):
        motion, values = self.edited(request)
        if what not in values:
            values[what] = compute(motion)
        return values[what]

    def positions(self, request: Request) -> Response:
        entry = self.edited(request)[1]["entry"]
        original = self.api.compute(entry, "motion", None)
        original_view = self.api.compute(entry, "positions", takes.view_positions)
        positions = self.cached(request, "positions",
                                lambda edited: takes.edited_view_positions(original, original_view, edited))
        return Response(positions.tobytes(), media_type="application/octet-stream")

    def series(self, request: Request) -> Response:
        kin = self.cached(request, "analysis", takes.analysis)
        return JSONResponse(takes.series_query(kin, request.query_params))

    async def save(self, request: Request) -> Response:
        """Save as: a job writing ``<stem>.edit.<format>`` in the output folder; its result
        names the new file and its library id."""
        from usdmotion.io import write_motion

        body = await json_body(request)
        entry, ops, others = self.operations(body)

        def work(progress, outputs):
            progress(0, 2, "editing")
            _, edited = self.run(entry, ops, others)
            progress(1, 2, f"writing {outputs[0].name}")
            write_motion(edited, outputs[0])
            progress(2, 2, "saved")
            return saved(self.api, outputs[0])

        return JSONResponse(submit_save(self.api, "edit", entry, "edit", body.get("format", "bvh"), SAVE_FORMATS, work))


def routes(api) -> list[Route]:
    """The edits panel's routes over ``api``, the app's :class:`usdmotion.studio.app.StudioApi`
    (library, take cache, reading options, output folder, ``jobs``)."""
    return EditPanel(api).routes()
