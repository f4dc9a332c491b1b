"""``usdmotion batch``: real Dask clusters (a LocalCluster, and a scheduler plus two workers
started as separate processes, one of them killed mid-run) over a temporary library of
shared takes, generated variants and two malformed files.

Every output is compared byte for byte with the single-file command's output for the same
take; catalogue facts are checked against the files themselves (BVH headers, usd-core).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from usdmotion.batch import run_batch
from usdmotion.cli import main
from usdmotion.io import read_motion, write_motion

SHARED_TAKES = ("cmu/cgspeed_12_01_walk.bvh", "cmu/max_jumping_jacks_30fps.bvh", "edge_cases/bvhanim_test_simple.bvh",
                "edge_cases/pybvh_bvh_example_mixed_orders_zup.bvh", "bandai1/dataset-1_kick_normal_001.bvh")
#: The bundled walk (no ../shared needed).
WALK = Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
MALFORMED = {"broken/truncated.bvh": "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n",
             "broken/bad_number.bvh": "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xrotation Yrotation "
                                      "Zrotation\n  End Site\n  {\n    OFFSET 0 1 0\n  }\n}\nMOTION\nFrames: 2\n"
                                      "Frame Time: 0.1\n0 0 0\n0 zero 0\n"}


@pytest.fixture(scope="module")
def library(tmp_path_factory, request) -> Path:
    """A motion library: shared takes in subfolders, trimmed and renamed variants, a USD take,
    and two malformed BVH files."""
    from conftest import shared_path

    src = tmp_path_factory.mktemp("library")
    for rel in SHARED_TAKES:
        path = shared_path(rel)
        (src / "session1" / Path(rel).parent).mkdir(parents=True, exist_ok=True)
        shutil.copy(path, src / "session1" / rel)
    walk = read_motion(src / "session1" / SHARED_TAKES[0])
    (src / "session2" / "trimmed").mkdir(parents=True)
    for i, (start, stop) in enumerate(((0, 100), (100, 300), (300, None))):
        write_motion(walk.sliced(start, stop), src / "session2" / "trimmed" / f"walk_part{i}.bvh")
    shutil.copy(src / "session1" / SHARED_TAKES[1], src / "session2" / "jacks renamed.bvh")
    write_motion(walk.sliced(0, 60), src / "session2" / "walk_head.usda")
    for rel, text in MALFORMED.items():
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / rel).write_text(text)
    (src / "notes.txt").write_text("not a motion")
    return src


def _motion_files(src: Path) -> list[Path]:
    return sorted(p for p in src.rglob("*") if p.suffix in (".bvh", ".usda"))


def _bvh_header_counts(path: Path) -> tuple[int, int]:
    """(joints, frames) straight from a BVH file's text: ROOT/JOINT lines and 'Frames:'."""
    text = path.read_text()
    joints = len(re.findall(r"^\s*(ROOT|JOINT)\s", text, re.M))
    return joints, int(re.search(r"^Frames:\s*(\d+)", text, re.M).group(1))


def _catalogue(out: Path):
    import pandas as pd

    return pd.read_parquet(out / "catalogue.parquet")


def _no_temporaries(out: Path) -> None:
    assert not [p for p in out.rglob(".*") if ".tmp" in p.name]


