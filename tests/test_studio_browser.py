"""Studio in a real browser: Playwright drives Debian's Chromium (headless, WebGL through
SwiftShader) against a real server on a temporary library, and checks through the page.

Screenshots go to ``out/studio-screenshots/`` (the best are committed under ``docs/``).
"""

from __future__ import annotations

import base64
import io
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from studio_support import REPO, SHIFT, cli_error_line, make_library, running_studio
from usdmotion.io import read_motion
from usdmotion.kinematics import joint_positions

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox",
        "--disable-gpu-sandbox"]
SHOTS = REPO / "out" / "studio-screenshots"
WALK_ID = "0/walk.bvh"
TURNED_ID = "0/session2/walk_turned.usda"

pytestmark = pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="Debian's chromium is not installed "
                                "(scripts/setup.sh installs it)")


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    from usdmotion.studio.app import missing_web_packages

    if missing_web_packages():
        pytest.skip(f"studio web packages missing ({missing_web_packages()}): run scripts/setup.sh")
    lib = make_library(tmp_path_factory.mktemp("studio"))
    with running_studio([lib]) as base:
        yield base, lib


@pytest.fixture(scope="module")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    yield page
    context.close()
    assert not errors, errors


def open_view(page, base, query):
    page.goto(f"{base}/?{query}")
    page.wait_for_selector('body[data-loaded="1"]', state="attached", timeout=60_000)


def address(page) -> str:
    """The page's address as the page has it now. ``page.url`` is Playwright's copy, updated by
    an event that can arrive after the next line of the test when the page called
    ``history.replaceState`` (a range set by a key press was missing from a link once)."""
    return page.evaluate("location.href")


def frame_of(page) -> int:
    return int(re.match(r"frame (\d+)", page.inner_text("#readout")).group(1))


def canvas_pixels(page) -> np.ndarray:
    """The canvas as it is drawn (RGB, device pixels = CSS pixels here)."""
    from PIL import Image

    png = page.locator("#canvas").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def projected_joints(page, positions: np.ndarray) -> np.ndarray:
    """Screen pixels of world points ``(N, 3)`` with the page's camera (projection × view)."""
    cam = page.evaluate("""() => { const c = window.studio.player.camera; c.updateMatrixWorld();
        return {p: c.projectionMatrix.elements, v: c.matrixWorldInverse.elements,
                w: window.studio.player.canvas.clientWidth, h: window.studio.player.canvas.clientHeight}; }""")
    proj = np.array(cam["p"]).reshape(4, 4).T @ np.array(cam["v"]).reshape(4, 4).T  # column-major
    clip = np.c_[positions, np.ones(len(positions))] @ proj.T
    ndc = clip[:, :2] / clip[:, 3:]
    return np.c_[(ndc[:, 0] + 1) / 2 * cam["w"], (1 - ndc[:, 1]) / 2 * cam["h"]]


def test_library_lists_takes_and_the_malformed_file(studio, page):
    base, lib = studio
    requested = []
    page.on("request", lambda r: requested.append(r.url))
    open_view(page, base, "")
    page.wait_for_function("!document.querySelector('#library-status').textContent.includes('reading')")
    rows = page.locator("#takes tbody tr")
    assert rows.count() == 3
    text = page.inner_text("#takes")
    assert "walk.bvh\t31\t524\t120\t4.36\tcmu_cgspeed" in text
    assert f"session2/walk_turned.usda\t31\t{524 - SHIFT}" in text
    # the malformed file's row: its name, and the very line `usdmotion info broken.bvh` prints in that folder
    assert page.locator("#takes tr.failed td").all_inner_texts() == ["broken.bvh", cli_error_line(lib, "broken.bvh")]
    page.fill("#filter", "turned")
    assert page.locator("#takes tbody tr").count() == 1
    page.fill("#filter", "")
    page.click("#takes th[data-sort=frames]")
    names = page.locator("#takes tbody tr td:first-child").all_inner_texts()
    assert names[:2] == ["session2/walk_turned.usda", "walk.bvh"]  # fewer frames first, the failed file last
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / "library.png")
    # everything the page loads (three.js, uPlot, our modules, data) comes from the studio itself: no CDN
    assert any("/vendor/three/build/three.module.js" in u for u in requested)
    assert [u for u in requested if not u.startswith(base) and not u.startswith("data:")] == []


