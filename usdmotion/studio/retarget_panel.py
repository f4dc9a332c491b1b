"""The Studio's retarget panel: the automatic joint map, retargeting as a job, the result
played over the source with its per-joint error, and Save as USD or BVH.

Everything is :mod:`usdmotion.ops.retarget`, as ``usdmotion retarget`` runs it: the map
comes from :func:`~usdmotion.ops.retarget.prepare` (what could not be mapped included), the
job calls :func:`~usdmotion.ops.retarget.retarget` with the job's progress (cancel stops it
after the current chunk of frames; JAX's persistent compile cache is not switched on, so nothing
is written outside the output folder), and Save as writes the result with the CLI's writer
(:func:`usdmotion.io.write_motion`), so the file holds the numbers ``usdmotion retarget
SOURCE OUT --target TARGET`` writes with the same options.
"""

from __future__ import annotations

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from usdmotion.errors import UsdMotionError, error_line
from usdmotion.studio import takes
from usdmotion.studio.errors import StudioError
from usdmotion.studio.jobs import Kept, json_body, saved, submit_save

#: Retarget results kept for playing and saving.
KEEP_RESULTS = 4
SAVE_FORMATS = ("usda", "usdc", "bvh")
#: Options the page may set, with the values ``usdmotion retarget`` accepts.
CHOICES = {"method": ("lm", "adam"), "lengths": ("source", "target"), "init": ("auto", "copy", "compose", "aim")}


