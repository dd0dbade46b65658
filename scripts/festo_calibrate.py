"""Calibrate the force-balance model on real Festo DMSP recordings (contractile McKibben muscles).

Data: ../shared/data/real/festo_dmsp beside the checkout, or $EFAM_SHARED_DIR (see its README; not
part of the package, not shipped). Skips cleanly (exit 0, one line) when that folder is absent.

Each file holds one muscle at one fixed length while the pressure ramps up to ~620 kPa and back
(isometric). A DMSP-10 was cut to six lengths (10-40 cm), each held at its rest length and at
25/50/75 % of its free contraction; a DMSP-20 (30 cm) at rest and 14/23/34 mm shorter. Every cut
length is its own muscle, so each is calibrated on its own four files.

Per muscle, on the training files:

1. the load cell's zero offset of each training file: the median tension before the pressure
   first exceeds 20 kPa (the muscle is slack or at rest then, so the true force is 0);
2. dead band and blocked-force slope (paper Sec. 4.3): the hinge fit to the rest-length file;
3. geometry: the inner diameter is the datasheet's (10 or 20 mm). The outer (braid) diameter D is
   chosen on a fixed grid (from a 1 mm wall to 2.5 x the inner diameter): for each D the braid
   angle follows from the blocked-force slope by Eq. 9 (Sec. 4.4), the bladder volume from the
   wall, V_B = pi (D^2 - D_in^2) / 4 L_rest, and the stress law is fitted; D is the grid point
   with the smallest RMS (ties within 1e-6 relative go to the smaller D). The error is flat in
   D, so D is weakly determined by these data;
4. stress law: every law, least squares in N over all samples (``objective="lsq"``: Eq. 14 needs
   isobaric strokes), tension-only (a slack muscle carries no force).

Held-out (leave one shortened length out; the rest-length file always stays in training because
steps 2-3 need its blocked force): steps 1-4 re-run without the held-out file. Nothing of the
held-out file is used: its load-cell zero is the median of the training files' zeros (the same
load cell), and the law reported as "ours" is, per fold, the law with the lowest training RMS.
Errors: RMS (N) over the whole up-and-down ramp, and as % of the muscle's largest force.

Like for like with Martens & Boblan 2017: the same pipeline fitted to their Appendix A force maps
(DMSP-10-250, DMSP-20-300; published/ beside the recordings), scored by the maximum absolute
error over the map as % of the map's largest force (the measure behind their 4.4 % and 2.35 %),
in-sample as theirs is, and leave-one-length-out.

Determinism (the held-out figures agree to 0.01 % across numpy/scipy versions and machines): D
on a fixed grid with a tie rule (no continuous search whose end point a last-bit difference can
move along a flat valley), BLAS/OpenMP limited to one thread before numpy loads (no
thread-count-dependent summation order), files and laws in sorted order, no random numbers.

Writes bench/results/festo_calibrate.json and docs/figures/calibration_festo.png; prints a table.
Usage: python scripts/festo_calibrate.py [--laws linear,exponential_decay] [--quick]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ[_var] = "1"  # before numpy loads: one summation order whatever the machine

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from efam_mujoco.calibrate import blocked_points, fit_blocked, fit_law, pool  # noqa: E402
from efam_mujoco.calibrate.blocked import braid_angle_from_slope  # noqa: E402
from efam_mujoco.files import write_json_atomic  # noqa: E402
from efam_mujoco.muscle import NEUTRAL_BRAID_ANGLE_DEG, Muscle, MuscleError  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402
from efam_mujoco.recordings import Recording, read_csv  # noqa: E402
from efam_mujoco.stress import LAW_NAMES, LAWS, StressLaw, StressLawError  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from shared_data import festo_dir  # noqa: E402

DATA = festo_dir()
ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results" / "festo_calibrate.json"
FIGURE = ROOT / "docs" / "figures" / "calibration_festo.png"

#: Datasheet inner diameters (the model number is the inner diameter in mm).
INNER_DIAMETER_M = {"DMSP-10": 0.010, "DMSP-20": 0.020}
#: Martens & Boblan 2017: their static model's maximum error on their force maps (% of max force).
PUBLISHED_PCT = {"DMSP-10": 4.4, "DMSP-20": 2.35}
PUBLISHED_MAPS = {"DMSP-10-250": "DMSP-10", "DMSP-20-300": "DMSP-20"}
OFFSET_BELOW_PA = 20e3
#: Thinnest membrane wall searched: the DMSP membrane is a fibre-reinforced rubber tube.
MIN_WALL_M = 1e-3
#: Outer diameters tried (fixed grid, from the thinnest wall to 2.5 x the inner diameter).
DIAMETER_GRID = 13
TIE_REL = 1e-6
QUICK = ("DMSP-10 cut 25 cm", "DMSP-20 cut 30 cm")
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
        offset = zero_offset(rec)  # this file's own zero: used only when the file is in training
        rec.meta.update(offset_N=offset, held_length_m=info["held_length_m"], file=name)
        group = groups.setdefault(label, {"type": kind, "rest_length_m": info["rest_length_m"], "files": []})
        group["files"].append((name, rec, offset))
    return groups


def tared(rec: Recording, offset_N: float) -> Recording:
    """``rec`` with the load-cell zero ``offset_N`` (a tension) removed."""
    return replace(rec, force_N=rec.force_N + offset_N, meta=dict(rec.meta, tare_N=offset_N))


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

    grid = np.linspace(inner + 2 * MIN_WALL_M, inner * 2.5, DIAMETER_GRID)
    costs = np.array([fit_for(d).rms_N if fit_for(d) is not None else np.inf for d in grid])
    if not np.isfinite(costs).any():
        raise ValueError("no outer diameter on the grid gives a contractile muscle")
    best = int(np.nonzero(costs <= costs.min() * (1 + TIE_REL))[0][0])  # ties: the smaller D
    return fit_for(float(grid[best])), blocked


def rms(fit, rec) -> float:
    predicted = fit.muscle.tension(rec.pressure_Pa, rec.length_m)
    return float(np.sqrt(np.mean((predicted - rec.tension_N) ** 2)))


def is_rest(rec, rest_length: float) -> bool:
    """Whether ``rec`` is held at the rest length (the blocked-force file)."""
    return abs(rec.meta["held_length_m"] - rest_length) < 1e-6


def folds(group: dict) -> list[str | None]:
    """None (all files: the in-sample fit), then each shortened file's name (held out)."""
    rest = group["rest_length_m"]
    return [None] + [name for name, rec, _ in group["files"] if not is_rest(rec, rest)]


