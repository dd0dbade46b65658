"""Calibration bench: speed, recovery and Eq. 14 against the paper's Nelder-Mead procedure.

For each of the paper's muscles (FAM1, FAM2) and each of its four Table 4 laws as the truth:
recordings are synthesised with the paper's protocol (five pressures 15-75 psi, strokes from rest
to 198 % of the rest length and back at 5.1 mm/s, 20 Hz, a 2 s blocked hold, 0.5 N Gaussian
force noise), then

* ``calibrate`` (dead band and braid angle from blocked forces, all six laws, leave-one-pressure-out
  held-out errors) is timed on ONE core (the process is pinned to one CPU, BLAS to one thread);
* recovery: the same law fitted with the true geometry (``fit_law``) and by ``calibrate``: the
  largest force error over the tested range relative to that pressure's force range;
* the paper's procedure (fminsearch-like Nelder-Mead on Eq. 14, linear law first) is run on the
  same Problem (same braid angle and dead band) and timed; Eq. 14 compared law by law;
* every law's Eq. 14 error on every truth (a Table 3-style matrix).

Prints the tables and writes bench/results/calibrate.json.
Usage: python bench/bench_calibrate.py [--seeds 1]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _machine import pin_one_core  # noqa: E402  (bench/, the script's own folder)

from efam_mujoco.calibrate import calibrate, fit_law, paper_baseline, recovery_error, synthesize  # noqa: E402
from efam_mujoco.files import write_json_atomic  # noqa: E402
from efam_mujoco.musclefile import load_muscle  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402
from efam_mujoco.stress import LAW_NAMES  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "calibrate.json"
TRUTH_LAWS = ("linear", "polynomial", "exponential_decay", "exponent")
SPEED_GOAL_S = 5.0


def run_case(preset: str, truth_law: str, seed: int) -> dict:
    truth = load_muscle(preset, truth_law)
    recs = synthesize(truth, seed=seed)
    t0 = time.perf_counter()
    cal = calibrate(recs, truth, "all")
    seconds_all = time.perf_counter() - t0
    t0 = time.perf_counter()
    calibrate(recs, truth, "all", heldout=False)
    seconds_no_heldout = time.perf_counter() - t0
    t0 = time.perf_counter()
    same = fit_law(truth, recs, truth_law, fit_deadband=False)
    seconds_same = time.perf_counter() - t0
    base_muscle = cal.fits["linear"].muscle  # calibrated braid angle and dead band, as ours used
    t0 = time.perf_counter()
    nm = paper_baseline(base_muscle, cal.problem, LAW_NAMES)
    seconds_nm = time.perf_counter() - t0
    laws = {}
    for law in LAW_NAMES:
        ours, theirs = cal.fits[law], nm[law]
        laws[law] = {
            "eq14_pct": ours.eq14_error_pct, "rms_N": ours.rms_N, "heldout_rms_N": cal.heldout_rms_N[law],
            "seconds": ours.seconds, "stable": ours.stable, "coefficients": ours.coefficients,
            "nm_eq14_pct": theirs.eq14_error_pct, "nm_rms_N": theirs.rms_N, "nm_seconds": theirs.seconds,
            "nm_coefficients": theirs.coefficients, "ours_le_nm": ours.eq14_error_pct <= theirs.eq14_error_pct,
            "table3_rows_pct": ours.eq14_by_k,
        }  # fmt: skip
    return {
        "muscle": preset, "truth_law": truth_law, "seed": seed,
        "deadband_kPa": cal.deadband_Pa / 1e3, "deadband_true_kPa": truth.deadband_Pa / 1e3,
        "theta_rest_deg": cal.theta_rest_deg, "theta_true_deg": truth.theta_rest_deg,
        "calibrate_all_laws_s": seconds_all, "calibrate_all_laws_no_heldout_s": seconds_no_heldout,
        "recovery_true_geometry_pct": 100 * recovery_error(same.muscle, truth),
        "recovery_true_geometry_s": seconds_same,
        "recovery_calibrated_pct": 100 * recovery_error(cal.fits[truth_law].muscle, truth),
        "best_law": cal.best_law, "nelder_mead_all_laws_s": seconds_nm, "laws": laws,
    }  # fmt: skip


def print_tables(cases: list[dict]) -> None:
    print("\ncase                     calibrate s (no held-out)  recovery: true geom / calibrated   best law")
    for c in cases:
        print(f"{c['muscle']} {c['truth_law']:18s} {c['calibrate_all_laws_s']:6.2f} ({c['calibrate_all_laws_no_heldout_s']:5.2f})"
              f"          {c['recovery_true_geometry_pct']:6.3f} % / {c['recovery_calibrated_pct']:6.3f} %"
              f"         {c['best_law']}")  # fmt: skip
    print("\nEq. 14 error (%) of each fitted law (columns) on data from each truth (rows); NM in brackets")
    print("truth".ljust(26) + "".join(f"{law[:14]:>22s}" for law in LAW_NAMES))
    for c in cases:
        cells = "".join(
            f"{c['laws'][law]['eq14_pct']:>10.2f} ({c['laws'][law]['nm_eq14_pct']:7.2f})  "
            for law in LAW_NAMES
        )
        print(f"{c['muscle']} {c['truth_law']:21s}" + cells)
    ours = sum(sum(v["seconds"] for v in c["laws"].values()) for c in cases)
    theirs = sum(c["nelder_mead_all_laws_s"] for c in cases)
    print(f"\nfit time, all laws and cases: ours {ours:.2f} s, Nelder-Mead {theirs:.2f} s")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="calibration bench")
    parser.add_argument("--seeds", type=int, default=1, help="noise realisations per case")
    parser.add_argument("--out", default=str(RESULTS))
    parser.add_argument(
        "--figures", metavar="PREFIX", help="also write the docs figures (FAM1, exponential-decay truth)"
    )
    args = parser.parse_args(argv)
    pinned = pin_one_core()
    cases = []
    jobs = [
        (preset, law, seed) for preset in ("FAM1", "FAM2") for law in TRUTH_LAWS for seed in range(args.seeds)
    ]
    for preset, law, seed in progress(jobs, "calibration cases", total=len(jobs)):
        cases.append(run_case(preset, law, seed))
        c = cases[-1]
        print(f"{preset} {law:18s} seed {seed}: calibrate {c['calibrate_all_laws_s']:.2f} s, recovery "
              f"{c['recovery_true_geometry_pct']:.3f} % / {c['recovery_calibrated_pct']:.3f} %", flush=True)  # fmt: skip
    print_tables(cases)
    worst_time = max(c["calibrate_all_laws_s"] for c in cases)
    worst_recovery = max(max(c["recovery_true_geometry_pct"], c["recovery_calibrated_pct"]) for c in cases)
    all_le = all(v["ours_le_nm"] for c in cases for v in c["laws"].values())
    summary = {
        "one_core": pinned,
        "python": platform.python_version(),
        "calibrate_all_laws_s_max": worst_time,
        "calibrate_all_laws_s_mean": float(np.mean([c["calibrate_all_laws_s"] for c in cases])),
        "speed_goal_s": SPEED_GOAL_S,
        "speed_goal_met": worst_time < SPEED_GOAL_S,
        "recovery_worst_pct": worst_recovery,
        "recovery_goal_met": worst_recovery < 0.5,
        "eq14_ours_le_nelder_mead_everywhere": all_le,
    }
    print(f"\n6-law calibration (with held-out) on one core: worst {worst_time:.2f} s (goal < {SPEED_GOAL_S} s); "
          f"worst recovery {worst_recovery:.3f} % (goal < 0.5 %); Eq. 14 <= Nelder-Mead everywhere: {all_le}")  # fmt: skip
    out = write_json_atomic(args.out, {"summary": summary, "cases": cases})
    print(f"wrote {out}")
    if args.figures:
        from efam_mujoco.calibrate.report import write_figures

        truth = load_muscle("FAM1", "exponential_decay")
        for path in write_figures(calibrate(synthesize(truth, seed=0), truth, "all"), args.figures):
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
