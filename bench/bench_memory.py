"""Peak memory and time of ``efam diagnose`` and ``efam calibrate`` on long recordings, and the
memory growth of MuJoCo models the plugin rejects.

Each command runs in its own process (``python -m efam_mujoco.cli ...``) on recordings of 20 k,
200 k and 2 M rows; its peak resident memory is the child's ``ru_maxrss``, its time the wall
clock. The recordings tile a synthetic bench test (``diagnose.synth`` for diagnose, the paper's
protocol from ``calibrate.synth`` for calibrate), so longer files hold more cycles of the same
physics. Goal (issue 13): under 2 GB at 2 M rows, time growing linearly (the reader streams; the
fit sees at most ``--max-samples`` samples, see ``recordings.decimate``), and calibrate treating
the data the same way (isobaric strokes) at every size.

Then 5000 models whose efam.muscle config is rejected are compiled in one process: resident
memory may grow by less than 1 MB.

    python bench/bench_memory.py              # all sizes (about 5 minutes)
    python bench/bench_memory.py --quick      # 20 k and 200 k rows, 1000 rejected models
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from efam_mujoco.files import write_json_atomic  # noqa: E402
from efam_mujoco.progress import progress  # noqa: E402

SIZES = (20_000, 200_000, 2_000_000)
GOAL_PEAK_MB = 2000.0
GOAL_REJECTED_GROWTH_MB = 1.0


def tiled_csv(path: Path, recordings, rows: int) -> Path:
    """A CSV of ``rows`` rows: the recordings one after another, repeated, time running on."""
    t = np.concatenate([r.time_s - r.time_s[0] for r in recordings])
    step = float(np.median(np.diff(recordings[0].time_s)))
    offsets = np.cumsum([0.0] + [float(r.time_s[-1] - r.time_s[0]) + step for r in recordings[:-1]])
    t = np.concatenate([r.time_s - r.time_s[0] + o for r, o in zip(recordings, offsets)])
    span = float(t[-1]) + step
    L = np.concatenate([r.length_m for r in recordings])
    P = np.concatenate([r.pressure_Pa for r in recordings]) / 1e3
    F = np.concatenate([r.force_N for r in recordings])
    reps = -(-rows // len(t))
    index = np.arange(rows) % len(t)
    time_s = t[index] + span * (np.arange(rows) // len(t))
    assert reps >= 1
    data = np.column_stack([time_s, L[index], P[index], F[index]])
    with open(path, "w") as handle:
        handle.write("time_s,length_m,pressure_kPa,force_N\n")
        np.savetxt(handle, data, fmt="%.9g", delimiter=",")
    return path


def run_child(argv: list[str]) -> dict:
    """Run ``efam argv`` in a child process: exit status, wall time, peak resident memory."""
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "efam_mujoco.cli", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=ROOT,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    out, err = proc.stdout.read(), proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - start
    return {
        "exit": os.waitstatus_to_exitcode(status),
        "seconds": round(seconds, 2),
        "peak_MB": round(usage.ru_maxrss / 1024.0, 1),  # Linux: kilobytes
        "stdout": out.decode(errors="replace"),
        "stderr": err.decode(errors="replace")[-400:],
    }


def rejected_configs_growth(count: int) -> dict:
    """Resident-memory growth over ``count`` compiles that the plugin rejects (a child process)."""
    code = f"""
import gc, json
import mujoco
from efam_mujoco.musclefile import load_muscle
from efam_mujoco.plugin import load
from efam_mujoco.rig import RigOptions, rig_xml
load()
xml = rig_xml(load_muscle("FAM1"), RigOptions(mode="stroke"))
bad = [xml.replace('key="rest_length_m" value="', 'key="rest_length_m" value="-'),
       xml.replace('key="law" value="exponential_decay"', 'key="law" value="ogden"'),
       xml.replace('key="deadband_Pa" value="', 'key="deadband_Pa" value="x')]
