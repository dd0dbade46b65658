"""``efam calibrate FILES... --muscle PRESET_OR_FILE [--stress LAW|all] [--out FILE] [--json FILE]``."""

from __future__ import annotations

from ..files import write_json_atomic
from ..musclefile import muscle_from_document, read_document
from ..recordings import read_recordings
from ..stress import LAW_NAMES
from . import report
from .baseline import paper_baseline
from .core import calibrate
from .fit import OBJECTIVES

#: A placeholder law for a muscle file that has geometry but no stress law yet.
_PLACEHOLDER_LAW = {"E1_Pa": 1.0e6, "E2": 0.0}


def load_uncalibrated(source: str):
    """A preset or muscle file as the starting geometry. The stress law and the dead band are
    what calibration estimates, so a file may leave them out (a placeholder is used)."""
    doc, label = read_document(source)
    doc = dict(doc)
    doc.setdefault("deadband_kPa", 0.0)
    laws = doc.get("stress", {}).get("laws", {}) if isinstance(doc.get("stress"), dict) else {}
    if not laws:
        doc["stress"] = {"default": "linear", "laws": {"linear": dict(_PLACEHOLDER_LAW)}}
    law = "linear" if "linear" in doc["stress"]["laws"] else None
    return muscle_from_document(doc, label, law)


def register_cli(subparsers) -> None:
    """Add the ``calibrate`` subcommand to the ``efam`` parser."""
    p = subparsers.add_parser(
        "calibrate",
        help="identify a muscle's dead band, braid angle and stress laws from bench recordings",
        description=(
            "Calibrate the force-balance model on recordings (CSV: time_s, length_m or displacement_mm, "
            "pressure_kPa/_Pa/_psi, force_N or tension_N). Estimates the dead band and resting braid "
            "angle from blocked forces (paper Sec. 4.3-4.4), then each stress law; prints the paper's "
            "Table 3 and Table 4 forms and held-out errors; writes a calibrated muscle file."
        ),
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="recording CSV files")
    p.add_argument("--muscle", required=True, help="preset (FAM1, FAM2) or muscle file: the geometry")
    p.add_argument("--stress", default="all", help=f"law to fit: {', '.join(LAW_NAMES)} or all (default)")
    p.add_argument("--out", help="write the calibrated muscle file here (all laws, best as default)")
    p.add_argument("--json", help="write the JSON summary here")
    p.add_argument("--figures", metavar="PREFIX", help="write PREFIX_blocked/_strokes/_stress.png")
    p.add_argument("--on-bad-rows", choices=("error", "drop"), default="error",
                   help="bad CSV rows: stop with an error (default) or drop them and report which")  # fmt: skip
    p.add_argument("--objective", choices=OBJECTIVES, default=None,
                   help="eq14: the paper's Eq. 14 error (default for isobaric strokes); lsq: least "
                   "squares in N")  # fmt: skip
    p.add_argument("--keep-theta", action="store_true",
                   help="keep the muscle file's braid angle instead of estimating it from blocked forces")  # fmt: skip
    p.add_argument("--fit-deadband", action="store_true",
                   help="refit the dead band with each law (default: the Sec. 4.3 blocked-force estimate)")  # fmt: skip
    p.add_argument("--tension-only", action="store_true", help="a muscle that cannot push (contractile)")
    p.add_argument("--no-heldout", action="store_true", help="skip the leave-one-pressure-out errors")
    p.add_argument("--baseline", action="store_true",
                   help="also run the paper's Nelder-Mead procedure and compare (Eq. 14 and time)")  # fmt: skip
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``efam calibrate`` with parsed arguments; returns the exit code."""
    muscle = load_uncalibrated(args.muscle)
    if args.tension_only:
        from dataclasses import replace

        muscle = replace(muscle, tension_only=True)
    recordings = read_recordings(args.files, rest_length_m=muscle.rest_length_m, on_bad_rows=args.on_bad_rows)
    laws = LAW_NAMES if args.stress == "all" else (args.stress,)
    cal = calibrate(
        recordings, muscle, laws, estimate_theta=not args.keep_theta, fit_deadband=args.fit_deadband,
        objective=args.objective, heldout=not args.no_heldout,
    )  # fmt: skip
    print(report.summary(cal))
    print("\nTable 3 form: Eq. 14 relative error (%) per comparison length")
    print(report.table3(cal.fits))
    print("\nTable 4 form: coefficients and errors")
    print(report.table4(cal))
    if args.baseline and cal.problem.points is not None:
        base = paper_baseline(cal.fits[cal.best_law].muscle, cal.problem, list(cal.fits))
        print("\nthe paper's procedure (Nelder-Mead on Eq. 14) vs this calibration")
        print(report.baseline_table(cal.fits, base))
    if args.out:
        print(f"\nwrote muscle file {cal.save_muscle(args.out)}")
    if args.json:
        write_json_atomic(args.json, cal.to_json())
        print(f"wrote {args.json}")
    if args.figures:
        for path in report.write_figures(cal, args.figures):
            print(f"wrote {path}")
    return 0
