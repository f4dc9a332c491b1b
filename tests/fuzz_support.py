"""Mutation fuzzing shared by the hypothesis properties (tests/test_fuzz_properties.py) and
the campaign (benchmarks/fuzz.py): valid seeds, mutators, and the outcome classifier.

An *entry point* is a CLI command line with one user file in it (``{src}``) and where it
writes (``{out}``). A case runs in-process through :func:`usdmotion.cli.main` with file
descriptors 1 and 2 captured (USD's C++ diagnostics bypass Python's ``sys.stderr``), and
is classified:

* ``ok``: exit 0, only ``usdmotion:`` lines on stderr, and a motion output reads back;
* ``clean``: exit 2, exactly one ``usdmotion: error: ...`` line and nothing else, no
  traceback, nothing left in the output folder;
* ``defect``: anything else (exit 1 "internal error", an exception escaping ``main``,
  a raw library diagnostic, a stray file, exit 0 with an unreadable output, a time-out).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import random
import re
import shutil
import signal
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
WALK = REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
MALFORMED = REPO / "tests" / "data" / "malformed"

#: Numbers an attacker tries first.
INTERESTING_NUMBERS = ("0", "-0", "1e39", "-1e39", "1e308", "1e400", "nan", "NaN", "inf", "-inf", "Infinity",
                       "3.4028236e38", "1e-320", "-1", "99999999999999999999", "2147483648", "0x10", "1_0", "",
                       "1e15", "1e16", "1,5", "+", "-", ".", "e5")
INTERESTING_TOKENS = ("{", "}", "[", "]", "ROOT", "JOINT", "End Site", "OFFSET", "CHANNELS", "MOTION", "Frames:",
                      "Frame Time:", '"', "\x00", "\xff", "\u00e9", "def", "over", "(", ")", "=", "@", "</a>",
                      "null", "true", "{}", "[]", ":", ",", "\n", "\t")
_NUMPY_WARNING = re.compile(r"encountered in|SVD did not converge|Mean of empty slice|Degrees of freedom")
_NUMBER = re.compile(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


# --------------------------------------------------------------------------- mutators


def mutate(data: bytes, rng: random.Random, rounds: int | None = None) -> bytes:
    """``data`` with 1–4 random mutations (numbers, tokens, lines, bytes)."""
    for _ in range(rounds or rng.choice((1, 1, 1, 2, 3))):
        data = rng.choice(MUTATORS)(data, rng)
    return data


def _replace_number(data: bytes, rng: random.Random) -> bytes:
    matches = list(_NUMBER.finditer(data[:200_000]))
    if not matches:
        return _insert_token(data, rng)
    m = rng.choice(matches)
    new = rng.choice(INTERESTING_NUMBERS).encode() if rng.random() < 0.8 else str(rng.uniform(-1e6, 1e6)).encode()
    return data[:m.start()] + new + data[m.end():]


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def _delete_line(data: bytes, rng: random.Random) -> bytes:
    lines = _lines(data)
    del lines[rng.randrange(len(lines))]
    return b"\n".join(lines)


def _duplicate_line(data: bytes, rng: random.Random) -> bytes:
    lines = _lines(data)
    k = rng.randrange(len(lines))
    lines.insert(k, lines[k])
    return b"\n".join(lines)


def _swap_lines(data: bytes, rng: random.Random) -> bytes:
    lines = _lines(data)
    a, b = rng.randrange(len(lines)), rng.randrange(len(lines))
    lines[a], lines[b] = lines[b], lines[a]
    return b"\n".join(lines)


def _insert_token(data: bytes, rng: random.Random) -> bytes:
    k = rng.randrange(len(data) + 1)
    return data[:k] + rng.choice(INTERESTING_TOKENS).encode("utf-8") + data[k:]


def _delete_span(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return data
    a = rng.randrange(len(data))
    return data[:a] + data[a + rng.randint(1, 64):]


def _flip_byte(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return bytes([rng.randrange(256)])
    k = rng.randrange(len(data))
    return data[:k] + bytes([rng.randrange(256)]) + data[k + 1:]


def _truncate(data: bytes, rng: random.Random) -> bytes:
    return data[:rng.randrange(len(data) + 1)]


def _repeat_block(data: bytes, rng: random.Random) -> bytes:
    """Nest or repeat a span many times (deep/huge inputs)."""
    if not data:
        return data
    a = rng.randrange(len(data))
    span = data[a:a + rng.randint(1, 40)]
    return data[:a] + span * rng.choice((2, 10, 200, 3000)) + data[a:]


MUTATORS = (_replace_number, _replace_number, _delete_line, _duplicate_line, _swap_lines, _insert_token,
            _delete_span, _flip_byte, _truncate, _repeat_block)


# ------------------------------------------------------------------------------- seeds

#: A synthetic CMU-style Acclaim skeleton (name, parent, direction, length in 1/0.45 inch,
#: axis angles + order, dofs, limits given): 18 bones, both legs and arms, a 2-DOF foot and
#: clavicle, a DOF-less hip joint. Not copied from a CMU file (``../shared/data`` stays there).
_ASF_BONES = (
    ("lhipjoint", "root", (0.56, -0.53, 0.64), 2.4, (0, 0, 0), (), False),
    ("lfemur", "lhipjoint", (0.34, -0.94, 0), 7.2, (0, 0, 20), ("rx", "ry", "rz"), True),
    ("ltibia", "lfemur", (0.34, -0.94, 0), 7.4, (0, 0, 20), ("rx",), True),
    ("lfoot", "ltibia", (0.0, -0.2, 0.98), 2.2, (-90, 7, 20), ("rx", "rz"), True),
    ("rhipjoint", "root", (-0.56, -0.53, 0.64), 2.4, (0, 0, 0), (), False),
    ("rfemur", "rhipjoint", (-0.34, -0.94, 0), 7.2, (0, 0, -20), ("rx", "ry", "rz"), True),
    ("rtibia", "rfemur", (-0.34, -0.94, 0), 7.4, (0, 0, -20), ("rx",), False),
    ("rfoot", "rtibia", (0.0, -0.2, 0.98), 2.2, (-90, -7, -20), ("rx", "rz"), False),
    ("lowerback", "root", (0.02, 0.99, -0.05), 2.0, (0, 0, 0), ("rx", "ry", "rz"), True),
    ("upperback", "lowerback", (0.0, 1.0, 0.01), 2.0, (0, 0, 0), ("rx", "ry", "rz"), False),
    ("thorax", "upperback", (0.0, 1.0, 0.0), 2.0, (0, 0, 0), ("rx", "ry", "rz"), False),
    ("head", "thorax", (0.0, 1.0, 0.05), 2.9, (0, 0, 0), ("rx", "ry", "rz"), True),
    ("lclavicle", "thorax", (0.99, 0.05, 0.0), 3.5, (0, 0, -20), ("ry", "rz"), True),
    ("lhumerus", "lclavicle", (1.0, 0.0, 0.0), 5.0, (0, 0, -90), ("rx", "ry", "rz"), True),
    ("lradius", "lhumerus", (1.0, 0.0, 0.0), 3.4, (0, 0, -90), ("rx",), False),
    ("rclavicle", "thorax", (-0.99, 0.05, 0.0), 3.5, (0, 0, 20), ("ry", "rz"), False),
    ("rhumerus", "rclavicle", (-1.0, 0.0, 0.0), 5.0, (0, 0, 90), ("rx", "ry", "rz"), False),
    ("rradius", "rhumerus", (-1.0, 0.0, 0.0), 3.4, (0, 0, 90), ("rx",), False),
)


def asf_seed_text() -> str:
    """The ASF text of :data:`_ASF_BONES` (CMU layout: units, documentation, root, bonedata,
    hierarchy)."""
    lines = ["# synthetic CMU-style skeleton for the fuzzer", ":version 1.10", ":name VICON", ":units",
             "  mass 1.0", "  length 0.45", "  angle deg", ":documentation", "   synthetic, for tests",
             ":root", "   order TX TY TZ RX RY RZ", "   axis XYZ", "   position 0 0 0", "   orientation 0 0 0",
             ":bonedata"]
    for k, (name, _, direction, length, axis, dofs, limits) in enumerate(_ASF_BONES, start=1):
        lines += ["  begin", f"     id {k}", f"     name {name}", "     direction " + " ".join(f"{v:g}" for v in direction),
                  f"     length {length:g}", "     axis " + " ".join(f"{v:g}" for v in axis) + "  XYZ"]
        if dofs:
            lines.append("    dof " + " ".join(dofs))
            if limits:
                lines += [f"    {'limits' if i == 0 else '      '} (-{60 + 10 * i}.0 {45 + 5 * i}.0)" for i in range(len(dofs))]
        lines.append("  end")
    lines += [":hierarchy", "  begin"]
    children: dict[str, list[str]] = {}
    for name, parent, *_ in _ASF_BONES:
        children.setdefault(parent, []).append(name)
    lines += [f"    {parent} {' '.join(names)}" for parent, names in children.items()]
    lines += ["  end", ""]
    return "\n".join(lines)


def amc_seed_text(frames: int = 4) -> str:
    """An AMC of ``frames`` frames on :func:`asf_seed_text` (a small walking sway, degrees)."""
    lines = ["#!OML:ASF seed.asf", ":FULLY-SPECIFIED", ":DEGREES"]
    for f in range(1, frames + 1):
        lines += [str(f), f"root {1.5 * f:g} 17.5 {0.2 * f:g} {-3 + f:g} {2 * f:g} {0.5 * f:g}"]
        for k, (name, _, _, _, _, dofs, _) in enumerate(_ASF_BONES):
            if dofs:
                lines.append(name + "".join(f" {((7 * k + 3 * i + 5 * f) % 40) - 20:g}" for i in range(len(dofs))))
    return "\n".join(lines) + "\n"



def make_seeds(folder: Path) -> dict[str, Path]:
    """Valid seed files, written to ``folder``: BVH, USDA, USDC, GLB, joint map, segments JSON,
    USD camera (from the shipped CMU walk and the malformed corpus's valid base), and a
    synthetic ASF skeleton with a 4-frame AMC on it."""
    from usdmotion.io import read_motion, write_motion

    folder.mkdir(parents=True, exist_ok=True)
    walk = read_motion(WALK).sliced(0, 6)  # small seeds: mutations stay fast
    seeds = {"bvh": write_motion(walk, folder / "walk.bvh"), "usda": write_motion(walk, folder / "walk.usda"),
             "usdc": write_motion(walk, folder / "walk.usdc"),
             "walk": write_motion(read_motion(WALK).sliced(0, 120), folder / "walk120.bvh"),
             "glb": write_motion(walk, folder / "walk.glb")}
    small = folder / "small.bvh"
    shutil.copy(MALFORMED / "frames_more_than_rows.bvh", small)  # a valid base with one defect, fixed below
    text = small.read_text()
    small.write_text(re.sub(r"Frames: \d+", "Frames: 2", text))
    seeds["bvh_small"] = small
    jmap = folder / "map.json"
    jmap.write_text('{"auto": true, "joints": {"Hips": "Hips", "Head": {"source": "Head", "weight": 2.0}},\n'
                    ' "weights": {"LeftFoot": 0.5}}\n')
    seeds["jointmap"] = jmap
    segments = folder / "walk_segments.json"
    segments.write_text('{"method": "kcpd", "fps": 120.0, "frames": 120, "cuts": [40, 80],\n'
                        ' "segments": [{"start": 0, "stop": 40}, {"start": 40, "stop": 80}, '
                        '{"start": 80, "stop": 120}]}\n')
    seeds["segments"] = segments
    camera = folder / "cam.usda"
    camera.write_text('#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n\ndef Camera "cam"\n{\n'
                      '    float focalLength = 35\n    float verticalAperture = 15.2\n'
                      '    double3 xformOp:translate = (0, 1, 6)\n    uniform token[] xformOpOrder = ["xformOp:translate"]\n'
                      '    float2 clippingRange = (0.1, 100)\n}\n')
    seeds["camera"] = camera
    asf, amc = folder / "seed.asf", folder / "seed.amc"
    asf.write_text(asf_seed_text())
    amc.write_text(amc_seed_text())
    seeds["asf"], seeds["amc"] = asf, amc
    return seeds


#: Entry points: name → (seed kind, argument template). ``{src}`` is the mutated file,
#: ``{out}`` the output, ``{walk}`` the valid walk seed, ``{asf}``/``{amc}`` the valid ASF/AMC seeds
#: (the other half of a mutated AMC/ASF).
ENTRY_POINTS = {
    "convert_bvh": ("bvh", ["convert", "{src}", "{out}.usda", "--no-validate"]),
    "convert_bvh_small": ("bvh_small", ["convert", "{src}", "{out}.bvh"]),
    "info_bvh": ("bvh", ["info", "{src}"]),
    "convert_usda": ("usda", ["convert", "{src}", "{out}.bvh"]),
    "convert_usdc": ("usdc", ["convert", "{src}", "{out}.bvh"]),
    "info_usda": ("usda", ["info", "{src}"]),
    "convert_glb": ("glb", ["convert", "{src}", "{out}.bvh"]),
    "jointmap": ("jointmap", ["retarget", "{walk}", "{out}.bvh", "--remove", "LThumb", "--map", "{src}",
                              "--iterations", "1"]),
    "segments": ("segments", ["segment-eval", "{walk}", "{src}"]),
    "camera": ("camera", ["render", "{walk}", "{out}.mp4", "--camera", "{src}", "--size", "64x48",
                          "--frames", "0:2", "--style", "stick"]),
    "convert_asf": ("asf", ["convert", "{amc}", "{out}.bvh", "--skeleton", "{src}"]),
    "convert_amc": ("amc", ["convert", "{src}", "{out}.usda", "--skeleton", "{asf}", "--no-validate"]),
    "info_amc": ("amc", ["info", "{src}", "--skeleton", "{asf}"]),
}

#: Option values tried on render and retarget (the campaign draws one per case).
RENDER_OPTIONS = {
    "--size": ["64x48", "0x0", "-16x16", "64x", "x", "100000x100000", "1e3x64", "64x48x2", "nan"],
    "--frames": ["0:2", "-1:", "5:2", "a:b", ":", "0:99999999999", "1:1", "::", "2"],
    "--fps": ["30", "0", "-1", "nan", "inf", "1e308", "1e-300"],
    "--speed": ["1", "0", "-2", "nan", "inf", "1e-300"],
    "--msaa": ["0", "4", "-1", "3", "1000000"],
    "--quality": ["20", "-1", "52", "1000"],
    "--grid-scale": ["1", "0", "-1", "nan", "inf"],
    "--style": ["stick", "body", "both", "", "x"],
    "--camera": ["side", "orbit", "nope", "missing.usda", ":/cam", "x.usda:/a"],
    "--compare-mode": ["ghost", "side", "nope"],
    "--trace": ["Hips", "com", "Nope", ""],
}
RETARGET_OPTIONS = {
    "--remove": ["LThumb", "Hips", "Nope", "", "LThumb,LThumb"],
    "--add": ["Tip:Head:0,1,0", "Tip:Nope:0,1,0", "Tip:Head:nan,0,0", "Tip:Head:1e39,0,0", "::", "Tip:Head:0,1"],
    "--iterations": ["1", "0", "-1", "1e9"],
    "--scale": ["units", "auto", "0", "-1", "nan", "inf", "x", "1e30", "1e-30", "100", "0.9"],
    "--units": ["cm", "m", "0", "-1", "nan", "inf", "furlong", "1e-300"],
}


#: Numbers past any sensible range: a result too long to hold, a body mass of a planet...
HUGE_AND_TINY = ["0", "-1", "nan", "inf", "1e-300", "1e-9", "1e9", "1e300", "99999999999999999999"]
#: The edit and analysis commands (one take in, one out or a report), each with its own
#: options; a case draws one command and 1–3 of its options.
EDIT_COMMANDS = {
    "speed": (["speed", "{walk}", "{out}.bvh"], {"--factor": ["0.5", "2", *HUGE_AND_TINY],
                                                 "--key": ["0=1e-9", "10=1e9", "0=nan", "99999999=1", "0=0.5"]}),
    "resample": (["resample", "{walk}", "{out}.bvh", "--fps", "30"], {"--fps": ["60", "0.5", *HUGE_AND_TINY]}),
    "cycle": (["cycle", "{walk}", "{out}.bvh"], {"--loops": ["1", "3", "100000000", "-2", "x"],
                                                 "--transition": ["0.1", "1e9", "-1", "nan"],
                                                 "--frames": ["0:100", "0:3", "5:2", "0:99999999999"]}),
    "reorient": (["reorient", "{walk}", "{out}.bvh"], {"--rotate": ["90", "1e300", "nan"],
                                                       "--translate": ["1,2,3", "1e16,0,0", "1e14,0,0", "nan,0,0"],
                                                       "--position": ["0,0", "1e300,0", "inf,0"]}),
    "displace": (["displace", "{walk}", "{out}.bvh"], {"--move": ["Hips@10=1e15,0,0", "Hips@10=1,2,3",
                                                                  "Hips@99999999999=1,1,1"],
                                                       "--rotate": ["Head@10=1e300,0,0", "Head@10=10,0,0"],
                                                       "--falloff": ["0.5", "1e300", "-1", "nan"]}),
    "analyze": (["analyze", "{walk}", "--out", "{out}.csv"], {"--cutoff": ["6", *HUGE_AND_TINY],
                                                              "--mass": ["70", *HUGE_AND_TINY]}),
    "segment": (["segment", "{walk}", "--out", "{out}.json"], {"--cutoff": ["2", *HUGE_AND_TINY],
                                                               "--penalty": ["5", *HUGE_AND_TINY],
                                                               "--min-length": ["1", *HUGE_AND_TINY]}),
    "contacts": (["contacts", "{walk}", "--json", "{out}.json"], {
        "--floor": ["0", "1e20", "nan"], "--height-enter": ["0.05", *HUGE_AND_TINY],
        "--height-exit": ["0.08", *HUGE_AND_TINY], "--speed-enter": ["0.3", *HUGE_AND_TINY],
        "--min-duration": ["0.05", *HUGE_AND_TINY]}),
}


def option_case(rng: random.Random, command: str) -> list[str]:
    """A render, retarget or edit/analysis command line with 1–3 fuzzed options."""
    if command == "edit":
        args, table = EDIT_COMMANDS[rng.choice(sorted(EDIT_COMMANDS))]
        args = list(args)
    else:
        table = RENDER_OPTIONS if command == "render" else RETARGET_OPTIONS
        args = (["render", "{walk}", "{out}.mp4", "--size", "64x48", "--frames", "0:2", "--style", "stick"]
                if command == "render" else ["retarget", "{walk}", "{out}.bvh", "--iterations", "1"])
    for option in rng.sample(sorted(table), rng.randint(1, min(3, len(table)))):
        args += [option, rng.choice(table[option])]
    if command == "retarget" and "--remove" not in args and "--add" not in args:
        args += ["--remove", "LThumb"]
    return args


# ------------------------------------------------------------------------------ running


@dataclasses.dataclass
class Outcome:
    kind: str               # "ok", "clean" or "defect"
    code: int | None
    stderr: str
    reason: str = ""


class _Timeout(BaseException):
    pass


@contextlib.contextmanager
def _captured_fds() -> tuple[Path, Path]:
    """Redirect fds 1 and 2 to temporary files for the block (C++ writes there directly)."""
    files = [tempfile.TemporaryFile(mode="w+b") for _ in range(2)]
    saved = [os.dup(1), os.dup(2)]
    import sys

    sys.stdout.flush()
    sys.stderr.flush()
    streams = sys.stdout, sys.stderr  # pytest replaces them by objects that are not fds 1 and 2
    try:
        os.dup2(files[0].fileno(), 1)
        os.dup2(files[1].fileno(), 2)
        sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115
        sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115
        yield files
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        sys.stdout, sys.stderr = streams
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in saved:
            os.close(fd)


def run_case(args: list[str], out_dir: Path, timeout_s: int = 300) -> Outcome:
    """Run ``usdmotion ARGS`` in-process and classify the outcome (see the module docstring)."""
    import sys

    from usdmotion.cli import main

    def on_alarm(signum, frame):
        raise _Timeout

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(timeout_s)
    error = None
    with _captured_fds() as (out_file, err_file):
        try:
            code = main(args)
        except _Timeout:
            code, error = None, f"no result after {timeout_s} s"
        except BaseException as exc:  # noqa: BLE001 - an escaping exception is the defect
            code, error = None, f"{type(exc).__name__} escaped main: {exc}"
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, previous)
        sys.stdout.flush()
        sys.stderr.flush()
        err_file.seek(0)
        stderr = err_file.read().decode("utf-8", "replace")
    if error:
        return Outcome("defect", code, stderr, error)
    return classify(code, stderr, args, out_dir)


#: Library messages that reached the error line as they are: they name no file or option and
#: say nothing a user can act on (numpy's allocation failure, scipy's linear algebra, reprs).
_RAW_DIAGNOSTIC = re.compile(r"Unable to allocate|Singular matrix|np\.(float|int)\d*\(|array with shape|"
                             r"has no attribute|unhashable type|is out of bounds for axis|could not be broadcast|"
                             r"object is not subscriptable|math domain error|invalid value encountered")


def classify(code: int, stderr: str, args: list[str], out_dir: Path) -> Outcome:
    lines = [line for line in stderr.splitlines() if line.strip()]
    # analyze says "wrote FILE" on stderr (its stdout is the summary, JSON with --json)
    foreign = [line for line in lines if not line.startswith(("usdmotion: ", "wrote "))]
    left = sorted(p.name for p in out_dir.iterdir())
    if "Traceback" in stderr or foreign:
        return Outcome("defect", code, stderr, f"foreign output: {(foreign or ['Traceback'])[0][:120]}")
    leaked = [line for line in lines if _NUMPY_WARNING.search(line)]
    if leaked:
        return Outcome("defect", code, stderr, f"NumPy warning leaked: {leaked[0][:120]}")
    if code == 2:
        errors = [line for line in lines if line.startswith("usdmotion: error: ")]
        if len(errors) != 1:
            return Outcome("defect", code, stderr, f"{len(errors)} error lines")
        if left:
            return Outcome("defect", code, stderr, f"left behind: {left}")
        raw = _RAW_DIAGNOSTIC.search(errors[0])
        if raw:
            return Outcome("defect", code, stderr, f"raw library diagnostic ({raw.group(0)}): {errors[0][:160]}")
        return Outcome("clean", code, stderr)
    if code == 0:
        outputs = [p for p in out_dir.iterdir() if p.suffix in (".bvh", ".usda", ".usdc")]
        for path in outputs:
            try:
                from usdmotion.io import read_motion

                read_motion(path)
            except Exception as exc:  # noqa: BLE001
                return Outcome("defect", code, stderr, f"exit 0 but {path.name} does not read back: {exc}")
        stray = [name for name in left if name.startswith(".")]
        if stray:
            return Outcome("defect", code, stderr, f"temporary files left: {stray}")
        return Outcome("ok", code, stderr)
    return Outcome("defect", code, stderr, f"exit {code}: {(lines or [''])[-1][:160]}")


def expand(args: list[str], src: Path, out: Path, walk: Path, seeds: dict[str, Path] | None = None) -> list[str]:
    """``args`` with the placeholders replaced (``{asf}``/``{amc}`` from ``seeds``)."""
    values = {"{src}": src, "{out}": out, "{walk}": walk, **{f"{{{k}}}": v for k, v in (seeds or {}).items()
                                                          if k in ("asf", "amc")}}
    expanded = []
    for a in args:
        for key, value in values.items():
            a = a.replace(key, str(value))
        expanded.append(a)
    return expanded
