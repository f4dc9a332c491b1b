"""Cross-rig retargeting that a coach can trust (issue 17): feet, floor, flips, speed.

For every pair (CMU walk / jump / 86_01 → Bandai, DAZ, Mixamo, Rokoko rigs, and the CMU
walk onto its own skeleton with legs 0.8× and 1.2× as long, ``--lengths target
--root-scale legs``) three results are measured on the same targets:

* **rotation copy**: the source's local rotations copied onto the target's rest pose,
  the root placed on the source's (what Blender's and three.js' retargeting do);
* **plain**: the position-matching LM solve without contacts;
* **contacts**: the contact-aware LM solve (contacts detected in the source).

Columns: foot skate during contact (mean cm/s, share of contact steps sliding > 2 cm/s),
penetration (deepest contact joint below its planted level, cm; and the deepest of *all*
joints below the floor), floating (share of contact frames > 2 cm above the planted
level), joint-position RMS to the (scaled) source in cm, solve frames/s (compile
excluded, after a warm-up run; load average printed), and the no-flip check (joints whose largest per-frame
rotation step exceeds twice the source joint's, or 30°/frame at 120 fps if unmapped).
Then the automatic joint maps of the CMU source onto every rig profile's test skeleton
(``tests/data/rigs``, where present). Goals (issue 17): skate ≤ 1 cm/s and ≥ 80 % below
plain, penetration ≤ 0.5 cm, RMS ≤ +10 % over plain, ≥ 10,000 frames/s.

Also per pair the **stance drift** of the contact solve: the largest horizontal distance (mm)
of a contact joint from where it stood at the start of its contact, over every contact
(float64 forward kinematics of the written motion; issue 17's "stance feet fixed to 1 mm").

Run: ``python benchmarks/retarget_contacts.py [--quick] [--pairs TEXT[,TEXT...]] [--damping
fixed|nielsen]`` (quick: the walk pairs only; ``--pairs bandai,1.2x``: the pairs whose label
contains one of the texts; ``--damping``: LM's λ update, see
``usdmotion/ops/retarget/problem.py``). The frames/s column also gives the LM iterations of
the solve (the most any chunk ran): deterministic, unlike the timings on a loaded machine.
Writes ``benchmarks/results/retarget_contacts.json`` (``retarget_contacts_fixed.json``
with ``--damping fixed``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, SHARED_DATA, print_table, write_results  # noqa: E402

WALK = ("cmu/cgspeed_12_01_walk.bvh", {"units": "asf"}, 1, None)  # frame 0 is a synthetic T-pose
JUMP = ("cmu/cgspeed_01_01_playground_jumps.bvh", {"units": "asf"}, 1, 1201)
TAKE86 = ("cmu86/86_01_from_amc_cgspeed_layout.bvh", {"units": "asf"}, 0, 1200)
PAIRS = [
    ("walk -> Bandai", WALK, "bandai1/dataset-1_walk_normal_001.bvh", {}),
    ("walk -> DAZ", WALK, "cmu/daz_10_01_soccer_kick.bvh", {}),
    ("jumps -> Mixamo", JUMP, "other_rigs/20tab_test_freebvh_mixamorig.bvh", {}),
    ("86_01 -> Rokoko", TAKE86, "other_rigs/ad_rokoko_jesse_dance.bvh", {}),
    ("walk -> legs 0.8x", WALK, 0.8, {}),
    ("walk -> legs 1.2x", WALK, 1.2, {}),
]


def read(relative: str, frames=None, **kw):
    from usdmotion.io import read_motion

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        motion = read_motion(SHARED_DATA / relative, **kw)
    if frames is not None:
        first, stop = frames
        sl = slice(first, stop)
        jt = None if motion.joint_translations is None else motion.joint_translations[sl]
        motion = motion.with_frames(motion.rotations[sl], motion.root_translation[sl], jt)
    return motion


def scaled_legs(motion, factor: float):
    """The source skeleton with every bone below the hip joints ``factor`` times as long."""
    import dataclasses

    names = motion.joint_names
    offsets = motion.offsets.copy()
    for j, name in enumerate(names):
        p = motion.parents[j]
        if p >= 0 and any(k in names[p] for k in ("UpLeg", "Leg", "Foot", "Toe")):
            offsets[j] = offsets[j] * factor
    return dataclasses.replace(motion, offsets=offsets)


def load_pair(source_spec, target_spec, target_kw) -> tuple:
    """``(source, target, source path, target path, retarget options)`` of a pair of
    :data:`PAIRS`: a float target is the source with its legs scaled by it."""
    path, kw, first, stop = source_spec
    source = read(path, (first, stop), **kw)
    if isinstance(target_spec, float):
        options = {"lengths": "target", "root_scale": "legs"}
        return source, scaled_legs(source, target_spec), path, f"{path} (legs x{target_spec})", options
    return source, read(target_spec, **target_kw), path, target_spec, {}


def pairs_with_data(text: str = "", quick: bool = False) -> list[tuple]:
    """The :data:`PAIRS` whose label contains one of the comma-separated ``text`` (all when
    empty; ``quick``: the walk's only) and whose files are under ``SHARED_DATA`` (the others
    are named as skipped)."""
    wanted = [w.strip().lower() for w in text.split(",") if w.strip()]
    pairs = []
    for pair in PAIRS:
        label, source_spec, target_spec, _ = pair
        if (quick and source_spec is not WALK) or (wanted and not any(w in label.lower() for w in wanted)):
            continue
        missing = [p for p in (source_spec[0], target_spec) if isinstance(p, str) and not (SHARED_DATA / p).exists()]
        if missing:
            print(f"skip {label}: {missing[0]} not found under {SHARED_DATA}")
            continue
        pairs.append(pair)
    return pairs


def pairs_from_argv(description: str, argv=None) -> list[tuple]:
    """The pairs a ``--pairs TEXT[,TEXT...]`` command line picks (:func:`pairs_with_data`), with
    JAX's compile cache on: the command line of the per-pair studies of the contact solve."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--pairs", default="", help="comma-separated texts: only the pairs whose label contains one")
    args = parser.parse_args(argv)
    from usdmotion.ops.retarget.jax_runtime import enable_compilation_cache

    enable_compilation_cache()
    return pairs_with_data(args.pairs)