def test_local_cluster_convert_catalogue_and_resume(library, tmp_path, capsys):
    out = tmp_path / "out"
    with socket.socket() as dashboard:  # Dask's default dashboard port taken (another cluster's): no warning
        with contextlib.suppress(OSError):  # taken already
            dashboard.bind(("", 8787))
            dashboard.listen()
        assert main(["batch", "convert", str(library), str(out), "--workers", "2"]) == 1  # two takes failed
    captured = capsys.readouterr()
    assert "8787" not in captured.err and "warn" not in captured.err.lower()
    files = _motion_files(library)
    assert f"batch convert: {len(files)} takes: {len(files) - 2} done, 0 up to date, 2 failed" in captured.out
    assert f"usdmotion: error: {library / 'broken/truncated.bvh'}:" in captured.err
    assert f"usdmotion: error: {library / 'broken/bad_number.bvh'}:15:3: 'zero' is not a number" in captured.err
    assert "Traceback" not in captured.err

    cat = _catalogue(out).set_index("relpath")
    assert sorted(cat.index) == sorted(p.relative_to(library).as_posix() for p in files)
    assert set(cat.index[cat.status == "error"]) == set(MALFORMED)
    assert cat.loc["broken/bad_number.bvh", "error"].startswith(str(library / "broken/bad_number.bvh"))
    from pxr import Usd, UsdSkel

    for rel, row in cat[cat.status == "ok"].iterrows():
        src, dst = library / rel, out / Path(rel).with_suffix(".usdc")
        assert row.outputs.tolist() == [str(dst)] and row.sha256 and row.size_bytes == src.stat().st_size
        if src.suffix == ".bvh":
            assert (row.joints, row.frames) == _bvh_header_counts(src)
        stage = Usd.Stage.Open(str(dst))  # usd-core reads what the batch wrote
        anim = next(UsdSkel.Animation(p) for p in stage.Traverse() if p.IsA(UsdSkel.Animation))
        assert len(anim.GetRotationsAttr().GetTimeSamples()) == row.frames
        assert len(anim.GetJointsAttr().Get()) == row.joints + row.end_sites
    assert cat.loc["session1/cmu/cgspeed_12_01_walk.bvh", "rig_family"] == "cmu_cgspeed"
    _no_temporaries(out)

    for rel in ("session1/cmu/cgspeed_12_01_walk.bvh", "session2/walk_head.usda"):  # byte-identical to `convert`
        single = tmp_path / "single" / Path(rel).with_suffix(".usdc").name
        single.parent.mkdir(exist_ok=True)
        assert main(["convert", str(library / rel), str(single)]) == 0
        assert single.read_bytes() == (out / Path(rel).with_suffix(".usdc")).read_bytes()

    mtimes = {p: p.stat().st_mtime_ns for p in out.rglob("*.usdc")}
    again = run_batch("convert", library, out, params={"to": "usdc", "mesh": False}, workers=1)
    assert sorted(r["relpath"] for r in again.rows) == sorted(MALFORMED)  # no ok take redone
    assert again.skipped == len(files) - 2
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.usdc")} == mtimes
    touched = library / "session2" / "jacks renamed.bvh"
    before = touched.stat()
    os.utime(touched, (time.time() + 5, time.time() + 5))
    try:
        third = run_batch("convert", library, out, params={"to": "usdc", "mesh": False}, workers=1,
                          include=("session2/*.bvh",))
    finally:  # the library is shared by the module's tests: a source from the future would look edited to them
        os.utime(touched, ns=(before.st_atime_ns, before.st_mtime_ns))
    assert [r["relpath"] for r in third.rows] == ["session2/jacks renamed.bvh"]
    assert len(_catalogue(out)) == len(files)


