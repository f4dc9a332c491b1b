"""The Studio's segmentation editor, against a real server and in Debian's Chromium (Playwright).

* the API is the library's: the timeline's signal is the detector's own feature, the cuts are
  ``segment()``'s, Save writes the document of ``usdmotion segment --out`` (schema-valid, with the
  names), Export writes byte for byte the clips of ``usdmotion segment --export-clips``;
* Must-show 1 and 2 of issue 14 in the browser on CMU 86_01 (skipped where ``../shared/data`` is
  missing): drag, add, delete, name, save, export (FK of each clip's first frame = the source's);
  and cuts moved to the labelled boundaries score 100 % under ``usdmotion segment-eval --cuts``;
* the panel's errors (a take without arms, bad detector options, a saved file that does not
  validate, an output that cannot be written) are one line in the page and the server keeps running.

Screenshots go to ``out/studio-screenshots/`` (``segment*.png``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import shared_path
from studio_support import REPO, WALK, running_studio
from test_studio_browser import CHROMIUM, address, browser, page  # noqa: F401 - fixtures: Debian's Chromium, a page
from test_studio_jobs import request, wait_state
from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions

needs_chromium = pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="Debian's chromium is not installed "
                                    "(scripts/setup.sh installs it)")
SHOTS = REPO / "out" / "studio-screenshots"
TAKE_86 = "86_01_from_amc_cgspeed_layout.bvh"
ID_86 = f"0/{TAKE_86}"


def legs_only_bvh(frames: int = 240) -> str:
    """A pelvis with two legs and no arms or spine (nothing to segment with), walking in place."""
    joints = [("ROOT", "Hips", "0 0 0"), ("JOINT", "LeftUpLeg", "10 0 0"), ("JOINT", "LeftLeg", "0 -45 0"),
              ("End", "", "0 -45 0"), ("JOINT", "RightUpLeg", "-10 0 0"), ("JOINT", "RightLeg", "0 -45 0"),
              ("End", "", "0 -45 0")]
    lines, depth = ["HIERARCHY"], 0
    for kind, name, offset in joints:
        if kind == "JOINT" and name.startswith("Right"):
            while depth > 1:
                depth -= 1
                lines.append("  " * depth + "}")
        pad = "  " * depth
        lines += [f"{pad}{kind} {name}".rstrip() if kind != "End" else f"{pad}End Site", f"{pad}{{",
                  f"{pad}  OFFSET {offset}"]
        if kind != "End":
            lines.append(f"{pad}  CHANNELS {'6 Xposition Yposition Zposition' if kind == 'ROOT' else '3'} "
                         "Zrotation Xrotation Yrotation")
        depth += 1
        if kind == "End":
            depth -= 1
            lines.append(f"{pad}}}")
    while depth > 0:
        depth -= 1
        lines.append("  " * depth + "}")
    t = np.arange(frames) / 120.0
    swing = 30 * np.sin(2 * np.pi * t)
    rows = np.zeros((frames, 6 + 4 * 3))
    rows[:, 1] = 90
    rows[:, 7], rows[:, 13] = swing, -swing
    lines += ["MOTION", f"Frames: {frames}", "Frame Time: 0.0083333333"]
    lines += [" ".join(f"{v:.4f}" for v in row) for row in rows]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------- servers


@pytest.fixture(scope="module")
def studio86(tmp_path_factory):
    """A studio over the shared CMU 86 folder (86_01 and its labels) writing to a temporary folder."""
    from usdmotion.studio.app import missing_web_packages

    shared_path(f"cmu86/{TAKE_86}")
    if missing_web_packages():
        pytest.skip(f"studio web packages missing ({missing_web_packages()}): run scripts/setup.sh")
    out = tmp_path_factory.mktemp("seg86") / "out"
    root = shared_path(f"cmu86/{TAKE_86}").parent
    with running_studio([root], out=out) as base:
        yield base, root, out


@pytest.fixture(scope="module")
def studio_errors(tmp_path_factory):
    """A studio over the bundled walk, a take without arms and the walk with a broken saved segments
    file beside it; its output folder cannot hold the library's files (a file is in the way)."""
    folder = tmp_path_factory.mktemp("segerr")
    lib = folder / "lib"
    lib.mkdir()
    (lib / "walk.bvh").write_bytes(WALK.read_bytes())
    (lib / "legs.bvh").write_text(legs_only_bvh())
    (lib / "walk2.bvh").write_bytes(WALK.read_bytes())
    (lib / "walk2.segments.json").write_text(json.dumps({"method": "kcpd", "fps": 120, "frames": 524,
                                                         "cuts": ["200"], "segments": []}))
    (lib / "walk3.bvh").write_bytes(WALK.read_bytes())
    from usdmotion.cli import main

    assert main(["segment", str(lib / "walk3.bvh"), "--units", "asf", "--method", "heuristic",
                 "--out", str(lib / "walk3_segments.json")]) == 0
    out = folder / "out"
    out.mkdir()
    (out / "lib").write_text("a file where the studio's folder for this library should go\n")
    with running_studio([lib], out=out) as base:
        yield base, lib, out


