"""Edits panel in a real browser (Playwright + Debian's Chromium) against a real server:
an equaliser slider changes only the chosen joint group (the library's equalize, exactly),
Save as writes a new file in the output folder that appears in the library, and bad
parameters show the CLI's one line in the page while the server keeps running."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio_support import WALK as REPO_WALK
from studio_support import make_library, running_studio, shoot, studio_with_output
from test_studio_browser import CHROMIUM, TURNED_ID, WALK_ID, browser, open_view, page  # noqa: F401 - fixtures
from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions

pytestmark = pytest.mark.skipif(not Path(CHROMIUM).exists(),
                                reason="Debian's chromium is not installed (scripts/setup.sh installs it)")


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    with studio_with_output(tmp_path_factory.mktemp("edits")) as served:
        yield served


def page_positions(page, which: str) -> np.ndarray:
    data = page.evaluate(f"""() => {{ const t = window.studio.player.{which}.take;
        return {{p: Array.from(t.positions), f: t.frames, j: t.joint_names.length}}; }}""")
    return np.asarray(data["p"], dtype=np.float32).reshape(data["f"], data["j"], 3)


def test_equaliser_slider_changes_only_the_chosen_limb(studio, page):
    from usdmotion.ops.edit import equalize
    from usdmotion.motion import subtree_indices

    base, lib, out = studio
    open_view(page, base, f"take={WALK_ID}")
    page.click("#edit-panel summary")
    page.select_option("#eq-group", "LeftUpLeg")
    slider = page.locator("#eq-bands input[data-band='4']")
    slider.fill("3")  # a user dragging band 4 (about 2.7 Hz at 120 fps) to 3x (input + change)
    page.wait_for_selector("#edit-panel[data-state=preview]", timeout=60_000)
    edited, original = page_positions(page, "figure"), page_positions(page, "ghost")
    walk = read_motion(lib / "walk.bvh", units="asf")
    chosen = np.zeros(walk.n_joints, bool)
    chosen[subtree_indices(walk.parents, walk.joint_names.index("LeftUpLeg"))] = True
    # the other joints are exactly the original (the same float32 FK of unchanged rotations)
    np.testing.assert_array_equal(edited[:, ~chosen], original[:, ~chosen])
    # the chosen limb moved, and by what the library's equaliser gives (independent run)
    moved = np.abs(edited[:, chosen] - original[:, chosen]).max()
    assert moved > 0.005  # metres
    n_bands = page.locator("#eq-bands input").count()
    gains = [1.0] * n_bands
    gains[4] = 3.0
    expected = joint_positions(equalize(walk, gains=gains, joint="LeftUpLeg", subtree=True)) * walk.meters_per_unit
    np.testing.assert_allclose(edited, expected, atol=1e-5)
    # the plots show both takes: edited solid, original dashed
    labels = page.evaluate("() => [...document.querySelectorAll('#plots .u-legend .u-label')].map(e => e.textContent)")
    assert "LeftUpLeg joint angle (original) (deg)" in labels and "LeftUpLeg joint angle (deg)" in labels
    shoot(page, "edits.png", frame=200)

    # Save as: a new file in the output folder, listed in the library; the original untouched
    before = (lib / "walk.bvh").read_bytes()
    page.click("#edit-save")
    page.wait_for_selector("#edit-save-bar .job-bar[data-state=done]", timeout=60_000)
    saved = out / "lib" / "walk.edit.bvh"
    assert saved.is_file() and (lib / "walk.bvh").read_bytes() == before
    written = read_motion(saved, units="asf")
    np.testing.assert_allclose(joint_positions(written) * written.meters_per_unit, expected, atol=2e-4)
    saved_id = page.get_attribute("#edit-panel", "data-saved")
    assert saved_id == "1/lib/walk.edit.bvh"
    page.wait_for_function(f"() => [...document.querySelectorAll('#takes td')].some(td => td.textContent === 'lib/walk.edit.bvh')")


def test_displace_at_the_current_frame_with_a_falloff_in_seconds(studio, page):
    """A key at the frame under the cursor, blended over 0.25 s: the library's displace with the
    same key (frame 150, falloff 30 frames at 120 fps)."""
    from usdmotion.ops.edit import displace

    base, lib, _ = studio
    open_view(page, base, f"take={WALK_ID}&f=150")
    page.click("#edit-panel summary")
    page.select_option("#disp-joint", "LeftArm")
    page.fill("#disp-falloff", "0.25")
    page.fill("#disp-rz", "30")
    page.dispatch_event("#disp-rz", "change")
    page.wait_for_selector("#edit-panel[data-state=preview]", timeout=60_000)
    walk = read_motion(lib / "walk.bvh", units="asf")
    expected = displace(walk, [{"joint": "LeftArm", "frame": 150, "rotate": [0, 0, 30]}], falloff=30)
    np.testing.assert_allclose(page_positions(page, "figure"),
                               joint_positions(expected) * walk.meters_per_unit, atol=1e-5)
    moved = np.abs(page_positions(page, "figure") - page_positions(page, "ghost")).max(axis=(1, 2))
    assert moved[150] > 0.02 and moved[:150 - 31].max() == 0 and moved[150 + 31:].max() == 0


def test_speed_curve_then_blend_with_a_second_take(studio, page):
    """The speed curve in seconds and a blend into the library's second take: the library's
    own operations with the same values (seconds × 120 fps)."""
    from usdmotion.ops.edit import blend, speed

    base, lib, _ = studio
    open_view(page, base, f"take={WALK_ID}")
    page.click("#edit-panel summary")
    page.fill("#edit-speed", "0:1, 2:0.5, 4:1.5")
    page.dispatch_event("#edit-speed", "change")
    page.wait_for_selector("#edit-panel[data-state=preview]", timeout=60_000)
    walk = read_motion(lib / "walk.bvh", units="asf")
    slowed = speed(walk, keys=[(0, 1.0), (240, 0.5), (480, 1.5)])
    assert page.evaluate("() => window.studio.player.figure.take.frames") == slowed.n_frames != walk.n_frames
    np.testing.assert_allclose(page_positions(page, "figure"), joint_positions(slowed) * walk.meters_per_unit,
                               atol=1e-5)
    page.fill("#edit-speed", "1")
    page.select_option("#blend-with", TURNED_ID)
    page.fill("#blend-at", "2")
    page.fill("#blend-transition", "0.5")
    page.evaluate("() => document.querySelector('#edit-panel').dataset.state = ''")
    page.dispatch_event("#blend-transition", "change")
    page.wait_for_selector("#edit-panel[data-state=preview]", timeout=60_000)
    turned = read_motion(lib / "session2" / "walk_turned.usda")
    blended = blend(walk, turned, at=240, transition=60)
    np.testing.assert_allclose(page_positions(page, "figure"), joint_positions(blended) * walk.meters_per_unit,
                               atol=1e-5)


@pytest.mark.parametrize("field, value, message", [
    ("#trim-start", "400", "usdmotion: error: walk.bvh: operation 0 (trim): trim range 400:300 is outside"),
    ("#edit-speed", "-2", "usdmotion: error: walk.bvh: operation 0 (speed): factor: -2 is less than or equal to"),
])
def test_bad_edit_parameters_show_one_line_and_the_server_keeps_running(studio, page, field, value, message):
    base, _, _ = studio
    open_view(page, base, f"take={WALK_ID}")
    page.click("#edit-panel summary")
    if field == "#trim-start":
        page.fill("#trim-stop", "300")
        page.dispatch_event("#trim-stop", "change")
    page.fill(field, value)
    page.dispatch_event(field, "change")
    page.wait_for_selector("#edit-panel[data-state=error]", timeout=30_000)
    text = page.inner_text("#edit-status")
    assert text.startswith(message) and "\n" not in text
    # the server still answers and the original still plays
    assert page.evaluate("async () => (await fetch('/api/takes')).status") == 200


def test_an_unwritable_output_folder_shows_one_line_and_writes_nothing(tmp_path, browser):  # noqa: F811
    """The output folder's place for this library is taken by a file: Save as cannot create its
    folder. The page shows one line; the server keeps running; nothing is written."""
    lib = make_library(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "lib").write_text("a file where the studio wants a folder")
    with running_studio([lib], out=out) as base:
        context = browser.new_context(viewport={"width": 1400, "height": 900})
        try:
            page = context.new_page()
            open_view(page, base, f"take={WALK_ID}")
            page.click("#edit-panel summary")
            page.fill("#trim-start", "10")
            page.dispatch_event("#trim-start", "change")
            page.wait_for_selector("#edit-panel[data-state=preview]", timeout=60_000)
            page.click("#edit-save")
            page.wait_for_selector("#edit-save-bar .job-bar[data-state=failed]", timeout=30_000)
            text = page.inner_text("#edit-save-bar .job-message")
            assert text.startswith("cannot write in the output folder ") and text.endswith(": File exists")
            assert "\n" not in text
            assert page.evaluate("async () => (await fetch('/api/takes')).status") == 200
        finally:
            context.close()
    assert sorted(p.name for p in out.iterdir()) == ["cache", "lib"]
    assert (out / "lib").read_text() == "a file where the studio wants a folder"


@pytest.mark.parametrize("edit", ["limb", "arm key", "whole body", "trim"])
def test_preview_positions_are_the_full_fk_bit_for_bit(edit):
    """The preview recomputes only the joints below a changed one: the numbers are exactly
    view_positions' (the library's FK of every joint)."""
    from usdmotion.ops.edit import displace, equalize, trim
    from usdmotion.studio.takes import edited_view_positions, view_positions

    walk = read_motion(REPO_WALK, units="asf")
    edited = {"limb": lambda: equalize(walk, gains=[1, 1, 1, 3], joint="RightUpLeg", subtree=True),
              "arm key": lambda: displace(walk, [{"joint": "LeftForeArm", "frame": 100, "rotate": [20, 0, 0]}],
                                          falloff=30),
              "whole body": lambda: equalize(walk, gains=[0, 1, 2]),
              "trim": lambda: trim(walk, 10, 300)}[edit]()
    original = view_positions(walk)
    fast = edited_view_positions(walk, original, edited)
    np.testing.assert_array_equal(fast, view_positions(edited))
    assert fast.dtype == np.float32 and fast.shape == (edited.n_frames, walk.n_joints, 3)