def test_local_cluster_analyze_frames_dataset(library, tmp_path):
    import pandas as pd

    out = tmp_path / "out"
    include = ("session1/**/*.bvh",)
    reports = []
    result = run_batch("analyze", library, out, workers=2, include=include,
                       progress=lambda done, total, message: reports.append((done, total, message)))
    assert not result.failed and len(result.rows) == len(SHARED_TAKES)
    n = len(SHARED_TAKES)  # usdmotion.progress.Progress: (takes done, takes to run, what finished last)
    assert reports[0] == (0, n, "batch analyze")
    assert [r[:2] for r in reports[1:]] == [(k, n) for k in range(1, n + 1)]
    assert sorted(r[2] for r in reports[1:]) == sorted(f"batch analyze: {row['relpath']}" for row in result.rows)
    cat = _catalogue(out).set_index("take")
    frames = pd.read_parquet(out / "frames")  # hive-partitioned by take, read directly
    assert set(frames["take"].unique()) == set(cat.index)
    for take, row in cat.iterrows():
        table = frames[frames["take"] == take]
        summary = json.loads((out / Path(row.relpath).with_suffix(".summary.json")).read_text())
        joint_rows = table[table["joint"].isin(list(summary["joints"]))]
        assert len(joint_rows) == row.frames * len(summary["joints"])
        assert row.peak_joint_speed == pytest.approx(joint_rows["speed"].max(), rel=1e-5)
        best = joint_rows.loc[joint_rows["speed"].idxmax()]
        assert row.peak_joint_speed_joint == best["joint"]
        if summary["com"] is not None:
            assert row.com_vertical_range == pytest.approx(summary["com"]["vertical"]["range"])

    rel = "session1/cmu/max_jumping_jacks_30fps.bvh"  # byte-identical to `analyze --summary --out`
    single = tmp_path / "single"
    single.mkdir()
    assert main(["analyze", str(library / rel), "--summary", str(single / "s.json"),
                 "--out", str(single / "f.parquet")]) == 0
    assert (single / "s.json").read_bytes() == (out / Path(rel).with_suffix(".summary.json")).read_bytes()
    part = out / "frames" / "take=session1__cmu__max_jumping_jacks_30fps.bvh" / "part-0.parquet"
    assert (single / "f.parquet").read_bytes() == part.read_bytes()


def test_bad_arguments_exit_2(tmp_path, capsys):
    assert main(["batch", "convert", str(tmp_path / "missing"), str(tmp_path / "out")]) == 2
    assert "source folder does not exist" in capsys.readouterr().err
    assert main(["batch", "convert", str(tmp_path), str(tmp_path / "out"), "--to", "fbx"]) == 2
    assert main(["batch", "convert", str(tmp_path), str(tmp_path / "out"), "--to", "bvh", "--mesh"]) == 2
    assert not (tmp_path / "out").exists()


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("usdmotion: error: ") and "Traceback" not in err, err
    return lines[0]


def test_an_output_folder_that_is_or_holds_the_source_folder_is_refused(tmp_path, capsys):
    """OUT == SRC once ran 0 takes with exit 0 (every take was skipped as output); OUT above SRC
    ran 0 takes too, or with --to bvh would have put one take's output on another take."""
    src = tmp_path / "lib" / "session"
    (src / "sub").mkdir(parents=True)
    shutil.copy(WALK, src / "a.bvh")
    shutil.copy(WALK, src / "sub" / "a.bvh")
    before = sorted(p for p in tmp_path.rglob("*"))
    for out, word in ((src, "is"), (tmp_path / "lib", "contains"), (tmp_path, "contains")):
        assert main(["batch", "convert", str(src), str(out), "--to", "bvh"]) == 2
        line = _one_error_line(capsys.readouterr().err)
        assert line == (f"usdmotion: error: {out}: the output folder {word} the source folder: choose one outside "
                        "the source tree (or inside it: it is then skipped)")
    assert sorted(p for p in tmp_path.rglob("*")) == before


