"""Calibrate the force-balance model on real Festo DMSP recordings (contractile McKibben muscles).

Data: ../shared/data/real/festo_dmsp beside the checkout, or $EFAM_SHARED_DIR (see its README; not part of the package, not shipped).
Skips cleanly (exit 0, one line) when that folder is absent.

Each file holds one muscle at one fixed length while the pressure ramps up to ~620 kPa and back
(isometric). A DMSP-10 was cut to six lengths (10-40 cm), each held at its rest length and at
25/50/75 % of its free contraction; a DMSP-20 (30 cm) at rest and 14/23/34 mm shorter. Every cut
length is its own muscle, so each is calibrated on its own four files.

Per muscle:

1. the load cell's zero offset of each file: the median tension before the pressure first
   exceeds 20 kPa (the muscle is slack or at rest then, so the true force is 0); subtracted;
2. dead band and blocked-force slope (paper Sec. 4.3): the hinge fit to the rest-length file;
3. geometry: the inner diameter is the datasheet's (10 or 20 mm). The outer (braid) diameter D is
   identified (searched from a 1 mm wall to 2.5 x the inner diameter; the error is flat in D, so
   D is weakly determined by these data): for each trial D the braid angle follows from the blocked-force slope by Eq. 9
   (Sec. 4.4), the bladder volume from the wall between the inner and outer diameters,
   V_B = pi (D^2 - D_in^2) / 4 L_rest, and the stress law is fitted; D is the one with the
   smallest RMS error (bounded 1-D search);
4. stress law: every law, least squares in N over all samples (``objective="lsq"``: Eq. 14 needs
   isobaric strokes), tension-only (a slack muscle carries no force);
5. errors: RMS (N) per held length, and held-out: leave one held length out (the three shortened
   lengths in turn; the rest-length file always stays in training because steps 2-3 need its
   blocked force), re-run 2-4 without it, predict it. Also as % of the muscle's largest force.

Writes bench/results/festo_calibrate.json and docs/figures/calibration_festo.png; prints a table.
Usage: python scripts/festo_calibrate.py [--laws linear,exponential_decay] [--quick]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from efam_mujoco.calibrate import blocked_points, fit_blocked, fit_law, pool
from efam_mujoco.calibrate.blocked import braid_angle_from_slope
from efam_mujoco.files import write_json_atomic
from efam_mujoco.muscle import NEUTRAL_BRAID_ANGLE_DEG, Muscle, MuscleError
from efam_mujoco.recordings import read_csv
from efam_mujoco.stress import LAW_NAMES, StressLaw, StressLawError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from shared_data import festo_dir  # noqa: E402

DATA = festo_dir()
ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results" / "festo_calibrate.json"
FIGURE = ROOT / "docs" / "figures" / "calibration_festo.png"

#: Datasheet inner diameters (the model number is the inner diameter in mm).
INNER_DIAMETER_M = {"DMSP-10": 0.010, "DMSP-20": 0.020}
#: Martens & Boblan 2017 static-model fit errors for the same muscle types (README).
PUBLISHED_PCT = {"DMSP-10": 4.4, "DMSP-20": 2.35}
OFFSET_BELOW_PA = 20e3
#: Thinnest membrane wall searched: the DMSP membrane is a fibre-reinforced rubber tube.
MIN_WALL_M = 1e-3
_PLACEHOLDER = StressLaw("linear", (1e6, 0.0))


def load_groups() -> dict[str, dict]:
    """{muscle label: {"type", "rest_length_m", "files": [(name, Recording, offset_N)]}}."""
    meta = json.loads((DATA / "recordings.json").read_text())
    groups: dict[str, dict] = {}
    for name in sorted(meta):
        info = meta[name]
        kind = "DMSP-10" if name.startswith("dmsp10") else "DMSP-20"
        label = f"{kind} cut {round(info['cut_length_m'] * 100)} cm"
        rec = read_csv(DATA / "recordings" / name, on_bad_rows="drop")
        if abs(float(np.median(rec.length_m)) - info["held_length_m"]) > 1e-6:
            raise ValueError(f"{name}: length column disagrees with recordings.json")
        offset = zero_offset(rec)
        rec.force_N = rec.force_N + offset  # force = -tension; remove the tension offset
        rec.meta.update(offset_N=offset, held_length_m=info["held_length_m"], file=name)
        group = groups.setdefault(label, {"type": kind, "rest_length_m": info["rest_length_m"], "files": []})
        group["files"].append((name, rec, offset))
    return groups


def zero_offset(rec) -> float:
    """Median tension before the pressure first exceeds 20 kPa (true force 0 there)."""
    above = np.nonzero(rec.pressure_Pa > OFFSET_BELOW_PA)[0]
    stop = int(above[0]) if len(above) else len(rec)
    if stop < 5:
        raise ValueError(f"{rec.meta['source']}: no zero-pressure segment to estimate the load-cell offset")
    return float(np.median(rec.tension_N[:stop]))


def muscle_for_diameter(rest_length: float, inner: float, outer: float, slope: float, deadband: float):
    theta = braid_angle_from_slope(slope, outer)
    if theta <= NEUTRAL_BRAID_ANGLE_DEG:
        raise MuscleError(f"braid angle {theta:.2f} deg is not contractile")
    volume = math.pi * (outer**2 - inner**2) / 4 * rest_length
    return Muscle(rest_length, outer, theta, volume, deadband, _PLACEHOLDER, tension_only=True, name="festo")


def identify(recordings, rest_length: float, inner: float, law: str):
    """Steps 2-4 on the given files (one of them held at the rest length)."""
    at_rest = [r for r in recordings if abs(r.meta["held_length_m"] - rest_length) < 1e-6]
    samples = pool(at_rest)
    P, F = blocked_points(samples, rest_length)
    blocked = fit_blocked(P, F)
    cache = {}

    def fit_for(outer: float):
        key = round(outer, 9)
        if key not in cache:
            try:
                muscle = muscle_for_diameter(
                    rest_length, inner, outer, blocked.slope_N_per_Pa, blocked.deadband_Pa
                )
                cache[key] = fit_law(muscle, recordings, law, fit_deadband=False, objective="lsq")
            except (MuscleError, StressLawError, ValueError):
                cache[key] = None
        return cache[key]

    cost = lambda d: fit_for(d).rms_N if fit_for(d) is not None else 1e12  # noqa: E731  (finite for Brent)
    lo, hi = inner + 2 * MIN_WALL_M, inner * 2.5
    grid = np.linspace(lo, hi, 12)
    costs = [cost(d) for d in grid]
    i = int(np.argmin(costs))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    best = minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-6})
    outer = float(best.x) if best.fun <= costs[i] else float(grid[i])
    return fit_for(outer), blocked


def rms(fit, rec) -> float:
    predicted = fit.muscle.tension(rec.pressure_Pa, rec.length_m)
    return float(np.sqrt(np.mean((predicted - rec.tension_N) ** 2)))


def calibrate_group(label: str, group: dict, laws) -> dict:
    inner = INNER_DIAMETER_M[group["type"]]
    rest = group["rest_length_m"]
    recs = [rec for _, rec, _ in group["files"]]
    f_max = max(float(np.max(r.tension_N)) for r in recs)
    out = {
        "type": group["type"], "rest_length_m": rest, "max_force_N": f_max,
        "offsets_N": {name: off for name, _, off in group["files"]}, "laws": {},
    }  # fmt: skip
    for law in laws:
        t0 = time.perf_counter()
        fit, blocked = identify(recs, rest, inner, law)
        per_length = {r.meta["file"]: rms(fit, r) for r in recs}
        held_sq, held_n, held_per = 0.0, 0, {}
        for out_rec in recs:
            if abs(out_rec.meta["held_length_m"] - rest) < 1e-6:
                continue
            train = [r for r in recs if r is not out_rec]
            fold_fit, _ = identify(train, rest, inner, law)
            e = rms(fold_fit, out_rec)
            held_per[out_rec.meta["file"]] = e
            held_sq += e * e * len(out_rec)
            held_n += len(out_rec)
        all_sq = sum(per_length[r.meta["file"]] ** 2 * len(r) for r in recs)
        m = fit.muscle
        out["laws"][law] = {
            "coefficients": fit.coefficients,
            "deadband_kPa": m.deadband_Pa / 1e3,
            "theta_rest_deg": m.theta_rest_deg,
            "outer_diameter_mm": m.rest_diameter_m * 1e3,
            "bladder_volume_cm3": m.bladder_volume_m3 * 1e6,
            "rms_N": math.sqrt(all_sq / sum(len(r) for r in recs)),
            "rms_pct_of_max": 100 * math.sqrt(all_sq / sum(len(r) for r in recs)) / f_max,
            "rms_per_length_N": per_length,
            "heldout_rms_N": math.sqrt(held_sq / held_n) if held_n else None,
            "heldout_pct_of_max": 100 * math.sqrt(held_sq / held_n) / f_max if held_n else None,
            "heldout_per_length_N": held_per,
            "blocked_rms_N": blocked.rms_N,
            "seconds": time.perf_counter() - t0,
        }
        print(f"  {label:18s} {law:18s} D {m.rest_diameter_m * 1e3:6.2f} mm theta {m.theta_rest_deg:6.2f} deg "
              f"Pdb {m.deadband_Pa / 1e3:6.1f} kPa | RMS {out['laws'][law]['rms_N']:6.2f} N "
              f"({out['laws'][law]['rms_pct_of_max']:.2f} %) held-out "
              f"{out['laws'][law]['heldout_rms_N']:6.2f} N ({out['laws'][law]['heldout_pct_of_max']:.2f} %)",
              flush=True)  # fmt: skip
    best = min(laws, key=lambda law: out["laws"][law]["heldout_rms_N"])
    out["best_law"] = best
    out["fit_for_figure"] = best
    return out


def summarise(results: dict, laws) -> dict:
    """Per muscle type: the sample-weighted RMS over its muscles, per law (in N and % of max)."""
    summary = {}
    for kind in ("DMSP-10", "DMSP-20"):
        rows = [r for r in results.values() if r["type"] == kind]
        if not rows:
            continue
        summary[kind] = {"published_static_model_pct": PUBLISHED_PCT[kind], "laws": {}}
        for law in laws:
            held = [r["laws"][law]["heldout_pct_of_max"] for r in rows]
            ins = [r["laws"][law]["rms_pct_of_max"] for r in rows]
            summary[kind]["laws"][law] = {
                "mean_rms_pct_of_max": float(np.mean(ins)),
                "mean_heldout_pct_of_max": float(np.mean(held)),
                "mean_heldout_rms_N": float(np.mean([r["laws"][law]["heldout_rms_N"] for r in rows])),
            }
    return summary


def figure(groups, results, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [k for k in ("DMSP-10 cut 25 cm", "DMSP-20 cut 30 cm") if k in results]
    fig, axes = plt.subplots(1, len(labels), figsize=(6 * len(labels), 4.2), squeeze=False)
    for ax, label in zip(axes[0], labels):
        res = results[label]
        law = res["best_law"]
        lr = res["laws"][law]
        muscle = Muscle(
            res["rest_length_m"], lr["outer_diameter_mm"] / 1e3, lr["theta_rest_deg"],
            lr["bladder_volume_cm3"] / 1e6, lr["deadband_kPa"] * 1e3,
            StressLaw.from_dict(law, lr["coefficients"]), tension_only=True,
        )  # fmt: skip
        for _name, rec, _ in groups[label]["files"]:
            step = max(1, len(rec) // 1500)
            line = ax.plot(rec.pressure_Pa[::step] / 1e3, rec.tension_N[::step], ".", ms=1.5, alpha=0.5)[0]
            P = np.linspace(0, rec.pressure_Pa.max(), 200)
            contraction = 100 * (1 - rec.meta["held_length_m"] / res["rest_length_m"])
            ax.plot(P / 1e3, muscle.tension(P, rec.meta["held_length_m"]), color=line.get_color(),
                    lw=1.5, label=f"held {contraction:.1f} % shorter")  # fmt: skip
        ax.set_title(f"{label}: {law}, held-out {lr['heldout_pct_of_max']:.1f} % of max force", fontsize=9)
        ax.set_xlabel("pressure (kPa)")
        ax.set_ylabel("tension (N), load-cell offset removed")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, title="dots: data; lines: model", title_fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--laws", default="all", help="comma-separated laws or all")
    parser.add_argument("--quick", action="store_true", help="only DMSP-10 cut 25 cm and DMSP-20")
    parser.add_argument("--out", default=str(RESULTS))
    parser.add_argument("--figure", default=str(FIGURE))
    args = parser.parse_args(argv)
    if not (DATA / "recordings.json").exists():
        print(f"festo_calibrate: skipped, {DATA} is absent")
        return 0
    laws = LAW_NAMES if args.laws == "all" else tuple(args.laws.split(","))
    t0 = time.perf_counter()
    groups = load_groups()
    if args.quick:
        groups = {k: v for k, v in groups.items() if k in ("DMSP-10 cut 25 cm", "DMSP-20 cut 30 cm")}
    results = {}
    for label, group in groups.items():
        results[label] = calibrate_group(label, group, laws)
    summary = summarise(results, laws)
    doc = {
        "data": str(DATA),
        "assumptions": {
            "inner_diameter_m": INNER_DIAMETER_M,
            "outer_diameter": "identified (bounded 1-D search, inner + 2 mm to 2.5 x inner) per muscle and law",
            "theta_rest": "Eq. 9 from the blocked-force slope of the rest-length file and the outer diameter",
            "bladder_volume": "pi (D_out^2 - D_in^2) / 4 x rest length",
            "deadband": "hinge fit to the rest-length file's tension vs pressure (Sec. 4.3)",
            "load_cell_offset": "median tension before the pressure first exceeds 20 kPa, per file",
            "objective": "least squares in N over all samples, tension-only model",
            "heldout": "leave one shortened length out; the rest-length file always in training",
        },
        "summary": summary,
        "muscles": results,
        "seconds": time.perf_counter() - t0,
    }
    out = write_json_atomic(args.out, doc)
    Path(args.figure).parent.mkdir(parents=True, exist_ok=True)
    figure(groups, results, args.figure)
    print("\nper muscle type (mean over its muscles), % of the muscle's largest measured force:")
    for kind, s in summary.items():
        for law, v in s["laws"].items():
            print(f"  {kind} {law:18s} in-sample {v['mean_rms_pct_of_max']:5.2f} %  held-out "
                  f"{v['mean_heldout_pct_of_max']:5.2f} % ({v['mean_heldout_rms_N']:.1f} N)  "
                  f"published static model {s['published_static_model_pct']} %")  # fmt: skip
    print(f"wrote {out} and {args.figure} ({doc['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
