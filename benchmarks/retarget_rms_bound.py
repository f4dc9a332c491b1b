"""How low the contact solve's RMS could go (issue 17): a near-lower bound per pair of
``benchmarks/retarget_contacts.py``.

Holding a foot still during its contact costs RMS to a source whose foot slides. This
benchmark asks what the least cost is, whatever the solver: from the contact solve's
result, a long LM solve of the **whole body** (every rotation the plain solve turns, the
root free; no temporal term, no no-flip limit, no floor term, i.e. fewer constraints than
the product has) with every contact joint held on one point per contact interval
(weight :data:`HARD_WEIGHT` per unit², the mapped joints weigh 1) at its planted level.
The horizontal points are chosen by the solve too: :data:`ROUNDS` rounds at a soft weight
(the joint pulled equally by its source and its point), each point then moved to the mean
of where the solve put its joint over the interval, before the hard solve of
:data:`ITERATIONS` iterations. Any result that holds its feet still at these levels has at
least about this RMS (LM finds a local minimum from a good start, so "about").

Run: ``python benchmarks/retarget_rms_bound.py [--pairs TEXT[,TEXT...]]``; writes
``benchmarks/results/retarget_rms_bound.json``.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, save_rows  # noqa: E402
from retarget_contacts import load_pair, pairs_from_argv  # noqa: E402
from retarget_rms_explain import contact_setup  # noqa: E402

#: Weight of a held contact joint's distance from its point (mapped joints: 1).
HARD_WEIGHT = 1e4
#: Soft rounds choosing the points, and their weight.
ROUNDS, SOFT_WEIGHT = 3, 1.0
#: LM iterations of each soft round and of the hard solve (it stops earlier when converged).
SOFT_ITERATIONS, ITERATIONS = 60, 400


def interval_means(world: np.ndarray, planted: np.ndarray, contact: np.ndarray, up: int) -> np.ndarray:
    """``planted (F, C, 3)`` with each contact interval's horizontal point moved to the mean of
    ``world (F, C, 3)`` (the solved contact joints) over the interval; levels kept."""
    from usdmotion.ops.contacts.detect import runs

    out = planted.copy()
    flat = [a for a in range(3) if a != up]
    for c in range(contact.shape[1]):
        for a, b in runs(contact[:, c]):
            out[a:b, c, flat] = world[a:b, c, flat].mean(axis=0)
    return out


def solver_start(setup, q0: np.ndarray, q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(q, t)`` of a result as the solver sees them: the unmapped joints above the anchor (a
    floor root bone, which the unmapped-joint rules turn and move) back at their start values,
    the anchor's local rotation and translation re-expressed so that every world pose is kept."""
    from usdmotion.kinematics import fk_arrays
    from usdmotion.rotations import quat_conjugate, quat_mul, quat_rotate

    parents, anchor = setup.rig.parents, setup.anchor
    above, j = [], int(parents[anchor])
    while j >= 0:
        above.append(j)
        j = int(parents[j])
    if not above:
        return q, t
    rot, pos = fk_arrays(q, t, parents)
    q, t = q.copy(), t.copy()
    q[:, above], t[:, above] = q0[:, above], setup.translations[:, above]
    rest_rot, rest_pos = fk_arrays(q, t, parents)
    inverse = quat_conjugate(rest_rot[:, above[0]])
    q[:, anchor] = quat_mul(inverse, rot[:, anchor])
    t[:, anchor] = quat_rotate(inverse, pos[:, anchor] - rest_pos[:, above[0]])
    return q, t