@pytest.mark.parametrize("address", ["garbage", "tcp://", "http://127.0.0.1:8786", "tls://127.0.0.1:1"])
def test_a_scheduler_address_dask_refuses_is_one_line(tmp_path, capsys, address):
    """Dask's own refusals came out without the address (``missing port number in address
    'garbage'``) or, for tls://, as an internal error (a TypeError)."""
    shutil.copy(WALK, tmp_path / "a.bvh")
    assert main(["batch", "convert", str(tmp_path), str(tmp_path / "out"), "--scheduler", address]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith(f"usdmotion: error: {address}: not a Dask scheduler address like tcp://HOST:8786 (Dask: ")
    assert not (tmp_path / "out").exists()


def test_a_render_size_out_of_range_is_refused_before_any_take(tmp_path, capsys):
    """It was a failed row per take (exit 1) after the cluster had started."""
    shutil.copy(WALK, tmp_path / "a.bvh")
    assert main(["batch", "render", str(tmp_path), str(tmp_path / "out"), "--size", "8x8"]) == 2
    assert _one_error_line(capsys.readouterr().err) == "usdmotion: error: image size 8x8 is outside 16..8192"
    assert not (tmp_path / "out").exists()


def test_a_library_without_takes_says_so(tmp_path, capsys):
    shutil.copy(WALK, tmp_path / "a.bvh")
    assert main(["batch", "convert", str(tmp_path), str(tmp_path / "out"), "--include", "**/*.glb"]) == 0
    err = capsys.readouterr().err
    assert f"usdmotion: warning: {tmp_path}: no takes found (include: **/*.glb): nothing to do" in err
    assert not (tmp_path / "out").exists()


class _DaskProcesses:
    """A ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1 (no nanny, so a killed
    worker stays dead); everything is killed on exit. ``scheduler_env``: extra environment of
    the scheduler (Dask settings as ``DASK_...`` variables)."""

    def __init__(self, folder: Path, n_workers: int, scheduler_env: dict | None = None):
        dask = str(Path(sys.executable).parent / "dask")
        self.file = folder / "scheduler.json"
        self.procs: list[subprocess.Popen] = []
        try:
            self._start(dask, n_workers, scheduler_env)
        except BaseException:  # nothing left running when the cluster does not come up
            self.close()
            raise

    def _start(self, dask: str, n_workers: int, scheduler_env: dict | None) -> None:
        self.procs += [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                        "--scheduler-file", str(self.file)], stderr=subprocess.DEVNULL,
                                       env={**os.environ, **(scheduler_env or {})})]
        deadline = time.time() + 60
        while time.time() < deadline and not self.file.exists():
            time.sleep(0.2)
        while True:  # the scheduler may not have finished writing it
            try:
                self.address = json.loads(self.file.read_text())["address"]
                break
            except (json.JSONDecodeError, KeyError):
                if time.time() > deadline:
                    raise
                time.sleep(0.2)
        self.workers = [subprocess.Popen([dask, "worker", self.address, "--nthreads", "1", "--no-nanny",
                                          "--no-dashboard", "--name", f"w{i}"], stderr=subprocess.DEVNULL)
                        for i in range(n_workers)]
        self.procs += self.workers
        from distributed import Client

        with Client(self.address, timeout="30s") as client:
            client.wait_for_workers(n_workers, timeout=60)
            self.by_address = {addr: self.workers[int(w["name"][1:])]
                               for addr, w in client.scheduler_info(n_workers=-1)["workers"].items()}

    def close(self) -> None:
        for proc in reversed(self.procs):
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=30)


@pytest.mark.parametrize("allowed_failures", [None, 0], ids=["scheduler-reruns", "batch-splits"])
def test_scheduler_and_two_worker_processes_survive_a_killed_worker(library, tmp_path, allowed_failures):
    """The killed worker's task is re-run by the scheduler (Dask's default), or, when the
    scheduler gives up on it at once (``allowed-failures: 0``), fails as a whole and the batch
    re-submits its takes one per task: either way every take is done once, correctly."""
    env = {} if allowed_failures is None else {"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": str(allowed_failures)}
    cluster = _DaskProcesses(tmp_path, 2, env)
    try:
        out = tmp_path / "out"
        killed = threading.Event()

        victim = []

        def kill_first_worker(row: dict) -> None:  # the worker of the first finished take, mid-run
            if not killed.is_set():
                killed.set()
                victim.append(cluster.by_address[row["worker"]])
                victim[0].send_signal(signal.SIGKILL)

        params = {"to": "usda", "mesh": False}
        result = run_batch("convert", library, out, params=params, scheduler=cluster.address, on_row=kill_first_worker,
                           task_bytes=10 << 20)  # groups of ≥ 640 kB (task_bytes / 16): 3 tasks of several takes
        assert sorted(r["relpath"] for r in result.rows) == sorted(p.relative_to(library).as_posix()
                                                                  for p in _motion_files(library)), \
            [(r["relpath"], r["worker"], r["status"], r["error"]) for r in result.rows]  # each once
        assert killed.is_set() and victim[0].wait(timeout=30) == -signal.SIGKILL
        assert len(result.rows) == len(_motion_files(library))  # every take finished
        assert sorted(r["relpath"] for r in result.failed) == sorted(MALFORMED)
        assert len({r["worker"] for r in result.rows}) == 2  # the killed worker's take stays in the catalogue
        _no_temporaries(out)
        for row in result.rows:
            if row["status"] != "ok":
                continue
            single = tmp_path / "single" / Path(row["relpath"]).with_suffix(".usda")
            single.parent.mkdir(parents=True, exist_ok=True)
            assert main(["convert", row["source"], str(single)]) == 0
            assert single.read_bytes() == Path(row["outputs"][0]).read_bytes(), row["relpath"]

        again = run_batch("convert", library, out, params=params, scheduler=cluster.address)
        assert sorted(r["relpath"] for r in again.rows) == sorted(MALFORMED)  # zero ok takes redone
    finally:
        cluster.close()


