"""Named tolerances and unit tables; every epsilon in the package lives here."""

from __future__ import annotations

from types import SimpleNamespace

#: Tolerances, by purpose.
tol = SimpleNamespace(
    small_angle=1e-8,        # radians; below this, log/exp use Taylor branches
)

#: Metres per unit for the names accepted by ``--units``.
METERS_PER_UNIT = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "in": 0.0254,
    "ft": 0.3048,
    # CMU ASF/AMC skeletons: 1 unit = 1/0.45 inch (cgspeed BVH conversions keep it).
    "asf": 0.0254 / 0.45,
}

UP_AXES = ("Y", "Z")

#: Largest frame count accepted from a file header before we call it absurd.
MAX_FRAMES = 100_000_000

#: Deepest joint chain accepted (root = depth 0). UsdSkel names every joint by its full
#: path from the root, so the joint tokens of a chain grow with the square of its depth
#: (a 50,000-deep chain needs gigabytes); real rigs stay far below: a body is ~10 deep,
#: fingers and spline tails/ropes add tens. 1,000 levels keeps paths under ~64 kB.
MAX_JOINT_DEPTH = 1_000

#: Most joints accepted in one skeleton (end sites included). Film and game rigs with
#: faces and fingers have a few hundred to ~2,000; with MAX_JOINT_DEPTH this bounds the
#: UsdSkel joint paths to tens of megabytes.
MAX_JOINTS = 10_000

#: Largest magnitude of any number read from a file (positions in file units, angles in
#: degrees). Beyond it no digit survives USD's float32 samples (max 3.4e38) or a sum in
#: forward kinematics; a kilometre in micrometres is 1e9.
MAX_ABS_VALUE = 1e15

#: Frame rates accepted (frames per second): one frame an hour (time-lapse) to a
#: megahertz sensor. ``Frame Time: 1e300`` is a typo, not a recording.
MIN_FPS = 1.0 / 3600.0
MAX_FPS = 1e6

#: Units accepted (metres per unit): a micrometre to 1,000 km. ``--units 1e-300`` would
#: scale a body to nothing and its numbers out of float32's range.
MIN_METERS_PER_UNIT = 1e-6
MAX_METERS_PER_UNIT = 1e6