def fold_data(group: dict, held_out: str | None):
    """(training recordings, held-out recording or None), each tared from training data only."""
    train_offsets = [off for name, _, off in group["files"] if name != held_out]
    train = [tared(rec, off) for name, rec, off in group["files"] if name != held_out]
    test = None
    if held_out is not None:
        rec = next(rec for name, rec, _ in group["files"] if name == held_out)
        test = tared(rec, float(np.median(train_offsets)))  # the training files' zeros, not its own
    return train, test


def choose_law(rms_by_law: dict[str, float]) -> str:
    """The law with the lowest RMS; within ``TIE_REL`` of it, the one with the fewest coefficients
    (then the order of LAW_NAMES): a tie is not decided by rounding noise."""
    best = min(rms_by_law.values())
    tied = [law for law, value in rms_by_law.items() if value <= best * (1 + TIE_REL)]
    return min(tied, key=lambda law: (len(LAWS[law].params), LAW_NAMES.index(law)))


def calibrate_group(label: str, group: dict, laws, tick) -> dict:
    """Every law on all files, and per held-out file on the rest; ``tick()`` after each fit."""
    inner = INNER_DIAMETER_M[group["type"]]
    rest = group["rest_length_m"]
    all_train, _ = fold_data(group, None)
    f_max = max(float(np.max(r.tension_N)) for r in all_train)
    out = {
        "type": group["type"], "rest_length_m": rest, "max_force_N": f_max,
        "offsets_N": {name: off for name, _, off in group["files"]}, "laws": {}, "folds": {},
    }  # fmt: skip
    for held_out in folds(group):
        train, test = fold_data(group, held_out)
        fold = {}
        for law in laws:
            t0 = time.perf_counter()
            fit, blocked = identify(train, rest, inner, law)
            fold[law] = {
                "train_rms_N": fit.rms_N,
                "test_rms_N": rms(fit, test) if test is not None else None,
                "test_samples": len(test) if test is not None else 0,
                "fit": fit,
                "blocked": blocked,
                "seconds": time.perf_counter() - t0,
            }
            tick()
        if held_out is None:
            for law in laws:
                fit, m = fold[law]["fit"], fold[law]["fit"].muscle
                per_length = {r.meta["file"]: rms(fit, r) for r in train}
                out["laws"][law] = {
                    "coefficients": fit.coefficients,
                    "deadband_kPa": m.deadband_Pa / 1e3,
                    "theta_rest_deg": m.theta_rest_deg,
                    "outer_diameter_mm": m.rest_diameter_m * 1e3,
                    "bladder_volume_cm3": m.bladder_volume_m3 * 1e6,
                    "rms_N": fit.rms_N,
                    "rms_pct_of_max": 100 * fit.rms_N / f_max,
                    "rms_per_length_N": per_length,
                    "blocked_rms_N": fold[law]["blocked"].rms_N,
                    "seconds": fold[law]["seconds"],
                }
        else:
            chosen = choose_law({law: fold[law]["train_rms_N"] for law in laws})  # training data only
            out["folds"][held_out] = {
                "tare_N": float(np.median([off for name, _, off in group["files"] if name != held_out])),
                "own_zero_N": out["offsets_N"][held_out],
                "chosen_law": chosen,
                "test_rms_N": {law: fold[law]["test_rms_N"] for law in laws},
                "train_rms_N": {law: fold[law]["train_rms_N"] for law in laws},
                "samples": fold[chosen]["test_samples"],
            }

    # pooled over held-out files (sample-weighted RMS)
    def pooled(pick) -> float | None:
        rows = list(out["folds"].values())
        if not rows:
            return None
        total = sum(r["samples"] for r in rows)
        return math.sqrt(sum(r["test_rms_N"][pick(r)] ** 2 * r["samples"] for r in rows) / total)

    for law in laws:
        held = pooled(lambda r, law=law: law)
        out["laws"][law]["heldout_rms_N"] = held
        out["laws"][law]["heldout_pct_of_max"] = 100 * held / f_max if held is not None else None
        out["laws"][law]["heldout_per_length_N"] = {k: r["test_rms_N"][law] for k, r in out["folds"].items()}
    chosen = pooled(lambda r: r["chosen_law"])
    out["heldout_chosen_law_rms_N"] = chosen
    out["heldout_chosen_law_pct_of_max"] = 100 * chosen / f_max if chosen is not None else None
    out["best_law_in_sample"] = choose_law({law: out["laws"][law]["rms_N"] for law in laws})
    out["fit_for_figure"] = out["best_law_in_sample"]
    return out


