"""The Studio's jobs framework over a real server: progress through the API, cancel, the
one-line error of a failed job, two jobs on one output, a server that keeps answering
while a job runs, and the one naming rule for the files the Studio writes."""

from __future__ import annotations

import http.client
import json
import threading
import time
from urllib.parse import urlsplit

import pytest

from studio_support import WALK, cli_error_line, make_library, serving
from usdmotion.errors import InputError
from usdmotion.io.atomic import atomic_output
from usdmotion.studio.app import StudioError
from usdmotion.studio.jobs import Jobs, output_path


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    """(base URL, library folder, output folder, the server's Jobs)."""
    from usdmotion.studio.app import create_app

    folder = tmp_path_factory.mktemp("jobs")
    lib = make_library(folder)
    app = create_app([lib], {"units": "asf"}, folder / "out")
    with serving(app) as base:
        yield base, lib, folder / "out", app.state.api.jobs


def request(base: str, method: str, target: str, body: dict | None = None, headers: dict | None = None):
    url = urlsplit(base)
    conn = http.client.HTTPConnection(url.hostname, url.port, timeout=30)
    try:
        data = None if body is None else json.dumps(body).encode()
        hdrs = {"Content-Type": "application/json"} if body is not None else {}
        conn.request(method, target, body=data, headers={**hdrs, **(headers or {})})
        response = conn.getresponse()
        data = response.read()
        is_json = response.getheader("content-type", "").startswith("application/json")
        return response.status, json.loads(data) if is_json else data
    finally:
        conn.close()


def wait_state(base: str, job_id: int, states=("done", "failed", "cancelled"), deadline_s: float = 60.0) -> dict:
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        status, job = request(base, "GET", f"/api/jobs/{job_id}")
        assert status == 200
        if job["state"] in states:
            return job
        time.sleep(0.02)
    raise AssertionError(f"job {job_id} did not reach {states}: {job}")


def stepping_work(steps: int, step_s: float, release: threading.Event | None = None):
    """Work that writes its output atomically while reporting ``steps`` steps."""
    def work(progress, outputs):
        with atomic_output(outputs[0]) as tmp:
            tmp.write_text("partial")
            for i in range(steps):
                progress(i, steps, "stepping")
                if release is not None:
                    release.wait(30)
                time.sleep(step_s)
            progress(steps, steps, "stepping")
            tmp.write_text("complete")
        return {"wrote": outputs[0].name}
    return work


def test_progress_and_result_reach_the_api(studio):
    base, _, out, jobs = studio
    target = jobs.output_path("lib/walk.bvh", "test", "txt")
    job = jobs.submit("test", [target], stepping_work(5, 0.05))
    seen = []
    while True:
        _, state = request(base, "GET", f"/api/jobs/{job.id}")
        seen.append(state)
        if state["state"] in ("done", "failed"):
            break
        time.sleep(0.01)
    assert state["state"] == "done" and state["result"] == {"wrote": "walk.test.txt"} and state["error"] is None
    assert target.read_text() == "complete"
    currents = [s["current"] for s in seen if s["state"] == "running"]
    # intermediate reports seen, in order (the last report, 5 of 5, comes before the file is
    # renamed into place, so a poll may also see it while the job still runs)
    assert currents == sorted(currents) and any(0 < c < 5 for c in currents) and max(currents) <= 5
    assert {s["total"] for s in seen if s["state"] == "running" and s["total"]} == {5.0}
    _, listing = request(base, "GET", "/api/jobs")
    assert job.id in [j["id"] for j in listing["jobs"]]


def test_cancel_stops_within_a_step_and_leaves_no_file(studio):
    base, _, out, jobs = studio
    target = jobs.output_path("lib/walk.bvh", "cancel", "txt")
    release = threading.Event()
    job = jobs.submit("test", [target], stepping_work(1000, 0.0, release))
    wait_state(base, job.id, ("running",))
    status, answer = request(base, "DELETE", f"/api/jobs/{job.id}")
    assert status == 200
    at_cancel = job.current
    release.set()  # the work goes on to its next report, which raises
    final = wait_state(base, job.id)
    assert final["state"] == "cancelled" and final["current"] <= at_cancel + 1
    assert not target.exists()
    assert [p.name for p in target.parent.iterdir() if p.name.startswith(".walk")] == []  # no temporary file