def rss():
    return int(open("/proc/self/statm").read().split()[1]) * 4096
def compile_all(n):
    refused = 0
    for i in range(n):
        try:
            mujoco.MjModel.from_xml_string(bad[i % 3])
        except ValueError:
            refused += 1
    return refused
compile_all(300)  # warm-up: allocator pools, caches
gc.collect(); before = rss()
refused = compile_all({count})
gc.collect(); after = rss()
print(json.dumps({{"rejected": refused, "growth_MB": (after - before) / 1e6}}))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20 k and 200 k rows, 1000 rejected models")
    parser.add_argument("--out", default=str(ROOT / "bench" / "results" / "memory.json"))
    args = parser.parse_args(argv)

    from efam_mujoco.calibrate.synth import synthesize as calibrate_synth
    from efam_mujoco.diagnose.synth import synthesize as diagnose_synth
    from efam_mujoco.musclefile import load_muscle

    sizes = SIZES[:2] if args.quick else SIZES
    diag_rec, _ = diagnose_synth(3, effect="friction", base="fam1")
    cal_recs = calibrate_synth(load_muscle("FAM1"))
    cases = []
    with tempfile.TemporaryDirectory(prefix="efam-bench-memory.") as folder:
        folder = Path(folder)
        for rows in progress(sizes, "bench_memory sizes"):
            diag_csv = tiled_csv(folder / f"diag_{rows}.csv", [diag_rec], rows)
            cal_csv = tiled_csv(folder / f"cal_{rows}.csv", cal_recs, rows)
            for command, argv in (
                ("diagnose", ["diagnose", str(diag_csv), "--muscle", "FAM1", "--json", str(folder / "d.json")]),
                ("calibrate", ["calibrate", str(cal_csv), "--muscle", "FAM1", "--stress", "linear",
                               "--json", str(folder / "c.json")]),
            ):  # fmt: skip
                result = run_child(argv)
                mode = re.search(r"treated as ([^\n]*)", result["stdout"])
                case = {
                    "command": command,
                    "rows": rows,
                    "exit": result["exit"],
                    "seconds": result["seconds"],
                    "peak_MB": result["peak_MB"],
                    "us_per_row": round(1e6 * result["seconds"] / rows, 2),
                    "calibrate_mode": mode.group(1) if mode else None,
                }
                if result["exit"]:
                    case["stderr"] = result["stderr"]
                cases.append(case)
                print(
                    f"{command:9s} {rows:>9d} rows: exit {case['exit']}, {case['seconds']:7.1f} s, "
                    f"peak {case['peak_MB']:7.1f} MB" + (f", {case['calibrate_mode']}" if mode else "")
                )
            diag_csv.unlink()
            cal_csv.unlink()
    count = 1000 if args.quick else 5000
    rejected = rejected_configs_growth(count)
    print(f"{rejected['rejected']} rejected plugin configs: memory grew {rejected['growth_MB']:.3f} MB")
    biggest = max(sizes)
    peak = max(c["peak_MB"] for c in cases if c["rows"] == biggest)
    modes = {c["calibrate_mode"] for c in cases if c["command"] == "calibrate"}
    summary = {
        "rows": list(sizes),
        "peak_MB_at_largest": peak,
        "goal_peak_MB": GOAL_PEAK_MB,
        "peak_met": peak < GOAL_PEAK_MB and all(c["exit"] == 0 for c in cases),
        "calibrate_same_mode_at_every_size": len(modes) == 1,
        "rejected_configs": rejected,
        "rejected_growth_met": rejected["growth_MB"] < GOAL_REJECTED_GROWTH_MB,
    }
    print(json.dumps(summary, indent=1))
    write_json_atomic(args.out, {"summary": summary, "cases": cases})
    return 0 if summary["peak_met"] and summary["rejected_growth_met"] else 1


if __name__ == "__main__":
    sys.exit(main())
