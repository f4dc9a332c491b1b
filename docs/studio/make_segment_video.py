"""Record the segmentation editor in use (docs/studio/segment_session.mp4 and segment_editor.png):

    .venv/bin/python docs/studio/make_segment_video.py

A studio over the shared CMU 86 folder (86_01: walk, jump, walk, punch, walk, leg kick, punch)
writing to a temporary folder; Debian's Chromium, driven by Playwright, records the page while a
scripted user runs the detector, previews frames under the pointer, drags a cut, adds and deletes
one, names the segments, loops one, saves and exports the clips.

The page is recorded with Chromium's screencast through Playwright's CDP session (JPEG frames with
their time stamps), not ``record_video_dir``: that needs Playwright's own ffmpeg build, which is
downloaded, and this project downloads no browser parts. The frames are resampled to 25 fps by
their time stamps and encoded as H.264 MP4 with PyAV (the project's video writer).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
DATA = Path(os.environ.get("USDMOTION_SHARED_DATA", ROOT.parent / "shared" / "data"))
OUT = ROOT / "docs" / "studio"
SIZE = {"width": 1280, "height": 900}
ARGS = ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox",
        "--disable-gpu-sandbox"]
LABELS = ["walk", "jump", "walk", "punch", "walk", "leg_kick", "punch"]


def glide(page, x0: float, x1: float, y: float, seconds: float, drag: bool = False) -> None:
    """Move the pointer from x0 to x1 (pressed when ``drag``) over about ``seconds``."""
    steps = max(2, int(seconds * 15))
    page.mouse.move(x0, y)
    if drag:
        page.mouse.down()
    for i in range(1, steps + 1):
        page.mouse.move(x0 + (x1 - x0) * i / steps, y)
        time.sleep(seconds / steps)
    if drag:
        page.mouse.up()


def at(page, frame: int) -> tuple[float, float]:
    return tuple(page.evaluate("""f => { const s = window.studio.segments, r = s.chart.over.getBoundingClientRect();
        return [r.left + s.xOfFrame(f), r.top + r.height / 2]; }""", frame))


def session(page, base: str, record) -> None:
    """The scripted user; ``record()`` starts the recording once the take is shown."""
    page.goto(f"{base}/?take=0/86_01_from_amc_cgspeed_layout.bvh&f=0&cam=follow")
    page.wait_for_selector('body[data-loaded="1"]', state="attached", timeout=120_000)
    page.wait_for_function("window.studio.player.figure.body !== null", timeout=120_000)
    record()
    time.sleep(1.0)
    page.click("#segment-panel summary")
    page.wait_for_function("document.querySelector('#seg-status').textContent.includes('cuts')", timeout=60_000)
    page.evaluate("document.querySelector('#segment-panel').scrollIntoView({block: 'start'})")
    page.evaluate("document.querySelector('main').scrollTop = 0")
    time.sleep(1.5)
    cuts = page.evaluate("window.studio.segments.cuts")
    y = at(page, 0)[1]
    glide(page, at(page, 200)[0], at(page, 4400)[0], y, 5.0)           # the body follows the pointer
    x, y = at(page, cuts[2])
    page.mouse.click(x, y)                                                # select a cut
    time.sleep(0.8)
    page.click("#seg-zoom-cut")
    time.sleep(0.8)
    glide(page, at(page, cuts[2])[0], at(page, cuts[2] - 28)[0], y, 2.5, drag=True)   # drag it 28 frames earlier
    time.sleep(0.8)
    page.click("#seg-zoom-all")
    time.sleep(0.8)
    page.mouse.dblclick(*at(page, 3700))                                  # add a cut...
    time.sleep(1.2)
    page.click("#seg-delete")                                             # ...and delete it again
    time.sleep(1.0)
    for i, name in enumerate(LABELS[:len(cuts) + 1]):
        page.locator("#seg-table .seg-label").nth(i).click()
        page.keyboard.type(name, delay=60)
        time.sleep(0.2)
    page.locator("#seg-table tbody tr").nth(3).locator("button").nth(1).click()  # loop the punch
    time.sleep(5.0)
    page.click("#play")
    page.click("#seg-save")
    page.wait_for_function("document.querySelector('#seg-output').textContent.startsWith('saved')")
    time.sleep(1.5)
    page.screenshot(path=OUT / "segment_editor.png")
    page.click("#seg-export")
    page.wait_for_function("document.querySelector('#seg-output').textContent.startsWith('clips in')",
                           timeout=120_000)
    time.sleep(2.0)


class Screencast:
    """Chromium's screencast of ``page``: ``(time stamp s, JPEG bytes)`` of every frame it paints."""

    def __init__(self, context, page) -> None:
        self.frames: list[tuple[float, bytes]] = []
        self.cdp = context.new_cdp_session(page)
        self.cdp.on("Page.screencastFrame", self.frame)
        self.cdp.send("Page.startScreencast", {"format": "jpeg", "quality": 85, "maxWidth": SIZE["width"],
                                               "maxHeight": SIZE["height"]})

    def frame(self, params: dict) -> None:
        import base64

        self.frames.append((params["metadata"]["timestamp"], base64.b64decode(params["data"])))
        self.cdp.send("Page.screencastFrameAck", {"sessionId": params["sessionId"]})

    def stop(self) -> None:
        self.cdp.send("Page.stopScreencast")


def to_mp4(frames: list[tuple[float, bytes]], mp4: Path, fps: float = 25.0) -> None:
    """Frames resampled to ``fps`` by their time stamps (the last painted one held), as H.264
    (CRF 30: the page is mostly still) through the project's video writer."""
    import io

    import numpy as np
    from PIL import Image

    from usdmotion.render.output import VideoWriter

    stamps = np.array([t for t, _ in frames])
    first = np.asarray(Image.open(io.BytesIO(frames[0][1])).convert("RGB"))
    h, w = first.shape[0] - first.shape[0] % 2, first.shape[1] - first.shape[1] % 2
    times = np.arange(stamps[0], stamps[-1] + 1.0, 1.0 / fps)
    shown = np.searchsorted(stamps, times, side="right") - 1
    writer = VideoWriter(mp4, w, h, fps, quality=30)
    decoded: dict[int, np.ndarray] = {}
    try:
        for i, k in enumerate(shown):
            if k not in decoded:
                decoded.clear()
                image = np.asarray(Image.open(io.BytesIO(frames[k][1])).convert("RGB"))
                decoded[k] = np.ascontiguousarray(np.pad(image, ((0, max(0, h - image.shape[0])),
                                                                 (0, max(0, w - image.shape[1])), (0, 0)))[:h, :w])
            writer.write(decoded[k], i)
        writer.commit()
    except BaseException:
        writer.abort()
        raise
    print(f"wrote {mp4} ({len(times)} frames from {len(frames)} painted, {times.size / fps:.0f} s, "
          f"{mp4.stat().st_size / 1e6:.1f} MB)")


def main() -> None:
    from playwright.sync_api import sync_playwright

    from studio_support import running_studio

    with tempfile.TemporaryDirectory() as tmp, running_studio([DATA / "cmu86"], out=Path(tmp) / "out") as base, \
            sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
        context = browser.new_context(viewport=SIZE)
        page = context.new_page()
        casts = []
        try:
            session(page, base, lambda: casts.append(Screencast(context, page)))
            casts[0].stop()
        finally:
            context.close()
            browser.close()
        to_mp4(casts[0].frames, OUT / "segment_session.mp4")


if __name__ == "__main__":
    main()
