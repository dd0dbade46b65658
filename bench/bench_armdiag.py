"""Blind benchmark of ``efam diagnose-arm``: arm recordings with one concealed effect, or none.

Each case: ``armdiag.synth`` runs the arm model with one concealed effect of random magnitude
(written independently of the library, in other functional forms: see that module) under a lab
protocol (steps, ramps, sinusoids, random sequences, a closed-loop tip controller), samples the
tip at 30-200 Hz with 0.2-1 mm marker noise and dropouts in bursts. The diagnosis sees only the
recording and the nominal arm model.

Arms (the physical, segmented arm with the exact arc geometry of its segments; few disks for
speed, the builder's default is 8 per section at a 1 ms step): 1 section of 3 FAM1 muscles
upright and 2 sections hanging, 4 disks per section (a hanging arm at 2 disks per section is
fragile: models a few kPa apart part by decimetres, see ``--discretisation``), 4 ms time step (stable
at the arm's damping, limit about 9 ms; the builder warns that it is within less than its 2x
margin); the timing case is a 3-section hanging arm (4 disks per section, 4 ms), 60 s at 100 Hz,
on one thread, CPU time of this process (the diagnosis alone, not the making of the recording).
At the default D = 8 and 1 ms one simulated second costs about 15 to 20 times more.

Calibration first: the probability temperature T and P(none) at the noise floor are fitted on
calibration cases whose seeds (``--cal-seed``) are disjoint from the evaluation's (``--seed``),
then the evaluation cases are diagnosed with them. The timing case runs before both.

Scored on the evaluation cases: top-1 among confident answers, false alarms on clean recordings,
ambiguous share (and that every ambiguous answer carries a next experiment), the right muscle for
weak_muscle, the reliability table and expected calibration error of the top-1 probability,
held-out tip RMS (model as built -> re-fitted -> identified, against the marker noise), the
confusion matrix, and that the written MJCF (identified terms switched on) reproduces the
held-out blocks.

Usage: python bench/bench_armdiag.py [--reps 5] [--reps-2 3] [--seed 91000] [--cal-reps 1]
[--cal-reps-2 1] [--cal-seed 71000] [--duration 30] [--truths a,b] [--no-timing] [--out PATH]
[--timing-json PATH] [--timing-only PATH [--timing-truths a,b]] [--whole-search]
[--discretisation PATH]
Writes bench/results/armdiag.json and docs/figures/armdiag_confusion.png, armdiag_reliability.png,
armdiag_tip.png; the rows are saved after every case (a cut-off run keeps what it did).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from efam_mujoco import arm  # noqa: E402
from efam_mujoco.armdiag import diagnose_arm, diagnosis  # noqa: E402
from efam_mujoco.armdiag.diagnosis import folds  # noqa: E402
from efam_mujoco.armdiag.replay import Replayer  # noqa: E402
from efam_mujoco.armdiag.report import figures, write_model  # noqa: E402
from efam_mujoco.armdiag.synth import PROTOCOLS, TRUTHS, make_recording, random_truth  # noqa: E402
from efam_mujoco.files import save_figure, write_json_atomic  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "armdiag.json"
#: disks per section of every bench arm: D = 2 is not a credible hanging arm (its tip departs
#: 56-219 mm RMS from the builder's D = 8, and two models a few kPa apart part by up to 390 mm
#: for seconds: see docs/armdiag.md); D = 4 at 4 ms is within 2.5-3.5 mm of D = 4 at 1 ms
DISKS = 4
FIGURES = ROOT / "docs" / "figures"


def arms() -> dict:
    """The benchmark's arm models (nominal specs)."""
    return {
        "1x3": arm.ArmSpec(sections=(arm.paper_section(disks=4),), timestep_s=4e-3, name="arm_1x3"),
        "2x3": arm.ArmSpec(sections=(arm.paper_section(disks=DISKS),) * 2, orientation="hanging", timestep_s=4e-3, name="arm_2x3"),
        "3x3": arm.ArmSpec(sections=(arm.paper_section(disks=DISKS),) * 3, orientation="hanging", timestep_s=4e-3, name="arm_3x3"),
    }  # fmt: skip


