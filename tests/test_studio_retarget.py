"""Retarget panel in a real browser against a real server: the joint map, a retarget job
with its progress bar, the target played over the source with the per-joint error, Save as
USD; the saved file holds the numbers ``usdmotion retarget`` writes with the same options.
A rig that cannot be mapped shows its one line in the page."""

from __future__ import annotations

import json

import numpy as np
import pytest

from studio_support import make_library, running_studio, shoot
from test_studio_browser import ARGS, CHROMIUM, SHOTS, WALK_ID, browser, open_view, page  # noqa: F401 - fixtures
from usdmotion.io import read_motion, write_motion

pytestmark = pytest.mark.skipif(not __import__("pathlib").Path(CHROMIUM).exists(),
                                reason="Debian's chromium is not installed (scripts/setup.sh installs it)")

#: The 18-joint rig of docs/retarget.md's example: the walk's skeleton without these joints.
REMOVE = "LHipJoint,RHipJoint,LowerBack,Spine1,Neck,LeftShoulder,RightShoulder,LeftFingerBase,RightFingerBase," \
         "LeftHandIndex1,RightHandIndex1,LThumb,RThumb"


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    from usdmotion.studio.app import missing_web_packages

    if missing_web_packages():
        pytest.skip(f"studio web packages missing ({missing_web_packages()}): run scripts/setup.sh")
    folder = tmp_path_factory.mktemp("retarget")
    lib = make_library(folder)
    # a rig no joint of the walk maps to (names with nothing in common, no profile)
    walk = read_motion(lib / "walk.bvh", units="asf")
    import dataclasses
    alien = dataclasses.replace(walk, joint_names=tuple(f"Bone{j:02d}" for j in range(walk.n_joints)))
    write_motion(alien.sliced(0, 2), lib / "alien_rig.bvh")
    with running_studio([lib], out=folder / "out") as base:
        yield base, lib, folder / "out"


def test_retarget_in_the_browser_matches_the_cli(studio, page, tmp_path):
    from usdmotion.cli import main

    base, lib, out = studio
    open_view(page, base, f"take={WALK_ID}")
    page.click("#retarget-panel summary")
    page.fill("#rt-remove", REMOVE)
    page.click("#rt-show-map")
    page.wait_for_selector("#retarget-panel[data-state=mapped]", timeout=30_000)
    assert page.locator("#rt-map tbody tr").count() == 18
    assert "identity (target derived from the source)" in page.inner_text("#retarget-status")
    progress_seen = []
    page.on("response", lambda r: progress_seen.append(r.url) if "/api/jobs/" in r.url else None)
    page.click("#rt-run")
    page.wait_for_selector("#retarget-panel[data-state=done]", timeout=240_000)
    assert progress_seen  # the page followed the job
    assert page.evaluate("() => window.studio.player.figure.take.end_sites.filter(e => !e).length") == 18
    assert page.evaluate("() => window.studio.player.ghost.take.id") == WALK_ID
    table = [row.split("\t") for row in page.locator("#rt-errors tbody tr").all_inner_texts()]
    shoot(page, "retarget.png", frame=200)
    page.select_option("#rt-format", "usda")
    page.click("#rt-save")
    page.wait_for_selector("#rt-save-bar .job-bar[data-state=done]", timeout=60_000)
    saved = out / "lib" / "walk.retarget.usda"
    assert saved.is_file()

    cli_out = tmp_path / "cli.usda"
    report = tmp_path / "cli.json"
    assert main(["retarget", str(lib / "walk.bvh"), str(cli_out), "--remove", REMOVE, "--units", "asf",
                 "--report", str(report)]) == 0
    # the page's per-joint error is the CLI report's, worst first
    rms = json.loads(report.read_text())["per_joint_rms"]  # target units
    assert [name for name, _ in table] == sorted(rms, key=lambda n: -rms[n])
    cm = 100 * theirs_mpu(cli_out)
    assert [float(v) for _, v in table] == pytest.approx([rms[n] * cm for n, _ in table], abs=6e-3)
    ours, theirs = read_motion(saved), read_motion(cli_out)
    assert ours.joint_names == theirs.joint_names and ours.n_frames == theirs.n_frames == 524
    np.testing.assert_allclose(ours.offsets, theirs.offsets, atol=1e-6)
    np.testing.assert_allclose(ours.root_translation, theirs.root_translation, atol=1e-5)
    sign = np.where(np.sum(ours.rotations * theirs.rotations, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    np.testing.assert_allclose(ours.rotations * sign, theirs.rotations, atol=1e-6)  # USD stores float32


def theirs_mpu(path) -> float:
    return read_motion(path).meters_per_unit


def test_a_rig_that_cannot_be_mapped_shows_one_line(studio, page):
    base, lib, out = studio
    written = lambda: sorted(p for p in out.rglob("*") if "cache" not in p.relative_to(out).parts)  # noqa: E731
    before = written()
    open_view(page, base, f"take={WALK_ID}")
    page.click("#retarget-panel summary")
    page.select_option("#rt-target", "0/alien_rig.bvh")
    page.click("#rt-run")
    page.wait_for_selector("#retarget-panel[data-state=error]", timeout=30_000)
    text = page.inner_text("#retarget-status")
    assert text.startswith("usdmotion: error: ") and "could be matched with source joints" in text
    assert "\n" not in text
    assert page.evaluate("async () => (await fetch('/api/takes')).status") == 200
    assert written() == before  # nothing written
