"""Retargeting from files to files (what ``usdmotion retarget`` runs): options as the
command line gives them, output written atomically, a one-line summary returned."""

from __future__ import annotations

import json
from pathlib import Path

from usdmotion.errors import OutputError
from usdmotion.io import BVH_EXTENSIONS, USD_EXTENSIONS, write_motion
from usdmotion.io.atomic import atomic_output
from usdmotion.motion import Motion
from usdmotion.ops.retarget.hierarchy import RetargetError, parse_add
from usdmotion.ops.retarget.jointmap import load_joint_map
from usdmotion.ops.retarget.pipeline import retarget
from usdmotion.progress import Progress


def parse_scale(text) -> str | float:
    """``"units"``, ``"auto"`` or a positive number from ``--scale``."""
    if isinstance(text, str) and text.strip().lower() in ("units", "auto"):
        return text.strip().lower()
    try:  # a number, or its text; not a list, an object or a JSON integer past float's range
        value = float(text) if isinstance(text, (str, int, float)) and not isinstance(text, bool) else None
    except (ValueError, OverflowError):
        value = None
    if value is None:
        raise RetargetError(f"--scale must be 'units', 'auto' or a positive number, got {text!r:.80}")
    if not (value > 0 and value < float("inf")):
        raise RetargetError(f"--scale must be a positive number, got {text!r}")
    return value


def retarget_files(source: Motion, source_path: Path, output: Path, target: Motion | None = None,
                   target_path: Path | None = None, remove=(), add=(), map_path: Path | None = None,
                   method: str = "lm", iterations: int | None = None, lengths: str = "source",
                   directions: str = "auto", scale="units", init: str = "auto", local: bool = False,
                   report_path: Path | None = None, progress: Progress | None = None, contacts: str | None = None,
                   root_scale: str = "off", compare: bool = False) -> str:
    """Retarget, write ``output`` (BVH or USD by extension) and the JSON report; return a summary line.

    ``contacts``: ``"auto"``, ``"off"`` or a contacts JSON path (default: ``"auto"`` with a
    target skeleton, ``"off"`` for rigs derived with remove/add). Nothing is written when
    anything fails (checks run before the optimiser).
    """
    output = Path(output)
    if output.suffix.lower() not in BVH_EXTENSIONS + USD_EXTENSIONS:
        raise OutputError(f"{output}: unknown output format {output.suffix!r} (use .bvh, {', '.join(USD_EXTENSIONS)})")
    inputs = [Path(source_path)] + ([Path(target_path)] if target_path else []) + ([Path(map_path)] if map_path else [])
    inputs += [Path(contacts)] if contacts not in (None, "off", "auto") else []
    for path in [output] + ([Path(report_path)] if report_path else []):
        if any(path.resolve() == p.resolve() for p in inputs):
            raise OutputError(f"{path}: output would overwrite an input")
        if not path.parent.is_dir():
            raise OutputError(f"{path}: folder {path.parent} does not exist")
    if target is None and not remove and not add:
        raise RetargetError("give --target, or joints to --remove / --add")
    joint_map = load_joint_map(map_path) if map_path else None
    foot_contacts = _contacts(contacts, source, target is not None, method)
    specs = [parse_add(spec) for spec in add]
    result = retarget(source, target, remove=remove, add=specs, joint_map=joint_map, method=method,
                      iterations=iterations, lengths=lengths, directions=directions, scale=parse_scale(scale),
                      init=init, local=local, source_path=str(source_path),
                      target_path=None if target_path is None else str(target_path), progress=progress,
                      contacts=foot_contacts, root_scale=root_scale, compare=compare and foot_contacts is not None)
    write_motion(result.motion, output)
    rep = result.report
    if report_path:
        with atomic_output(Path(report_path)) as tmp:
            tmp.write_text(json.dumps(rep, indent=2) + "\n", encoding="utf-8")
    return summary_line(result.motion, rep, output)


def _contacts(option: str | None, source: Motion, has_target: bool, method: str):
    """``None`` (off), ``"auto"`` or :class:`~usdmotion.ops.contacts.FootContacts` read from a JSON file."""
    if option is None:  # the default: contacts where the source's feet can be found
        if not (has_target and method == "lm"):
            return None
        import warnings

        from usdmotion.errors import InputError, UsdMotionWarning
        from usdmotion.ops.contacts import detect_contacts

        try:
            return detect_contacts(source)
        except InputError as exc:
            warnings.warn(f"no foot contacts ({exc.message}): solving without them (--contacts off)",
                          UsdMotionWarning, stacklevel=2)
            return None
    if option in ("off", "auto"):
        return None if option == "off" else option
    from usdmotion.ops.contacts.files import read_contacts_json

    return read_contacts_json(option, source)


def summary_line(motion: Motion, rep: dict, output: Path) -> str:
    """``wrote OUT: ... loss A -> B ...`` (one line)."""
    loss = rep["loss"]
    ratio = (f" = {100 * loss['final_over_copied']:.3g} % of copied rotations ({loss['copied']['total']:.6g})"
             if "final_over_copied" in loss else f" = {100 * loss['final_over_initial']:.3g} % of the initial guess")
    worst = max(rep["per_joint_rms"].items(), key=lambda kv: kv[1])
    return (f"wrote {output}: {rep['target_joints_without_end_sites']} joints, {rep['frames']} frames; "
            f"loss {loss['initial']['total']:.6g} -> {loss['final']['total']:.6g}{ratio}; per-joint RMS "
            f"{loss['final']['rms']:.4g} (worst {worst[0]} {worst[1]:.4g}) units; {rep['method']} on "
            f"{rep['device']}, {rep['time_s']['solve']:.2f} s ({rep['frames_per_second_solve']:.0f} frames/s) + "
            f"{rep['time_s']['compile']:.1f} s compiling{_feet(rep)}")


def _feet(rep: dict) -> str:
    """``; feet: skate X cm/s (plain Y) ...`` when the solve used contacts."""
    feet = rep.get("quality", {}).get("feet")
    if feet is None:
        return ""
    plain = rep.get("compare", {}).get("plain", {}).get("feet")
    versus = f" (plain solve {plain['skate_mean_cm_s']:.2f})" if plain else ""
    flips = rep["quality"]["flips"]
    return (f"; feet: skate {feet['skate_mean_cm_s']:.2f} cm/s{versus}, {100 * feet['skate_share']:.0f} % of "
            f"contact steps sliding, penetration {feet['penetration_max_cm']:.2f} cm, floating "
            f"{100 * feet['floating_share']:.0f} %; rotation steps above limit: "
            f"{', '.join(flips) if flips else 'none'}")
