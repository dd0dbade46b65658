"""Sizing bench: one sizing run over the whole catalogue, timed on ONE core, for a spread of
requests (feasible and infeasible; an infeasible one includes the closest-point and relaxation
analysis, which re-runs the search), and a broad check that the proposed designs do what was
asked in the MuJoCo rig.

Random requests (seeded): stroke 0.1-1.5, force 0-400 N, pressure 100-690 kPa, with or without a
length, a diameter limit, a blocked force. For each feasible result every design among the best
three is run in the rig (force at the stroke, stroke under the force) and must meet the request
within 2 %.

Prints a summary and writes bench/results/size.json.
Usage: python bench/bench_size.py [--requests 30] [--seed 1]
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

from efam_mujoco import rig  # noqa: E402
from efam_mujoco.files import write_json_atomic  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402
from efam_mujoco.size import Material, Request, load_catalogue, size  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "size.json"
GOAL_S = 10.0
PSI = 6894.757293168361


def random_request(rng) -> Request:
    return Request(
        stroke=float(rng.uniform(0.1, 1.5)),
        force_N=float(rng.choice([0.0, rng.uniform(1, 400)])),
        pressure_Pa=float(rng.uniform(100e3, 690e3)),
        length_m=float(rng.uniform(0.05, 0.4)) if rng.random() < 0.6 else None,
        max_diameter_m=float(rng.uniform(0.01, 0.05)) if rng.random() < 0.3 else None,
        blocked_force_N=float(rng.uniform(20, 600)) if rng.random() < 0.25 else None,
        unguided=bool(rng.random() < 0.1),
    )


def in_rig(design, request) -> tuple[bool, float, float]:
    m, P, S, F = design.muscle, request.pressure_Pa, request.stroke, request.muscle_force_N
    L = m.rest_length_m
    force = float(rig.stroke_forces(m, P, [L * (1 + S)])[0])
    stroke = (rig.equilibrium_length(m, P, load_N=F) if F > 0 else rig.equilibrium_length(m, P)) / L - 1
    ok = (force >= F * 0.98 if F > 0 else True) and stroke >= S * 0.98
    return ok, force, stroke


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=30, help="random requests (default 30)")
    parser.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    args = parser.parse_args()
    pinned = pin_one_core()
    catalogue, material = load_catalogue(), Material.from_muscle("FAM1")
    rng = np.random.default_rng(args.seed)
    fixed = [
        (
            "FAM1 measured",
            Request(stroke=0.98, force_N=0.0, pressure_Pa=75 * PSI, length_m=0.17018, blocked_force_N=280.0),
        ),
        ("40 N at 50 %", Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, length_m=0.15)),
        ("infeasible force", Request(stroke=1.0, force_N=300.0, pressure_Pa=300e3, length_m=0.2)),
        ("infeasible diameter", Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, max_diameter_m=0.015)),
        ("infeasible strain", Request(stroke=3.0, force_N=10.0, pressure_Pa=400e3)),
    ]
    cases = fixed + [(f"random {i}", random_request(rng)) for i in range(args.requests)]
    rows, checked, failed = [], 0, []
    for name, request in progress(cases, "sizing requests"):
        t0 = time.perf_counter()
        result = size(request, material, catalogue, verify=0)
        seconds = time.perf_counter() - t0
        row = {"case": name, "seconds": seconds, "feasible": result.feasible, "designs": len(result.designs),
               "candidates": result.candidates, "relax": [x.message for x in result.relax]}  # fmt: skip
        for design in result.designs[:3]:
            ok, force, stroke = in_rig(design, request)
            checked += 1
            if not ok:
                failed.append(
                    {"case": name, "tubing": design.tubing.name, "force_N": force, "stroke": stroke}
                )
        rows.append(row)
        print(f"{name:<20} {seconds:6.2f} s  feasible={result.feasible!s:<5} designs={len(result.designs):>3}"
              + ("" if result.feasible else f"  relax: {'; '.join(row['relax']) or 'none'}"))  # fmt: skip
    times = np.array([r["seconds"] for r in rows])
    feasible_times = np.array([r["seconds"] for r in rows if r["feasible"]])
    summary = {
        "goal_s": GOAL_S,
        "max_s": float(times.max()),
        "median_s": float(np.median(times)),
        "max_feasible_s": float(feasible_times.max()) if feasible_times.size else None,
        "catalogue": {"tubings": len(catalogue.tubings), "sleeves": len(catalogue.sleeves)},
        "requests": len(rows),
        "feasible_requests": int(sum(r["feasible"] for r in rows)),
        "designs_checked_in_mujoco": checked,
        "designs_failing_in_mujoco": failed,
        "pinned": pinned,
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
        "python": platform.python_version(),
        "rows": rows,
    }
    print(
        f"\nwhole-catalogue sizing, one core: median {summary['median_s']:.2f} s, max {summary['max_s']:.2f} s "
        f"(goal < {GOAL_S:g} s); {summary['feasible_requests']}/{len(rows)} feasible; "
        f"{checked} designs run in MuJoCo, {len(failed)} short of the request by more than 2 %"
    )
    write_json_atomic(RESULTS, summary)
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
