"""Where the contact solve's RMS rise comes from (issue 17), per pair of
``benchmarks/retarget_contacts.py``.

The contact solve is the plain solve, then :func:`usdmotion.ops.retarget.leg_ik.place_legs`
(root drop + leg IK). Here both are run on the same setup and the rise of the squared
error (mean over frames × mapped joints, cm², so the parts add up to RMS²) is split:

* **by joint group**: the *body* (mapped joints not on a leg: spine, arms, head, and the
  hips themselves) and the *legs* (:func:`usdmotion.ops.retarget.contact_terms.leg_joints`:
  hip joints, knees, ankles, toes and what hangs below them);
* **body, by cause**: *root drop* — the plain solve with only the root lowered by the
  drop (the body above the legs is the plain solve's otherwise, so this is all of it);
* **legs, by frames**: the contact joints on their contact frames (*fixed point*), split
  into the part no leg can avoid — the fixed point's own distance from the sliding
  source (*source slide*, the same for any pose that meets the contact) — and the rest;
  the other leg joints (hip joint, knee, and the joints below the contact joint) on the
  frames their leg's ankle is held (*stance leg*), on toe-only frames (*toe pivot*),
  and on the frames between contacts (*ramp blends*, where the offsets are blended).

Run: ``python benchmarks/retarget_rms_explain.py [--pairs TEXT[,TEXT...]]``; writes
``benchmarks/results/retarget_rms_explain.json``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, save_rows  # noqa: E402
from retarget_contacts import load_pair, pairs_from_argv  # noqa: E402


def contact_setup(source, target, options, path, target_path):
    """``(setup, terms, q0, rot_terms)`` as :func:`usdmotion.ops.retarget.pipeline.retarget` builds them."""
    from usdmotion.ops.contacts import detect_contacts
    from usdmotion.ops.retarget import pipeline
    from usdmotion.ops.retarget.contact_terms import contact_terms

    setup = pipeline.prepare(source, target, lengths=options.get("lengths", "source"), source_path=path,
                             target_path=target_path)
    terms = contact_terms(setup, source, detect_contacts(source, source=path), options.get("root_scale", "off"))
    setup.targets[:, setup.mapped] += terms.shift[:, setup.mapped]
    setup.translations[:, setup.anchor] += terms.root_shift
    rot_terms = (0.0, pipeline.PRIOR if setup.mode == "target" else 0.0)
    q0 = setup.inits[pipeline._choose_init(setup, "auto", "lm")]
    return setup, terms, q0, rot_terms


def explain_pair(label, source_spec, target_spec, target_kw) -> dict:
    from usdmotion.kinematics import fk_arrays
    from usdmotion.ops.retarget import pipeline
    from usdmotion.ops.retarget.contact_terms import leg_joints, solved_ankle_levels
    from usdmotion.ops.retarget.hierarchy import ancestor_matrix
    from usdmotion.ops.retarget.leg_ik import legs_of, place_legs
    from usdmotion.rotations import quat_conjugate, quat_rotate

    source, target, path, target_path, options = load_pair(source_spec, target_spec, target_kw)
    setup, terms, q0, rot_terms = contact_setup(source, target, options, path, target_path)
    parents, mapped = setup.rig.parents, setup.mapped
    q_p, t_p, _, _ = pipeline._solve(setup, q0, None, rot_terms, "lm", None, None, terms.floor)
    terms = solved_ankle_levels(setup, terms, fk_arrays(q_p, t_p, parents)[1])  # as the contact solve does
    legs = legs_of(parents, terms.joints, terms.target_contacts.parts, setup.offsets, setup.top)
    contact = terms.target_contacts.contact
    q_c, t_c, drop = place_legs(q_p, t_p, parents, setup.anchor, legs, terms.planted, contact, terms.level, terms.up,
                                terms.target_contacts.fps, terms.floor, pipeline.body_weight(setup, terms))
    # the plain solve with only the root lowered by the drop
    t_d = t_p.copy()
    shift = np.zeros((len(drop), 3))
    shift[:, terms.up] = -drop
    parent = parents[setup.anchor]
    world_q = fk_arrays(q_p, t_p, parents)[0]
    t_d[:, setup.anchor] += shift if parent < 0 else quat_rotate(quat_conjugate(world_q[:, parent]), shift)
    cm2 = (setup.rig.meters_per_unit * 100.0) ** 2
    n = len(mapped) * q_p.shape[0]

    def sq(q, t):  # (F, M) squared error in cm²
        world = fk_arrays(q, t, parents)[1]
        return np.sum((world[:, mapped] - setup.targets[:, mapped]) ** 2, axis=-1) * cm2

    plain, dropped, result = sq(q_p, t_p), sq(q_p, t_d), sq(q_c, t_c)
    on_leg = np.isin(mapped, leg_joints(setup, terms.joints))
    column = {int(j): m for m, j in enumerate(mapped)}
    # per mapped joint and frame: which category of the legs it falls in
    fixed = np.zeros(plain.shape, bool)   # a contact joint on its contact frames
    stance = np.zeros(plain.shape, bool)  # other leg joints while the ankle is held
    pivot = np.zeros(plain.shape, bool)   # other leg joints on toe-only frames
    slide = 0.0  # the fixed points' own distance from the (scaled) source, cm² summed
    for c, j in enumerate(terms.joints):
        if int(j) in column:
            fixed[contact[:, c], column[int(j)]] = True
            gap = terms.planted[contact[:, c], c] - setup.targets[contact[:, c], j]
            slide += float(np.sum(gap ** 2)) * cm2
    anc = ancestor_matrix(parents)
    for m, j in enumerate(mapped):
        if not on_leg[m]:
            continue
        leg = next((lg for lg in legs if j in (lg.hip, lg.knee, lg.ankle, lg.toe) or anc[lg.hip, j]), None)
        if leg is None:
            continue
        on_a = contact[:, leg.ankle_c]
        on_t = contact[:, leg.toe_c] if leg.toe >= 0 else np.zeros_like(on_a)
        stance[on_a & ~fixed[:, m], m] = True
        pivot[on_t & ~on_a & ~fixed[:, m], m] = True
    blend = on_leg[None] & ~fixed & ~stance & ~pivot

    def part(mask):  # mean-square contribution (cm²) of the rise on these entries
        return float(np.sum(np.where(mask, result - plain, 0.0)) / n)

    body = ~on_leg[None] & np.ones(plain.shape, bool)
    rms = lambda e: float(np.sqrt(e.mean()))  # noqa: E731
    row = {
        "pair": label, "frames": int(q_p.shape[0]), "mapped": int(len(mapped)), "legs_mapped": int(on_leg.sum()),
        "rms_plain_cm": rms(plain), "rms_contacts_cm": rms(result), "rms_drop_only_cm": rms(dropped),
        "ms_plain_cm2": float(plain.mean()), "ms_contacts_cm2": float(result.mean()),
        "drop_mean_cm": float(drop.mean() * np.sqrt(cm2)), "drop_max_cm": float(drop.max() * np.sqrt(cm2)),
        "drop_frames_share": float(np.mean(drop > 0)),
        "rise_cm2": {
            "body (root drop)": float(np.sum(np.where(body, dropped - plain, 0.0)) / n),
            "body (rest)": float(np.sum(np.where(body, result - dropped, 0.0)) / n),
            "legs: fixed point": part(fixed),
            "legs: fixed point, source slide": slide / n - float(np.sum(np.where(fixed, plain, 0.0)) / n),
            "legs: stance leg": part(stance),
            "legs: toe pivot": part(pivot),
            "legs: ramp blends": part(blend),
        },
    }
    by_joint = (result - plain).sum(axis=0) / n
    row["rise_cm2_by_joint"] = {setup.rig.joint_names[mapped[m]]: float(by_joint[m])
                                for m in np.argsort(-by_joint)[:6]}
    return row


def main(argv=None) -> int:
    rows = []
    for label, source_spec, target_spec, target_kw in pairs_from_argv(__doc__.splitlines()[0], argv):
        rows.append(explain_pair(label, source_spec, target_spec, target_kw))
        print(f"{label}: largest rises (cm²) " + ", ".join(f"{k} {v:.2f}" for k, v in
                                                          rows[-1]["rise_cm2_by_joint"].items()), flush=True)
    causes = list(rows[0]["rise_cm2"]) if rows else []
    print()
    print_table("RMS of the contact solve over the plain solve: rise of the mean squared error (cm², mean over "
                "frames x mapped joints; the parts add up; 'source slide' is the share of 'fixed point' no pose "
                f"meeting the contact avoids); 1-min load {os.getloadavg()[0]:.1f}",
                ["pair", "RMS plain", "drop only", "contacts", "rise cm²", *causes, "drop mean/max cm"],
                [[r["pair"], f"{r['rms_plain_cm']:.2f}", f"{r['rms_drop_only_cm']:.2f}", f"{r['rms_contacts_cm']:.2f}",
                  f"{r['ms_contacts_cm2'] - r['ms_plain_cm2']:.2f}", *(f"{r['rise_cm2'][k]:.2f}" for k in causes),
                  f"{r['drop_mean_cm']:.2f}/{r['drop_max_cm']:.2f}"] for r in rows])
    return save_rows("retarget_rms_explain", rows)


if __name__ == "__main__":
    raise SystemExit(main())
