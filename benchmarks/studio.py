"""Studio speed: opening a 5,000-frame, 31-joint take to its first drawn frame, and playback
in headless Chromium (software WebGL, SwiftShader) at 1280×720; GLB size and the server's
time per request.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/studio.py [--frames 5000] [--play 6] [--library 3000] \
        [--runs 5] [--peer DIR]

Goals (issue 13): ≤ 1.0 s from opening the take to its first drawn frame; playback that keeps
real time at 1280×720 (frames are dropped, never slowed: the take's clock advances at the
capture rate whatever the drawing rate). The take is the bundled CMU walk (31 joints, 120 fps)
cycled by the library's ``cycle`` to ``--frames`` frames. "First drawn frame" is the first
canvas render after the click with the take in it (the stick figure from the server's FK),
taken twice: when ``render()`` was called, and when its pixels were there (the GPU process
compiles and draws after ``render()`` returns; the page reads one pixel back to wait for it, only
under the benchmark's ``window.studioTimings``); the goal ratio is of the pixels. The skinned body
(GLB) follows and is timed separately, cold (built) and warm (cached in the output folder).
The ``url`` row is the first page of a freshly started browser on a take the server has not read
(it includes the browser's GPU process starting: its first WebGL context waits for it); the ``link``
row the same in a new tab of that running browser, on another unread take (a link opened in the
browser a coach already has open). Their ``on screen`` column is when the first frame was presented
(the page's first contentful paint: a linked page shows its view alone, and draws nothing in it,
until the take's first frame is there; Chrome times a paint when the GPU process presented it).
The ``url`` and ``link`` rows are taken ``--runs`` times (a fresh browser each time, each on takes the
server has not read) and their medians reported, against a ``usdmotion studio`` process of this checkout
(the way a coach runs it: its own process). ``--peer DIR`` (another checkout of usdmotion, e.g. main's:
``git worktree add /tmp/main main`` and a link to this checkout's ``usdmotion/studio/web/node_modules``)
runs the same rows against that checkout's studio, alternated run by run with ours, and prints the
ratios of the medians (ours / peer): the comparison that holds on a loaded machine.
The ``floor`` line is what the browser alone costs: ``--runs`` fresh browsers on a page that only opens
a WebGL2 context, clears it and reads one pixel back (no server, no three.js), in the same run: the
``url`` row cannot be below it (the GPU process starting is most of it).
Also: how soon a library of ``--library`` files is listed and filled in.
Prints a table; writes ``benchmarks/results/studio.json``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import socket
import statistics
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
from _common import scratch_folder  # noqa: E402

CSS = "#view{width:1280px;height:720px;flex:none}"


def make_take(folder: Path, frames: int) -> Path:
    from usdmotion.io import read_motion, write_motion
    from usdmotion.ops.edit.cycle import cycle

    walk = read_motion(ROOT / "usdmotion" / "data" / "cmu_12_01_walk.bvh", units="asf")
    period = 300 - 30  # frames per loop: [0, 300) with a 30-frame cross-fade
    long = cycle(walk, 0, 300, 30, loops=-(-frames // period))
    long = long.sliced(0, frames)
    path = folder / "lib" / f"walk_{frames}.bvh"
    path.parent.mkdir(parents=True)
    write_motion(long, path)
    return path


@contextlib.contextmanager
def studio_process(tree: Path, lib: Path, out: Path):
    """``usdmotion studio LIB --units asf`` of the checkout ``tree``, in its own process, on a free
    port; yields the base URL; always stopped."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    proc = subprocess.Popen([sys.executable, "-m", "usdmotion", "studio", str(lib), "--units", "asf", "--no-open",
                             "--port", str(port), "--out", str(out)], cwd=tree,
                            env={**os.environ, "PYTHONPATH": str(tree)}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                urllib.request.urlopen(base + "/api/takes", timeout=5).read()
                break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"the studio of {tree} did not start") from None
                time.sleep(0.1)
        yield base
    finally:
        proc.terminate()
        proc.wait(30)


def unread_copies(take: Path, tag: str, n: int) -> list[str]:
    """Ids of ``n`` copies of ``take`` (a server opening one has read nothing of it yet)."""
    ids = []
    for i in range(n):
        copy = take.with_name(f"{tag}{i}_{take.name}")
        copy.write_bytes(take.read_bytes())
        ids.append(f"0/{copy.name}")
    return ids