def run_pair(label, source_spec, target_spec, target_kw) -> dict:
    from usdmotion.ops.retarget.pipeline import retarget

    source, target, path, target_path, options = load_pair(source_spec, target_spec, target_kw)
    from usdmotion.ops.contacts import detect_contacts

    contacts = detect_contacts(source, source=path)
    # a first run compiles and warms up (the first call of a compiled solve pays one-time costs
    # that the plain solve of the timed run, called second, did not)
    retarget(source, target, contacts=contacts, source_path=path, target_path=target_path, **options)
    start = time.perf_counter()
    result = retarget(source, target, contacts=contacts, compare=True, source_path=path, target_path=target_path,
                      **options)
    rep = result.report
    rows = rep["compare"]
    rows["result"]["stance_drift_mm"] = stance_drift_mm(result.motion, rep, contacts)
    return {"pair": label, "source": path, "target": target_path, "frames": rep["frames"], "fps_motion": rep["fps"],
            "leg_ratio": rep["contacts"]["leg_ratio"], "contact_joints": rep["contacts"]["joints"],
            "options": options, "methods": {"rotation copy": rows["rotation_copy"], "plain": rows["plain"],
                                            "contacts": rows["result"]},
            "solve_fps": {"plain": rows["plain"].get("frames_per_second_solve"),
                          "contacts": rep["frames_per_second_solve"]},
            "iterations": {"plain": rows["plain"].get("iterations_run"), "contacts": rep["iterations_run"]},
            "wall_s": time.perf_counter() - start, "map": rep["map"]["pairs"]}


def stance_drift_mm(motion, report, contacts) -> float:
    """Largest horizontal distance (mm) of a target contact joint from its position at the
    start of its contact, over every contact interval of the report's contact joints."""
    from usdmotion.kinematics import joint_positions
    from usdmotion.ops.contacts.detect import UP_INDEX, runs

    world = joint_positions(motion) * motion.meters_per_unit * 1000.0
    horizontal = np.delete(world, UP_INDEX[motion.up_axis], axis=-1)
    worst = 0.0
    for name, part in zip(report["contacts"]["joints"], report["contacts"]["parts"]):
        j, c = motion.joint_names.index(name), contacts.parts.index(part)
        for a, b in runs(contacts.contact[:, c]):
            worst = max(worst, float(np.linalg.norm(horizontal[a:b, j] - horizontal[a, j], axis=-1).max()))
    return worst


def goals(row: dict) -> dict:
    plain, contact = row["methods"]["plain"], row["methods"]["contacts"]
    skate, plain_skate = contact["feet"]["skate_mean_cm_s"], plain["feet"]["skate_mean_cm_s"]
    return {
        "skate <= 1 cm/s": skate <= 1.0,
        "skate >= 80 % below plain": plain_skate > 0 and skate <= 0.2 * plain_skate,
        "penetration <= 0.5 cm": max(contact["feet"]["penetration_max_cm"], contact["floor"]["max_depth_cm"]) <= 0.5,
        "RMS <= +10 %": contact["rms_cm"] <= 1.1 * plain["rms_cm"],
        "no flips": not contact["flips"],
        ">= 10,000 frames/s": (row["solve_fps"]["contacts"] or 0) >= 10_000,
    }