def open_editor(page, base: str, take_id: str, wait_cuts: bool = True) -> None:
    page.goto(f"{base}/?take={take_id}&f=0")
    page.wait_for_selector('body[data-loaded="1"]', state="attached", timeout=60_000)
    page.click("#segment-panel summary")
    if wait_cuts:
        page.wait_for_function("document.querySelector('#seg-status').textContent.includes('cuts') || "
                               "document.querySelector('#seg-status').textContent.includes('saved')", timeout=60_000)


def page_cuts(page) -> list[int]:
    return [int(f) for f in page.locator("#seg-timeline .seg-cut").evaluate_all("hs => hs.map(h => h.dataset.frame)")]


def handle_x(page, frame: int) -> tuple[float, float]:
    """Screen position (page pixels) on the timeline of ``frame``: x of the frame, y mid-height."""
    return tuple(page.evaluate("""f => { const s = window.studio.segments, r = s.chart.over.getBoundingClientRect();
        return [r.left + s.xOfFrame(f), r.top + r.height / 2]; }""", frame))


def select_cut(page, frame: int) -> None:
    x, y = handle_x(page, frame)
    page.mouse.click(x, y)
    assert page.input_value("#seg-cut-frame") == str(frame)


def set_cut(page, frame: int, to: int) -> None:
    """Select the cut at ``frame`` and type its new frame (the precise way to move it)."""
    select_cut(page, frame)
    page.fill("#seg-cut-frame", str(to))
    page.press("#seg-cut-frame", "Enter")
    page.wait_for_function(f"[...document.querySelectorAll('.seg-cut')].some(h => h.dataset.frame === '{to}')")


def add_cut(page, frame: int) -> None:
    page.evaluate("f => window.studio.player.setFrame(f)", frame)
    page.click("#seg-add")
    assert frame in page_cuts(page)


def delete_cut(page, frame: int) -> None:
    select_cut(page, frame)
    page.click("#seg-delete")
    assert frame not in page_cuts(page)


def name_segments(page, names: list[str]) -> None:
    inputs = page.locator("#seg-table .seg-label")
    assert inputs.count() == len(names)
    for i, name in enumerate(names):
        inputs.nth(i).fill(name)


def save(page, out: Path) -> dict:
    page.click("#seg-save")
    page.wait_for_function("document.querySelector('#seg-output').textContent.startsWith('saved')", timeout=30_000)
    shown = page.get_attribute("#seg-output", "data-output")
    return json.loads((out.parent / shown).read_text())


def detector_cuts(path: Path) -> np.ndarray:
    from usdmotion.ops.segment.detect import segment

    return segment(read_motion(path, units="asf")).cuts


# ---------------------------------------------------------------------------------------- API


