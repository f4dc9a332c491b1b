"""Mutation-fuzzing campaign over every user input of the CLI (issue 16).

    python benchmarks/fuzz.py --minutes 10 [--seed 1] [--save] [--only convert_asf,convert_amc]

Mutates valid seeds (BVH, USDA, USDC, GLB, ASF, AMC, joint-map JSON, segments JSON, USD camera; see
``tests/fuzz_support.py``) and fuzzes render, retarget, edit and analysis options (absurd numbers
included), runs each case through
the real CLI in-process and classifies it: ``ok`` (exit 0, output reads back), ``clean``
(exit 2, one ``usdmotion: error:`` line that is not a raw library message, nothing left) or
``defect``. Prints counts per
entry point and writes ``benchmarks/results/fuzz.json``. With ``--save`` each distinct
defect is kept as a reproducer in ``tests/data/malformed/fuzz/`` (file + command in
``manifest.json``), which ``tests/test_bad_input.py`` replays.

A case that takes the process past ``--max-rss-gb`` of memory (default 6) is a defect too: a
watchdog thread prints it, keeps its input with ``--save`` and ends the campaign (the case
itself may be stuck in native code; otherwise the kernel's OOM killer ends the process with
no word of which input did it).

GLB input is fuzzed too (byte-level mutations of a binary glTF); ASF and AMC as a pair: a
mutated ASF under the valid AMC seed, a mutated AMC on the valid ASF seed (convert, info).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import random
import re
import shutil
import sys
import tempfile
import threading
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import print_table, write_results  # noqa: E402
from fuzz_support import ENTRY_POINTS, MALFORMED, expand, make_seeds, mutate, option_case, run_case  # noqa: E402

#: Relative weight of each entry point (slow ones — JAX, GL — drawn less often).
WEIGHTS = {"convert_bvh": 6, "convert_bvh_small": 6, "info_bvh": 3, "convert_usda": 6, "convert_usdc": 3,
           "info_usda": 3, "convert_glb": 4, "convert_asf": 4, "convert_amc": 4, "info_amc": 2,
           "jointmap": 1, "segments": 3, "camera": 1, "render_options": 1, "retarget_options": 1,
           "edit_options": 2}
FUZZ_DIR = MALFORMED / "fuzz"


def _signature(reason: str) -> str:
    return re.sub(r"\d+|/[^ :]+", "#", reason)[:80]


def _save(case_name: str, data: bytes | None, suffix: str, args: list[str], reason: str, seen: set) -> None:
    key = (case_name, _signature(reason))
    if key in seen:
        return
    seen.add(key)
    FUZZ_DIR.mkdir(parents=True, exist_ok=True)
    manifest_path = FUZZ_DIR / "manifest.json"
    manifest = json.loads(manifest_path.read_text()) if manifest_path.is_file() else []
    name = f"{case_name}_{len(manifest):03d}{suffix}"
    if data is not None:
        (FUZZ_DIR / name).write_bytes(data)
    manifest.append({"file": name, "entry_point": case_name, "args": args, "found": reason[:200]})
    manifest_path.write_text(json.dumps(manifest, indent=1) + "\n")


def _stored(args: list[str], seeds: dict, src: Path, out_dir: Path) -> list[str]:
    """``args`` with the campaign's temporary paths as the placeholders the manifest keeps."""
    return [a.replace(str(seeds["walk"]), "{walk}").replace(str(src), "{src}").replace(str(out_dir / "out"), "{out}")
            .replace(str(seeds["asf"]), "{asf}").replace(str(seeds["amc"]), "{amc}") for a in args]


def _rss_bytes() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def watch_memory(limit_bytes: float, case: dict, save: bool, seen: set, work: Path) -> None:
    """Start a daemon thread that, once this process's RSS passes ``limit_bytes``, reports
    the running ``case`` (``{"name", "data", "suffix", "args", "stored"}``) as a defect on the
    real stdout (a case's own output is captured), keeps it with ``save``, removes ``work``
    and exits with status 3."""
    stdout = os.dup(1)

    def run() -> None:
        while _rss_bytes() <= limit_bytes:
            time.sleep(0.05)
        reason = f"memory: the process passed {limit_bytes / 2**30:.1f} GB of RSS"
        os.write(stdout, f"DEFECT {case.get('name')}: {reason}; usdmotion {' '.join(case.get('args', []))}\n".encode())
        if save and case.get("name"):
            _save(case["name"], case["data"], case["suffix"], case["stored"], reason, seen)
        shutil.rmtree(work, ignore_errors=True)
        os._exit(3)

    threading.Thread(target=run, daemon=True).start()


