#!/usr/bin/env bash
# The main job end to end on the bundled CMU walk (no ../shared needed):
# set up .venv, inspect the BVH, convert it to DCC-ready UsdSkel (.usda/.usdc/.usdz, and a
# skinned volumetric body), convert back to BVH and check the round trip, retarget it onto a
# reduced 17-joint skeleton, analyse it (speeds, angles, centre of mass), and render a
# feedback video. Outputs land in out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
export PYOPENGL_PLATFORM=egl
U=.venv/bin/usdmotion
IN=usdmotion/data/cmu_12_01_walk.bvh
OUT=out/demo
mkdir -p "$OUT"

echo "== 1. what is in the file"
$U info "$IN" --units asf | head -12
echo "== 2. BVH -> OpenUSD (UsdSkel), three encodings"
for ext in usda usdc usdz; do $U convert "$IN" "$OUT/walk.$ext" --units asf; done
echo "== 3. USD -> BVH (round trip)"
$U convert "$OUT/walk.usdz" "$OUT/walk_roundtrip.bvh"
echo "== 4. same joint positions after the round trip (frame 100, left foot)"
$U positions "$IN" --frames 100 --joints LeftFoot,RightHand --units asf
$U positions "$OUT/walk_roundtrip.bvh" --frames 100 --joints LeftFoot,RightHand --units asf
echo "== 5. a skinned volumetric body bound to the skeleton (opens skinned in Blender, Maya, Houdini, Omniverse)"
$U convert "$IN" "$OUT/walk_body.usdz" --units asf --mesh
echo "== 5b. the same body as GLB (glTF 2.0: web viewers, three.js, game engines), resampled to 30 fps"
$U convert "$IN" "$OUT/walk_body.glb" --units asf --mesh --fps 30
echo "== 6. retarget onto a 17-joint skeleton (14 joints removed; JAX solves all frames at once)"
$U retarget "$IN" "$OUT/walk_17joints.usdz" --units asf --report "$OUT/retarget_report.json" \
  --remove LHipJoint,RHipJoint,LowerBack,Neck,LeftShoulder,RightShoulder,LeftFingerBase,RightFingerBase,LeftHandIndex1,RightHandIndex1,LThumb,RThumb,LeftToeBase,RightToeBase
echo "== 7. biomechanics: speeds, joint angles, centre of mass (70 kg) -> table and figure"
$U analyze "$IN" --units asf --frames 1: --mass 70 --joints Hips,LeftFoot,RightHand --out "$OUT/kinematics.csv" --plot "$OUT/kinematics.png"
echo "== 8. feedback video: side view, body, wrist and centre-of-mass paths (frame 0 is cgspeed's T-pose: skipped)"
$U render "$IN" "$OUT/walk_side.mp4" --units asf --frames 1:524 --fps 30 --trace LeftHand --trace com
$U render "$IN" "$OUT/stills/####.png" --units asf --frames 1:524 --fps 2 --camera front --style both --size 640x480
echo "demo outputs in $OUT/:"
ls -la "$OUT"