def reproduce(spec, d, rec) -> float:
    """Held-out tip RMS of the written MJCF (identified terms on), replayed from the file alone."""
    with tempfile.TemporaryDirectory() as tmp:
        path = write_model(Path(tmp) / "identified.xml", spec, d)
        model_spec = mujoco.MjSpec.from_file(str(path))
    replayer = Replayer(model_spec, rec.time_s, rec.command_Pa, threads=1)
    tip = replayer.tips([replayer.nominal])[0]
    _, held = folds(rec.time_s, rec.valid)
    return float(np.sqrt(np.mean((tip[held] - rec.tip_m[held]) ** 2)))


def run_case(arm_name, spec, truth_name, protocol, seed, duration):
    rng = np.random.default_rng(seed)
    muscles = [a.name for a in spec.actuators]
    truth = random_truth(truth_name, muscles, rng)
    rec = make_recording(spec, truth, protocol, rng, duration_s=duration)
    d = diagnose_arm(spec, rec, threads=1)
    v = d.verdict
    row = {
        "arm": arm_name, "seed": seed, "truth": truth_name, "truth_muscle": truth.muscle,
        "truth_parameters": truth.parameters, "protocol": protocol, "rate_Hz": rec.meta["rate_Hz"],
        "noise_true_m": rec.meta["noise_m"], "noise_m": d.noise_m, "answer": v["answer"],
        "probability": v["probability"], "confident": v["confident"], "ambiguous": v["ambiguous"],
        "alternatives": v["alternatives"], "muscle": d.effects[0]["muscle"] if d.effects else None,
        "parameters": d.effects[0]["parameters"] if d.effects else {},
        "heldout_rms_nominal_m": d.heldout_rms_nominal_m, "heldout_rms_refit_m": d.heldout_rms_before_m,
        "heldout_rms_after_m": d.heldout_rms_after_m, "seconds_cpu": d.seconds,
        "next_experiment": d.next_experiment["recommended"] if d.next_experiment else None,
        "rollouts": d.decisions["rollouts"], "unstable_variants": d.decisions["unstable_variants"],
        "source_muscle": d.effects[0]["source_muscle"] if d.effects else None,
        "scores": {c["name"]: c["score"] for c in d.candidates}, "at_floor": "noise floor" in v["reason"],
        "paired": v["paired"],
    }  # fmt: skip
    row["heldout_rms_mjcf_m"] = reproduce(spec, d, rec)
    return row, d


def score(rows) -> dict:
    effect = [r for r in rows if r["truth"] != "none"]
    clean = [r for r in rows if r["truth"] == "none"]
    confident = [r for r in rows if r["confident"]]
    weak_truth = [r for r in effect if r["truth"] == "weak_muscle"]
    weak = [r for r in weak_truth if r["answer"] == "weak_muscle"]
    red_nom = [1 - r["heldout_rms_after_m"] / r["heldout_rms_nominal_m"] for r in effect]
    red_refit = [1 - r["heldout_rms_after_m"] / r["heldout_rms_refit_m"] for r in effect]
    labels = list(TRUTHS)
    matrix = {t: {a: 0 for a in labels} for t in labels}
    for r in rows:
        matrix[r["truth"]][r["answer"]] += 1
    per_truth = {
        t: {"n": sum(1 for r in rows if r["truth"] == t), "right": sum(1 for r in rows if r["truth"] == t and r["answer"] == t)}
        for t in labels
    }  # fmt: skip
    return {
        "cases": len(rows),
        "top1_all": float(np.mean([r["answer"] == r["truth"] for r in rows])),
        "top1_confident": float(np.mean([r["answer"] == r["truth"] for r in confident])) if confident else None,
        "confident_share": len(confident) / len(rows),
        "false_alarms": float(np.mean([r["answer"] != "none" for r in clean])) if clean else None,
        "ambiguous_share": float(np.mean([r["ambiguous"] for r in effect])) if effect else None,
        "weak_muscle_named_right": float(np.mean([r["muscle"] == r["truth_muscle"] for r in weak])) if weak else None,
        # stricter: of every concealed weak muscle, named weak_muscle on the right muscle
        "weak_muscle_right_of_all": sum(r["muscle"] == r["truth_muscle"] for r in weak) / len(weak_truth) if weak_truth else None,
        "median_heldout_reduction_vs_as_built": float(np.median(red_nom)) if effect else None,
        "median_heldout_reduction_vs_refit": float(np.median(red_refit)) if effect else None,
        "median_mjcf_over_diagnosis_heldout": float(np.median([r["heldout_rms_mjcf_m"] / r["heldout_rms_after_m"] for r in rows])),
        "median_heldout_after_over_noise": float(np.median([r["heldout_rms_after_m"] / r["noise_true_m"] for r in effect])) if effect else None,
        "ambiguous_with_next_experiment": float(np.mean([r["next_experiment"] is not None for r in rows if r["ambiguous"]])) if any(r["ambiguous"] for r in rows) else None,
        "heldout_rms_m_median": {
            "as_built": float(np.median([r["heldout_rms_nominal_m"] for r in effect])) if effect else None,
            "refit": float(np.median([r["heldout_rms_refit_m"] for r in effect])) if effect else None,
            "identified": float(np.median([r["heldout_rms_after_m"] for r in effect])) if effect else None,
            "marker_noise_true": float(np.median([r["noise_true_m"] for r in effect])) if effect else None,
        },
        "reliability": reliability(rows),
        "per_truth": per_truth,
        "confusion": matrix,
    }  # fmt: skip


