"""``usdmotion batch``: real Dask clusters (a LocalCluster, and a scheduler plus two workers
started as separate processes, one of them killed mid-run) over a temporary library of
shared takes, generated variants and two malformed files.

Every output is compared byte for byte with the single-file command's output for the same
take; catalogue facts are checked against the files themselves (BVH headers, usd-core).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
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
    assert main(["batch", "convert", str(library), str(out), "--workers", "2"]) == 1  # two takes failed
    captured = capsys.readouterr()
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


class _DaskProcesses:
    """A ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1 (no nanny, so a killed
    worker stays dead); everything is killed on exit."""

    def __init__(self, folder: Path, n_workers: int):
        dask = str(Path(sys.executable).parent / "dask")
        self.file = folder / "scheduler.json"
        self.procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                        "--scheduler-file", str(self.file)], stderr=subprocess.DEVNULL)]
        deadline = time.time() + 60
        while not self.file.exists() and time.time() < deadline:
            time.sleep(0.2)
        self.address = json.loads(self.file.read_text())["address"]
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


def test_scheduler_and_two_worker_processes_survive_a_killed_worker(library, tmp_path):
    cluster = _DaskProcesses(tmp_path, 2)
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
        result = run_batch("convert", library, out, params=params, scheduler=cluster.address, on_row=kill_first_worker)
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
