"""Feedback-video panel in a real browser against a real server: the view (loop range, speed,
compare ghost) rendered to MP4 by usdmotion.render as a job, downloaded through the page's
link and decoded (frame count, size); a render cancelled from the page stops and leaves no file."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

from studio_support import shoot, studio_with_output
from test_studio_browser import CHROMIUM, TURNED_ID, WALK_ID, browser, open_view, page  # noqa: F401

pytestmark = pytest.mark.skipif(not Path(CHROMIUM).exists(),
                                reason="Debian's chromium is not installed (scripts/setup.sh installs it)")


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    with studio_with_output(tmp_path_factory.mktemp("video")) as served:
        yield served


def test_render_the_view_to_mp4_and_download_it(studio, page):
    import av

    base, lib, out = studio
    start, last, speed = 10, 49, 0.5
    open_view(page, base, f"take={WALK_ID}&range={start}-{last}&speed={speed}&cmp={TURNED_ID}&align=offset")
    page.click("#video-panel summary")
    page.select_option("#video-size", "640x360")
    page.select_option("#video-style", "stick")
    page.click("#video-render")
    page.wait_for_selector("#video-bar .job-bar[data-state=done]", timeout=180_000)
    saved = out / "lib" / "walk.video.mp4"
    assert saved.is_file()
    url = page.get_attribute("#video-download", "href")
    with page.expect_download() as download:
        page.click("#video-download")
    fetched = download.value.path().read_bytes()
    assert fetched == saved.read_bytes()
    with av.open(io.BytesIO(fetched)) as container:
        stream = container.streams.video[0]
        frames = [f for f in container.decode(stream)]
        rate = float(stream.average_rate)
    assert (frames[0].width, frames[0].height) == (640, 360)
    # the loop range at half speed: (last - start) / 120 s of capture shown over twice the time
    assert len(frames) == math.floor((last - start) / 120 * rate / speed + 1e-6) + 1
    assert url.startswith("/api/video/file?name=")
    # only videos under the output folder are served
    for bad in ("../lib/walk.bvh", "lib/walk.video.mp4/../../../lib/walk.bvh", "/etc/passwd", "cache"):
        status = page.evaluate("async u => (await fetch(u)).status", f"/api/video/file?name={bad}")
        assert status == 404
    shoot(page, "video.png", frame=200)


def test_cancel_a_render_from_the_page_leaves_no_file(studio, page):
    base, lib, out = studio
    open_view(page, base, "take=0/session2/walk_turned.usda")
    page.click("#video-panel summary")
    page.select_option("#video-size", "1920x1080")
    page.click("#video-render")
    page.wait_for_function("() => { const p = document.querySelector('#video-bar progress');"
                           " return p && !p.hidden && p.value > 0; }", timeout=120_000)
    page.click("#video-bar .job-cancel")
    page.wait_for_selector("#video-bar .job-bar[data-state=cancelled]", timeout=30_000)
    assert "cancelled; no file was kept" in page.inner_text("#video-bar")
    assert not [p for p in out.rglob("*walk_turned*") if "cache" not in p.parts]  # no video, no temporary file


@pytest.mark.parametrize("offset", [0.5, -0.25, 0.0])
def test_a_manual_offset_renders_the_ghost_the_page_shows(offset):
    """The video's ghost frames (the renderer's plan) are the player's ghost frames for the
    same manual offset (the studio's compare.offset_frame_map), frame by frame."""
    from studio_support import SHIFT, WALK
    from usdmotion.io import read_motion
    from usdmotion.render import plan_render
    from usdmotion.studio.compare import offset_frame_map
    from usdmotion.studio.video_panel import render_options

    walk = read_motion(WALK, units="asf")
    other = walk.sliced(SHIFT, None)
    options = render_options({"align": "offset", "offset": offset, "size": "640x360"}, walk, other)
    plan = plan_render(walk, options, other)
    shown = offset_frame_map(walk, other, offset)[plan.frames]
    np.testing.assert_allclose(plan.other_frames, shown, atol=0.5 + 1e-9)
