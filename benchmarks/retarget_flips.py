"""Where the no-flip rule of issue 17 fails: per benchmark pair and method, the joints whose
per-frame rotation step exceeds their limit (``usdmotion.ops.retarget.quality``), with the
frames and steps, and the same for the initial guess (to tell the solve's flips from the
guess's).

Methods: the initial guess the pipeline picks (``init``), rotation copy, the plain solve
and the contact solve, each computed exactly as ``retarget(..., contacts="auto")`` does.
Solves are cached (``$USDMOTION_FLIPS_CACHE`` or ``/tmp/usdmotion_flips``; ``--fresh``
recomputes). Pairs: those of ``benchmarks/retarget_contacts.py`` (``--pair SUBSTRING``
picks some).

Run: ``python benchmarks/retarget_flips.py [--pair walk] [--fresh]``; writes
``benchmarks/results/retarget_flips.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, write_results  # noqa: E402
from retarget_contacts import PAIRS, read, scaled_legs  # noqa: E402

CACHE = Path(os.environ.get("USDMOTION_FLIPS_CACHE", "/tmp/usdmotion_flips"))


def setup_pair(source_spec, target_spec, target_kw):
    """``(source, setup, terms, options)`` exactly as ``retarget(contacts="auto")`` builds them."""
    from usdmotion.ops.contacts import detect_contacts
    from usdmotion.ops.retarget.contact_terms import contact_terms
    from usdmotion.ops.retarget.pipeline import prepare

    path, kw, first, stop = source_spec
    source = read(path, (first, stop), **kw)
    options = {}
    if isinstance(target_spec, float):
        target = scaled_legs(source, target_spec)
        options = {"lengths": "target", "root_scale": "legs"}
    else:
        target = read(target_spec, **target_kw)
    setup = prepare(source, target, lengths=options.get("lengths", "source"))
    terms = contact_terms(setup, source, detect_contacts(source), options.get("root_scale", "off"))
    if terms is not None:
        setup.targets[:, setup.mapped] += terms.shift[:, setup.mapped]
        setup.translations[:, setup.anchor] += terms.root_shift
    return source, setup, terms


def solutions(label, source, setup, terms, fresh: bool) -> dict:
    """``{method: (F, J, 4) local rotations}``; the solves cached on disk by pair and code version."""
    from usdmotion.ops.retarget import pipeline
    from usdmotion.ops.retarget.unmapped import continuous_hemisphere, unmapped_rules

    init = pipeline._choose_init(setup, "auto", "lm")
    q0 = setup.inits[init]
    rot_terms = (0.0, pipeline.PRIOR)
    out = {f"init ({init})": continuous_hemisphere(unmapped_rules(setup, q0, setup.translations.copy(),
                                                                  terms.floor if terms else None)[0])}
    copy_q = unmapped_rules(setup, setup.inits["copy"], setup.translations.copy(), terms.floor if terms else None)[0]
    out["rotation copy"] = continuous_hemisphere(copy_q)
    CACHE.mkdir(parents=True, exist_ok=True)
    key = hashlib.sha1((label + _code_version()).encode()).hexdigest()[:16]
    cached = CACHE / f"{key}.npz"
    if cached.exists() and not fresh:
        data = np.load(cached)
        out["plain"], out["contacts"] = data["plain"], data["contacts"]
        return out
    start = time.perf_counter()
    out["plain"] = pipeline._solve(setup, q0, None, rot_terms, "lm", None, None, terms.floor if terms else None)[0]
    out["contacts"] = pipeline._solve(setup, q0, terms, rot_terms, "lm", None, None)[0] if terms else out["plain"]
    np.savez(cached, plain=out["plain"], contacts=out["contacts"])
    print(f"  solved {label} in {time.perf_counter() - start:.0f} s (load {os.getloadavg()[0]:.1f})", flush=True)
    return out


def _code_version() -> str:
    """A hash of the retarget package's sources (a changed solver invalidates the cache)."""
    folder = Path(__file__).resolve().parents[1] / "usdmotion" / "ops"
    h = hashlib.sha1()
    for p in sorted(folder.rglob("*.py")):
        h.update(p.read_bytes())
    return h.hexdigest()


def flips(source, setup, q: np.ndarray, top: int = 3) -> list[dict]:
    """The joints of ``q (F, J, 4)`` above their limit: step, limit, the frames above it."""
    from usdmotion.ops.retarget.quality import step_limits

    rig = setup.rig
    dot = np.abs(np.sum(q[1:] * q[:-1], axis=-1)).clip(0.0, 1.0)
    steps = np.degrees(2 * np.arccos(dot))  # (F-1, J): step from frame f to f+1
    limits = step_limits(source, setup)
    rows = []
    for j in np.flatnonzero(~rig.end_sites & (steps.max(axis=0) > limits)):
        over = np.flatnonzero(steps[:, j] > limits[j])
        worst = over[np.argsort(-steps[over, j])][:top]
        src = setup.source_of[j]
        rows.append({"joint": rig.joint_names[j], "follows": setup.source.joint_names[src] if src >= 0 else None,
                     "step_deg": float(steps[:, j].max()), "limit_deg": float(limits[j]), "frames_over": len(over),
                     "worst": [(int(f + 1), round(float(steps[f, j]), 1)) for f in worst],
                     "optimised": bool(np.isin(j, setup.rot_joints))})
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pair", action="append", help="only pairs whose label contains this (repeatable)")
    parser.add_argument("--fresh", action="store_true", help="recompute cached solves")
    args = parser.parse_args(argv)
    from usdmotion.ops.retarget.jax_runtime import enable_compilation_cache

    enable_compilation_cache()
    report = []
    for label, source_spec, target_spec, target_kw in PAIRS:
        if args.pair and not any(p in label for p in args.pair):
            continue
        if any(isinstance(p, str) and not (SHARED_DATA / p).exists() for p in (source_spec[0], target_spec)):
            print(f"skip {label}: data not found under {SHARED_DATA}")
            continue
        source, setup, terms = setup_pair(source_spec, target_spec, target_kw)
        setup.source = source
        print(f"{label} ({source.n_frames} frames at {source.fps:g} fps)", flush=True)
        methods = solutions(label, source, setup, terms, args.fresh)
        row = {"pair": label, "methods": {}}
        for method, q in methods.items():
            found = flips(source, setup, q)
            row["methods"][method] = found
            print(f"  {method:16s} " + ("none" if not found else ""))
            for f in found:
                print(f"    {f['joint']:22s} <- {str(f['follows']):16s} {f['step_deg']:6.1f}/{f['limit_deg']:5.1f}° "
                      f"{f['frames_over']:4d} frames over; worst (frame, step) {f['worst']}"
                      + ("" if f["optimised"] else " [not optimised]"))
        report.append(row)
    write_results("retarget_flips", {"rows": report, "load_1min": os.getloadavg()[0]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