BINS = (0.0, 0.5, 0.7, 0.8, 0.9, 0.95, 0.99, 1.0)


def reliability(rows) -> dict:
    """Top-1 probability against how often the top-1 answer is right, in bins; the expected
    calibration error ECE = sum_b n_b / N |accuracy_b - mean probability_b|."""
    p = np.array([r["probability"] for r in rows])
    right = np.array([r["answer"] == r["truth"] for r in rows], float)
    table, ece = [], 0.0
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        inside = (p >= lo) & ((p < hi) if hi < 1 else (p <= hi))
        if inside.any():
            table.append({"from": lo, "to": hi, "n": int(inside.sum()), "mean_probability": float(p[inside].mean()),
                          "accuracy": float(right[inside].mean())})  # fmt: skip
            ece += inside.sum() / len(p) * abs(right[inside].mean() - p[inside].mean())
    return {"bins": table, "ece": float(ece), "n": len(rows)}


def fit_calibration(rows) -> dict:
    """The probability temperature T (max likelihood of the concealed truth under p ~ exp(score/T))
    and P(none) at the noise floor, from calibration rows (seeds disjoint from the evaluation's)."""
    scored = [r for r in rows if not r["at_floor"]]
    grid = np.exp(np.linspace(np.log(0.2), np.log(50.0), 121))

    def nll(T):
        total = 0.0
        for r in scored:
            s = np.array(list(r["scores"].values()))
            names = list(r["scores"])
            z = (s - s.max()) / T
            logp = z - np.log(np.sum(np.exp(z)))
            total -= logp[names.index(r["truth"])]
        return total

    losses = [nll(T) for T in grid]
    T = float(grid[int(np.argmin(losses))])
    floor = [r for r in rows if r["at_floor"]]
    p_none = (sum(r["truth"] == "none" for r in floor) + 1) / (len(floor) + 2)
    return {"temperature": T, "nll": float(min(losses)), "nll_at_T1": float(nll(1.0)), "rows_scored": len(scored),
            "p_none_at_floor": float(p_none), "rows_at_floor": len(floor)}  # fmt: skip


def timing_case(spec, seed, truth_name="weak_muscle") -> dict:
    """A 60 s recording at 100 Hz of the 3-section arm (random protocol, one concealed effect)
    diagnosed on one thread: CPU seconds of this process, and whether the answer is right."""
    rng = np.random.default_rng(seed)
    muscles = [a.name for a in spec.actuators]
    truth = random_truth(truth_name, muscles, rng)
    rec = make_recording(spec, truth, "random", rng, duration_s=60.0, rate_Hz=100.0)
    wall = time.perf_counter()
    d = diagnose_arm(spec, rec, threads=1)
    return {
        "arm": f"3 sections x 3 FAM1 muscles, hanging, D = {DISKS} disks per section, arc geometry, 4 ms time step", "samples": len(rec), "duration_s": 60.0, "rate_Hz": 100.0,
        "seed": seed, "seconds_cpu_one_thread": d.seconds, "search_window_s": d.decisions["search_window_s"], "seconds_wall": time.perf_counter() - wall, "rollouts": d.decisions["rollouts"],
        "simulated_s": d.decisions["simulated_s"], "heldout_rms_nominal_m": d.heldout_rms_nominal_m,
        "heldout_rms_refit_m": d.heldout_rms_before_m, "noise_m": d.noise_m,
        "truth": truth.name, "truth_muscle": truth.muscle, "answer": d.verdict["answer"],
        "muscle": d.effects[0]["muscle"] if d.effects else None, "heldout_rms_after_m": d.heldout_rms_after_m,
        "probability": d.verdict["probability"], "confident": d.verdict["confident"],
        "ambiguous": d.verdict["ambiguous"], "alternatives": d.verdict["alternatives"],
        "candidates_heldout_rms_m": {c["name"]: c["heldout_rms_m"] for c in d.candidates},
    }  # fmt: skip


