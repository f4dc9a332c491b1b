"""Random-request campaign against a running Studio (the CLI's fuzz.py, for the web API).

    python benchmarks/studio_fuzz.py --minutes 5 [--seed 1]

Serves the Studio (uvicorn, 127.0.0.1) over a library of two 120-frame walks and a malformed
BVH, and sends it random GET requests (every read endpoint; take ids valid, missing, outside
the library; joints, quantities and numbers from the plausible to NaN, 1e309 and 2**63) and
random POST bodies (edit previews with random pipelines, joint maps, segment detect / save /
export, edit save; keys from the page's requests with random values, nesting included). A
request is a defect when it gets a 5xx, when a refusal is not one ``{"error": line}``, or when
the server stops answering. The job-starting endpoints (retarget, video) are left out: their
errors come back through the job, which the Studio's tests check. Prints the counts by
endpoint and status, the defects, and writes ``benchmarks/results/studio_fuzz.json``.
"""

from __future__ import annotations

import argparse
import collections
import http.client
import json
import random
import sys
import time
from pathlib import Path
from urllib.parse import urlencode

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import print_table, scratch_folder, write_results  # noqa: E402

WALK = ROOT / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
TAKES = ["0/walk.bvh", "0/walk2.bvh", "0/bad.bvh", "0/../x", "1/walk.bvh", "", "0/nope.bvh", "0/%00",
         "0/" + "a" * 5000, "walk.bvh"]
GETS = ["/api/takes", "/api/meta", "/api/skeleton", "/api/positions", "/api/com", "/api/series", "/api/glb",
        "/api/compare", "/api/edit/groups", "/api/edit/positions", "/api/edit/series", "/api/retarget/positions",
        "/api/retarget/profiles", "/api/segment/signal", "/api/segment/saved", "/api/segment/labels",
        "/api/video/file", "/api/jobs"]
POSTS = ["/api/edit/preview", "/api/retarget/map", "/api/segment/detect", "/api/segment/save", "/api/segment/export",
         "/api/edit/save"]
PARAMS = ["take", "id", "joints", "q", "mode", "offset", "frame", "key", "name", "with", "other", "start", "stop"]
#: Keys of the page's POST bodies (``body.get(...)`` in usdmotion/studio).
KEYS = ["take", "format", "detector", "target", "compare", "traces", "style", "start", "speed", "size", "scale",
        "remove", "profiles", "ops", "offset", "labels", "label", "key", "iterations", "grid", "end", "cuts", "camera",
        "align", "method", "cutoff", "frames", "joint", "stop", "fps"]
OPS = ["equalize", "reorient", "displace", "layer", "blend", "speed", "resample", "cycle", "trim"]
#: Parameters of the edit operations (schemas/edit-pipeline.schema.json).
OP_KEYS = ["gains", "preset", "joint", "subtree", "translations", "rotate", "heading", "position", "translate",
           "keys", "falloff", "frame", "channel", "with", "transition", "at", "offset", "speed0", "speed1", "align",
           "align_joint", "align_channel", "curve", "method", "joint_map", "interp", "factor", "fps", "start", "stop",
           "loops"]
#: Job-starting endpoints (one job at a time) and the options their bodies take.
JOB_POSTS = ["/api/retarget", "/api/video", "/api/retarget/save"]
JOB_OPTIONS = {"method": ["lm", "adam"], "lengths": ["source", "target"], "init": ["auto", "copy", "compose", "aim"],
               "scale": ["units", "height", "1.0", "0.01", "2", "-1", "nan", "inf", "", 0, 1.5],
               "iterations": [0, 1, 5, 20], "remove": [["LeftHand"], "LeftHand,RightHand", ["Hips"]],
               "profiles": [["cmu", "cmu"], ["cmu", "mixamo"], ["nope", "cmu"]],
               "format": ["usda", "usdc", "bvh", "glb", "usdz", "txt"],
               "size": ["320x180"] * 6 + ["640x360"], "camera": ["side", "front", "top", "follow", "orbit"],
               "style": ["body", "stick", "both"], "start": [0, 10, 60, 119, 120], "end": [1, 30, 120],
               "speed": [0.05, 0.5, 1.0, 4], "traces": [["LeftFoot"], ["com"], ["nope"], ["LeftFoot", "com"]],
               "align": ["dtw", "start"], "offset": [0.0, 0.5, -0.5, 100.0], "grid": [True, False]}
