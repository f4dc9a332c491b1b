"""``--units auto`` / ``--up-axis auto`` (the default for BVH) on every BVH in ../shared/data, against the data README.

    .venv/bin/python benchmarks/units_guess.py        # prints the table, writes docs/units_guess.md

For each file: the guess of :func:`usdmotion.units_guess.guess_body` (units, up axis,
reasons) next to the units and up axis the data README states in its "Units, up" column
(parsed: "metres…" → m, "ASF" → asf, "inch" → in, "cm" → cm, anything else → no unit;
"Z-up"/"Y-up"), and whether they agree. A file whose README states no unit ("n/a",
"cm-like" synthetic files) counts as right when no guess is made. Then the default reading,
``read_motion(path)`` without options, against the README too (its units in metres per unit:
the README's where it states one, cm otherwise; its up axis: the README's, Y where it states none).
"""

from __future__ import annotations

import re
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, SHARED_DATA, print_table, write_results  # noqa: E402

DOC = REPO / "docs" / "units_guess.md"


def readme_units() -> dict[str, tuple[str | None, str | None, str]]:
    """File → (unit, up axis, the README's words) from the data README's file table."""
    table = {}
    for line in (SHARED_DATA / "README.md").read_text().splitlines():
        cells = [c.strip() for c in line.split("|")]
        if len(cells) < 9 or not cells[1].startswith("`") or not cells[1].endswith(".bvh`"):
            continue
        words = cells[5]
        unit = ("m" if words.startswith("metres") else "asf" if "ASF" in words else "in" if "inch" in words
                else "cm" if re.match(r"cm(,|-scale)", words) else None)
        up = "Z" if "Z-up" in words else "Y" if "Y-up" in words else None
        table[cells[1].strip("`")] = (unit, up, words)
    return table


def main() -> None:
    from usdmotion.constants import METERS_PER_UNIT
    from usdmotion.io import read_motion
    from usdmotion.io.bvh import read_bvh
    from usdmotion.units_guess import guess_body

    stated = readme_units()
    rows, records = [], []
    for name, (unit, up, words) in sorted(stated.items()):
        path = SHARED_DATA / name
        if not path.is_file():
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            guess = guess_body(read_bvh(path, lenient=True))
            default = read_motion(path, lenient=True)
        unit_ok = guess.units == unit
        up_ok = guess.up_axis == up if unit is not None else guess.up_axis in (None, up)
        default_ok = (default.meters_per_unit == METERS_PER_UNIT[unit or "cm"]
                      and default.up_axis == (up if unit is not None else up or "Y"))
        records.append({"file": name, "guess_units": guess.units, "guess_up": guess.up_axis,
                        "units_reason": guess.units_reason, "up_reason": guess.up_reason,
                        "readme": words, "readme_units": unit, "readme_up": up, "units_right": unit_ok,
                        "up_right": up_ok, "default_mpu": default.meters_per_unit, "default_up": default.up_axis,
                        "default_right": default_ok})
        rows.append([name, guess.units or "-", guess.up_axis or "-", unit or "-", up or "-",
                     "yes" if unit_ok and up_ok else "NO", "yes" if default_ok else "NO"])
    right = sum(r["units_right"] and r["up_right"] for r in records)
    default_right = sum(r["default_right"] for r in records)
    print_table("--units auto / --up-axis auto vs the data README", ["file", "units", "up", "README units",
                                                                      "README up", "right", "default read right"],
                rows)
    print(f"right: {right} of {len(records)}; default reading right: {default_right} of {len(records)}")
    write_results("units_guess", {"right": right, "default_right": default_right, "files": len(records),
                                  "records": records})
    write_doc(records, right, default_right)
    print(f"wrote {DOC}")


def write_doc(records: list[dict], right: int, default_right: int) -> None:
    lines = ["# `--units auto` and `--up-axis auto` on the shared data", "",
             "Made by `.venv/bin/python benchmarks/units_guess.py` (do not edit by hand). The guess comes from",
             "the body: the ankle → head bone chain (summed OFFSET lengths) must be 1.1–2.3 m in exactly one of",
             "cm, m, mm, in, asf (CMU, 1/0.45 in), ft; the up axis is the direction from the ankles to the head",
             "in the median of 101 frames (see `usdmotion/units_guess.py`). Files without head/neck and ankle",
             "joints get no guess (cm and Y-up stay; with `--units auto` a warning says so).", "",
             f"**Right on {right} of {len(records)} files** (units and up axis both as the data README states;",
             "files the README gives no unit for count as right when no guess is made).", "",
             "Being right on every file, the guess is the **default for BVH**: a BVH read without `--units` /",
             "`--up-axis` is read in the guessed units and up axis, with a warning stating the guess and its",
             "reason where it is not the nominal cm / Y-up (`usdmotion info` always shows it); a skeleton that is",
             "not recognisably human keeps cm / Y-up. Give `--units` / `--up-axis` to choose. The default reading",
             f"(`read_motion(path)`, no options) gives the README's units and up axis on **{default_right} of "
             f"{len(records)} files** (cm / Y-up where the README states none). USD and glTF keep their own metadata.",
             "",
             "| file | guess | reason | up | up reason | data README | right |",
             "|---|---|---|---|---|---|---|"]
    for r in records:
        lines.append(f"| `{r['file']}` | {r['guess_units'] or '–'} | {r['units_reason']} | {r['guess_up'] or '–'} "
                     f"| {r['up_reason']} | {r['readme']} | {'yes' if r['units_right'] and r['up_right'] else 'NO'} |")
    DOC.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
