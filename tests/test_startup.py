"""Start-up is the user's time: each command imports only what it uses (whole processes)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

WALK = Path(__file__).resolve().parents[1] / "usdmotion" / "data" / "cmu_12_01_walk.bvh"
HEAVY = ("jax", "pandas", "pyrender", "scipy", "scipy.signal", "numpy", "pxr", "pydantic", "rich", "pyarrow",
         "jsonschema", "numpy.ma", "pxr.Usd", "pxr.UsdGeom", "pxr.UsdSkel", "pxr.UsdValidation")
SCRIPT = ("import atexit, json, sys\n"
          f"atexit.register(lambda: print('MODULES ' + json.dumps([m for m in {HEAVY!r} if m in sys.modules]"
          " + sorted(m for m in sys.modules if m.startswith('usdmotion.cli.') and '._' not in m"
          " and m != 'usdmotion.cli.app'))))\n"
          "from usdmotion.cli import main\n"
          "code = main(sys.argv[1:])\n"
          "sys.stdout.flush(); sys.exit(code)")


def imported(*args: str) -> set[str]:
    done = subprocess.run([sys.executable, "-c", SCRIPT, *args], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    line = next(line for line in done.stdout.splitlines() if line.startswith("MODULES "))
    return set(json.loads(line.removeprefix("MODULES ")))


@pytest.mark.parametrize("args", [["info", str(WALK)], ["convert", str(WALK), "{tmp}/walk.usdc"],
                                  ["convert", str(WALK), "{tmp}/walk.usda"], ["convert", str(WALK), "{tmp}/walk.bvh"]],
                         ids=["info", "convert-usdc", "convert-usda", "convert-bvh"])
def test_info_and_convert_import_no_heavy_optional_dependency(tmp_path, args):
    found = imported(*(a.format(tmp=tmp_path) for a in args))
    assert "numpy" in found  # the check sees the process's modules (the command did read the motion)
    assert found & {"jax", "pandas", "pyrender", "scipy.signal", "pydantic", "jsonschema"} == set()
    # writing BVH rows uses pyarrow's CSV writer and SciPy's quaternion → Euler (so the check does see
    # them); reading needs neither
    writes_bvh = args[0] == "convert" and args[-1].endswith(".bvh")
    assert ("pyarrow" in found) == writes_bvh and ("scipy" in found) == writes_bvh
    assert {m for m in found if m.startswith("usdmotion.cli.")} == {f"usdmotion.cli.{args[0]}"}  # its own only
    if args[0] == "convert":
        assert "rich" not in found  # the progress bar imports rich only when it is drawn
    if not writes_bvh:  # np.median and np.unique import numpy.ma (0.03 s); the units guess avoids them
        assert "numpy.ma" not in found
    if args[0] == "convert" and not writes_bvh:  # a skeleton is authored into an Sdf layer: no Usd.Stage, no
        # schema classes, no UsdValidation (0.03 s; io/usd_schema.py, io/usd_check.py)
        assert "pxr" in found and found & {"pxr.Usd", "pxr.UsdGeom", "pxr.UsdSkel", "pxr.UsdValidation"} == set()


def test_version_and_help_import_no_numpy():
    assert imported("--version") == set()
    assert imported("info", "--help") == {"rich", "usdmotion.cli.info"}  # help is formatted by rich


def test_help_lists_every_command():
    found = imported("--help")
    commands = {p.stem for p in (WALK.parents[1] / "cli").glob("*.py") if not p.stem.startswith("_")} - {"app"}
    assert {m for m in found if m.startswith("usdmotion.cli.")} == {f"usdmotion.cli.{c}" for c in commands}


def test_the_check_sees_a_heavy_import_where_a_command_needs_one():
    assert "scipy.signal" in imported("analyze", str(WALK), "--units", "asf", "--frames", "1:")


def test_importing_the_renderer_loads_no_gl_video_or_usd_library():
    # render/ imports its light modules at the top; pyrender/OpenGL, PyAV, pxr and SciPy load when used
    code = ("import sys, usdmotion.render, usdmotion.render.views, usdmotion.render.strobe\n"
            "print(sorted(m for m in ('pyrender', 'OpenGL', 'av', 'pxr', 'scipy', 'jax', 'matplotlib') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_info_opens_a_usd_file_once(tmp_path):
    from usdmotion.io import read_motion, write_motion

    stage = write_motion(read_motion(WALK, units="asf"), tmp_path / "walk.usda")  # text: every open parses it all
    env = {**os.environ, "TF_DEBUG": "USD_STAGE_OPEN USD_STAGE_CACHE"}  # usd-core's own account of its opens
    done = subprocess.run([sys.executable, "-m", "usdmotion", "info", str(stage), "--json"], capture_output=True,
                          text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count(f"UsdStage::Open(rootLayer=@{stage}@") == 2  # read, then the skeletons listed ...
    assert done.stdout.count("Creating new UsdStage") == 1  # ... from the stage the read opened
    summary = json.loads(done.stdout[done.stdout.index("{\n"):])
    assert summary["skeletons"] == ["/walk/Skeleton"] and summary["frames"] == 524