def test_signal_and_cuts_are_the_librarys(studio86):
    from usdmotion.ops.segment.detect import bone_angles, norm_signal

    base, root, _ = studio86
    status, sig = request(base, "GET", f"/api/segment/signal?take={ID_86}")
    assert status == 200
    motion = read_motion(root / TAKE_86, units="asf")
    np.testing.assert_allclose(sig["q"], np.degrees(norm_signal(bone_angles(motion))), atol=1e-3)
    status, answer = request(base, "POST", "/api/segment/detect", {"take": ID_86})
    assert status == 200 and answer["doc"]["cuts"] == detector_cuts(root / TAKE_86).tolist()
    status, answer = request(base, "POST", "/api/segment/detect",
                             {"take": ID_86, "detector": {"method": "heuristic", "param": 0.3}})
    from usdmotion.ops.segment.detect import segment

    assert answer["doc"]["cuts"] == segment(motion, method="heuristic", param=0.3).cuts.tolist()


def test_export_of_the_detectors_cuts_is_the_clis(studio86, tmp_path, capsys):
    """Same cuts → the same files as ``usdmotion segment --export-clips`` (names and bytes)."""
    from usdmotion.cli import main

    base, root, out = studio86
    cuts = detector_cuts(root / TAKE_86).tolist()
    status, started = request(base, "POST", "/api/segment/export", {"take": ID_86, "cuts": cuts, "format": "bvh"})
    assert status == 200, started
    job = wait_state(base, started["job"])
    assert job["state"] == "done", job
    cli = tmp_path / "cli"
    assert main(["segment", str(root / TAKE_86), "--units", "asf", "--export-clips", str(cli)]) == 0
    studio_files = sorted((out.parent / job["result"]["folder"]).iterdir())
    cli_files = sorted(cli.iterdir())
    assert [p.name for p in studio_files] == [p.name for p in cli_files] and len(cli_files) == len(cuts) + 1
    for ours, theirs in zip(studio_files, cli_files):
        assert ours.read_bytes() == theirs.read_bytes(), ours.name
    # the clips are in the library (the output folder is listed as a root)
    status, listing = request(base, "GET", "/api/takes")
    assert set(job["result"]["ids"]) <= {t["id"] for t in listing["takes"]}


def test_errors_are_one_line_and_the_server_keeps_running(studio_errors):
    base, lib, _ = studio_errors
    status, answer = request(base, "GET", "/api/segment/signal?take=0/legs.bvh")
    assert status == 422 and re.fullmatch(
        r"usdmotion: error: legs\.bvh: cannot find the joints for role\(s\) [^\n]*left_elbow[^\n]*",
        answer["error"]), answer
    for detector, word in [({"penalty": -1}, "penalty"), ({"min_length": "long"}, "min length"),
                           ({"method": "heuristic", "param": 1.5}, "param"), ({"method": "ppca"}, "detector"),
                           ({"method": "heuristic", "cutoff": 0}, "cutoff"), ({"cutoff": float("nan")}, "cutoff"),
                           ({"speed": 2}, "detector options")]:
        status, answer = request(base, "POST", "/api/segment/detect", {"take": "0/walk.bvh", "detector": detector})
        assert status == 400 and word in answer["error"] and "\n" not in answer["error"], (detector, answer)
    status, answer = request(base, "GET", "/api/segment/saved?take=0/walk2.bvh")
    assert status == 422 and answer["error"].startswith("usdmotion: error: walk2.segments.json: /"), answer
    status, answer = request(base, "POST", "/api/segment/save",
                             {"take": "0/walk.bvh", "cuts": [200], "labels": ["a", "b"]})
    assert status == 507 and "cannot write in the output folder" in answer["error"], answer
    status, answer = request(base, "POST", "/api/segment/save", {"take": "0/walk.bvh", "cuts": [300, 200]})
    assert status == 400 and answer["error"] == "walk.bvh: cuts must be increasing, at most one per frame"
    status, _ = request(base, "GET", "/api/takes")
    assert status == 200