def profile_maps() -> list[dict]:
    """The automatic map of the CMU walk onto every test skeleton in tests/data/rigs."""
    from usdmotion.ops.retarget.jointmap import resolve_map
    from usdmotion.ops.retarget.hierarchy import rig_from_motion
    from usdmotion.io import read_motion

    source = read(WALK[0], **WALK[1])
    folder = REPO / "tests" / "data" / "rigs"
    out = []
    for path in sorted(folder.glob("*")) if folder.is_dir() else []:
        if path.suffix.lower() not in (".bvh", ".usda", ".usd", ".usdc"):
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rig = rig_from_motion(read_motion(path), str(path))
            source_of, weights, jmap = resolve_map(None, source.joint_names, rig.joint_names, rig.end_sites)
        except Exception as exc:  # noqa: BLE001 - a benchmark lists what failed
            out.append({"rig": path.name, "error": str(exc)})
            continue
        pairs = {rig.joint_names[j]: source.joint_names[o] for j, o in enumerate(source_of) if o >= 0}
        out.append({"rig": path.name, "how": jmap.how, "mapped": len(pairs),
                    "joints": int((~rig.end_sites).sum()), "pairs": pairs})
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the walk pairs only")
    parser.add_argument("--damping", choices=("fixed", "nielsen"), default="nielsen",
                        help="LM's damping update (default nielsen, the library's default)")
    parser.add_argument("--pairs", default="", help="comma-separated texts: only the pairs whose label contains one "
                                                      "(case-insensitive), e.g. 'bandai,1.2x'")
    args = parser.parse_args(argv)
    import importlib

    from usdmotion.ops.retarget.jax_runtime import device_description, enable_compilation_cache

    importlib.import_module("usdmotion.ops.retarget.solve").DAMPING = args.damping
    name = "retarget_contacts" + ("" if args.damping == "nielsen" else "_" + args.damping)
    enable_compilation_cache()
    rows = []
    for label, source_spec, target_spec, target_kw in pairs_with_data(args.pairs, quick=args.quick):
        row = run_pair(label, source_spec, target_spec, target_kw)
        row["load_1min"] = os.getloadavg()[0]
        row["goals"] = goals(row)
        rows.append(row)
        c, pl = row["methods"]["contacts"], row["methods"]["plain"]
        print(f"{label}: {row['wall_s']:.0f} s, load {row['load_1min']:.1f}; skate {pl['feet']['skate_mean_cm_s']:.2f}"
              f" -> {c['feet']['skate_mean_cm_s']:.2f} cm/s, RMS {pl['rms_cm']:.2f} -> {c['rms_cm']:.2f} cm, "
              f"stance drift {c['stance_drift_mm']:.1f} mm, flips {len(c['flips'])}", flush=True)
        write_results(name, {"device": device_description(), "damping": args.damping, "rows": rows,
                             "partial": True})
    table = []
    for row in rows:
        for method, q in row["methods"].items():
            fps = row["solve_fps"].get(method)
            table.append([row["pair"], method, f"{q['feet']['skate_mean_cm_s']:.2f}",
                          f"{100 * q['feet']['skate_share']:.0f} %", f"{q['feet']['penetration_max_cm']:.2f}",
                          f"{q['floor']['max_depth_cm']:.2f}", f"{100 * q['feet']['floating_share']:.0f} %",
                          f"{q['rms_cm']:.2f}", "-" if fps is None else f"{fps:,.0f} ({row['iterations'][method]})",
                          f"{q['stance_drift_mm']:.2f}" if "stance_drift_mm" in q else "-",
                          ", ".join(f"{k} {v['step_deg']:.0f}/{v['limit_deg']:.0f}°" for k, v in
                                    list(q["flips"].items())[:3]) + (" ..." if len(q["flips"]) > 3 else "")
                          or "none"])
    print()
    print_table(f"Retargeting with contacts ({device_description()}; LM damping {args.damping}; 1-min load average "
                f"{os.getloadavg()[0]:.1f}; frames/s: solve only, compile excluded)",
                ["pair", "method", "skate cm/s", "sliding", "pen. feet cm", "below floor cm", "floating", "RMS cm",
                 "frames/s (LM iterations)", "stance drift mm", "rotation steps above limit (step/limit)"], table)
    print()
    print_table("Goals (contact solve)", ["pair", *rows[0]["goals"]] if rows else ["pair"],
                [[r["pair"], *("yes" if v else "NO" for v in r["goals"].values())] for r in rows])
    maps = profile_maps()
    print()
    for m in maps:
        if "error" in m:
            print(f"map onto {m['rig']}: {m['error']}")
        else:
            print(f"map onto {m['rig']} ({m['how']}): {m['mapped']} of {m['joints']} joints: "
                  + ", ".join(f"{k}<-{v}" for k, v in m["pairs"].items()))
    path = write_results(name, {"device": device_description(), "damping": args.damping, "rows": rows, "maps": maps})
    print(f"\nwrote {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