def links(p, trees: list[Path], lib: Path, tmp: Path, runs: int, play_s: float) -> dict:
    """The ``url`` and ``link`` rows, ``runs`` times per checkout, alternated: ``{tree: {"url": [row...],
    "link": [row...]}}``."""
    from test_studio_browser import ARGS, CHROMIUM

    take = lib / next(f.name for f in lib.iterdir() if f.name.startswith("walk_"))
    ids = {tree: (unread_copies(take, f"url{k}_", runs), unread_copies(take, f"link{k}_", runs))
           for k, tree in enumerate(trees)}
    rows = {tree: {"url": [], "link": []} for tree in trees}
    with contextlib.ExitStack() as stack:
        bases = {tree: stack.enter_context(studio_process(tree, lib, tmp / f"out_{k}")) for k, tree in enumerate(trees)}
        for i in range(runs):
            for tree in trees:
                browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
                try:
                    rows[tree]["url"].append(open_and_play(browser, bases[tree], ids[tree][0][i], play_s, by_url=True))
                    rows[tree]["link"].append(open_and_play(browser, bases[tree], ids[tree][1][i], play_s,
                                                            by_url=True))  # a new tab of the running browser
                finally:
                    browser.close()
    return rows


#: The floor of the ``url`` row: a page that only opens a WebGL2 context, clears it and reads one pixel back,
#: and shows one word (its first contentful paint), in a fresh browser with the same flags.
FLOOR_PAGE = """<!doctype html><p>floor</p><canvas width=1280 height=720></canvas><script>
const gl = document.querySelector('canvas').getContext('webgl2');
gl.clearColor(0.5, 0.5, 0.5, 1); gl.clear(gl.COLOR_BUFFER_BIT);
gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
window.floorPixels = performance.now();
</script>"""


def floor_runs(p, base: str, runs: int) -> list[dict]:
    """``runs`` fresh browsers on :data:`FLOOR_PAGE` (answered by Playwright's router, no server):
    seconds from navigation to the pixel read back and to the first contentful paint."""
    from test_studio_browser import ARGS, CHROMIUM

    rows = []
    for _ in range(runs):
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1800, "height": 1200})
            page.route(f"{base}/floor", lambda route: route.fulfill(body=FLOOR_PAGE, content_type="text/html"))
            page.goto(f"{base}/floor")
            page.wait_for_function("window.floorPixels && performance.getEntriesByName('first-contentful-paint')"
                                   ".length", timeout=60_000)
            pixels, shown = page.evaluate("[window.floorPixels, performance.getEntriesByName("
                                          "'first-contentful-paint')[0].startTime]")
            rows.append({"pixels_s": pixels / 1000, "on_screen_s": shown / 1000})
        finally:
            browser.close()
    return rows


def median_row(rows: list[dict]) -> dict:
    """The median of each number over ``rows`` (the canvas size of the first)."""
    return {k: (rows[0][k] if k == "canvas" else statistics.median(r[k] for r in rows)) for k in rows[0]}


def server_timing(base: str, target: str) -> tuple[float, int, float]:
    """(server ms from the Server-Timing header, bytes, client ms) of one GET."""
    t = time.perf_counter()
    with urllib.request.urlopen(base + target, timeout=300) as r:
        body = r.read()
        header = r.headers.get("server-timing", "app;dur=nan")
    return float(header.split("dur=")[1]), len(body), 1e3 * (time.perf_counter() - t)