def test_opening_a_take_draws_the_body_at_its_joints(studio, page):
    base, lib = studio
    open_view(page, base, f"take={WALK_ID}&f=200&cam=side")
    page.wait_for_function("window.studio.player.figure.body !== null", timeout=60_000)
    page.wait_for_timeout(300)
    drawn = canvas_pixels(page)
    page.uncheck("#show-stick")
    page.wait_for_timeout(300)
    body_only = canvas_pixels(page)
    page.uncheck("#show-body")
    page.wait_for_timeout(300)
    empty = canvas_pixels(page)
    walk = read_motion(lib / "walk.bvh", units="asf")
    non_end = np.flatnonzero(~walk.end_sites)
    points = projected_joints(page, (joint_positions(walk)[200] * walk.meters_per_unit)[non_end])
    h, w = drawn.shape[:2]
    assert (points[:, 0] > 0).all() and (points[:, 0] < w).all() and (points[:, 1] > 0).all()
    changed = np.abs(drawn - empty).sum(axis=2) > 30
    hits = [changed[max(0, int(y) - 2):int(y) + 3, max(0, int(x) - 2):int(x) + 3].any() for x, y in points]
    assert np.mean(hits) >= 0.9, f"{np.mean(hits):.0%} of joints drawn"
    # the skinned body alone (GPU skinning of the server's GLB) covers the joints too
    changed = np.abs(body_only - empty).sum(axis=2) > 30
    hits = [changed[max(0, int(y) - 2):int(y) + 3, max(0, int(x) - 2):int(x) + 3].any() for x, y in points]
    assert np.mean(hits) >= 0.9, f"{np.mean(hits):.0%} of joints inside the drawn body"
    # and the frame is what was asked
    assert frame_of(page) == 200


def test_play_runs_at_the_capture_rate_and_scrub_lands(studio, page):
    base, _ = studio
    open_view(page, base, f"take={WALK_ID}&f=0&body=0")
    page.set_viewport_size({"width": 1280, "height": 720})
    sample = "() => [performance.now(), document.querySelector('#readout').textContent]"  # one JS task: consistent
    page.keyboard.press("Space")
    page.wait_for_timeout(300)
    start = page.evaluate(sample)
    page.wait_for_timeout(2000)
    end = page.evaluate(sample)
    page.keyboard.press("Space")
    frames = [int(re.match(r"frame (\d+)", text).group(1)) for _, text in (start, end)]
    rate = (frames[1] - frames[0]) / ((end[0] - start[0]) / 1000.0)
    assert 120 * 0.8 <= rate <= 120 * 1.2, f"played {rate:.1f} frames/s, capture is 120"
    # a loop range keeps playback inside it, wrapping from its end to its start
    page.keyboard.press("Home")
    page.locator("#scrub").fill("100")
    page.keyboard.press("[")
    page.locator("#scrub").fill("130")
    page.keyboard.press("]")
    assert page.inner_text("#range") == "loop 100–130"
    page.keyboard.press("Space")
    seen = []
    for _ in range(12):
        page.wait_for_timeout(80)
        seen.append(frame_of(page))
    page.keyboard.press("Space")
    assert min(seen) >= 100 and max(seen) <= 130 and any(b < a for a, b in zip(seen, seen[1:])), seen
    page.locator("#scrub").fill("333")
    assert frame_of(page) == 333
    page.keyboard.press("ArrowRight")
    assert frame_of(page) == 334
    assert "t=" not in address(page) and "f=334" in address(page)


def test_plot_cursor_follows_and_clicking_seeks(studio, page):
    base, _ = studio
    open_view(page, base, f"take={WALK_ID}&f=262&joints=LeftLeg&q=bend,com_height&comtrace=1&trace=RightHand&stick=0")
    page.wait_for_selector(".plot-cursor")
    page.wait_for_function("window.studio.player.figure.body !== null && window.studio.player.figure.traces.length == 2",
                           timeout=60_000)
    assert page.locator("#plots .plot").count() == 2  # deg and m
    over = page.locator("#plots .plot").first.locator(".u-over")
    box = over.bounding_box()
    cursor = page.locator("#plots .plot").first.locator(".plot-cursor").bounding_box()
    duration = 523 / 120.0
    assert abs(cursor["x"] - (box["x"] + box["width"] * (262 / 120.0) / duration)) < 3
    over.click(position={"x": box["width"] * 0.25, "y": box["height"] / 2})
    assert abs(frame_of(page) - 0.25 * 523) <= 2
    cursor = page.locator("#plots .plot").first.locator(".plot-cursor").bounding_box()
    assert abs(cursor["x"] - (box["x"] + box["width"] * 0.25)) < 3
    page.screenshot(path=SHOTS / "player_plots.png")