class RetargetPanel:
    def __init__(self, api) -> None:
        self.api = api
        self._results = Kept(KEEP_RESULTS)

    def routes(self) -> list[Route]:
        return [Route("/api/retarget/map", self.joint_map, methods=["POST"]),
                Route("/api/retarget", self.start, methods=["POST"]),
                Route("/api/retarget/positions", self.positions),
                Route("/api/retarget/save", self.save, methods=["POST"]),
                Route("/api/retarget/profiles", self.profiles)]

    def request(self, body: dict) -> tuple:
        """Source and target entries and the retarget keywords of a request body."""
        source = self.api.library.get(body.get("take", ""))
        target = self.api.library.get(body["target"]) if body.get("target") else None
        remove = body.get("remove") or []
        if isinstance(remove, str):
            remove = [n.strip() for n in remove.split(",") if n.strip()]
        if not isinstance(remove, list) or not all(isinstance(n, str) for n in remove):
            raise StudioError(400, "remove must be a list of joint names")
        options = {"remove": remove}
        for name, allowed in CHOICES.items():
            value = body.get(name, allowed[0])
            if value not in allowed:
                raise StudioError(400, f"{name} must be one of {', '.join(allowed)}, got {value!r}")
            options[name] = value
        from usdmotion.ops.retarget.files import parse_scale

        scale = body.get("scale", "units")
        try:
            parse_scale(scale)
        except UsdMotionError as exc:  # RetargetError: the CLI's line, named as the page names the field
            raise StudioError(400, str(exc).replace("--scale", "scale")) from None
        options["scale"] = scale
        iterations = body.get("iterations")
        if iterations is not None and not (isinstance(iterations, int) and 0 <= iterations <= 100_000):
            raise StudioError(400, f"iterations must be an integer in 0..100000, got {iterations!r}")
        options["iterations"] = iterations
        profiles = body.get("profiles")  # [source profile, target profile]: the map goes through them
        options["map"] = None
        if profiles:
            if not (isinstance(profiles, list) and len(profiles) == 2 and all(isinstance(p, str) for p in profiles)):
                raise StudioError(400, "profiles must be [source profile, target profile]")
            from usdmotion.skeleton_names import rig_profiles

            unknown = [p for p in profiles if p not in rig_profiles()]
            if unknown:
                raise StudioError(400, f"profiles: unknown rig profile {unknown[0]!r:.80} "
                                       f"(known: {', '.join(sorted(rig_profiles()))})")
            options["map"] = {"source_profile": profiles[0], "target_profile": profiles[1], "auto": True}
        if target is None and not remove:
            raise StudioError(400, "choose a target take, or joints to remove")
        return source, target, options

    def profiles(self, request: Request) -> Response:
        """The rig profiles a joint map can go through: ``[{name, description}]``."""
        from usdmotion.skeleton_names import rig_profiles

        return JSONResponse({"profiles": [{"name": n, "description": p.get("description", "")}
                                          for n, p in sorted(rig_profiles().items())]})

    def motions(self, source, target):
        src = self.api.compute(source, "motion", None)
        tgt = None if target is None else self.api.compute(target, "motion", None)
        return src, tgt

    def one_line(self, exc: BaseException, *entries) -> StudioError:
        line = error_line(exc)
        for entry in entries:
            if entry is not None:
                line = line.replace(str(entry.path), entry.name)
        return StudioError(422, line)

    async def joint_map(self, request: Request) -> Response:
        """The automatic joint map: ``{how, pairs: [[target, source|null]], unmapped, unused}``."""
        from usdmotion.ops.retarget import prepare
        from usdmotion.ops.retarget.files import parse_scale

        source, target, options = self.request(await json_body(request))

        def compute() -> dict:
            try:
                src, tgt = self.motions(source, target)
                setup = prepare(src, tgt, remove=options["remove"], joint_map=joint_map(options),
                                lengths=options["lengths"],
                                scale=parse_scale(options["scale"]), source_path=str(source.path),
                                target_path=None if target is None else str(target.path))
            except Exception as exc:  # noqa: BLE001 - one line to the page
                raise self.one_line(exc, source, target) from None
            names, ends = setup.rig.joint_names, setup.rig.end_sites
            pairs = [[n, setup.joint_map.pairs.get(n)] for n, e in zip(names, ends) if not e]
            used = {s for _, s in pairs if s}
            return {"how": setup.joint_map.how, "pairs": pairs, "unmapped": [t for t, s in pairs if s is None],
                    "unused": [n for n, e in zip(src.joint_names, src.end_sites) if not e and n not in used]}

        return JSONResponse(await run_in_threadpool(compute))

    async def start(self, request: Request) -> Response:
        """Retarget as a job; its result: ``{key, per_joint_rms, unit, summary, skeleton...}``."""
        import hashlib
        import json

        from usdmotion.ops.retarget import retarget
        from usdmotion.ops.retarget.files import parse_scale

        body = await json_body(request)
        source, target, options = self.request(body)
        key = hashlib.sha1(json.dumps([source.id, source.mtime_ns, None if target is None else target.id, options],
                                      sort_keys=True).encode()).hexdigest()[:16]

        def work(progress, outputs):
            src, tgt = self.motions(source, target)
            progress(0, src.n_frames, "preparing (the first run compiles the solver)")
            result = retarget(src, tgt, remove=options["remove"], joint_map=joint_map(options),
                              method=options["method"],
                              iterations=options["iterations"], lengths=options["lengths"],
                              scale=parse_scale(options["scale"]), init=options["init"], source_path=str(source.path),
                              target_path=None if target is None else str(target.path), progress=progress)
            self._results.put(key, (result, source, target, options))
            rep = result.report
            cm = 100.0 * result.motion.meters_per_unit  # the report is in target units
            return {"key": key, **takes.skeleton(result.motion),
                    "per_joint_rms_cm": {n: v * cm for n, v in rep["per_joint_rms"].items()},
                    "summary": f"{rep['target_joints_without_end_sites']} joints, {rep['frames']} frames; "
                               f"RMS error {rep['loss']['final']['rms'] * cm:.3g} cm per mapped joint"}

        names = {str(source.path): source.name, **({str(target.path): target.name} if target else {})}
        job = self.api.jobs.submit("retarget", [], work, names=names)
        return JSONResponse({"job": job.id})

    def result(self, key: str):
        found = self._results.get(key)
        if found is None:
            raise StudioError(404, "this retarget result is no longer kept: run it again")
        return found

    def positions(self, request: Request) -> Response:
        result = self.result(request.query_params.get("key", ""))[0]
        return Response(takes.view_positions(result.motion).tobytes(), media_type="application/octet-stream")

    async def save(self, request: Request) -> Response:
        """Save as: a job writing the kept result with the CLI's writer (``<stem>.retarget.<ext>``)."""
        from usdmotion.io import write_motion

        body = await json_body(request)
        result, source, target, _ = self.result(str(body.get("key", "")))

        def work(progress, outputs):
            progress(0, 1, f"writing {outputs[0].name}")
            write_motion(result.motion, outputs[0])
            progress(1, 1, "saved")
            return saved(self.api, outputs[0])

        return JSONResponse(submit_save(self.api, "retarget-save", source, "retarget", body.get("format", "usda"),
                                        SAVE_FORMATS, work))


def joint_map(options: dict):
    """The request's joint map (through two rig profiles, the rest automatic), or ``None``: automatic."""
    from usdmotion.ops.retarget.jointmap import joint_map_from_document

    return None if options["map"] is None else joint_map_from_document(options["map"])


def routes(api) -> list[Route]:
    """The retarget panel's routes over ``api``, the app's :class:`usdmotion.studio.app.StudioApi`
    (library, take cache, reading options, output folder, ``jobs``)."""
    return RetargetPanel(api).routes()