def discretisation_case(seed, duration_s=20.0) -> dict:
    """How far coarse arms (D = 2 and 4 disks per section, 4 ms and 1 ms) are from the builder's
    default (D = 8, its own step) under the same lab commands (the random protocol, 3 sections
    hanging, no effect), and how far 4 ms is from 1 ms at the same D: tip RMS per 5 s block
    between the replays, and the CPU cost of one simulated second of each, side by side in this
    process."""
    rng = np.random.default_rng(seed)

    def spec(disks, timestep_s):
        return arm.build_spec(arm.ArmSpec(sections=(arm.paper_section(disks=disks),) * 3, orientation="hanging",
                                          timestep_s=timestep_s, name="arm_3x3"))  # fmt: skip

    rec = make_recording(spec(2, 4e-3), synth_none(), "random", rng, duration_s=duration_s, rate_Hz=100.0)
    variants = {"D=2, 4 ms": (2, 4e-3), "D=2, 1 ms": (2, 1e-3), "D=4, 4 ms": (4, 4e-3), "D=4, 1 ms": (4, 1e-3),
                "D=8, builder's step": (8, None)}  # fmt: skip
    tips, cost = {}, {}
    for name, (disks, dt) in variants.items():
        replayer = Replayer(spec(disks, dt), rec.time_s, rec.command_Pa, threads=1)
        clock = time.process_time()
        tips[name] = replayer.tips([replayer.nominal])[0]
        cost[name] = (time.process_time() - clock) / (duration_s + replayer.settle_s)
    ref = tips["D=8, builder's step"]
    edges = np.arange(0.0, duration_s + 1e-9, 5.0)
    out = {
        "protocol": "random",
        "duration_s": duration_s,
        "cpu_s_per_simulated_s": cost,
        "tip_rms_vs_default_m": {},
        "tip_rms_4ms_vs_1ms_same_D_m": {},
    }
    for name, tip in tips.items():
        err = np.linalg.norm(tip - ref, axis=1)
        out["tip_rms_vs_default_m"][name] = [
            float(np.sqrt(np.mean(err[(rec.time_s >= a) & (rec.time_s < b)] ** 2))) for a, b in zip(edges[:-1], edges[1:])
        ]  # fmt: skip
    for disks in (2, 4):  # the time step alone: 4 ms against 1 ms at the same D
        err = np.linalg.norm(tips[f"D={disks}, 4 ms"] - tips[f"D={disks}, 1 ms"], axis=1)
        out["tip_rms_4ms_vs_1ms_same_D_m"][f"D={disks}"] = [
            float(np.sqrt(np.mean(err[(rec.time_s >= a) & (rec.time_s < b)] ** 2))) for a, b in zip(edges[:-1], edges[1:])
        ]  # fmt: skip
    return out


def synth_none():
    """The concealed truth 'none' (no effect)."""
    from efam_mujoco.armdiag.synth import Truth

    return Truth("none")


