"""Data shipped with usdmotion (a CMU walk for the demo, preset files)."""

from __future__ import annotations

from pathlib import Path

DATA_DIR = Path(__file__).resolve().parent
DEMO_BVH = DATA_DIR / "cmu_12_01_walk.bvh"