def summarise(results: dict, laws) -> dict:
    """Per muscle type: the mean over its muscles, per law and for the law chosen on training data."""
    summary = {}
    for kind in ("DMSP-10", "DMSP-20"):
        rows = [r for r in results.values() if r["type"] == kind]
        if not rows:
            continue
        summary[kind] = {
            "muscles": len(rows),
            "published_static_model_max_error_pct": PUBLISHED_PCT[kind],
            "heldout_chosen_law_pct_of_max": float(
                np.mean([r["heldout_chosen_law_pct_of_max"] for r in rows])
            ),
            "heldout_chosen_law_rms_N": float(np.mean([r["heldout_chosen_law_rms_N"] for r in rows])),
            "chosen_laws": sorted({f["chosen_law"] for r in rows for f in r["folds"].values()}),
            "laws": {},
        }
        for law in laws:
            summary[kind]["laws"][law] = {
                "mean_rms_pct_of_max": float(np.mean([r["laws"][law]["rms_pct_of_max"] for r in rows])),
                "mean_heldout_pct_of_max": float(
                    np.mean([r["laws"][law]["heldout_pct_of_max"] for r in rows])
                ),
                "mean_heldout_rms_N": float(np.mean([r["laws"][law]["heldout_rms_N"] for r in rows])),
            }
    return summary


# ------------------------------------------------------------ Martens & Boblan's force maps
def load_maps() -> dict[str, list[Recording]]:
    """Their Appendix A force maps as one isometric "recording" per length (pressure ascending).
    Force 0 is slack there; the maps are already zeroed (no tare)."""
    path = DATA / "published" / "martens_boblan_2017_appendixA_force_maps.csv"
    rows: dict[str, dict[float, list]] = {}
    with open(path, newline="") as handle:
        for row in csv.DictReader(handle):
            by_length = rows.setdefault(row["muscle"], {})
            by_length.setdefault(float(row["length_m"]), []).append(
                (float(row["pressure_Pa"]), float(row["force_N"]))
            )
    maps = {}
    for muscle, by_length in sorted(rows.items()):
        recs = []
        for length, points in sorted(by_length.items(), reverse=True):
            points.sort()
            P = np.array([p for p, _ in points])
            F = np.array([f for _, f in points])
            recs.append(
                Recording(np.arange(len(P), dtype=float), np.full(len(P), length), P, -F,
                          {"file": f"{muscle} L={length:.3f} m", "held_length_m": length, "source": str(path)})
            )  # fmt: skip
        maps[muscle] = recs
    return maps