def test_compare_shows_two_bodies(studio, page):
    base, _ = studio
    open_view(page, base, f"take={TURNED_ID}&f=150&cmp={WALK_ID}&align=dtw&space=side&joints=LeftLeg")
    page.wait_for_function("window.studio.player.ghost !== null")
    assert "aligned in time by DTW" in page.inner_text("#compare-status")
    page.wait_for_function("window.studio.player.ghost.body !== null && window.studio.player.figure.body !== null",
                           timeout=60_000)
    page.wait_for_timeout(300)
    page.screenshot(path=SHOTS / "compare.png")
    both = canvas_pixels(page)
    hide = "(which) => { window.studio.player[which].group.visible = false; window.studio.player.dirty = true; }"
    page.evaluate(hide, "ghost")
    page.wait_for_timeout(300)
    main_only = canvas_pixels(page)
    page.evaluate(hide, "figure")
    page.wait_for_timeout(300)
    empty = canvas_pixels(page)
    ghost_px = (np.abs(both - main_only).sum(axis=2) > 30).sum()
    main_px = (np.abs(main_only - empty).sum(axis=2) > 30).sum()
    assert ghost_px > 2000 and main_px > 2000, (ghost_px, main_px)
    # the ghost is translucent orange: where only it differs, red dominates blue
    ghost_mask = (np.abs(both - main_only).sum(axis=2) > 30) & (np.abs(main_only - empty).sum(axis=2) <= 30)
    assert (both[ghost_mask][:, 0] - both[ghost_mask][:, 2]).mean() > 30
    ghost_frame = page.evaluate("window.studio.player.ghost.frame")
    assert abs(ghost_frame - (150 + SHIFT)) <= 2
    assert page.locator("#plots .uplot .u-legend").first.inner_text().count("(compare)") == 1
    # two synchronized views: the take on the left half, the ghost (orange) on the right half
    page.evaluate("() => { window.studio.player.figure.group.visible = true; }")
    page.select_option("#align-space", "split")
    page.wait_for_function("window.studio.player.split && window.studio.player.ghost && "
                           "window.studio.player.ghost.body !== null", timeout=60_000)
    page.wait_for_timeout(300)
    page.screenshot(path=SHOTS / "compare_two_views.png")
    split = canvas_pixels(page)
    orange = (split[..., 0] - split[..., 2] > 60) & (split[..., 0] > 150)
    half = split.shape[1] // 2
    assert orange[:, half:].sum() > 1000 and orange[:, :half].sum() < 50, (orange[:, :half].sum(), orange[:, half:].sum())
    assert (np.abs(split[:, :half] - empty[:, :half]).sum(axis=2) > 30).sum() > 1000  # the take on the left


def test_url_reopens_the_same_frame_and_camera(studio, browser, page):
    base, _ = studio
    open_view(page, base, f"take={WALK_ID}&f=10")
    page.select_option("#camera", "front")
    page.locator("#scrub").fill("77")
    page.keyboard.press("]")
    url = address(page)
    pose = page.evaluate("window.studio.player.cameraPose()")
    other = browser.new_page(viewport={"width": 1400, "height": 900})
    asked = []
    other.on("request", lambda r: asked.append(r.url.split("/api/")[1].split("?")[0]) if "/api/" in r.url else None)
    try:
        other.goto(url)
        other.wait_for_selector('body[data-loaded="1"]', state="attached", timeout=60_000)
        assert frame_of(other) == 77
        assert other.input_value("#camera") == "front"
        assert other.evaluate("window.studio.player.cameraPose()") == pose
        assert other.inner_text("#range") == "loop 0–77"
        # the page asked for the take's arrays before its scripts ran, and for its body once it could
        # draw (building it would slow the first frame), each once, and drew into the one WebGL context
        # it opened (index.html's openContext, once the take's arrays were read)
        assert [asked.count(what) for what in ("skeleton", "positions", "glb")] == [1, 1, 1], asked
        assert asked.index("positions") < asked.index("takes") and asked.index("positions") < asked.index("glb")
        assert other.evaluate("window.studio.player.renderer.getContext() === window.early.gl")
        # at the size the page lays the canvas out: its drawing buffer was made once (style.css and the
        # guess in index.html agree)
        assert other.evaluate("window.early.resized") is False
        # software WebGL here (SwiftShader): drawn without multisampling, which a GPU would do for free
        renderer, antialias = other.evaluate("[window.early.renderer, window.studio.player.renderer.getContext()"
                                             ".getContextAttributes().antialias]")
        assert "SwiftShader" in renderer and antialias is False, (renderer, antialias)
        # the tool panels' modules (and uPlot) and the library's list (hidden until then) are fetched only
        # once the take's first frame is drawn
        assert other.evaluate("""() => ['app/segment.js', 'app/edits.js', 'app/retarget.js', 'app/video.js',
            'vendor/uplot/dist/uPlot.esm.js', 'api/takes'].map(path => performance.getEntriesByName(new URL(path, location.origin).href)[0])
            .every(entry => entry && entry.startTime > window.studio.player.firstDrawnAt)""")
        assert other.evaluate("window.studio.player.figure.body !== null")
    finally:
        other.close()


