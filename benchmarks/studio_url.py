"""Where a fresh page on a take's URL spends its time before the first frame (issue 13's `url` row of
``benchmarks/studio.py``, taken apart).

    PYTHONPATH=$PWD .venv/bin/python benchmarks/studio_url.py [--runs 3] [--frames 5000] [--peer DIR] [--link]

Each run starts a fresh headless Chromium (software WebGL, the tests' flags) on a copy of the
5,000-frame take the server has not read, opens ``/?take=...`` and records, in ms from navigation:
the HTML parsed (``domInteractive``), main.js fetched, the server had the take's positions (their
response started: it is sent once computed; the server reads the file first), the first
render and its pixels, when that frame was on the screen (the page's first contentful paint: a
linked page shows its view alone, and draws nothing in it, until the take's first frame; Chrome
times a paint when the GPU process presented it), the body's pixels; and the calls into WebGL that
blocked the page for more than 3 ms before the first pixels (each is a round trip to the GPU process:
context creation, the first query after it, shader link status, the benchmark's pixel read-back), by kind. Medians over
the runs; prints a table and writes ``benchmarks/results/studio_url.json``. The server is
``usdmotion studio`` of this checkout in its own process; ``--peer DIR`` (another checkout, e.g. main's,
see ``benchmarks/studio.py``) runs the same against its studio, alternated run by run, and prints the
ratios of the medians (ours / peer).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import scratch_folder  # noqa: E402

#: Times every WebGL call and getContext; keeps those over 3 ms (they waited for the GPU process).
GL_LOG = """(() => {
  window.glWaits = [];
  const wrap = (proto, name) => {
    const f = proto[name];
    proto[name] = function (...args) {
      const t = performance.now(), result = f.apply(this, args), dt = performance.now() - t;
      if (dt > 3) window.glWaits.push([name, t, dt]);
      return result;
    };
  };
  for (const name of Object.getOwnPropertyNames(WebGL2RenderingContext.prototype)) {
    if (typeof Object.getOwnPropertyDescriptor(WebGL2RenderingContext.prototype, name).value === 'function') {
      wrap(WebGL2RenderingContext.prototype, name);
    }
  }
  wrap(HTMLCanvasElement.prototype, 'getContext');
})()"""

READ = """() => {
  const p = window.studio.player, nav = performance.getEntriesByType('navigation')[0];
  const entry = part => performance.getEntriesByType('resource').find(e => e.name.includes(part)) || {};
  const waits = window.glWaits.filter(([, t]) => t < p.firstPixelsAt);
  return {request: nav.requestStart, response: nav.responseStart, dom_interactive: nav.domInteractive,
          main_js: entry('/app/main.js').responseEnd,
          positions: entry('/api/positions').responseStart, positions_end: entry('/api/positions').responseEnd,
          skeleton: entry('/api/skeleton').responseStart, skeleton_end: entry('/api/skeleton').responseEnd,
          first_render: p.firstDrawnAt, first_pixels: p.firstPixelsAt,
          on_screen: (performance.getEntriesByName('first-contentful-paint')[0] || {startTime: NaN}).startTime,
          body_pixels: p.bodyPixelsAt,
          marks: Object.fromEntries(performance.getEntriesByType('mark').map(m => [m.name, m.startTime])),
          gl_waits: waits.map(([name, , dt]) => [name, dt])};
}"""

COLUMNS = ("request", "response", "dom_interactive", "main_js", "skeleton", "skeleton_end", "positions",
           "positions_end", "first_render", "first_pixels",
           "on_screen", "body_pixels", "gl_wait_total")


def one_run(p, base: str, take_ids: list[str]) -> dict:
    """The row of the last of ``take_ids``, each opened in turn in a new page of one fresh browser
    (two: ``--link``, the second a link opened in a running browser)."""
    from test_studio_browser import ARGS, CHROMIUM

    browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
    try:
        for take_id in take_ids:
            page = browser.new_page(viewport={"width": 1800, "height": 1200})
            page.add_init_script("window.studioTimings = true")
            page.add_init_script(GL_LOG)
            page.goto(f"{base}/?take={take_id}")
            page.wait_for_function("window.studio && window.studio.player.bodyPixelsAt !== null", timeout=300_000)
            page.wait_for_function("performance.getEntriesByName('first-contentful-paint').length", timeout=60_000)
            row = page.evaluate(READ)
            page.close()  # as benchmarks/studio.py closes the page before its link
    finally:
        browser.close()
    by_kind = collections.Counter()
    for name, dt in row.pop("gl_waits"):
        by_kind[name] += dt
    row["gl_wait_total"] = sum(by_kind.values())
    row["gl_waits_ms"] = dict(by_kind.most_common())
    row["load_average_1min"] = os.getloadavg()[0]
    row.update({f"mark_{name}": t for name, t in row.pop("marks").items()})
    return row


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--frames", type=int, default=5000)
    ap.add_argument("--peer", type=Path, help="another checkout to compare with, alternated run by run")
    ap.add_argument("--link", action="store_true", help="time a second page, opened in the running browser on "
                                                         "another unread take (the link row of studio.py)")
    args = ap.parse_args()
    import contextlib

    from playwright.sync_api import sync_playwright

    from studio import make_take, studio_process, unread_copies

    tmp = scratch_folder("studio_url_")
    take = make_take(tmp, args.frames)
    trees = [ROOT, *([args.peer.resolve()] if args.peer else [])]
    pages = 2 if args.link else 1
    ids = {tree: unread_copies(take, f"unread{k}_", args.runs * pages) for k, tree in enumerate(trees)}
    runs = {tree: [] for tree in trees}
    loads = [os.getloadavg()[0]]
    with contextlib.ExitStack() as stack, sync_playwright() as p:
        bases = {tree: stack.enter_context(studio_process(tree, take.parent, tmp / f"out{k}"))
                 for k, tree in enumerate(trees)}
        for i in range(args.runs):
            for tree in trees:
                runs[tree].append(one_run(p, bases[tree], ids[tree][i * pages:(i + 1) * pages]))
    loads.append(os.getloadavg()[0])
    rows = runs[ROOT]
    print(f"load average (1 min): {min(loads):.1f}-{max(loads):.1f}")
    opened = "a new page of a running browser" if args.link else "fresh page"
    print(f"{opened} on the URL of an unread {args.frames}-frame take; ms from navigation, median of {args.runs}")
    print("".join(f"{c:>{max(9, len(c) + 1)}}" for c in COLUMNS))
    medians = {c: statistics.median(r[c] for r in rows) for c in COLUMNS}
    print("".join(f"{medians[c]:>{max(9, len(c) + 1)}.0f}" for c in COLUMNS))
    marks = sorted({k for r in rows for k in r if k.startswith("mark_")},
                   key=lambda k: statistics.median(r.get(k, float("nan")) for r in rows))
    if marks:  # the page's own performance.mark()s (index.html, main.js), in the order they came
        print("page marks (ms from navigation, median): " + ", ".join(
            f"{k[5:]} {statistics.median(r[k] for r in rows if k in r):.0f}" for k in marks))
    kinds = collections.Counter()
    for r in rows:
        kinds.update(r["gl_waits_ms"])
    print("WebGL calls that waited for the GPU process before the first pixels (ms, mean per run): " +
          ", ".join(f"{name} {ms / len(rows):.0f}" for name, ms in kinds.most_common()))
    peer = None
    if args.peer:
        peer = {c: statistics.median(r[c] for r in runs[trees[1]]) for c in COLUMNS}
        print(f"peer {trees[1]}, medians (alternated run by run with ours):")
        print("".join(f"{peer[c]:>{max(9, len(c) + 1)}.0f}" for c in COLUMNS))
        print("ratio ours / peer: " + ", ".join(
            f"{c} {medians[c] / peer[c]:.2f}" for c in ("positions", "first_render", "first_pixels", "on_screen",
                                                       "body_pixels")))
    out = ROOT / "benchmarks" / "results" / "studio_url.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"frames": args.frames, "medians_ms": medians, "runs": rows,
                               "peer": None if peer is None else {"tree": str(trees[1]), "medians_ms": peer,
                                                                  "runs": runs[trees[1]]},
                               "load_average_1min": os.getloadavg()[0], "load_average_runs": loads}, indent=2))
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