def max_error_pct(fit, recs, f_max: float) -> float:
    """Martens & Boblan's measure: the largest |model - measured| over the map, % of its largest force."""
    return (
        100
        * max(
            float(np.max(np.abs(fit.muscle.tension(r.pressure_Pa, r.length_m) - r.tension_N))) for r in recs
        )
        / f_max
    )


def compare_published(laws, tick) -> dict:
    """Our pipeline on their force maps, scored by their error measure (and RMS)."""
    out = {}
    for muscle, recs in load_maps().items():
        kind = PUBLISHED_MAPS[muscle]
        rest = recs[0].meta["held_length_m"]  # the longest length: blocked-like (0 N at the first level)
        inner = INNER_DIAMETER_M[kind]
        f_max = max(float(np.max(r.tension_N)) for r in recs)
        entry = {"type": kind, "rest_length_m": rest, "max_force_N": f_max,
                 "published_max_error_pct": PUBLISHED_PCT[kind], "points": sum(len(r) for r in recs),
                 "laws": {}}  # fmt: skip
        for law in laws:
            fit, _ = identify(recs, rest, inner, law)
            held_max, held_sq, held_n = 0.0, 0.0, 0
            for out_rec in recs[1:]:  # leave one length out (the blocked-force length stays)
                fold_fit, _ = identify([r for r in recs if r is not out_rec], rest, inner, law)
                err = fold_fit.muscle.tension(out_rec.pressure_Pa, out_rec.length_m) - out_rec.tension_N
                held_max = max(held_max, float(np.max(np.abs(err))))
                held_sq += float(err @ err)
                held_n += len(err)
            entry["laws"][law] = {
                "max_error_pct_of_max": max_error_pct(fit, recs, f_max),
                "rms_pct_of_max": 100 * fit.rms_N / f_max,
                "heldout_max_error_pct_of_max": 100 * held_max / f_max,
                "heldout_rms_pct_of_max": 100 * math.sqrt(held_sq / held_n) / f_max,
                "outer_diameter_mm": fit.muscle.rest_diameter_m * 1e3,
                "theta_rest_deg": fit.muscle.theta_rest_deg,
                "deadband_kPa": fit.muscle.deadband_Pa / 1e3,
            }
            tick()
        best = choose_law({law: entry["laws"][law]["max_error_pct_of_max"] for law in laws})
        entry["best_law"] = best
        out[muscle] = entry
    return out