NUMBERS = [0, 1, -1, 0.5, 1e309, -1e309, float("nan"), 1e18, -1e18, 2**63, 3, 120, 119, 121, 1e-300, 0.001, "1",
           None, True, [], {}]


class Requests:
    """Random requests from one seed."""

    def __init__(self, seed: int, joints: list[str]) -> None:
        self.rng = random.Random(seed)
        self.joints = [*joints, "", "nope", "Hips,LeftLeg", "," * 50]

    def value(self, depth: int = 0):
        r = self.rng.random()
        if r < 0.4:
            return self.rng.choice(NUMBERS)
        if r < 0.6:
            return self.rng.choice(self.joints + TAKES + ["dtw", "peaks", "none", "smooth", "x" * 3000, "\0", "é"])
        if depth >= 3:
            return None
        if r < 0.8:
            return [self.value(depth + 1) for _ in range(self.rng.randint(0, 4))]
        return {self.rng.choice(KEYS): self.value(depth + 1) for _ in range(self.rng.randint(0, 3))}

    def body(self) -> dict:
        body = {"take": self.rng.choice(TAKES[:3])} if self.rng.random() < 0.9 else {}
        body.update({self.rng.choice(KEYS): self.value() for _ in range(self.rng.randint(0, 5))})
        if self.rng.random() < 0.5:
            body["ops"] = [{"op": self.rng.choice(OPS), **{self.rng.choice(OP_KEYS): self.value()
                                                           for _ in range(self.rng.randint(0, 4))}}
                           for _ in range(self.rng.randint(1, 3))]
        return body

    def job(self, keys: list[str]) -> tuple[str, dict]:
        """A job POST: the endpoint and a body of its options, plausible values mostly and random
        ones (:meth:`value`) now and then; the retarget save's ``key`` is one of ``keys`` (results
        of finished retargets) where there are any."""
        target = self.rng.choice(JOB_POSTS)
        if target == "/api/retarget/save":
            body = {"key": self.rng.choice(keys or ["nope"]), "format": self.rng.choice(JOB_OPTIONS["format"])}
        else:
            body = {"take": self.rng.choice(TAKES[:3]) if self.rng.random() < 0.95 else self.rng.choice(TAKES)}
            other = "target" if target == "/api/retarget" else "compare"
            if self.rng.random() < 0.8:
                body[other] = self.rng.choice(TAKES[:2] if self.rng.random() < 0.9 else TAKES)
            for name, values in JOB_OPTIONS.items():
                if self.rng.random() < 0.3:
                    body[name] = self.rng.choice(values) if self.rng.random() < 0.8 else self.value()
        if target == "/api/video":
            body.setdefault("size", "320x180")  # the page's default (1280x720) takes a minute per take here
        return target, body

    def query(self) -> str:
        pairs = [(self.rng.choice(PARAMS), self.rng.choice([
            self.rng.choice(TAKES), self.rng.choice(self.joints), str(self.rng.choice(NUMBERS)),
            "bend,speed,com_height", "nan", "-1", "9" * 20, "x" * 3000])) for _ in range(self.rng.randint(0, 5))]
        if self.rng.random() < 0.7:
            pairs.append(("take", self.rng.choice(TAKES[:3])))
        return urlencode(pairs)

    def next(self) -> tuple[str, str, bytes | None]:
        if self.rng.random() < 0.5:
            return "GET", f"{self.rng.choice(GETS)}?{self.query()}", None
        return "POST", self.rng.choice(POSTS), json.dumps(self.body()).encode()


def send(host: str, port: int, method: str, target: str, data: bytes | None) -> tuple[int, bytes]:
    conn = http.client.HTTPConnection(host, port, timeout=120)
    try:
        conn.request(method, target, body=data, headers={"Content-Type": "application/json"} if data else {})
        response = conn.getresponse()
        return response.status, response.read()
    finally:
        conn.close()


def refusal_problem(status: int, payload: bytes) -> str | None:
    """Why an answer is a defect (``None``: it is not)."""
    if status >= 500:
        return f"{status}: {payload[:200]!r}"
    if status >= 400:
        try:
            error = json.loads(payload)["error"]
        except (ValueError, KeyError, TypeError):
            return f"{status} without a JSON error: {payload[:200]!r}"
        if not isinstance(error, str) or "\n" in error or "Traceback" in error:
            return f"{status} error is not one line: {error!r:.200}"
    return None