def test_a_saved_file_beside_the_take_is_shown(studio_errors):
    base, lib, _ = studio_errors
    status, answer = request(base, "GET", "/api/segment/saved?take=0/walk3.bvh")
    assert status == 200 and answer["output"] == "walk3_segments.json"
    assert answer["doc"] == json.loads((lib / "walk3_segments.json").read_text())
    status, answer = request(base, "GET", "/api/segment/saved?take=0/walk.bvh")
    assert (status, answer) == (200, {"doc": None, "output": None})


def test_saves_never_overwrite_and_the_newest_is_shown_with_its_names(studio86):
    base, _, out = studio86
    body = {"take": ID_86, "cuts": [549, 1149], "labels": ["warm-up", "jump", "cool-down"]}
    outputs = []
    for cuts in ([549, 1149], [600, 1200]):
        status, answer = request(base, "POST", "/api/segment/save", {**body, "cuts": cuts})
        assert status == 200, answer
        outputs.append(answer["output"])
    assert outputs[1] != outputs[0] and (out.parent / outputs[0]).is_file()
    assert re.fullmatch(r"out/cmu86/86_01_from_amc_cgspeed_layout\.segments(-\d+)?\.json", outputs[0])
    status, shown = request(base, "GET", f"/api/segment/saved?take={ID_86}")
    assert shown["output"] == outputs[1] and shown["doc"]["cuts"] == [600, 1200]
    status, answer = request(base, "GET", "/api/segment/labels")
    assert {"walk", "jump", "punch", "leg_kick", "warm-up", "cool-down"} <= set(answer["labels"])


def test_a_long_take_is_segmented_as_a_job(studio86, monkeypatch):
    from usdmotion.studio import segment_panel

    base, root, _ = studio86
    monkeypatch.setattr(segment_panel, "LONG_TAKE_FRAMES", 1000)
    status, started = request(base, "POST", "/api/segment/detect", {"take": ID_86, "detector": {"min_length": 2}})
    assert status == 200 and "job" in started, started
    job = wait_state(base, started["job"])
    assert job["state"] == "done" and job["kind"] == "segment"
    from usdmotion.ops.segment.detect import segment

    expected = segment(read_motion(root / TAKE_86, units="asf"), min_length_s=2).cuts
    assert job["result"]["doc"]["cuts"] == expected.tolist()


def test_a_failed_detector_job_keeps_the_clis_line(studio_errors, monkeypatch):
    from usdmotion.studio import segment_panel

    base, _, _ = studio_errors
    monkeypatch.setattr(segment_panel, "LONG_TAKE_FRAMES", 100)
    status, started = request(base, "POST", "/api/segment/detect", {"take": "0/legs.bvh"})
    assert status == 200 and "job" in started, started
    job = wait_state(base, started["job"])
    assert job["state"] == "failed" and re.fullmatch(
        r"usdmotion: error: legs\.bvh: cannot find the joints for role\(s\) [^\n]*", job["error"]), job


def test_a_cancelled_export_leaves_no_clip_and_no_folder(studio86):
    base, _, out = studio86
    cuts = list(range(20, 4579, 20))  # 229 clips: seconds of work, cancelled at once
    status, started = request(base, "POST", "/api/segment/export", {"take": ID_86, "cuts": cuts, "format": "usda"})
    assert status == 200, started
    status, _ = request(base, "DELETE", f"/api/jobs/{started['job']}")
    job = wait_state(base, started["job"])
    assert job["state"] == "cancelled", job
    assert not (out.parent / started["output"]).exists()


# ---------------------------------------------------------------------------------------- browser