def confusion_figure(matrix, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(matrix)
    m = np.array([[matrix[t][a] for a in labels] for t in labels])
    fig, ax = plt.subplots(figsize=(7, 6))
    ax.imshow(m, cmap="Blues")
    for i in range(len(labels)):
        for j in range(len(labels)):
            if m[i, j]:
                ax.text(j, i, m[i, j], ha="center", va="center", color="k" if m[i, j] < m.max() / 2 else "w")
    ax.set_xticks(range(len(labels)), labels, rotation=45, ha="right")
    ax.set_yticks(range(len(labels)), labels)
    ax.set_xlabel("named by efam diagnose-arm")
    ax.set_ylabel("concealed in the recording")
    ax.set_title("Arm diagnosis, blind benchmark")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def plan_cases(seed: int, reps_1: int, reps_2: int, truths: tuple[str, ...] = TRUTHS) -> list[tuple]:
    """(arm, truth, protocol, seed) for every case: each truth ``reps_1`` times on the 1-section
    arm and ``reps_2`` times on the 2-section arm, protocols cycled."""
    per_arm = []
    for arm_name, reps in (("1x3", reps_1), ("2x3", reps_2)):
        cases = []
        for rep in range(reps):
            for i, truth in enumerate(truths):
                case_seed = seed + 1000 * (arm_name == "2x3") + 20 * rep + i
                cases.append((arm_name, truth, PROTOCOLS[(i + rep * 2) % len(PROTOCOLS)], case_seed))
        per_arm.append(cases)
    # both arms' cases interleaved, every truth early: a run cut short keeps a balanced sample
    plan = []
    for k in range(max(len(c) for c in per_arm)):
        plan += [c[k] for c in per_arm if k < len(c)]
    return plan


def run_plan(plan, specs, duration, label, out, partial_doc):
    """Run the cases, printing one line each and saving the rows after each case."""
    rows, example = [], None
    for arm_name, truth, protocol, seed in progress(plan, label):
        row, d = run_case(arm_name, specs[arm_name], truth, protocol, seed, duration)
        rows.append(row)
        if example is None and truth == "weak_muscle":
            example = d
        write_json_atomic(out, {**partial_doc, label: rows, "partial": True})  # survives an interruption
        print(
            f"{label} {arm_name} {truth:16s} {protocol:11s} {row['rate_Hz']:5.0f} Hz -> {row['answer']:16s} "
            f"p {row['probability']:.2f}{' AMB' if row['ambiguous'] else ''} muscle {row['muscle']} (true {row['truth_muscle']}); "
            f"held-out {row['heldout_rms_nominal_m'] * 1e3:.2f} / {row['heldout_rms_refit_m'] * 1e3:.2f} / "
            f"{row['heldout_rms_after_m'] * 1e3:.2f} mm (MJCF {row['heldout_rms_mjcf_m'] * 1e3:.2f}, noise "
            f"{row['noise_true_m'] * 1e3:.2f}), {row['seconds_cpu']:.1f} s",
            flush=True,
        )  # fmt: skip
    return rows, example


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=5, help="evaluation cases per truth, 1-section arm")
    parser.add_argument("--reps-2", type=int, default=3, help="evaluation cases per truth, 2-section arm")
    parser.add_argument("--seed", type=int, default=91000, help="evaluation seeds start here")
    parser.add_argument("--cal-reps", type=int, default=1, help="calibration cases per truth, 1-section arm")
    parser.add_argument(
        "--cal-reps-2", type=int, default=1, help="calibration cases per truth, 2-section arm"
    )
    parser.add_argument("--cal-seed", type=int, default=71000, help="calibration seeds start here (disjoint)")
    parser.add_argument(
        "--duration",
        type=float,
        default=30.0,
        help="seconds per recording (up to 15 s: searched whole; longer ones are searched on a window)",
    )
    parser.add_argument("--no-timing", action="store_true", help="skip the 3-section timing case")
    parser.add_argument("--out", type=Path, default=RESULTS)
    parser.add_argument(
        "--timing-json", type=Path, help="take the timing case from this JSON (measured by an earlier run)"
    )
    parser.add_argument(
        "--timing-only",
        type=Path,
        help="only the timing case (seed --seed + 5000, weak muscle) and further cases on the next seeds "
        "with the truths of --timing-truths; JSON here (the first case, plus 'more_cases')",
    )
    parser.add_argument("--timing-truths", default="weak_muscle,pressure_lag,cross_talk")
    parser.add_argument(
        "--truths", help="evaluate only these concealed truths (comma list), e.g. a larger weak_muscle sample"
    )
    parser.add_argument(
        "--whole-search",
        action="store_true",
        help="search every recording whole (the coarse-to-fine window switched off), for comparison",
    )
    parser.add_argument(
        "--discretisation",
        type=Path,
        help="only compare the timing arm's D = 2 with the default D = 8; JSON here",
    )
    args = parser.parse_args(argv)
    if args.discretisation:
        result = discretisation_case(args.seed + 6000)
        write_json_atomic(args.discretisation, result)
        print(result)
        return 0
    specs = {k: arm.build_spec(v) for k, v in arms().items()}
    if args.whole_search:
        diagnosis.WINDOW_TRAIN_S = float("inf")
    if args.timing_only:
        first = timing_case(specs["3x3"], args.seed + 5000)
        print("timing:", first, flush=True)
        more = []
        for i, truth_name in enumerate(args.timing_truths.split(",") if args.timing_truths else []):
            more.append(timing_case(specs["3x3"], args.seed + 5001 + i, truth_name))
            print("timing:", more[-1], flush=True)
            write_json_atomic(args.timing_only, first | {"more_cases": more})
        write_json_atomic(args.timing_only, first | {"more_cases": more})
        return 0
    started = time.perf_counter()
    truths = tuple(args.truths.split(",")) if args.truths else TRUTHS
    if set(truths) - set(TRUTHS):
        raise SystemExit(f"--truths: unknown {sorted(set(truths) - set(TRUTHS))}; known: {', '.join(TRUTHS)}")
    evaluation = plan_cases(args.seed, args.reps, args.reps_2, truths)
    calibration_plan = plan_cases(args.cal_seed, args.cal_reps, args.cal_reps_2)
    if {c[3] for c in evaluation} & {c[3] for c in calibration_plan}:
        raise SystemExit("calibration and evaluation seeds overlap")
    doc = {"seed": args.seed, "cal_seed": args.cal_seed}
    # the timing case first: short, and its figure stands even if a long run is cut off
    if args.timing_json:
        import json

        timing = json.loads(args.timing_json.read_text()) | {"measured_by": "an earlier run of this script"}
    else:
        timing = None if args.no_timing else timing_case(specs["3x3"], args.seed + 5000)
    doc["timing"] = timing
    print("timing:", timing, flush=True)
    calibration = None
    if calibration_plan:
        cal_rows, _ = run_plan(calibration_plan, specs, args.duration, "calibration", args.out, doc)
        calibration = fit_calibration(cal_rows) | {
            "cases": len(cal_rows),
            "reliability_before": reliability(cal_rows),
        }
        diagnosis.PROBABILITY_TEMPERATURE = calibration["temperature"]
        diagnosis.P_NONE_AT_FLOOR = calibration["p_none_at_floor"]
        doc |= {"calibration": calibration, "calibration_rows": cal_rows}
        print("calibration:", {k: v for k, v in calibration.items() if k != "reliability_before"}, flush=True)
    rows, example = run_plan(evaluation, specs, args.duration, "evaluation", args.out, doc)
    summary = score(rows) if rows else None
    doc = {
        "summary": summary, "timing": timing, "calibration": calibration,
        "probability_temperature_used": diagnosis.PROBABILITY_TEMPERATURE,
        "p_none_at_floor_used": diagnosis.P_NONE_AT_FLOOR, "rows": rows,
        "calibration_rows": doc.get("calibration_rows", []), "seed": args.seed, "cal_seed": args.cal_seed,
        "duration_s_per_recording": args.duration, "bench_wall_s": time.perf_counter() - started,
        "machine": {"python": platform.python_version(), "mujoco": mujoco.__version__, "cpu_count": os.cpu_count()},
    }  # fmt: skip
    write_json_atomic(args.out, doc)
    if args.out == RESULTS and summary:
        confusion_figure(summary["confusion"], FIGURES / "armdiag_confusion.png")
        reliability_figure(summary["reliability"], FIGURES / "armdiag_reliability.png")
        if example is not None:
            figures(example, FIGURES)
    _print(summary, timing)
    return 0


def reliability_figure(rel, path):
    """Reliability diagram: mean top-1 probability against accuracy per bin."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 4.2))
    ax.plot([0, 1], [0, 1], "k:", lw=0.8)
    for b in rel["bins"]:
        ax.plot(
            b["mean_probability"], b["accuracy"], "o", ms=3 + 1.5 * np.sqrt(b["n"]), color="C0", alpha=0.7
        )
        ax.annotate(
            str(b["n"]),
            (b["mean_probability"], b["accuracy"]),
            fontsize=7,
            xytext=(4, -10),
            textcoords="offset points",
        )
    ax.set_xlabel("top-1 probability (bin mean)")
    ax.set_ylabel("top-1 right (share)")
    ax.set_title(f"Arm diagnosis reliability, ECE {rel['ece']:.3f} (n = {rel['n']})", fontsize=9)
    ax.set_xlim(0, 1.02)
    ax.set_ylim(0, 1.02)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def _print(summary, timing):
    if summary:
        print({k: v for k, v in summary.items() if k not in ("confusion", "per_truth")})
        print("per truth:", {k: f"{v['right']}/{v['n']}" for k, v in summary["per_truth"].items()})
    if timing:
        print("timing:", timing)


if __name__ == "__main__":
    raise SystemExit(main())