def job_problem(job: dict) -> str | None:
    """Why a finished job (``GET /api/jobs/{id}``) is a defect (``None``: it is not)."""
    if job.get("state") != "failed":
        return None
    error = job.get("error")
    if not isinstance(error, str) or not error.startswith("usdmotion: error: ") or "\n" in error \
            or "Traceback" in error or "internal error" in error:
        return f"job failed with: {error!r:.300}"
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=5.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    from studio_support import serving

    from usdmotion.io import read_motion, write_motion
    from usdmotion.studio.app import create_app

    folder = scratch_folder("studio_fuzz_")
    library = folder / "lib"
    library.mkdir()
    walk = read_motion(WALK, units="asf")
    write_motion(walk.sliced(0, 120), library / "walk.bvh")
    write_motion(walk.sliced(100, 220), library / "walk2.bvh")
    (library / "bad.bvh").write_text("HIERARCHY\nROOT x {\n")
    requests = Requests(args.seed, list(walk.joint_names))
    counts: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    defects: list[dict] = []
    started = time.monotonic()
    with serving(create_app([library], {"units": "asf"}, folder / "out")) as base:
        host, port = base.split("//")[1].split(":")
        running: dict[int, tuple[str, bytes]] = {}  # the one job in flight: id -> its request
        finished_keys: list[str] = []
        jobs: collections.Counter = collections.Counter()
        job_errors: collections.Counter = collections.Counter()  # the lines failed jobs ended with
        ending, polled = started + 60 * args.minutes, 0.0
        while time.monotonic() < ending or (running and time.monotonic() < ending + 120):
            if running and time.monotonic() > polled + 0.25:  # poll the job in flight
                polled = time.monotonic()
                (job_id, (job_target, job_data)), = running.items()
                status, payload = send(host, int(port), "GET", f"/api/jobs/{job_id}", None)
                job = json.loads(payload) if status == 200 else {"state": "gone"}
                if job.get("state") not in ("queued", "running"):
                    del running[job_id]
                    jobs[f"{job_target} {job.get('state')}"] += 1
                    if job.get("error"):
                        job_errors[f"{job_target}: {job['error']}"] += 1
                    if job.get("state") == "done" and (job.get("result") or {}).get("key"):
                        finished_keys.append(job["result"]["key"])
                    problem = job_problem(job)
                    if problem:
                        defects.append({"request": f"POST {job_target}", "body": job_data[:500].decode(),
                                        "found": problem})
                        print(f"DEFECT POST {job_target} {job_data[:300].decode()}: {problem}", flush=True)
            if time.monotonic() >= ending:
                time.sleep(0.05)
                continue
            if not running and requests.rng.random() < 0.01:
                target, body = requests.job(finished_keys)
                method, data = "POST", json.dumps(body).encode()
            else:
                method, target, data = requests.next()
            try:
                status, payload = send(host, int(port), method, target, data)
            except OSError as exc:
                defects.append({"request": f"{method} {target[:200]}", "body": (data or b"")[:500].decode(),
                                "found": f"no answer: {exc}"})
                break
            counts[target.split("?")[0]][status] += 1
            if target in JOB_POSTS and status == 200:
                running[json.loads(payload)["job"]] = (target, data)
            problem = refusal_problem(status, payload)
            if problem:
                defects.append({"request": f"{method} {target[:200]}", "body": (data or b"")[:500].decode(),
                                "found": problem})
                print(f"DEFECT {method} {target[:120]}: {problem}", flush=True)
        for job_id, (job_target, job_data) in running.items():
            defects.append({"request": f"POST {job_target}", "body": job_data[:500].decode(),
                            "found": f"job {job_id} had not ended two minutes after the campaign"})
    seconds = time.monotonic() - started
    statuses = sorted({s for c in counts.values() for s in c})
    rows = [[endpoint, *(counts[endpoint].get(s, 0) for s in statuses)] for endpoint in sorted(counts)]
    total = sum(sum(c.values()) for c in counts.values())
    print_table(f"Studio request fuzz: {total} requests in {seconds:.0f} s (seed {args.seed}), "
                f"{len(defects)} defects", ["endpoint", *map(str, statuses)], rows)
    path = write_results("studio_fuzz", {"seed": args.seed, "minutes": args.minutes, "requests": total,
                                         "counts": {e: dict(c) for e, c in counts.items()}, "jobs": dict(jobs),
                                         "job_errors": dict(job_errors.most_common(50)), "defects": defects[:100]})
    print("jobs: " + (", ".join(f"{k}: {v}" for k, v in sorted(jobs.items())) or "none"))
    print(f"wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
