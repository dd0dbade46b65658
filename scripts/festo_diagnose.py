"""Diagnose real Festo DMSP recordings: what the force-balance model leaves out, on real hardware.

Data: ../shared/data/real/festo_dmsp beside the checkout, or $EFAM_SHARED_DIR (see its README; not part of the package, not shipped).
Skips cleanly (exit 0, one line) when that folder is absent.

Each file holds one contractile McKibben muscle at one fixed length while the pressure steps up to
~620 kPa and back down (isometric; the rate of the test is the pressure rate). Every cut length of
the DMSP-10, and the DMSP-20, is its own muscle, diagnosed on its own four files (held at rest
length and three shorter lengths). Held out (``diagnose``'s rule for these data, stated in its
report): whole half-cycles (each file's pressurising and venting branch), dealt round-robin into
5 folds, so no fold holds a whole file out and every fold's training set has both branches at
every length; each held-out sample is predicted by effect amplitudes and parameter corrections
fitted without its half-cycle. The stress-law re-fit, the linearisation point, saw all data.

The slow hysteresis (the issue's finding): in the rest-length file the tension during the final
low-pressure hold after venting stays above the rising branch at the same pressure. For each
rest-length file the script measures that gap (hold mean less the rising branch interpolated to
the hold's pressure, settled samples only: not the transient of a step; also against all rising
samples, transients included), the gap each model replays (before and after the named terms, and with the
data-driven correction), and the held-out RMS over the hold; a gap over 2 N is *modelled* when the
named terms reproduce it within half of it, else *unexplained*.

The starting model (``diagnose`` re-fits it): the datasheet's inner diameter (10 or 20 mm), an
outer (braid) diameter of 1.3 x that, the bladder the wall between them, the braid angle and dead
band from the rest-length file's blocked forces (paper Sec. 4.3-4.4, ``calibrate.fit_blocked``),
tension-only (a slack McKibben carries no force). Nothing is subtracted from the data: the load
cell's zero offset of a few newtons stays in (README), as it would in a user's recordings.

Rows with a repeated time stamp (the logger's) are dropped and counted; the recordings are then
averaged in pairs (about 260 Hz; the pressure steps every 0.5 s).

Writes bench/results/diagnose_festo.json and docs/figures/diagnose_festo_*.png; prints a table.
Usage: python scripts/festo_diagnose.py [--only dmsp10_cut20cm] [--no-figures]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from efam_mujoco.calibrate import blocked_points, fit_blocked, pool
from efam_mujoco.diagnose import diagnose
from efam_mujoco.diagnose.report import figures, text
from efam_mujoco.files import write_json_atomic
from efam_mujoco.muscle import Muscle
from efam_mujoco.recordings import Recording, drop_report, read_csv
from efam_mujoco.stress import StressLaw

sys.path.insert(0, str(Path(__file__).resolve().parent))
from shared_data import festo_dir  # noqa: E402

DATA = festo_dir()
ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results" / "diagnose_festo.json"
FIGURES = ROOT / "docs" / "figures"
HYSTERESIS_EFFECTS = ("friction", "viscoelasticity", "pressure_lag", "softening")  # direction-dependent terms
#: Samples averaged into one (about 19 ms): the quasi-static test, without the regulator's ringing
#: at each pressure step (~50 Hz), which no quasi-static model (nor these candidates) describes.
AVERAGE = 10
#: Real data hold several effects at once (static non-linearity, load-cell zero, hysteresis...).
MAX_EFFECTS = 4
#: Muscles whose figures go to docs/figures (all muscles are in the JSON).
FIGURE_MUSCLES = ("dmsp10_cut20cm", "dmsp20_cut30cm")


def groups(meta: dict) -> dict[str, list[str]]:
    """Files of one muscle: the DMSP-10 per cut length, the DMSP-20."""
    out: dict[str, list[str]] = {}
    for name in sorted(meta):
        key = name.split("_kink")[0].split("_short")[0]
        out.setdefault(key, []).append(name)
    return out


def averaged(recording: Recording, k: int = 2) -> Recording:
    n = len(recording) // k * k

    def avg(x):
        return x[:n].reshape(-1, k).mean(axis=1)

    return Recording(avg(recording.time_s), avg(recording.length_m), avg(recording.pressure_Pa),
                     avg(recording.force_N), dict(recording.meta))  # fmt: skip


def starting_muscle(key: str, files: list[str], meta: dict, recordings: list[Recording]) -> Muscle:
    inner = 0.020 if key.startswith("dmsp20") else 0.010
    rest = float(meta[files[0]]["rest_length_m"])
    outer = 1.3 * inner
    volume = math.pi * (outer**2 - inner**2) / 4 * rest
    at_rest = [r for f, r in zip(files, recordings) if abs(meta[f]["held_length_m"] - rest) < 1e-6]
    P, F = blocked_points(pool(at_rest), rest)
    blocked = fit_blocked(P, F, outer)
    return Muscle(
        rest_length_m=rest, rest_diameter_m=outer, theta_rest_deg=blocked.theta_rest_deg,
        bladder_volume_m3=volume, deadband_Pa=blocked.deadband_Pa, stress=StressLaw("linear", (2e6, 1.0)),
        tension_only=True, name=f"Festo {key}",
    )  # fmt: skip


def final_hold(
    recording: Recording, tolerance_Pa: float = 5e3, settled_Pa_per_s: float = 30e3
) -> tuple[np.ndarray, np.ndarray]:
    """(final-hold mask, rising-branch mask) of one pressure sweep: the hold is the run at the
    end where the pressure stays within ``tolerance_Pa`` of its final value; the rising branch is
    every SETTLED sample before the peak pressure (the pressure moving slower than
    ``settled_Pa_per_s``: on the plateaus between the regulator's steps, so that a fast step's
    transient, which a pressure lag explains, is not taken for the slow hysteresis)."""
    P = recording.pressure_Pa
    n = len(P)
    end = float(np.median(P[-max(n // 20, 5) :]))
    k = n
    while k > 0 and abs(P[k - 1] - end) < tolerance_Pa:
        k -= 1
    hold = np.zeros(n, dtype=bool)
    hold[k:] = True
    rising = np.zeros(n, dtype=bool)
    rate = np.abs(np.gradient(P, recording.time_s))
    peak = int(np.argmax(P))
    rising[:peak] = rate[:peak] < settled_Pa_per_s
    return hold, rising


def _rising_at(P, tension, rising, p_hold) -> float:
    """Tension of the rising branch at pressure ``p_hold``: the branch's tension against pressure
    (mean per 5 kPa bin, monotone in time), interpolated linearly (the regulator steps through
    low pressures in one jump, so the branch rarely sits at the hold's pressure)."""
    Pr, Tr = P[rising], tension[rising]
    edges = np.arange(Pr.min(), Pr.max() + 5e3, 5e3)
    idx = np.digitize(Pr, edges)
    centres = [float(Pr[idx == i].mean()) for i in np.unique(idx)]
    values = [float(Tr[idx == i].mean()) for i in np.unique(idx)]
    return float(np.interp(p_hold, centres, values))


def slow_hysteresis(d, recordings: list[Recording], files: list[str], meta: dict) -> list[dict]:
    """The slow hysteresis of each rest-length file: tension in the final low-pressure hold after
    venting less the tension on the rising branch at the same pressure, measured and as the
    models replay it (before and after the named terms, and the data-driven correction), with the
    held-out RMS over those holds (each sample predicted by models fitted without its half-cycle)."""
    out = []
    start = 0
    for f, r in zip(files, recordings):
        n = len(r)
        sl = slice(start, start + n)
        start += n
        if abs(meta[f]["held_length_m"] - meta[f]["rest_length_m"]) > 1e-6:
            continue
        hold, rising = final_hold(r)
        _, rising_all = final_hold(r, settled_Pa_per_s=np.inf)
        if hold.sum() < 5 or rising.sum() < 3:
            continue
        P = r.pressure_Pa
        p_hold = float(np.median(P[hold]))

        def gap(push, P=P, hold=hold, rising=rising, p_hold=p_hold):
            tension = -np.asarray(push)
            return float(tension[hold].mean() - _rising_at(P, tension, rising, p_hold))

        def gap_all(push, P=P, hold=hold, rising=rising_all, p_hold=p_hold):
            return gap(push, P, hold, rising, p_hold)

        dd = (
            d.correction.prediction[sl]
            if d.correction is not None and d.correction.prediction is not None
            else 0.0
        )
        rms = lambda x: float(np.sqrt(np.mean(np.square(x))))  # noqa: E731
        measured, after = gap(d.force[sl]), gap(d.predicted_after[sl])
        out.append({
            "status": "below 2 N" if abs(measured) < 2.0 else "modelled" if abs(after - measured) <= 0.5 * abs(measured) else "unexplained",
            "file": f, "hold_kPa": float(np.median(r.pressure_Pa[hold]) / 1e3), "hold_samples": int(hold.sum()),
            "gap_measured_N": gap(d.force[sl]), "gap_model_before_N": gap(d.predicted_before[sl]),
            "gap_model_after_N": gap(d.predicted_after[sl]),
            "gap_with_datadriven_N": gap(d.predicted_after[sl] + dd),
            "gap_vs_all_rising_measured_N": gap_all(d.force[sl]),
            "gap_vs_all_rising_model_before_N": gap_all(d.predicted_before[sl]),
            "gap_vs_all_rising_model_after_N": gap_all(d.predicted_after[sl]),
            "hold_heldout_rms_before_N": rms(d.heldout_residual_before[sl][hold]),
            "hold_heldout_rms_after_N": rms(d.heldout_residual_after[sl][hold]),
        })  # fmt: skip
    return out


def run_group(key: str, files: list[str], meta: dict, make_figures: bool) -> dict:
    raw = [read_csv(DATA / "recordings" / f, on_bad_rows="drop") for f in files]
    for r in raw:
        note = drop_report(r, limit=2)
        if note:
            print(note)
    recordings = [averaged(r, AVERAGE) for r in raw]
    muscle = starting_muscle(key, files, meta, recordings)
    t0 = time.perf_counter()
    d = diagnose(recordings, muscle, max_effects=MAX_EFFECTS)
    seconds = time.perf_counter() - t0
    print(text(d))
    if make_figures:
        for path in figures(d, FIGURES, prefix=f"diagnose_festo_{key}"):
            print(f"figure: {path}")
    names = d.names
    return {
        "muscle": key,
        "files": files,
        "held_lengths_m": [meta[f]["held_length_m"] for f in files],
        "samples": d.n_samples,
        "seconds": seconds,
        **d.rms_summary(),
        "effects": d.to_json()["effects"],
        "hysteresis_N": d.located["hysteresis_N"],
        "direction_above_noise": d.located["factors"]["direction"]["above_noise"],
        "hysteresis_found": bool(any(n in HYSTERESIS_EFFECTS for n in names)),
        "located": d.located["summary"],
        "max_force_N": float(np.max(np.abs(d.force))),
        "slow_hysteresis": slow_hysteresis(d, recordings, files, meta),
        "verdict": d.verdict.to_json() if d.verdict else None,
        "datadriven_correction": d.correction.to_json() if d.correction else None,
        "unexplained": d.unexplained.get("summary", []),
        "structure": d.structure,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", help="diagnose only this muscle (e.g. dmsp10_cut20cm)")
    ap.add_argument("--no-figures", action="store_true")
    args = ap.parse_args(argv)
    if not (DATA / "recordings.json").exists():
        print(f"skipped: {DATA / 'recordings.json'} is absent (real Festo data are not part of the package)")
        return 0
    meta = json.loads((DATA / "recordings.json").read_text())
    rows = []
    for key, files in groups(meta).items():
        if args.only and key != args.only:
            continue
        print(f"==== {key}: {', '.join(files)}")
        rows.append(run_group(key, files, meta, make_figures=not args.no_figures and key in FIGURE_MUSCLES))
    print(f"\n{'muscle':16s} {'named':34s} {'held-out N':>18s} {'gain':>6s} {'noise N':>8s} {'hyst. N':>8s}")
    for r in rows:
        named = " + ".join(e["name"] for e in r["effects"]) or "none"
        gain = 1 - r["heldout_rms_after_N"] / r["heldout_rms_before_N"]
        print(
            f"{r['muscle']:16s} {named:34s} {r['heldout_rms_before_N']:8.2f} -> {r['heldout_rms_after_N']:6.2f} "
            f"{gain:6.1%} {r['noise_N']:8.2f} {r['hysteresis_N']:8.2f}"
        )
    found = sum(r["hysteresis_found"] for r in rows)
    print(f"\nhysteresis found and modelled in {found} of {len(rows)} muscles")
    print(
        "\nslow hysteresis: tension in the final hold after venting less the rising branch at that pressure"
    )
    print(
        f"{'file':28s} {'kPa':>5s} {'measured':>9s} {'before':>7s} {'after':>7s} {'+dd':>7s} {'held-out hold RMS':>20s}"
    )
    for r in rows:
        for h in r["slow_hysteresis"]:
            print(
                f"{h['file']:28s} {h['hold_kPa']:5.0f} {h['gap_measured_N']:9.2f} {h['gap_model_before_N']:7.2f} "
                f"{h['gap_model_after_N']:7.2f} {h['gap_with_datadriven_N']:7.2f} "
                f"{h['hold_heldout_rms_before_N']:8.2f} -> {h['hold_heldout_rms_after_N']:6.2f}  "
                f"{h['status']}  "
                f"({h['gap_vs_all_rising_measured_N']:.2f} / {h['gap_vs_all_rising_model_after_N']:.2f})"
            )
    if not args.only:
        write_json_atomic(RESULTS, {"muscles": rows, "hysteresis_found": found, "of": len(rows)})
        print(f"wrote {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
