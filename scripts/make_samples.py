"""Write the sample recordings in examples/recordings/: small, SYNTHETIC, reproducible.

They exist so that every command in the README and docs runs as written on a fresh clone
(``efam calibrate``, ``efam diagnose``); they are not measurements. Made from the package's own
generators with fixed seeds:

* ``fam1_p15psi.csv`` ... ``fam1_p75psi.csv``: the paper's calibration test (Sec. 3) on FAM1 with
  its Table 4 exponential-decay law: an isobaric stroke per pressure (15-75 psi), from the resting
  length to 198 % and back at 5.1 mm/s, a 2 s blocked hold first, 10 Hz, 0.5 N force noise
  (``efam_mujoco.calibrate.synthesize``, seed 0).
* ``fam1_bench_part1.csv``, ``fam1_bench_part2.csv``: one bench session of a FAM1-like muscle
  (randomly perturbed geometry and law) with a concealed Dahl-type braid friction, split in two
  files at half time: an unpressurised cycle, then 15, 45 and 75 psi, each with slow, fast and slow
  strokes, regulator dynamics and sensor noise, 10 Hz (``efam_mujoco.diagnose.synth.synthesize``,
  seed 3). ``efam diagnose`` names ``friction``.

Usage: python scripts/make_samples.py [--out examples/recordings] [--check]
(--check: regenerate in memory and fail if the committed files differ.)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from efam_mujoco import load_muscle
from efam_mujoco.calibrate import PAPER_PRESSURES_PA, synthesize
from efam_mujoco.diagnose.synth import Protocol
from efam_mujoco.diagnose.synth import synthesize as synthesize_bench
from efam_mujoco.recordings import write_csv
from efam_mujoco.units import PRESSURE

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "examples" / "recordings"
BENCH = Protocol(pressures_kPa=(103.4, 310.3, 517.1), cycles=("slow", "fast", "slow"), repeat_first=False,
                 sample_hz=10.0)  # fmt: skip


def write_samples(out: Path) -> list[Path]:
    """Write every sample recording into ``out``; returns the paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    fam1 = load_muscle("FAM1")
    for pressure, recording in zip(PAPER_PRESSURES_PA, synthesize(fam1, rate_Hz=10.0, seed=0)):
        psi = round(pressure / PRESSURE["psi"])
        paths.append(write_csv(out / f"fam1_p{psi}psi.csv", recording, pressure_unit="psi"))
    recording, truth = synthesize_bench(3, "friction", BENCH, base="FAM1")
    half = int(np.searchsorted(recording.time_s, recording.time_s[-1] / 2))
    for part, piece in enumerate((slice(0, half), slice(half, None)), start=1):
        segment = recording.subset(piece)
        segment.time_s = segment.time_s - segment.time_s[0]
        paths.append(write_csv(out / f"fam1_bench_part{part}.csv", segment, pressure_unit="kPa"))
    return paths


def main(argv=None) -> int:
    """Write the samples, or with ``--check`` compare them with the committed ones."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(OUT), help="output folder (default: examples/recordings)")
    parser.add_argument(
        "--check", action="store_true", help="fail if the committed samples are not reproduced"
    )
    args = parser.parse_args(argv)
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            fresh = write_samples(Path(tmp))
            stale = [p.name for p in fresh if (Path(args.out) / p.name).read_bytes() != p.read_bytes()]
        if stale:
            print(f"make_samples: {', '.join(stale)} differ from a fresh run", file=sys.stderr)
            return 1
        print(f"make_samples: {len(fresh)} samples reproduced exactly")
        return 0
    for path in write_samples(Path(args.out)):
        print(f"wrote {path} ({path.stat().st_size // 1024} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