def open_and_play(browser, base: str, take_id: str, play_s: float, by_url: bool = False) -> dict:
    """Open the take by clicking it in the library (timed from the click), or by its URL on a
    fresh page (timed from navigation start: page, scripts, reading the file, FK)."""
    page = browser.new_page(viewport={"width": 1800, "height": 1200})
    page.add_init_script("window.studioTimings = true")  # the player also times when pixels are there
    if by_url:
        page.goto(f"{base}/?take={take_id}")
        t_click = 0.0
        page.wait_for_selector('body[data-loaded="1"]', state="attached", timeout=300_000)
        page.add_style_tag(content=CSS)
    else:
        page.goto(base + "/")
        page.wait_for_selector('body[data-loaded="1"]', state="attached", timeout=120_000)
        page.add_style_tag(content=CSS)
        row = page.locator(f'#takes tr[data-id="{take_id}"]')
        page.evaluate("() => { window.studio.player.firstDrawnAt = window.studio.player.firstPixelsAt = null; }")
        t_click = page.evaluate("() => performance.now()")
        row.click()
    page.wait_for_function("window.studio.player.firstPixelsAt !== null", timeout=120_000)
    page.wait_for_function("window.studio.player.bodyPixelsAt !== null", timeout=300_000)
    first, body, first_px, body_px = page.evaluate("['firstDrawnAt', 'bodyDrawnAt', 'firstPixelsAt', 'bodyPixelsAt']"
                                                   ".map(k => window.studio.player[k])")
    on_screen = None
    if by_url:  # the first contentful paint: the take's first frame presented (see the docstring)
        page.wait_for_function("performance.getEntriesByName('first-contentful-paint').length", timeout=60_000)
        on_screen = page.evaluate("performance.getEntriesByName('first-contentful-paint')[0].startTime") / 1000
    size = page.evaluate("[window.studio.player.canvas.width, window.studio.player.canvas.height]")
    page.keyboard.press("Space")
    page.wait_for_timeout(play_s * 1000)
    page.keyboard.press("Space")
    log = page.evaluate("window.studio.player.playLog")  # [ms, frame] of every frame drawn while playing
    page.close()
    (t0, f0), (t1, f1) = log[0], log[-1]
    seconds = (t1 - t0) / 1000
    return {"first_frame_s": (first - t_click) / 1000, "body_s": (body - t_click) / 1000,
            "first_pixels_s": (first_px - t_click) / 1000, "on_screen_s": on_screen,
            "body_pixels_s": (body_px - t_click) / 1000, "canvas": size,
            "take_frames_per_s": (f1 - f0) / seconds, "drawn_per_s": (len(log) - 1) / seconds}


