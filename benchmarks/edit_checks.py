"""The "Must show" figures of issue 7 on the shared files, with plots.

Prints every figure, writes ``benchmarks/results/edit_checks.json`` and the plots
``benchmarks/results/edit_blend_speed.png`` and ``edit_cycle.png`` (matplotlib, Agg).

    PYTHONPATH=$PWD python benchmarks/edit_checks.py [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

from edit_support import angle_between, frame_steps, position_spectrum, walker  # noqa: E402

from usdmotion.io import read_motion  # noqa: E402
from usdmotion.kinematics import joint_positions  # noqa: E402
from usdmotion.ops import edit as E  # noqa: E402
from usdmotion.ops.edit import align as A  # noqa: E402
from usdmotion.ops.edit.cycle import loop_end  # noqa: E402


ASF_CM = 2.54 / 0.45  # CMU files: 1 unit = 1/0.45 inch



def equaliser(data: Path) -> dict:
    m = read_motion(data / "cmu/cgspeed_12_01_walk.bvh")
    identity = E.equalize(m, gains=[1.0] * 6)
    walk = E.trim(m, 1)

    X0, f = position_spectrum(walk)
    X1, _ = position_spectrum(E.equalize(walk, gains=[0, 0]))
    high = f >= 15
    low = np.fft.irfft(np.where((f < 2)[:, None], X1 - X0, 0), n=walk.n_frames, axis=0)
    # a root turning through ±180° with noise (synthetic; see tests/test_edit_equalize.py)
    noisy = walker(n_frames=240, heading_deg=150, turn_deg_per_frame=0.25, noise_deg=0.8, seed=3)
    out = E.equalize(noisy, gains=[0, 0, 0])
    step_in, step_out = (np.degrees(angle_between(q.rotations[1:, 0], q.rotations[:-1, 0])) for q in (noisy, out))
    return {
        "unit_gains_max_rotation_error_rad": float(angle_between(identity.rotations, m.rotations).max()),
        "unit_gains_max_translation_error": float(np.abs(identity.root_translation - m.root_translation).max()),
        "zero_bands_0_1_energy_above_15Hz_ratio": float((np.abs(X1[high]) ** 2).sum() / (np.abs(X0[high]) ** 2).sum()),
        "zero_bands_0_1_low_band_below_2Hz_max_change_units": float(np.abs(low).max()),
        "zero_bands_0_1_low_band_below_2Hz_max_change_cm": float(np.abs(low).max() * ASF_CM),
        "wrap_input_max_step_deg": float(step_in.max()),
        "wrap_output_max_step_deg": float(step_out.max()),
    }


def cycle_check(data: Path) -> tuple[dict, dict]:
    m = E.trim(read_motion(data / "cmu/cgspeed_12_01_walk.bvh"), 1)
    start, n, loops = 50, 30, 4
    stop = loop_end(m, start, n)
    out = E.cycle(m, start, stop, transition=n, loops=loops)
    period = stop - start - n
    step, jerk = frame_steps(joint_positions(out))
    step0, jerk0 = frame_steps(joint_positions(E.trim(m, start, stop)))
    fade = np.concatenate([np.arange(period - n - 1, period + 1) + k * period for k in range(loops - 1)])
    per_loop = np.linalg.norm(np.diff(out.root_translation[::period][:, [0, 2]], axis=0), axis=1)
    # the same gait phase in the original: output frame k shows loop frame (k + n) mod P, which is original frame
    # start + φ (or a fade of start + φ and start + P + φ); compare the seam frames with both
    _, jerk_all = frame_steps(joint_positions(m))
    phase = (fade[:-1] + 1 + n) % period  # jerk[k] is centred on output frame k + 1
    same_phase = np.maximum(jerk_all[start + phase - 1], jerk_all[np.minimum(start + period + phase - 1,
                                                                               len(jerk_all) - 1)])
    figures = {
        "range": [start, int(stop)], "transition": n, "loops": loops, "period": int(period),
        "seam_max_step": float(step[fade].max()), "original_max_step": float(step0.max()),
        "original_median_step": float(np.median(step0)),
        "seam_max_velocity_change": float(jerk[fade[:-1]].max()), "original_max_velocity_change": float(jerk0.max()),
        "original_median_velocity_change": float(np.median(jerk0)),
        "seam_velocity_change_minus_same_phase_original_max": float((jerk[fade[:-1]] - same_phase).max()),
        "travel_per_loop": [float(v) for v in per_loop],
        "original_travel_per_period": float(np.linalg.norm(
            m.root_translation[start + period, [0, 2]] - m.root_translation[start, [0, 2]])),
        "file_unit_cm": ASF_CM,
    }
    return figures, {"out": out, "step": step, "jerk": jerk, "period": period, "n": n, "step0": step0}


def blend_speed(data: Path) -> tuple[dict, dict]:
    walk = read_motion(data / "bandai1/dataset-1_walk_normal_001.bvh")
    run = read_motion(data / "bandai1/dataset-1_run_normal_001.bvh")
    out = E.blend(walk, run, transition=10, align="peaks", align_joint="UpperLeg_L")
    pw, pr, pb = joint_positions(walk), joint_positions(run), joint_positions(out)
    step, jerk = frame_steps(pb)
    (walk_step, walk_jerk), (run_step, run_jerk) = frame_steps(pw), frame_steps(pr)
    keys = [(0, 1.0), (100, 2.0), (194, 0.5)]
    fast = E.speed(walk, keys=keys)
    ps = joint_positions(fast)
    s_step, s_jerk = frame_steps(ps)
    from scipy.interpolate import PchipInterpolator

    from usdmotion.ops.edit.timewarp import speed_times

    tau = speed_times(walk.n_frames, keys=keys)
    local = PchipInterpolator([k[0] for k in keys], [k[1] for k in keys])(0.5 * (tau[1:] + tau[:-1]))
    thigh = walk.joint_names.index("UpperLeg_L")
    s0, s1 = A.rotation_channels(walk.rotations[:, thigh], run.rotations[:, thigh])
    figures = {
        "blend_frames": out.n_frames, "walk_frames": walk.n_frames, "run_frames": run.n_frames,
        "blend_max_step_cm": float(step.max()), "walk_max_step_cm": float(walk_step.max()),
        "run_max_step_cm": float(run_step.max()),
        "blend_max_velocity_change_cm": float(jerk.max()), "walk_max_velocity_change_cm": float(walk_jerk.max()),
        "run_max_velocity_change_cm": float(run_jerk.max()),
        "hips_end_speed_cm_per_frame": float(np.linalg.norm(np.diff(pb[-6:, 1, [0, 2]], axis=0), axis=1).mean()),
        "run_hips_speed_cm_per_frame": float(np.linalg.norm(np.diff(pr[-6:, 1, [0, 2]], axis=0), axis=1).mean()),
        "speed_curve_frames": fast.n_frames, "speed_max_step_cm": float(s_step.max()),
        "speed_max_velocity_change_cm": float(s_jerk.max()),
        "speed_max_step_over_local_speed_cm": float((s_step / local).max()),
        "speed_max_velocity_change_over_speed_squared_cm": float((s_jerk / (local[1:] * local[:-1])).max()),
    }
    return figures, {"walk": walk, "run": run, "out": out, "pw": pw, "pr": pr, "pb": pb, "step": step,
                     "fast": fast, "ps": ps, "s0": s0, "s1": s1, "thigh": thigh}


def plot(blend: dict, cyc: dict, folder: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(12, 8))
    pb, pr = blend["pb"], blend["pr"]
    join = len(pb) - len(pr)  # the run's first frame on the output timeline
    ax[0, 0].plot(blend["pw"][140:, 1, 0], blend["pw"][140:, 1, 2], "C0", lw=3, alpha=0.5, label="walk")
    moved = pr[:, 1] - pr[0, 1] + pb[join, 1]
    ax[0, 0].plot(moved[:, 0], moved[:, 2], "C1", lw=3, alpha=0.5, label="run (moved to the join)")
    ax[0, 0].plot(pb[140:, 1, 0], pb[140:, 1, 2], "k.-", lw=1, label="blend (every frame)")
    ax[0, 0].set(title="Hips path, top view (cm, equal axes), last 66 frames", xlabel="x", ylabel="z")
    ax[0, 0].set_aspect("equal", adjustable="datalim")
    ax[0, 0].legend()
    frames = np.arange(1, len(blend["step"]) + 1)
    ax[0, 1].plot(frames, blend["step"], "k", label="blend")
    ax[0, 1].plot(np.arange(1, len(blend["pw"])), np.linalg.norm(np.diff(blend["pw"], axis=0), axis=-1).max(1), "C0",
                  alpha=0.6, label="walk")
    ax[0, 1].axvspan(185, 195, color="orange", alpha=0.3, label="transition")
    ax[0, 1].set(title="Largest joint displacement per frame (cm)", xlabel="output frame")
    ax[0, 1].legend()
    thigh = blend["thigh"]
    _, out_thigh = A.rotation_channels(blend["walk"].rotations[:, thigh], blend["out"].rotations[:, thigh])
    _, run_thigh = A.rotation_channels(blend["walk"].rotations[:, thigh], blend["run"].rotations[:, thigh])
    ax[1, 0].plot(np.degrees(blend["s0"]), "C0", label="walk")
    ax[1, 0].plot(np.degrees(out_thigh), "k", label="blend")
    offset = blend["out"].n_frames - blend["run"].n_frames
    ax[1, 0].plot(np.arange(offset, offset + len(run_thigh)), np.degrees(run_thigh), "C1--", label="run (placed)")
    ax[1, 0].axvspan(185, 195, color="orange", alpha=0.3)
    ax[1, 0].set(title="Left thigh swing (deg, principal axis), peaks aligned", xlabel="frame")
    ax[1, 0].legend()
    fast = blend["fast"]
    _, fast_thigh = A.rotation_channels(blend["walk"].rotations[:, thigh], fast.rotations[:, thigh])
    ax[1, 1].plot(np.degrees(blend["s0"]), "C0", label="walk (195 frames)")
    ax[1, 1].plot(np.degrees(fast_thigh), "C3", label=f"speed 1 → 2 → 0.5 ({fast.n_frames} frames)")
    ax[1, 1].set(title="Speed curve: left thigh swing (deg)", xlabel="output frame")
    ax[1, 1].legend()
    fig.tight_layout()
    first = folder / "edit_blend_speed.png"
    fig.savefig(first, dpi=80)
    plt.close(fig)

    fig, ax = plt.subplots(1, 2, figsize=(12, 4))
    root = cyc["out"].root_translation
    ax[0].plot(root[:, 0], root[:, 2], "k")
    ax[0].plot(root[:: cyc["period"], 0], root[:: cyc["period"], 2], "ro", label="loop starts")
    ax[0].set(title="Cycled CMU walk: root path (4 loops, equal axes)", xlabel="x", ylabel="z")
    ax[0].set_aspect("equal", adjustable="datalim")
    ax[0].legend()
    ax[1].plot(cyc["step"], "k", label="largest joint step per frame")
    for k in range(1, 4):
        ax[1].axvspan(k * cyc["period"] - cyc["n"], k * cyc["period"], color="orange", alpha=0.3)
    ax[1].axhline(cyc["step0"].max(), color="C0", ls="--", label="original's largest step")
    ax[1].set(title="Continuity across the cross-fades (orange)", xlabel="output frame")
    ax[1].legend()
    fig.tight_layout()
    second = folder / "edit_cycle.png"
    fig.savefig(second, dpi=80)
    plt.close(fig)
    return [first, second]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    args = parser.parse_args()
    results = {"equaliser": equaliser(args.data)}
    results["cycle"], cyc = cycle_check(args.data)
    results["blend_speed"], blend = blend_speed(args.data)
    folder = REPO / "benchmarks" / "results"
    for section, figures in results.items():
        print(f"[{section}]")
        for key, value in figures.items():
            print(f"  {key:48s} {value if not isinstance(value, float) else f'{value:.6g}'}")
    paths = plot(blend, cyc, folder)
    (folder / "edit_checks.json").write_text(json.dumps(results, indent=2) + "\n")
    print("wrote", ", ".join(str(p.relative_to(REPO)) for p in paths + [folder / "edit_checks.json"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