def bound_pair(label, source_spec, target_spec, target_kw) -> dict:
    from usdmotion.kinematics import fk_arrays
    from usdmotion.ops.retarget import pipeline
    from usdmotion.ops.retarget.solve import solve

    source, target, path, target_path, options = load_pair(source_spec, target_spec, target_kw)
    setup, terms, q0, rot_terms = contact_setup(source, target, options, path, target_path)
    q_plain, t_plain, _, _ = pipeline._solve(setup, q0, None, rot_terms, "lm", None, None)
    q, t, _, terms = pipeline._solve(setup, q0, terms, rot_terms, "lm", None, None)
    mapped, anchor, parents = setup.mapped, setup.anchor, setup.rig.parents
    cm = setup.rig.meters_per_unit * 100.0

    def rms(q, t) -> float:
        world = fk_arrays(q, t, parents)[1]
        return float(np.sqrt(np.mean(np.sum((world[:, mapped] - setup.targets[:, mapped]) ** 2, axis=-1))) * cm)

    problem = dataclasses.replace(pipeline._problem(setup, *rot_terms), contact_joints=terms.joints, up=terms.up)
    contact = np.asarray(terms.target_contacts.contact, bool)
    centre = setup.translations[:, anchor]
    mapped_weights = np.broadcast_to(setup.weights[mapped], (q.shape[0], len(mapped)))
    planted = terms.planted.copy()
    qb, tb = solver_start(setup, q0, q, t)
    started = time.perf_counter()
    for weight, iterations in [(SOFT_WEIGHT, SOFT_ITERATIONS)] * ROUNDS + [(HARD_WEIGHT, ITERATIONS)]:
        t0 = tb.copy()
        t0[:, anchor] -= centre
        targets = np.concatenate([setup.targets[:, mapped], planted], axis=1) - centre[:, None]
        weights = np.concatenate([mapped_weights, weight * contact], axis=1)
        solution = solve(problem, qb, t0, targets, iterations=iterations, weights=weights)
        qb, tb = solution.q, solution.t
        tb[:, anchor] += centre
        if weight != HARD_WEIGHT:
            planted = interval_means(fk_arrays(qb, tb, parents)[1][:, terms.joints], planted, contact, terms.up)
    world = fk_arrays(qb, tb, parents)[1][:, terms.joints]
    off_mm = float(np.linalg.norm(world - planted, axis=-1)[contact].max()) * cm * 10.0
    plain, contacts, bound = rms(q_plain, t_plain), rms(q, t), rms(qb, tb)
    return {"pair": label, "frames": int(q.shape[0]), "rms_plain_cm": plain, "rms_contacts_cm": contacts,
            "rms_bound_cm": bound, "rise_contacts_pct": 100 * (contacts / plain - 1),
            "rise_bound_pct": 100 * (bound / plain - 1), "bound_off_point_mm": off_mm,
            "bound_iterations": int(solution.iterations), "bound_s": time.perf_counter() - started}


def main(argv=None) -> int:
    rows = []
    for label, source_spec, target_spec, target_kw in pairs_from_argv(__doc__.splitlines()[0], argv):
        rows.append(bound_pair(label, source_spec, target_spec, target_kw))
        r = rows[-1]
        print(f"{label}: plain {r['rms_plain_cm']:.3f}, contacts {r['rms_contacts_cm']:.3f}, "
              f"bound {r['rms_bound_cm']:.3f} cm", flush=True)
    print()
    print_table("Joint-position RMS to the (scaled) source, cm: the plain solve, the contact solve, and the least a "
                "whole-body solve holding each contact joint on one point per contact reaches (no temporal, "
                f"no-flip or floor terms); 1-min load {os.getloadavg()[0]:.1f}",
                ["pair", "plain", "contacts", "rise", "bound", "bound rise", "bound off its points mm"],
                [[r["pair"], f"{r['rms_plain_cm']:.2f}", f"{r['rms_contacts_cm']:.2f}",
                  f"{r['rise_contacts_pct']:+.1f} %", f"{r['rms_bound_cm']:.2f}", f"{r['rise_bound_pct']:+.1f} %",
                  f"{r['bound_off_point_mm']:.2f}"] for r in rows])
    return save_rows("retarget_rms_bound", rows)


if __name__ == "__main__":
    raise SystemExit(main())
