"""Write docs/errors.md: every error and warning message usdmotion can print, one line
each, with what to do.

    .venv/bin/python scripts/errors_catalogue.py          # rewrite docs/errors.md
    .venv/bin/python scripts/errors_catalogue.py --check  # exit 1 if it is out of date

Messages are read from the source (``raise …Error("…")`` and ``warnings.warn("…")``,
f-string fields shown as ``…``), so the catalogue cannot miss one; the advice comes from
the rules below (first match wins, then the area's default). tests/test_bad_input.py
checks that the committed file is current.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "usdmotion"
OUT = REPO / "docs" / "errors.md"

#: (pattern on the message, what to do); first match wins.
ADVICE = [
    (r"not valid UsdSkel|fails pxr.UsdValidation",
     "A bug in usdmotion's USD writer, caught before anything was written: report it with the input file and "
     "command (USDMOTION_DEBUG=1 shows a traceback)."),
    (r"levels deep|joints; at most|more than … joints",
     "The skeleton exceeds the supported size (1,000 levels, 10,000 joints); check that the file really is a rig."),
    (r"no reader accepts",
     "The edit moved a value past ±1e15 (e.g. a huge --translate or --move); give the edit smaller values."),
    (r"float32", "A translation is too large for USD's float32 samples; fix the input (values must stay within ±1e15)."),
    (r"not a finite|non-finite|NaN|beyond ±|within ±",
     "A number is NaN, infinite or absurd (beyond ±1e15); fix the value at the line or path shown."),
    (r"--cutoff", "Give a low-pass cutoff in Hz within the range stated (see `usdmotion COMMAND --help`)."),
    (r"Frame Time|frame rate|^fps|fps must",
     "Give the frame time in seconds (0.008333 for 120 fps); rates from one frame an hour to 1 MHz are accepted."),
    (r"Frames:|--lenient", "Make 'Frames:' match the motion rows, or pass --lenient to keep the complete rows."),
    (r"guessed from the body|--units auto|--up-axis auto",
     "The units / up axis were guessed from the body (docs/units_guess.md); give --units / --up-axis to choose."),
    (r"repeats; renamed", "Nothing to do; rename the joint in the source if the new name matters downstream."),
    (r"USDMOTION_JAX_CACHE_MB", "Set it to a number of megabytes (0 or more), or unset it for the default (2000)."),
    (r"lies far from the source",
     "Look at the result before using it: the map may pair the wrong joints (`--report` lists it; write one with "
     "--map, docs/retarget.md) or the source is distorted (see its other warnings)."),
    (r"world positions", "Pass --ignore-joint-positions if the skeleton looks distorted."),
    (r"T-pose frame|--frames 1:", "Pass --frames 1: to skip the first frame."),
    (r"binary data|NUL|UTF-8|non-ASCII|empty file|not a BVH|is this a BVH",
     "The file is not a text BVH (or is empty/damaged); re-export it."),
    (r"OFFSET|CHANNELS|HIERARCHY|ROOT|JOINT|End Site|MOTION|'}'|'{'|braces|motion row|channel names|channel …",
     "The BVH is malformed at the line shown; fix it there (compare with a valid file from the same exporter)."),
    (r"USD: ", "USD's own diagnostic about the prim shown; check the file with `usdchecker FILE`."),
    (r"--scale|units look mismatched",
     "Retargeting's source size: `--scale units` (physical size, the default), `auto` (fitted to the target) or a "
     "factor near auto's; see docs/retarget.md."),
    (r"non-uniform scale … above the skeleton is not supported",
     "Apply the scale to the rig in the DCC tool and export again."),
    (r"joint scales|non-uniform scale",
     "Nothing to do unless the scale matters: usdmotion keeps rotations and translations only."),
    (r"as USD|UsdSkel|[Ss]keleton|root joints|rest transforms|usdz",
     "Check the file with usdview or `usdchecker FILE`: it must hold one UsdSkel Skeleton with a single root joint."),
    (r"[Cc]amera", "Give a USD file with a Camera prim (cam.usda or cam.usda:/Path/To/Camera) or a preset name."),
    (r"not valid JSON|not valid YAML|nested more|JSON serialisable",
     "Fix the JSON/YAML syntax at the line shown (`python -m json.tool FILE` points at it)."),
    (r"^/|invalid joint map at|^…: /", "The document does not follow its schema (schemas/); fix the value at the path shown."),
    (r"no joint named|no target joint|no source joint|joint map|rig profile|could be matched|not a joint of",
     "Use joint names from `usdmotion info FILE` (case-sensitive); write a joint map (docs/retarget.md)."),
    (r"overwrite the input", "Choose a different output path."),
    (r"folder|cannot write|permission", "Choose an existing, writable output folder."),
    (r"extension|format|pattern", "Use one of the extensions listed in the message."),
    (r"no such file", "Check the path."),
    (r"--\w|must be|outside|got …", "Give a value in the range stated (see `usdmotion COMMAND --help`)."),
]

#: Default advice by the module's area (path prefix under usdmotion/).
AREAS = [
    ("io/bvh", "Reading and writing BVH", "Fix the BVH at the line shown."),
    ("io/usd", "Reading and writing USD", "Check the stage with usdview or `usdchecker`."),
    ("usd_diagnostics", "Reading and writing USD", "Check the stage with usdview or `usdchecker`."),
    ("io", "Files in general", "Check the path and the file's format."),
    ("motion", "Motion data model (library use)", "Library use: pass arrays of the stated shapes (from files these "
                                                  "are reported as FILE: errors)."),
    ("render", "Rendering (docs/render.md)", "See docs/render.md for the option."),
    ("ops/retarget", "Retargeting (docs/retarget.md)", "See docs/retarget.md."),
    ("ops/jointmap", "Joint maps (docs/retarget.md)", "See docs/retarget.md (joint maps)."),
    ("ops/edit", "Editing (docs/edit.md)", "Adjust the edit's parameters as the message says (docs/edit.md)."),
    ("ops/segment", "Segmentation (docs/segment.md)", "See docs/segment.md."),
    ("ops/analys", "Analysis (docs/analyze.md)", "See docs/analyze.md."),
    ("ops", "Other operations", "Adjust the options as the message says."),
    ("cli", "Command-line options", "See `usdmotion COMMAND --help`."),
    ("studio", "Studio (docs/studio.md)", "Shown in the Studio's page (or its API answer); see docs/studio.md."),
    ("", "Biomechanics documents and models", "Fix the document at the path shown (schemas/)."),
]

FIXED = """\
| `interrupted; no partial output was kept` (exit 130) | Ctrl-C (at any moment, start-up and `batch` included): nothing was written; rerun. |
| `terminated by SIGTERM; no partial output was kept` (exit 143) | The process was stopped: nothing was written; rerun. |
| `internal error (…); rerun with USDMOTION_DEBUG=1 for a traceback` (exit 1) | A bug, not your input: report it with the traceback. |
| `… (see --help)` (exit 2) | A usage error (unknown option, missing argument): see `usdmotion COMMAND --help`. |
| (the help, no error line; exit 0) | `usdmotion` or `usdmotion batch` without a command shows what there is to run. |
"""


def _text(node) -> str | None:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "…" for v in node.values)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        return (_text(node.left) or "…") + (_text(node.right) or "…")
    return None


def messages() -> list[tuple[str, str, str]]:
    """``(module path, "error"|"warning", message template)`` of every message in the package."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = path.relative_to(PACKAGE).as_posix()
        for node in ast.walk(ast.parse(path.read_text("utf-8"))):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
                texts = [t for t in (_text(a) for a in node.exc.args[:2]) if t]
                if texts:
                    found.append((module, "error", texts[-1]))
            elif isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "warn" and node.args:
                text = _text(node.args[0])
                if text:
                    found.append((module, "warning", text))
    return found