@needs_chromium
def test_edit_save_and_export_in_the_browser(studio86, page):
    """Must-show 1 (segmentation): drag a cut by a known number of frames, add one, delete one, name
    the segments, save; the JSON has those cuts and names, the clips the right frames (FK)."""
    from usdmotion.schemas import load_document

    base, root, out = studio86
    open_editor(page, base, ID_86)
    page.click("#seg-run")  # from the detector's cuts, even where an earlier test saved some
    page.wait_for_function("document.querySelector('#seg-status').textContent.startsWith('kcpd')")
    detected = detector_cuts(root / TAKE_86).tolist()
    assert page_cuts(page) == detected
    assert "seg=1" in address(page)  # a link opens the editor too
    from usdmotion.ops.segment.detect import segment

    confidence = segment(read_motion(root / TAKE_86, units="asf")).confidence
    shown = page.locator("#seg-table tbody tr td:nth-child(5)").all_inner_texts()
    assert shown == [""] + [f"{c:.2f}{' check' if c < 0.5 else ''}" for c in confidence]
    moved, by = detected[2], 30
    # drag: zoomed to ±1 s around the cut, one frame is ~3 px; the body shows the frame under the pointer
    select_cut(page, moved)
    page.click("#seg-zoom-cut")
    x0, y = handle_x(page, moved)
    x1, _ = handle_x(page, moved + by)
    page.mouse.move(x0, y)
    page.mouse.down()
    page.mouse.move((x0 + x1) / 2, y, steps=4)
    page.mouse.move(x1, y, steps=4)
    assert page.evaluate("window.studio.player.figure.frame") == moved + by
    page.mouse.up()
    assert page.input_value("#seg-cut-frame") == str(moved + by)
    for key in [".", ".", ","]:  # nudge: one frame each
        page.keyboard.press(key)
    by += 1
    assert page.input_value("#seg-cut-frame") == str(moved + by)
    page.click("#seg-zoom-all")
    added, deleted = 3700, detected[4]
    add_cut(page, added)
    delete_cut(page, deleted)
    cuts = sorted({*detected, added} - {moved, deleted} | {moved + by})
    assert page_cuts(page) == cuts
    names = [f"part {i} ({'walk' if i % 2 == 0 else 'action'})" for i in range(len(cuts) + 1)]
    name_segments(page, names)
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / "segment_editor.png")
    doc = save(page, out)
    path = out.parent / page.get_attribute("#seg-output", "data-output")
    assert load_document(path, "segments") == doc
    assert doc["cuts"] == cuts and [s["label"] for s in doc["segments"]] == names and doc["edited"] is True
    assert doc["method"] == "kcpd" and doc["frames"] == 4579
    # opening the take again (a link with seg=1) shows the saved segments, names and all
    page.goto(address(page))
    page.wait_for_function("document.querySelector('#seg-status').textContent.startsWith('showing the saved')",
                           timeout=60_000)
    assert page.inner_text("#seg-status") == f"showing the saved segments {path.relative_to(out.parent).as_posix()}"
    assert page_cuts(page) == cuts
    assert page.locator("#seg-table .seg-label").evaluate_all("xs => xs.map(x => x.value)") == names
    # export: a job with progress; clips of the saved cuts, first frame = the source's frame (FK)
    page.select_option("#seg-format", "usda")
    page.click("#seg-export")
    page.wait_for_function("document.querySelector('#seg-output').textContent.startsWith('clips in')", timeout=120_000)
    folder = out.parent / page.get_attribute("#seg-output", "data-output")
    clips = sorted(folder.glob("*.usda"))
    source = read_motion(root / TAKE_86, units="asf")
    src = joint_positions(source) * source.meters_per_unit
    bounds = list(zip([0, *cuts], [c - 1 for c in cuts] + [source.n_frames - 1]))
    assert [p.name for p in clips] == [f"{Path(TAKE_86).stem}_{i:03d}_{a}-{b}.usda" for i, (a, b) in enumerate(bounds)]
    for clip_path, (a, b) in zip(clips, bounds):
        clip = read_motion(clip_path)
        assert clip.n_frames == b - a + 1
        first = joint_positions(clip)[0] * clip.meters_per_unit
        np.testing.assert_allclose(first, src[a], atol=1e-5, err_msg=clip_path.name)
        if b > a:
            assert not np.allclose(first, src[a + 1], atol=1e-5)  # a frame off would fail