def test_a_failed_job_keeps_the_clis_one_line_error_and_no_file(studio):
    base, _, out, jobs = studio
    target = jobs.output_path("lib/walk.bvh", "fail", "txt")

    def work(progress, outputs):
        with atomic_output(outputs[0]) as tmp:
            tmp.write_text("partial")
            raise InputError("walk.bvh", "OFFSET has 2 values, expected 3\nsecond line", line=4)

    job = jobs.submit("test", [target], work)
    final = wait_state(base, job.id)
    assert final["state"] == "failed"
    assert final["error"] == "usdmotion: error: walk.bvh:4: OFFSET has 2 values, expected 3"
    assert not target.exists()
    assert request(base, "GET", "/api/takes")[0] == 200  # the server keeps running


def test_two_jobs_on_one_output_collide_with_one_line(studio):
    base, _, out, jobs = studio
    target = jobs.output_path("lib/walk.bvh", "collide", "txt")
    release = threading.Event()
    first = jobs.submit("test", [target], stepping_work(3, 0.0, release))
    with pytest.raises(StudioError) as caught:
        jobs.submit("test", [target], stepping_work(1, 0.0))
    assert caught.value.status == 409
    assert str(caught.value) == (f"out/lib/walk.collide.txt is already being written by job {first.id} (test); "
                                 "wait for it or cancel it")
    # the naming rule skips the claimed file: a second Save-as gets its own name
    assert jobs.output_path("lib/walk.bvh", "collide", "txt").name == "walk.collide-2.txt"
    release.set()
    assert wait_state(base, first.id)["state"] == "done"
    assert target.read_text() == "complete"


def test_the_server_answers_other_requests_while_a_job_runs(studio):
    base, _, out, jobs = studio
    target = jobs.output_path("lib/walk.bvh", "busy", "txt")
    release = threading.Event()

    def busy(progress, outputs):  # holds a worker thread and the CPU until released
        n = 0
        while not release.is_set():
            n += sum(i * i for i in range(2000))
            progress(0, None, "busy")
        return {"n": n}

    job = jobs.submit("test", [target], busy)
    wait_state(base, job.id, ("running",))
    status, listing = request(base, "GET", "/api/takes")
    assert status == 200 and len(listing["takes"]) == 3
    assert request(base, "GET", "/api/skeleton?take=0/walk.bvh")[0] == 200
    assert request(base, "GET", f"/api/jobs/{job.id}")[1]["state"] == "running"  # answered during the job
    release.set()
    assert wait_state(base, job.id)["state"] == "done"


def test_writes_only_under_the_output_folder(studio, tmp_path):
    base, lib, out, jobs = studio
    with pytest.raises(StudioError, match="writes only under its output folder"):
        jobs.submit("test", [lib / "walk.edit.bvh"], stepping_work(1, 0.0))
    with pytest.raises(StudioError, match="without an output folder"):
        Jobs(None).submit("test", [tmp_path / "x.txt"], stepping_work(1, 0.0))
    with pytest.raises(StudioError, match="not a library name"):
        output_path(out, "../walk.bvh", "edit", "bvh")


def test_output_names_never_overwrite(tmp_path):
    first = output_path(tmp_path, "lab/session 2/walk.bvh", "edit", "bvh")
    assert first == tmp_path / "lab" / "session 2" / "walk.edit.bvh"
    first.write_text("x")
    assert output_path(tmp_path, "lab/session 2/walk.bvh", "edit", "bvh").name == "walk.edit-2.bvh"
    assert output_path(tmp_path, "lab/walk.usda", "retarget", ".usda").name == "walk.retarget.usda"


def test_cross_site_and_non_json_posts_are_refused(studio):
    base = studio[0]
    assert request(base, "DELETE", "/api/jobs/1", headers={"Origin": "http://evil.example"})[0] == 405
    assert request(base, "POST", "/api/jobs", body={}, headers={"Origin": "http://evil.example"})[0] == 405
    assert request(base, "DELETE", "/api/jobs/99999")[0] == 404
    assert request(base, "DELETE", "/api/takes")[0] == 405


def test_a_post_body_nested_deeper_than_json_recurses_is_a_400_and_the_studio_keeps_serving(studio):
    """60 kB of nested arrays (under the 64 kB body limit) once escaped as a RecursionError."""
    url = urlsplit(studio[0])
    conn = http.client.HTTPConnection(url.hostname, url.port, timeout=30)
    try:
        conn.request("POST", "/api/edit/preview", body=b"[" * 30000 + b"]" * 30000,
                     headers={"Content-Type": "application/json"})
        response = conn.getresponse()
        answer = json.loads(response.read())
    finally:
        conn.close()
    assert (response.status, answer) == (400, {"error": "the request body is not JSON"})
    assert request(studio[0], "GET", "/api/takes")[0] == 200