def _clean(message: str) -> str:
    message = re.sub(r"^…:(…:)? ?", "", " ".join(message.split()))  # the FILE[:LINE] prefix
    return message.replace("|", "\\|").replace("`", "'")


def _advice(message: str, default: str) -> str:
    for pattern, advice in ADVICE:
        if re.search(pattern, message):
            return advice
    return default


def render() -> str:
    sections: dict[str, list[str]] = {}
    seen = set()
    for module, kind, message in messages():
        text = _clean(message)
        key = (kind, text)
        if key in seen or len(text) < 4:
            continue
        seen.add(key)
        prefix, title, default = next(a for a in AREAS if module.startswith(a[0]))
        row = f"| {'warning: ' if kind == 'warning' else ''}`{text}` | {_advice(text, default)} |"
        sections.setdefault(title, []).append(row)
    parts = ["# Errors and warnings",
             "",
             "Every message usdmotion can print, generated from the source by `scripts/errors_catalogue.py` "
             "(do not edit by hand; rerun it). `…` stands for a value filled in at run time.",
             "",
             "Errors are one line, `usdmotion: error: FILE[:LINE[:COLUMN]]: message`, exit code 2, and nothing is "
             "written; warnings are `usdmotion: warning: …` and the command goes on. USD's own C++ diagnostics are "
             "re-issued as `FILE: USD: </prim>: message` warnings (at most 5 per file). NumPy warnings never reach "
             "the user: while a file is read they become `FILE: invalid numbers in the motion (…)`.",
             "",
             "## Limits",
             "",
             "| Limit | Value | Why |",
             "|---|---|---|",
             "| joint depth | 1,000 levels | UsdSkel joint paths grow with depth² (a 50,000-deep chain needs "
             "gigabytes); bodies are ~10 deep, fingers and spline tails add tens |",
             "| joints | 10,000 | rigs with faces and fingers have a few hundred to ~2,000 |",
             "| any number read | ±1e15 | beyond it nothing survives USD's float32 or a sum in forward kinematics |",
             "| frame rate | 1/3600 … 1,000,000 fps | one frame an hour to a megahertz sensor |",
             "| JSON/YAML nesting | 64 levels | usdmotion documents need 4 |",
             "| Frames: | 100,000,000 | beyond, the header is called absurd |",
             "",
             "## Lenient cases, decided",
             "",
             "| Input | Decision |",
             "|---|---|",
             "| `Frame Time: 1e300` (or 1e-300) | refused: outside the frame-rate range above |",
             "| NaN, Infinity, 1e400 weights in a joint map | refused with the JSON path |",
             "| a joint map whose weights are all 0 | refused: fewer than 2 joints to fit |",
             "| `render --frames -1:` | refused: frames count from 0, no Python-style negative indices |",
             "| `End Site` without OFFSET | accepted: the tip sits at its joint (offset 0); an End Site only marks "
             "where a leaf ends, while a JOINT's OFFSET places every descendant, so a JOINT without one is refused |",
             "| a USD channel layout (customData) that is not a BVH layout | refused: it would be written into a BVH "
             "no reader can read |",
             "",
             "## Signals and bugs",
             "",
             "| Message | What to do |",
             "|---|---|",
             FIXED.rstrip()]
    for title in dict.fromkeys(title for _, title, _ in AREAS):
        if title in sections:
            parts += ["", f"## {title}", "", "| Message | What to do |", "|---|---|", *sections[title]]
    return "\n".join(parts) + "\n"


def main() -> int:
    text = render()
    if "--check" in sys.argv:
        if not OUT.is_file() or OUT.read_text("utf-8") != text:
            print(f"{OUT} is out of date: run .venv/bin/python scripts/errors_catalogue.py", file=sys.stderr)
            return 1
        return 0
    OUT.write_text(text, "utf-8")
    print(f"wrote {OUT}: {text.count(chr(10) + '| ')} lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())