# ------------------------------------------------------------------------------- figure
def figure(groups, results, path) -> None:
    """Data and model, tension-positive (the paper's sign), for two muscles."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [k for k in QUICK if k in results]
    fig, axes = plt.subplots(1, len(labels), figsize=(6.2 * len(labels), 5.0), squeeze=False)
    for ax, label in zip(axes[0], labels):
        res = results[label]
        law = res["fit_for_figure"]
        lr = res["laws"][law]
        muscle = Muscle(
            res["rest_length_m"], lr["outer_diameter_mm"] / 1e3, lr["theta_rest_deg"],
            lr["bladder_volume_cm3"] / 1e6, lr["deadband_kPa"] * 1e3,
            StressLaw.from_dict(law, lr["coefficients"]), tension_only=True,
        )  # fmt: skip
        colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
        for k, (_name, rec, offset) in enumerate(groups[label]["files"]):
            color = colors[k % len(colors)]
            rec = tared(rec, offset)
            step = max(1, len(rec) // 1500)
            contraction = 100 * (1 - rec.meta["held_length_m"] / res["rest_length_m"])
            P = np.linspace(0, rec.pressure_Pa.max(), 200)
            ax.plot(P / 1e3, muscle.tension(P, rec.meta["held_length_m"]), "-", color=color, lw=1.3, alpha=0.9,
                    zorder=2, label=f"held {contraction:.1f} % shorter")  # fmt: skip
            ax.plot(rec.pressure_Pa[::step] / 1e3, rec.tension_N[::step], ".", ms=2.5, color=color, alpha=0.6,
                    mec="none", zorder=3)  # data on top of the model: nothing hidden  # fmt: skip
        held = lr["heldout_pct_of_max"]
        ax.set_title(f"{label}\n{law} law, in-sample RMS {lr['rms_pct_of_max']:.1f} %, "
                     f"held-out {held:.1f} % of max force", fontsize=9)  # fmt: skip
        ax.set_xlabel("pressure (kPa)")
        ax.set_ylabel("tension (N), pull positive; load-cell zero removed")
        ax.grid(alpha=0.3)
        ax.set_ylim(bottom=min(-0.03 * res["max_force_N"], ax.get_ylim()[0]))
        ax.legend(loc="upper left", fontsize=7, title="lines: model; dots: data", title_fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    """Run the calibration (see the module docstring); returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--laws", default="all", help="comma-separated laws or all (default)")
    parser.add_argument("--quick", action="store_true",
                        help="development run: only DMSP-10 cut 25 cm and DMSP-20, no published maps")  # fmt: skip
    parser.add_argument("--out", default=str(RESULTS), help="JSON results (default: bench/results/...)")
    parser.add_argument("--figure", default=str(FIGURE), help="PNG figure (default: docs/figures/...)")
    args = parser.parse_args(argv)
    if not (DATA / "recordings.json").exists():
        print(
            f"festo_calibrate: skipped, {DATA / 'recordings.json'} is absent (real Festo data are not part of the package)"
        )
        return 0
    laws = LAW_NAMES if args.laws == "all" else tuple(args.laws.split(","))
    t0 = time.perf_counter()
    groups = load_groups()
    if args.quick:
        groups = {k: v for k, v in groups.items() if k in QUICK}
    maps = {} if args.quick else load_maps()
    total = sum(len(folds(g)) for g in groups.values()) * len(laws) + len(maps) * len(laws)
    bar = progress(range(total), "festo calibration (fits)", total=total)
    tick = lambda: next(bar, None)  # noqa: E731
    results = {label: calibrate_group(label, group, laws, tick) for label, group in groups.items()}
    published = {} if args.quick else compare_published(laws, tick)
    summary = summarise(results, laws)
    doc = {
        "data": "../shared/data/real/festo_dmsp (or $EFAM_SHARED_DIR)",
        "assumptions": {
            "inner_diameter_m": INNER_DIAMETER_M,
            "outer_diameter": f"fixed grid of {DIAMETER_GRID} from inner + 2 mm to 2.5 x inner, per muscle, law "
            "and fold; smallest RMS, ties (1e-6 relative) to the smaller",
            "theta_rest": "Eq. 9 from the blocked-force slope of the rest-length file and the outer diameter",
            "bladder_volume": "pi (D_out^2 - D_in^2) / 4 x rest length",
            "deadband": "hinge fit to the rest-length file's tension vs pressure (Sec. 4.3)",
            "load_cell_offset": "training files: median tension before the pressure first exceeds 20 kPa; "
            "held-out file: the median of the training files' offsets (nothing of the held-out file)",
            "objective": "least squares in N over all samples, tension-only model",
            "heldout": "leave one shortened length out; the rest-length file always in training",
            "law_choice": "per fold, the law with the lowest training RMS",
            "published_comparison": "our pipeline on Martens & Boblan's Appendix A force maps; their measure: "
            "max |model - measured| over the map as % of the map's largest force",
            "determinism": "fixed grids, one BLAS/OpenMP thread, sorted files and laws, no random numbers",
        },
        "versions": versions(),
        "summary": summary,
        "published_maps": published,
        "muscles": results,
        "seconds": time.perf_counter() - t0,
    }
    for res in results.values():
        for law in res["laws"].values():
            law.pop("seconds", None)  # timing varies run to run: keep the JSON comparable
    out = write_json_atomic(args.out, doc)
    Path(args.figure).parent.mkdir(parents=True, exist_ok=True)
    figure(groups, results, args.figure)
    print("per muscle type (mean over its muscles), % of the muscle's largest measured force:")
    for kind, s in summary.items():
        print(f"  {kind}: held-out, law chosen on training data ({', '.join(s['chosen_laws'])}): "
              f"{s['heldout_chosen_law_pct_of_max']:.3f} % ({s['heldout_chosen_law_rms_N']:.2f} N)")  # fmt: skip
        for law, v in s["laws"].items():
            print(f"    {law:18s} in-sample {v['mean_rms_pct_of_max']:6.3f} %  held-out "
                  f"{v['mean_heldout_pct_of_max']:6.3f} % ({v['mean_heldout_rms_N']:.2f} N)")  # fmt: skip
    for muscle, entry in published.items():
        best = entry["laws"][entry["best_law"]]
        print(f"  {muscle} force map (Martens & Boblan's measure, max error % of max force): ours "
              f"{best['max_error_pct_of_max']:.2f} % in-sample ({entry['best_law']}), "
              f"{best['heldout_max_error_pct_of_max']:.2f} % leave-one-length-out; theirs "
              f"{entry['published_max_error_pct']} %")  # fmt: skip
    print(f"wrote {out} and {args.figure} ({doc['seconds']:.0f} s)")
    return 0


def versions() -> dict[str, str]:
    """The versions the figures were computed with (they agree across versions: see the docstring)."""
    import platform

    import scipy

    return {"python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__}


if __name__ == "__main__":
    sys.exit(main())