def library_fill(browser, n_files: int, tmp: Path) -> dict:
    """A library of ``n_files`` small (malformed) BVH files: seconds from navigation until the
    list is shown, and until every file's metadata (here: its error) is filled in."""
    from studio_support import running_studio

    lib = tmp / "many"
    for i in range(n_files):
        folder = lib / f"athlete{i % 30:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / f"take{i:05d}.bvh").write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\n")
    with running_studio([lib], out=tmp / "out_many") as base:
        page = browser.new_page()
        t = time.perf_counter()
        page.goto(base + "/")
        page.wait_for_function(f"document.querySelectorAll('#takes tbody tr').length >= {n_files}")
        shown = time.perf_counter() - t
        page.wait_for_function("!document.querySelector('#library-status').textContent.includes('reading')",
                               timeout=600_000)
        filled = time.perf_counter() - t
        page.close()
    return {"files": n_files, "list_shown_s": shown, "filled_s": filled}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=5000)
    ap.add_argument("--play", type=float, default=6.0)
    ap.add_argument("--library", type=int, default=3000, help="files in the library-listing case")
    ap.add_argument("--runs", type=int, default=5, help="runs of the url and link rows (medians)")
    ap.add_argument("--peer", type=Path, help="another checkout to compare the url and link rows with")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    from studio_support import running_studio
    from test_studio_browser import ARGS, CHROMIUM

    tmp = scratch_folder("studio_bench_")
    take = make_take(tmp, args.frames)
    take_id = f"0/{take.name}"
    trees = [ROOT, *([args.peer.resolve()] if args.peer else [])]
    loads = [os.getloadavg()[0]]
    with sync_playwright() as p:
        link_rows = links(p, trees, take.parent, tmp, args.runs, args.play)
        floor = floor_runs(p, "http://127.0.0.1:9", args.runs)  # routed by Playwright: nothing listens there
    loads.append(os.getloadavg()[0])
    medians = {tree: {row: median_row(runs) for row, runs in link_rows[tree].items()} for tree in trees}
    rows = dict(medians[ROOT])
    with running_studio([take.parent], units="asf", out=tmp / "out") as base, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            rows["cold"] = open_and_play(browser, base, take_id, args.play)  # server reads, FK, builds the body
            rows["warm"] = open_and_play(browser, base, take_id, args.play)  # server caches, GLB from out/cache
            library = library_fill(browser, args.library, tmp)
        finally:
            browser.close()
        requests = {name: server_timing(base, target) for name, target in [
            ("takes", "/api/takes"), ("meta", f"/api/meta?id={take_id}"), ("skeleton", f"/api/skeleton?take={take_id}"),
            ("positions", f"/api/positions?take={take_id}"), ("com", f"/api/com?take={take_id}"),
            ("series", f"/api/series?take={take_id}&joints=LeftLeg,RightLeg&q=bend,speed,com_height"),
            ("glb", f"/api/glb?take={take_id}")]}
    print(f"load average (1 min): {min(loads):.1f}-{max(loads):.1f} while the url and link rows ran, "
          f"{os.getloadavg()[0]:.1f} at the end")
    print(f"studio: {args.frames}-frame, 31-joint take at 120 fps; headless Chromium {platform.machine()}, "
          "SwiftShader WebGL, canvas " + "x".join(map(str, rows["cold"]["canvas"])))
    print("url: fresh page on the take's URL, timed from navigation (reads the file); link: the same in a new tab "
          "of the running browser (another unread take); cold: click in the library (file read while listing), "
          "body built; warm: click again, body from the cache")
    print("first frame / body: when render() was called; pixels: when the GPU process had drawn that frame "
          "(one pixel read back)")
    print("on screen (url, link): the page's first contentful paint, i.e. the take's first frame presented")
    print(f"{'open':<6}{'first frame s':>15}{'pixels s':>10}{'goal ratio':>12}{'on screen s':>13}{'body s':>9}"
          f"{'pixels s':>10}{'take frames/s':>15}{'drawn/s':>9}")
    for name, r in rows.items():
        shown = f"{r['on_screen_s']:>13.3f}" if r["on_screen_s"] is not None else f"{'-':>13}"
        print(f"{name:<6}{r['first_frame_s']:>15.3f}{r['first_pixels_s']:>10.3f}"
              f"{r['first_pixels_s'] / 1.0:>12.2f}{shown}"
              f"{r['body_s']:>9.2f}{r['body_pixels_s']:>10.2f}{r['take_frames_per_s']:>15.1f}{r['drawn_per_s']:>9.1f}")
    print(f"url, link: medians of {args.runs} runs (a fresh browser each) against `usdmotion studio` in its own "
          "process; pixels over the runs: " + "; ".join(
              f"{row} " + ", ".join(f"{r['first_pixels_s']:.3f}" for r in link_rows[ROOT][row])
              for row in ("url", "link")))
    floor_median = median_row(floor)
    print(f"floor (a fresh browser on a page that only opens a WebGL2 context, clears it and reads a pixel, "
          f"median of {args.runs}): pixels {floor_median['pixels_s']:.3f} s, on screen "
          f"{floor_median['on_screen_s']:.3f} s (runs: " + ", ".join(f"{r['pixels_s']:.3f}" for r in floor) + ")")
    if args.peer:
        peer = medians[trees[1]]
        print(f"peer {trees[1]} (alternated run by run with ours), medians, s, and ours / peer:")
        for row in ("url", "link"):
            ours, theirs = medians[ROOT][row], peer[row]
            ratio = {k: ours[k] / theirs[k] for k in ("first_pixels_s", "on_screen_s", "body_pixels_s")}
            print(f"  {row:<5} pixels {theirs['first_pixels_s']:.3f} (ratio {ratio['first_pixels_s']:.2f}), "
                  f"on screen {theirs['on_screen_s']:.3f} (ratio {ratio['on_screen_s']:.2f}), "
                  f"body pixels {theirs['body_pixels_s']:.2f} (ratio {ratio['body_pixels_s']:.2f})")
    print(f"{'request (warm)':<16}{'server ms':>10}{'bytes':>12}{'client ms':>11}")
    for name, (server_ms, size, client_ms) in requests.items():
        print(f"{name:<16}{server_ms:>10.1f}{size:>12,}{client_ms:>11.1f}")
    print(f"library of {library['files']:,} files: list shown {library['list_shown_s']:.2f} s after navigation, "
          f"all metadata in {library['filled_s']:.2f} s")
    out = ROOT / "benchmarks" / "results" / "studio.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"frames": args.frames, "open": rows, "goal_first_frame_s": 1.0,
                               "load_average_1min": os.getloadavg()[0], "load_average_links": [min(loads), max(loads)],
                               "runs": args.runs, "floor_runs": floor, "link_runs": {str(t): v for t, v in link_rows.items()},
                               "peer": None if not args.peer else {"tree": str(trees[1]), "medians": medians[trees[1]]},
                               "requests_warm": {k: {"server_ms": v[0], "bytes": v[1], "client_ms": v[2]}
                                                 for k, v in requests.items()},
                               "glb_bytes": requests["glb"][1], "library": library}, indent=2))
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