def test_glb_segment_and_render_on_one_cluster(library, tmp_path):
    """Convert to GLB, segment (with clips) and render on one LocalCluster, byte-identical to the single-file
    commands (retarget's path is the same but its JAX compile is too slow for this suite)."""
    from usdmotion.batch.engine import dask_client

    take = library / "session2/trimmed/walk_part1.bvh"
    out, single = tmp_path / "out", tmp_path / "single"
    single.mkdir()
    with dask_client(2) as client:
        glb = run_batch("convert", library, out, params={"to": "glb"}, include=("session2/*.usda",), client=client)
        seg = run_batch("segment", library, out, params={"export_clips": True},
                        include=("session2/trimmed/walk_part[12].bvh",), client=client)
        ren = run_batch("render", library, out, include=("session2/walk_head.usda",), client=client)
    for result in (glb, seg, ren):
        assert not result.failed, [r["error"] for r in result.failed]
    assert len(seg.rows) == 2

    assert main(["segment", str(take), "--out", str(single / "s.json"), "--export-clips", str(single / "clips")]) == 0
    assert (single / "s.json").read_bytes() == (out / "session2/trimmed/walk_part1.segments.json").read_bytes()
    clips = sorted((out / "session2/trimmed/walk_part1_clips").iterdir())
    assert [c.name for c in clips] == sorted(c.name for c in (single / "clips").iterdir()) and clips
    assert all(c.read_bytes() == (single / "clips" / c.name).read_bytes() for c in clips)

    head = library / "session2/walk_head.usda"
    assert main(["convert", str(head), str(single / "walk_head.glb")]) == 0  # the file stores its name
    assert (single / "walk_head.glb").read_bytes() == (out / "session2/walk_head.glb").read_bytes()
    assert main(["render", str(head), str(single / "v.mp4"), "--size", "640x360"]) == 0
    assert (single / "v.mp4").read_bytes() == (out / "session2/walk_head.mp4").read_bytes()


def test_ctrl_c_leaves_complete_outputs_and_a_consistent_catalogue(library, tmp_path):
    """SIGINT to ``usdmotion batch convert`` mid-run: exit 130, no temporary files, every ok
    catalogue row's output complete (usd-core opens it); the next run does only the rest."""
    from pxr import Usd

    out = tmp_path / "out"
    cmd = [str(Path(sys.executable).parent / "usdmotion"), "batch", "convert", str(library), str(out), "--workers", "1"]
    # its own process group, signalled as a whole: what a terminal's Ctrl-C does (the Dask
    # workers get it too, and must neither print a traceback nor leave partial files)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.time() + 120
    while not list(out.rglob("*.usdc")) and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert err.strip().splitlines()[-1] == "usdmotion: error: interrupted; no partial output was kept", err
    _no_temporaries(out)
    cat = _catalogue(out)
    done = cat[cat.status == "ok"]
    assert len(done) < len(_motion_files(library)) - 2  # interrupted (a take whose row had not arrived is redone)
    written = sorted(out.rglob("*.usdc"))
    for path in written:
        assert Usd.Stage.Open(str(path)).GetPrimAtPath("/").IsValid()
    assert {str(p) for p in written} >= {o for outs in done.outputs for o in outs}

    rest = run_batch("convert", library, out, workers=1)
    assert rest.skipped == len(done) and len(rest.rows) == len(_motion_files(library)) - len(done)
    assert sum(r["status"] == "ok" for r in rest.rows) + len(done) == len(_motion_files(library)) - 2