def test_a_linked_page_is_painted_with_its_takes_first_frame(studio, browser):
    """A fresh page on a take's link shows its view alone, and draws nothing in it, until the take's
    first frame is there: the page's first contentful paint is that frame; then the rest of the page
    is shown, and the joints' spheres (left out of that frame: a costly shader program) follow. The
    address stays as it came until then (a new address repaints the browser's own window, which a
    software-rendered first frame waited for), and then holds the whole view. Nothing of the page is
    rendered before that frame either (its render-blocking hold: the browser's first rendering update,
    where animation frames run, comes after the frame was drawn)."""
    base, _ = studio
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.add_init_script("window.studioRevealMs = 120000")  # not the fallback's reveal on a slow machine
        page.add_init_script("""window.addressChanges = []; const replace = history.replaceState.bind(history);
            history.replaceState = (...args) => { window.addressChanges.push(performance.now()); replace(...args); };""")
        page.add_init_script("requestAnimationFrame(() => { window.firstRendering = performance.now(); })")
        open_view(page, base, f"take={WALK_ID}&f=100")
        page.wait_for_function("performance.getEntriesByName('first-contentful-paint').length > 0")
        painted, drawn, changes, rendering = page.evaluate(
            "[performance.getEntriesByName('first-contentful-paint')[0].startTime, "
            "window.studio.player.firstDrawnAt, window.addressChanges, window.firstRendering]")
        assert painted >= drawn, (painted, drawn)
        assert rendering >= drawn, (rendering, drawn)
        assert changes and min(changes) >= painted, (changes, painted)
        assert "f=100" in address(page) and "cam=side" in address(page), address(page)
        page.wait_for_function("!document.documentElement.classList.contains('opening')")
        assert page.is_visible("#library") and page.is_visible("#transport") and frame_of(page) == 100
        page.wait_for_function("window.studio.player.figure.joints.visible")
    finally:
        page.close()
    assert not errors, errors


def test_a_link_to_a_take_that_cannot_be_read_shows_its_line_alone(studio, page):
    """The CLI's line for the same file (``usdmotion info`` run in the library's folder), alone."""
    base, lib = studio
    for name in ("missing.bvh", "broken.bvh"):
        open_view(page, base, f"take=0/{name}")
        assert page.inner_text("#open-error") == cli_error_line(lib, name)
        assert page.is_hidden("#player")  # not the early canvas, grey with a stray line, beside the line
        assert not page.evaluate("document.documentElement.classList.contains('opening')")
    page.screenshot(path=SHOTS / "link_error.png")
    # the page and the server keep working: the list is there and a take opens from it
    assert page.locator("#takes tbody tr").count() == 3
    page.locator(f'#takes tr[data-id="{WALK_ID}"]').click()
    page.wait_for_function("window.studio.player.firstDrawnAt !== null")
    assert page.is_visible("#canvas") and page.is_hidden("#open-error") and page.is_hidden("#welcome")
    assert frame_of(page) == 0


def test_stroboscope_exports_a_png(studio, page):
    from PIL import Image

    base, _ = studio
    open_view(page, base, f"take={WALK_ID}&range=0-400&cam=side&stick=0")
    page.wait_for_function("window.studio.player.figure.body !== null", timeout=60_000)
    page.fill("#strobe-count", "6")
    page.click("#strobe")
    href = page.get_attribute("#strobe-png", "href")
    assert href.startswith("data:image/png;base64,")
    image = Image.open(io.BytesIO(base64.b64decode(href.split(",", 1)[1])))
    assert image.size == tuple(page.evaluate("[window.studio.player.canvas.width, window.studio.player.canvas.height]"))
    rgb = np.asarray(image.convert("RGB")).astype(int)
    body = (np.abs(rgb - [0xc8, 0xb8, 0xa8]).max(axis=2) < 40).sum()
    stick = ((rgb[..., 2] - rgb[..., 0] > 60) & (rgb[..., 2] > 120)).sum()  # the figure's blue
    assert body > 6 * 500 and stick < 20, (body, stick)  # six bodies, no stick figures (stick=0 in the view)
    page.screenshot(path=SHOTS / "stroboscope.png")