def test_a_full_disk_fails_the_job_with_one_line_and_no_file(studio):
    """The write runs out of space half-way (ENOSPC from the file system, raised where the
    writer writes): the job fails with the atomic writer's one line and leaves nothing."""
    import errno
    import os

    base, _, out, jobs = studio
    target = jobs.output_path("lib/walk.bvh", "full", "txt")

    def work(progress, outputs):
        with atomic_output(outputs[0]) as tmp:
            tmp.write_text("half of it")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    job = jobs.submit("test", [target], work)
    final = wait_state(base, job.id)
    assert final["state"] == "failed"
    assert final["error"] == f"usdmotion: error: {target}: cannot write: No space left on device"
    assert not target.exists() and not list(target.parent.glob(".walk.*"))


def test_a_retarget_of_a_take_that_does_not_read_fails_with_the_clis_line(studio):
    """The retarget job reads its takes on the job's thread: the reader's refusal (the
    Studio's 422, which already is the CLI's line) once came back as ``internal error
    (StudioError: ...)``, found by ``benchmarks/studio_fuzz.py``."""
    base, lib = studio[0], studio[1]
    status, answer = request(base, "POST", "/api/retarget", {"take": "0/broken.bvh", "target": "0/walk.bvh"})
    assert status == 200
    final = wait_state(base, answer["job"])
    assert (final["state"], final["error"]) == ("failed", cli_error_line(lib, "broken.bvh"))
    assert request(base, "GET", "/api/takes")[0] == 200


@pytest.mark.parametrize("field", ["size", "camera", "style"])
def test_a_video_option_the_page_cannot_send_is_a_400_with_one_line(studio, field):
    """An object where the page sends a name once made a 500 (``unhashable type``), found by
    ``benchmarks/studio_fuzz.py``."""
    for value in ({}, [], None, 3, "huge"):
        status, answer = request(studio[0], "POST", "/api/video", {"take": "0/walk.bvh", field: value})
        assert status == 400 and answer["error"].startswith(f"{field} must be one of "), (value, answer)
        assert "\n" not in answer["error"]


def test_a_ghost_offset_past_the_take_is_a_400_before_any_job(studio):
    """An offset past the take's end once started a job that failed with the renderer's
    ``--align frame:N,0`` line, which names an option the page does not have."""
    from usdmotion.io import read_motion

    base = studio[0]
    walk = read_motion(WALK, units="asf")
    seconds = walk.n_frames / walk.fps
    status, answer = request(base, "POST", "/api/video", {"take": "0/walk.bvh", "compare": "0/session2/walk_turned.usda",
                                                          "offset": seconds + 1, "size": "320x180"})
    assert (status, answer) == (400, {"error": f"offset must be under the take's {seconds:.3g} s, got {seconds + 1!r}"})


@pytest.mark.parametrize("view, error", [
    ({"traces": ["LeftFoot", "nope"]}, "traces: no joint named 'nope'"),
    ({"start": 120, "end": 30}, "no frames to render (the motion has {n} frames, range 120:30)"),
    ({"start": "{n}"}, "no frames to render (the motion has {n} frames, range {n}:{n})"),
])
def test_a_video_view_that_cannot_render_is_a_400_before_any_job(studio, view, error):
    """These started a job that failed a moment later (``benchmarks/studio_fuzz.py``)."""
    from usdmotion.io import read_motion

    n = read_motion(WALK, units="asf").n_frames
    view = {k: n if v == "{n}" else v for k, v in view.items()}
    _, listing = request(studio[0], "GET", "/api/jobs")
    status, answer = request(studio[0], "POST", "/api/video", {"take": "0/walk.bvh", "size": "320x180", **view})
    assert (status, answer) == (400, {"error": error.format(n=n)})
    assert request(studio[0], "GET", "/api/jobs")[1] == listing  # no job started