@needs_chromium
def test_cuts_moved_to_the_labels_score_100_percent(studio86, page, capsys):
    """Must-show 2: start from the detector's cuts, move each to its labelled boundary (add and
    delete where needed) in the editor; ``usdmotion segment-eval --cuts`` on the saved file: 100 %."""
    from usdmotion.cli import main
    from usdmotion.ops.segment.evaluate import edits_to_labels, load_labels

    base, root, out = studio86
    labels_csv = shared_path("cmu86/86_01_segments.csv")
    labels = load_labels(labels_csv)
    open_editor(page, base, ID_86)
    page.click("#seg-run")
    page.wait_for_function("document.querySelector('#seg-status').textContent.startsWith('kcpd')")
    detected = page_cuts(page)
    plan = edits_to_labels(detected, labels, 60)
    for frame in plan.deleted:
        delete_cut(page, frame)
    # leftward moves from the left, rightward from the right: a cut never meets its neighbour
    for frame, to in sorted(plan.moved, key=lambda m: m[0] if m[1] < m[0] else -m[0]):
        set_cut(page, frame, to)
    for frame in plan.added:
        add_cut(page, frame)
    assert page_cuts(page) == labels.cuts.tolist()
    doc = save(page, out)
    assert doc["cuts"] == labels.cuts.tolist()
    saved = out.parent / page.get_attribute("#seg-output", "data-output")
    capsys.readouterr()
    assert main(["segment-eval", str(root / TAKE_86), str(labels_csv), "--units", "asf", "--cuts", str(saved),
                 "--json"]) == 0
    score = json.loads(capsys.readouterr().out)["methods"][saved.name]
    assert score["precision"] == 1.0 and score["recall"] == 1.0 and score["labelled"] == 6
    print(f"\n86_01: {len(detected)} detected cuts; moved {len(plan.moved)} "
          f"({plan.needed} of them out of the labelled region), added {len(plan.added)}, deleted {len(plan.deleted)}")


@needs_chromium
def test_panel_errors_show_one_line_in_the_page(studio_errors, page):
    base, lib, _ = studio_errors
    open_editor(page, base, "0/legs.bvh", wait_cuts=False)
    page.wait_for_selector("#seg-status.error-text", timeout=30_000)
    assert re.fullmatch(r"usdmotion: error: legs\.bvh: cannot find the joints for role\(s\) .*",
                        page.inner_text("#seg-status"))
    page.click("#seg-run")  # the detector says the same, in one line
    page.wait_for_function("document.querySelector('#seg-status').textContent"
                           ".startsWith('usdmotion: error: legs.bvh: cannot')")
    # a saved file that does not validate: its error, and the detector's cuts instead
    open_editor(page, base, "0/walk2.bvh", wait_cuts=False)
    page.wait_for_selector("#seg-status.error-text", timeout=30_000)
    assert page.inner_text("#seg-status").startswith("usdmotion: error: walk2.segments.json: /")
    assert len(page_cuts(page)) >= 0 and page.locator("#seg-table tbody tr").count() >= 1
    # bad detector options
    open_editor(page, base, "0/walk.bvh")
    page.fill("#seg-penalty", "-2")
    page.click("#seg-run")
    page.wait_for_selector("#seg-status.error-text")
    assert page.inner_text("#seg-status") == "penalty must be greater than 0, not -2"
    page.fill("#seg-penalty", "")
    # an output folder that cannot be written: Save and Export say so in one line
    page.click("#seg-save")
    page.wait_for_function("document.querySelector('#seg-status').textContent.includes('cannot write')")
    assert "\n" not in page.inner_text("#seg-status")
    page.click("#seg-export")
    page.wait_for_function("document.querySelector('#seg-jobs .job-message').textContent.includes('cannot write')")
    page.screenshot(path=SHOTS / "segment_error.png")
    status, _ = request(base, "GET", "/api/takes")
    assert status == 200