def campaign(minutes: float, seed: int, save: bool, only: list[str] | None = None, max_rss_gb: float = 6.0) -> dict:
    rng = random.Random(seed)
    work = Path(tempfile.mkdtemp(prefix="usdmotion-fuzz-"))
    seeds = make_seeds(work / "seeds")
    seed_bytes = {kind: path.read_bytes() for kind, path in seeds.items()}
    counts: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    defects: list[dict] = []
    seen: set = set()
    running: dict = {}  # the case now running, for the memory watchdog
    watch_memory(max_rss_gb * 2**30, running, save, seen, work)
    names, weights = zip(*[(k, w) for k, w in WEIGHTS.items() if not only or k in only])
    deadline = time.monotonic() + 60 * minutes
    started = time.monotonic()
    n = 0
    try:
        while time.monotonic() < deadline:
            name = rng.choices(names, weights)[0]
            case_dir = work / f"case{n}"
            out_dir = case_dir / "out"
            out_dir.mkdir(parents=True)
            data, suffix = None, ""
            if name in ("render_options", "retarget_options", "edit_options"):
                template = option_case(rng, name.split("_")[0])
                src = seeds["walk"]
            else:
                kind, template = ENTRY_POINTS[name]
                suffix = seeds[kind].suffix
                data = mutate(seed_bytes[kind], rng)
                src = case_dir / f"input{suffix}"
                src.write_bytes(data)
            args = expand(template, src, out_dir / "out", seeds["walk"], seeds)
            running.update(name=name, data=data, suffix=suffix, args=args, stored=_stored(args, seeds, src, out_dir))
            with warnings.catch_warnings():
                outcome = run_case(args, out_dir)
            counts[name][outcome.kind] += 1
            if outcome.kind == "defect":
                defects.append({"entry_point": name, "reason": outcome.reason, "args": args})
                print(f"DEFECT {name}: {outcome.reason}", flush=True)
                if save:
                    _save(name, data, suffix, running["stored"], outcome.reason, seen)
            shutil.rmtree(case_dir, ignore_errors=True)
            n += 1
    finally:
        shutil.rmtree(work, ignore_errors=True)
    elapsed = time.monotonic() - started
    return {"minutes": minutes, "seed": seed, "cases": n, "seconds": round(elapsed, 1),
            "counts": {k: dict(v) for k, v in sorted(counts.items())}, "defects": defects[:200],
            "distinct_defects": len({(d["entry_point"], _signature(d["reason"])) for d in defects})}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--save", action="store_true", help="keep each distinct defect in tests/data/malformed/fuzz")
    parser.add_argument("--only", help=f"comma-separated entry points (of {', '.join(WEIGHTS)})")
    parser.add_argument("--max-rss-gb", type=float, default=6.0, help="a case past this much memory is a defect")
    args = parser.parse_args()
    only = args.only.split(",") if args.only else None
    if only and not set(only) <= set(WEIGHTS):
        parser.error(f"unknown entry points: {', '.join(sorted(set(only) - set(WEIGHTS)))}")
    result = campaign(args.minutes, args.seed, args.save, only, args.max_rss_gb)
    rows = [[name, sum(c.values()), c.get("ok", 0), c.get("clean", 0), c.get("defect", 0)]
            for name, c in result["counts"].items()]
    rows.append(["total", sum(r[1] for r in rows), sum(r[2] for r in rows), sum(r[3] for r in rows),
                 sum(r[4] for r in rows)])
    print_table(f"fuzz campaign: {result['cases']} cases in {result['seconds']} s (seed {result['seed']})",
                ["entry point", "cases", "ok", "clean error", "defect"], rows)
    print(f"distinct defects: {result['distinct_defects']}")
    print(f"wrote {write_results('fuzz' if not only else 'fuzz_only', result)}")


if __name__ == "__main__":
    main()
