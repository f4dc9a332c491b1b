"""The short public API at the package's top level, and the README's library example."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import usdmotion

REPO = Path(__file__).resolve().parents[1]


def readme_example() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    match = re.search(r"<!-- library-example -->\n```python\n(.*?)```", text, re.S)
    assert match, "README.md lost its library example"
    return match.group(1)


def test_readme_example_is_short_and_uses_only_the_top_level():
    code = readme_example()
    lines = [line for line in code.splitlines() if line.strip()]
    assert len(lines) <= 10
    imports = [node for node in ast.walk(ast.parse(code)) if isinstance(node, (ast.Import, ast.ImportFrom))]
    assert [alias.name for node in imports for alias in node.names] == ["usdmotion"]


def test_readme_example_runs(tmp_path):
    # the example's relative path, without that folder shadowing the package (-P)
    (tmp_path / "usdmotion").mkdir()
    (tmp_path / "usdmotion" / "data").symlink_to(REPO / "usdmotion" / "data")
    done = subprocess.run([sys.executable, "-P", "-c", readme_example()], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    # The bundled walk's header: 31 joints + 7 End Sites, 524 frames at 120 fps.
    header = (REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh").read_text()
    joints = len(re.findall(r"^\s*(ROOT|JOINT|End Site)", header, re.M))
    frames = int(re.search(r"Frames:\s*(\d+)", header).group(1))
    fast = (frames - 1) * 2 // 3 + 1  # every frame at 1.5 times the speed that falls inside the take
    assert done.stdout.split("\n")[-2].startswith(f"({frames}, {joints}, 3) {fast} ({frames}, {joints}, 3) ")
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(tmp_path / "walk.usdz"))
    animation = next(UsdSkel.Animation(p) for p in stage.Traverse() if p.IsA(UsdSkel.Animation))
    assert len(animation.GetRotationsAttr().GetTimeSamples()) == 199


def test_top_level_names_resolve_lazily():
    done = subprocess.run([sys.executable, "-c", "import sys, usdmotion; print('numpy' in sys.modules)"],
                          capture_output=True, text=True, timeout=120)
    assert done.stdout.strip() == "False"
    from usdmotion.io import read_motion
    from usdmotion.ops.edit import trim
    from usdmotion.render import render_motion

    assert usdmotion.read is read_motion and usdmotion.trim is trim and usdmotion.render_motion is render_motion
    assert set(usdmotion.__all__) <= set(dir(usdmotion))
