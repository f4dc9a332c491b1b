"""Retarget panel in a real browser against a real server: the joint map, a retarget job
with its progress bar, the target played over the source with the per-joint error, Save as
USD; the saved file holds the numbers ``usdmotion retarget`` writes with the same options.
A rig that cannot be mapped shows its one line in the page."""

from __future__ import annotations

import json

from pathlib import Path

import numpy as np
import pytest

from studio_support import shoot, studio_with_output
from test_studio_browser import CHROMIUM, WALK_ID, browser, open_view, page  # noqa: F401 - fixtures
from usdmotion.io import read_motion, write_motion

pytestmark = pytest.mark.skipif(not Path(CHROMIUM).exists(),
                                reason="Debian's chromium is not installed (scripts/setup.sh installs it)")

#: The 18-joint rig of docs/retarget.md's example: the walk's skeleton without these joints.
REMOVE = "LHipJoint,RHipJoint,LowerBack,Spine1,Neck,LeftShoulder,RightShoulder,LeftFingerBase,RightFingerBase," \
         "LeftHandIndex1,RightHandIndex1,LThumb,RThumb"


def add_alien_rig(lib) -> None:
    """A rig no joint of the walk maps to (names with nothing in common, no rig profile)."""
    import dataclasses

    walk = read_motion(lib / "walk.bvh", units="asf")
    alien = dataclasses.replace(walk, joint_names=tuple(f"Bone{j:02d}" for j in range(walk.n_joints)))
    write_motion(alien.sliced(0, 2), lib / "alien_rig.bvh")


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    with studio_with_output(tmp_path_factory.mktemp("retarget"), add_alien_rig) as served:
        yield served


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
    # the target's joints are coloured by their error: the worst red, the best green
    colours = page.evaluate("""names => names.map(n => { const f = window.studio.player.figure, c = f.joints.instanceColor;
        const j = f.take.joint_names.indexOf(n); return [c.getX(j), c.getY(j), c.getZ(j)]; })""",
                            [table[0][0], table[-1][0]])
    assert colours[0][0] > colours[0][1] and colours[1][1] > colours[1][0]
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


def test_joint_map_through_rig_profiles(studio, page):
    """A joint map through two rig profiles: a target that does not fit its profile shows the
    map reader's one line; one that fits shows the map that ``prepare`` makes from the same map
    document (the JSON ``usdmotion retarget --map`` would read)."""
    from usdmotion.ops.retarget import prepare
    from usdmotion.ops.retarget.jointmap import joint_map_from_document

    base, lib, _ = studio
    open_view(page, base, f"take={WALK_ID}")
    page.click("#retarget-panel summary")
    page.select_option("#rt-target", "0/alien_rig.bvh")
    page.select_option("#rt-source-profile", "cmu_cgspeed")
    page.select_option("#rt-target-profile", "mixamo")
    page.click("#rt-show-map")
    page.wait_for_selector("#retarget-panel[data-state=error]", timeout=30_000)
    text = page.inner_text("#retarget-status")
    assert text == "usdmotion: error: <input>: the target skeleton does not fit rig profile 'mixamo'"
    page.select_option("#rt-target", "0/session2/walk_turned.usda")
    page.select_option("#rt-target-profile", "cmu_cgspeed")
    page.click("#rt-show-map")
    page.wait_for_selector("#retarget-panel[data-state=mapped]", timeout=30_000)
    walk = read_motion(lib / "walk.bvh", units="asf")
    turned = read_motion(lib / "session2" / "walk_turned.usda")
    doc = {"source_profile": "cmu_cgspeed", "target_profile": "cmu_cgspeed", "auto": True}
    setup = prepare(walk, turned, joint_map=joint_map_from_document(doc))
    shown = [row.split("\t") for row in page.locator("#rt-map tbody tr").all_inner_texts()]
    expected = [[t, s or "— not mapped"] for t, s, e in
                zip(turned.joint_names, (setup.joint_map.pairs.get(n) for n in turned.joint_names), turned.end_sites)
                if not e]
    assert shown == expected
    assert "rig profiles cmu_cgspeed -> cmu_cgspeed" in page.inner_text("#retarget-status")
