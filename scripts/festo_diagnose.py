"""Diagnose real Festo DMSP recordings: what the force-balance model leaves out, on real hardware.

Data: ../shared/data/real/festo_dmsp beside the checkout, or $EFAM_SHARED_DIR (see its README; not part of the package, not shipped).
Skips cleanly (exit 0, one line) when that folder is absent.

Each file holds one contractile McKibben muscle at one fixed length while the pressure steps up to
~620 kPa and back down (isometric; the rate of the test is the pressure rate). Every cut length of
the DMSP-10, and the DMSP-20, is its own muscle, diagnosed on its own four files (held at rest
length and three shorter lengths). Held out: whole files, i.e. one held length at a time.

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
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", help="diagnose only this muscle (e.g. dmsp10_cut20cm)")
    ap.add_argument("--no-figures", action="store_true")
    args = ap.parse_args(argv)
    if not (DATA / "recordings.json").exists():
        print(f"skipped: {DATA} is absent (real Festo data are not part of the package)")
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
    if not args.only:
        write_json_atomic(RESULTS, {"muscles": rows, "hysteresis_found": found, "of": len(rows)})
        print(f"wrote {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