def test_group_jobs_sizes_and_order(library, tmp_path):
    """Groups keep every take once, in order; none over the byte budget unless one take is; they
    shrink towards the end; ``task_bytes=0`` gives one take per task."""
    from usdmotion.batch.plan import group_jobs, plan_jobs

    jobs = plan_jobs("convert", library, tmp_path / "out", {}, {})
    sizes = {job.take: (library / job.relpath).stat().st_size for job in jobs}
    budget = sum(sizes.values()) // 3
    groups = group_jobs(jobs, 1, budget)
    assert [job for group in groups for job in group] == jobs
    assert all(len(g) == 1 or sum(sizes[j.take] for j in g) <= budget for g in groups)
    assert 1 < len(groups) < len(jobs) and len(groups[-1]) <= len(groups[0])
    assert [len(g) for g in group_jobs(jobs, 2, 0)] == [1] * len(jobs)
    assert group_jobs([], 2, budget) == []


def test_retarget_batch_matches_the_single_file_command(tmp_path, monkeypatch, shared_file):
    """Two short takes retargeted onto a rig with other bone lengths by one worker (JAX compiles
    once there; the second take reuses it), outputs byte-identical to ``usdmotion retarget``'s
    and reports equal but for their timings. A 4-joint rig and the on-disk compilation cache
    (written by the worker, read by this process) keep the JAX compiles short."""
    monkeypatch.setenv("USDMOTION_JAX_CACHE", str(tmp_path / "jax"))  # inherited by the workers
    source = shared_file("edge_cases/fairmotion_sinusoidal_no_end_site.bvh")
    src, single = tmp_path / "takes", tmp_path / "single"
    src.mkdir(), single.mkdir()
    motion = read_motion(source)
    for start in (0, 60):
        write_motion(motion.sliced(start, start + 40), src / f"wave{start}.bvh")
    target = tmp_path / "other_lengths.bvh"  # same joint names, other bone lengths
    target.write_text(source.read_text().replace("OFFSET 0.0 5.0 0.0", "OFFSET 0.0 6.5 0.0")
                      .replace("OFFSET -5.0 0.0 0.0", "OFFSET -3.5 0.0 0.0"))
    out = tmp_path / "out"
    assert main(["batch", "retarget", str(src), str(out), "--target", str(target), "--to", "usda",
                 "--workers", "1"]) == 0
    cat = _catalogue(out)
    assert list(cat.status) == ["ok", "ok"] and cat.worker.nunique() == 1
    for name in ("wave0", "wave60"):
        assert main(["retarget", str(src / f"{name}.bvh"), str(single / f"{name}.usda"), "--target", str(target),
                     "--report", str(single / f"{name}.json")]) == 0
        assert (single / f"{name}.usda").read_bytes() == (out / f"{name}.usda").read_bytes()
        batch_report, own = (json.loads(p.read_text()) for p in (out / f"{name}.retarget.json", single / f"{name}.json"))
        for report in (batch_report, own):
            del report["time_s"], report["frames_per_second_solve"]
        assert batch_report == own
        assert own["frames"] == 40 and own["target_joints"] == 4
        assert read_motion(out / f"{name}.usda").n_frames == 40


def test_a_redone_task_removes_only_its_takes_temporaries(tmp_path):
    """What a killed worker leaves beside an output, atomic_output's temporary and the one
    usd-core writes beside that before renaming it, is removed when the take is redone;
    another take's temporaries and other files are kept."""
    from usdmotion.batch.plan import Job
    from usdmotion.batch.tasks import _remove_stale_temporaries

    stale = [".walk_part0.39rojb7m.tmp.usda", ".walk_part0.39rojb7m.tmp.jIIXun"]
    kept = [".walk.v2.39rojb7m.tmp.usda", ".walk_part0.39rojb7m.tmp.usdc", ".walk_part0.39rojb7m.tmp.usda.keep",
            "walk_part0.usda"]
    for name in stale + kept:
        (tmp_path / name).write_text("partial")
    jobs = tuple(Job("convert", stem, f"/src/{stem}.bvh", f"{stem}.bvh", {"motion": str(tmp_path / f"{stem}.usda")},
                     {}, {}) for stem in ("walk_part0", "walk"))
    _remove_stale_temporaries(jobs)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(kept)