def test_a_retarget_scale_the_cli_would_refuse_is_a_400_with_the_clis_line(studio):
    """``scale`` reached the job unchecked: an object there failed the job with ``internal
    error (TypeError: ...)``, found by ``benchmarks/studio_fuzz.py``. Now the request is
    refused with the CLI's ``--scale`` message, before any job starts."""
    from usdmotion.ops.retarget.files import parse_scale

    for value in ({}, [1], None, True, 10**400, "nan", -1, 0, "tall"):
        status, answer = request(studio[0], "POST", "/api/retarget",
                                 {"take": "0/walk.bvh", "remove": ["LeftHand"], "scale": value})
        with pytest.raises(Exception) as cli:
            parse_scale(value)
        assert (status, answer) == (400, {"error": str(cli.value).replace("--scale", "scale")}), value
        assert answer["error"].startswith("scale must be ")
    assert parse_scale("2") == parse_scale(2) == 2.0 and parse_scale(" Units ") == "units"


def test_an_unknown_rig_profile_is_a_400_naming_the_known_ones(studio):
    from usdmotion.skeleton_names import rig_profiles

    status, answer = request(studio[0], "POST", "/api/retarget",
                             {"take": "0/walk.bvh", "target": "0/walk.bvh", "profiles": ["cmu_cgspeed", "cmu"]})
    assert status == 400 and answer["error"].startswith("profiles: unknown rig profile 'cmu' (known: ")
    assert answer["error"].endswith(f"{', '.join(sorted(rig_profiles()))})")


def test_a_long_job_that_ends_after_many_short_ones_is_kept(tmp_path, monkeypatch):
    """Finished jobs are forgotten oldest-ended first: a retarget that ran while the page saved
    many edits is still there for the page that polls it (it was forgotten first, being the
    oldest started, the moment it ended)."""
    from usdmotion.studio import jobs as jobs_module

    monkeypatch.setattr(jobs_module, "KEEP_FINISHED", 5)
    jobs = Jobs(tmp_path)
    release = threading.Event()
    long_job = jobs.submit("long", [], lambda progress, outputs: {"waited": release.wait(30)})
    short = [jobs.submit("short", [], lambda progress, outputs: {}) for _ in range(8)]
    for job in short:
        job.thread.join(10)
    release.set()
    long_job.thread.join(10)
    later = jobs.submit("short", [], lambda progress, outputs: {})  # a submit forgets the oldest ended
    later.thread.join(10)
    jobs.submit("short", [], lambda progress, outputs: {}).thread.join(10)
    assert jobs.get(long_job.id).result == {"waited": True}
    kept = {job.id for job in jobs.list()}
    # the 5 that ended last and the last submit; the 5 forgotten are shorts that ended before the long one
    assert len(kept) == 6 and len({s.id for s in short} - kept) == 5 and later.id in kept


def test_saved_takes_are_listed_and_an_edit_of_one_is_written_beside_it(tmp_path):
    """The output folder is a root of the library (or inside one: the default ``out/studio``
    under the current folder); a take in it keeps its place there."""
    from usdmotion.studio.app import create_app
    from usdmotion.studio.jobs import library_name

    lib = make_library(tmp_path)
    for out in (tmp_path / "out", lib / "out" / "studio"):
        app = create_app([lib], {"units": "asf"}, out)
        api = app.state.api
        walk = api.library.resolve("0/walk.bvh")
        first = api.jobs.output_path(library_name(api.library, out, walk), "edit", "bvh")
        assert first == out / "lib" / "walk.edit.bvh"
        first.write_bytes((lib / "walk.bvh").read_bytes())
        (out / "cache" / "glb").mkdir(parents=True)
        (out / "cache" / "glb" / "body.glb").write_bytes(b"glTF")  # the body cache is never listed
        listed = {e.path: e for e in api.library.scan()}
        assert first in listed and not [p for p in listed if p.suffix == ".glb"]
        again = api.jobs.output_path(library_name(api.library, out, listed[first]), "edit", "bvh")
        assert again == out / "lib" / "walk.edit.edit.bvh"


def test_stopping_the_server_cancels_running_jobs_and_leaves_no_file(tmp_path):
    from usdmotion.studio.app import create_app

    app = create_app([make_library(tmp_path)], {"units": "asf"}, tmp_path / "out")
    jobs = app.state.api.jobs
    with serving(app) as base:
        target = jobs.output_path("lib/walk.bvh", "stop", "txt")
        job = jobs.submit("test", [target], stepping_work(100_000, 0.001))
        wait_state(base, job.id, ("running",))
    assert job.state == "cancelled" and not job.thread.is_alive()
    assert not target.exists() and not list(target.parent.glob(".walk.*"))