def test_asf_amc_takes_are_found_and_named_like_the_studio_names_them(tmp_path, shared_file):
    """An ``.amc`` take (its skeleton the ``.asf`` beside it) is a take of the default batch, its
    catalogue rig family is the Studio library's (CMU's ASF/AMC skeletons: ``cmu_asf``), and its output
    is byte-identical to ``usdmotion convert``'s."""
    from usdmotion.studio.library import describe_take

    asf, amc = shared_file("cmu86/86.asf"), shared_file("cmu86/86_01.amc")
    src, out = tmp_path / "src" / "s86", tmp_path / "out"
    src.mkdir(parents=True)
    shutil.copy(asf, src / "86.asf")
    lines = amc.read_text().splitlines(keepends=True)
    stop = lines.index("41\n")  # the header and frames 1-40 (an AMC frame starts with its number)
    (src / "86_01.amc").write_text("".join(lines[:stop]))
    assert main(["batch", "convert", str(src.parent), str(out), "--workers", "1"]) == 0
    cat = _catalogue(out)
    assert list(cat.relpath) == ["s86/86_01.amc"] and list(cat.status) == ["ok"]  # the .asf is no take
    studio = describe_take(src / "86_01.amc", lambda entry: read_motion(entry))["rig"]
    assert cat.rig_family[0] == studio == "cmu_asf"
    assert cat.frames[0] == 40
    assert main(["convert", str(src / "86_01.amc"), str(tmp_path / "86_01.usdc")]) == 0
    assert (tmp_path / "86_01.usdc").read_bytes() == (out / "s86/86_01.usdc").read_bytes()


def test_default_search_finds_what_the_globs_find(library, tmp_path):
    """The one-walk search for the default globs gives pathlib's answer for the same globs:
    symlinked files in, symlinked folders not entered, a file linked from the output folder
    out, upper-case suffixes and folders named like takes out, the output folder inside the
    source skipped."""
    from usdmotion.batch.plan import DEFAULT_INCLUDE, MOTION_SUFFIXES, find_sources

    src = tmp_path / "src"
    shutil.copytree(library, src)
    out = src / "out"
    (out / "s").mkdir(parents=True)
    (out / "s" / "old.bvh").write_text("written by an earlier run")
    (src / "link.bvh").symlink_to(src / "session2" / "jacks renamed.bvh")
    (src / "linked_out.bvh").symlink_to(out / "s" / "old.bvh")
    (src / "linked_folder").symlink_to(src / "session2", target_is_directory=True)
    (src / "UPPER.BVH").write_text("x")
    (src / "folder.bvh").mkdir()
    (src / ".hidden.bvh").write_text("x")

    def by_globs(exclude: Path | None) -> list[Path]:  # the general path: pathlib's glob per pattern
        found = {p for pattern in DEFAULT_INCLUDE for p in src.glob(pattern)}
        return sorted(p for p in found if p.is_file() and p.suffix.lower() in MOTION_SUFFIXES
                      and (exclude is None or not p.resolve().is_relative_to(exclude.resolve())))

    for exclude in (out, None, tmp_path / "elsewhere"):
        assert find_sources(src, DEFAULT_INCLUDE, exclude) == by_globs(exclude)
    names = {p.name for p in find_sources(src, DEFAULT_INCLUDE, out)}
    assert {"link.bvh", ".hidden.bvh"} <= names and not names & {"linked_out.bvh", "old.bvh", "UPPER.BVH"}
    assert find_sources(src, ("**/*.usda",), out) == [src / "session2" / "walk_head.usda"]
