"""``efam calibrate FILES... --muscle PRESET_OR_FILE [--stress LAW|all] [--out FILE] [--json FILE]``."""

from __future__ import annotations

import os
import sys
from dataclasses import replace
from pathlib import Path

from ..files import OutputError, OutputSet, check_outputs
from ..musclefile import FORMAT as MUSCLE_FORMAT
from ..musclefile import check_tension_only, muscle_from_document, read_document
from ..recordings import add_recording_arguments, read_for_fit
from ..stress import LAW_NAMES
from ..units import visible
from . import report
from .baseline import paper_baseline
from .core import calibrate
from .fit import OBJECTIVES

#: A placeholder law for a muscle file that has geometry but no stress law yet.
_PLACEHOLDER_LAW = {"E1_Pa": 1.0e6, "E2": 0.0}
FIGURE_SUFFIXES = ("_blocked.png", "_strokes.png", "_stress.png")


def load_uncalibrated(source: str):
    """A preset or muscle file as the starting geometry. The stress law and the dead band are
    what calibration estimates, so a file may leave them out (a placeholder is used)."""
    doc, label = read_document(source)
    doc = dict(doc)
    if not any(key == "deadband" or key.startswith("deadband_") for key in doc):
        doc["deadband_kPa"] = 0.0
    if "stress" not in doc:  # absent is allowed; present, it is read strictly
        doc["stress"] = {"default": "linear", "laws": {"linear": dict(_PLACEHOLDER_LAW)}}
    stress = doc["stress"]
    laws = stress.get("laws") if isinstance(stress, dict) else None
    law = None
    if isinstance(laws, dict) and laws:
        # calibration estimates the law anew: any of the file's laws serves as the start (a file of
        # several laws need not name one here)
        law = "linear" if "linear" in laws else stress.get("default") or next(iter(laws))
    return muscle_from_document(doc, label, law)


def register_cli(subparsers) -> None:
    """Add ``efam calibrate`` to the ``efam`` command line."""
    p = subparsers.add_parser(
        "calibrate",
        help="identify a muscle's dead band, braid angle and stress laws from bench recordings",
        description=(
            "Calibrate the force-balance model on recordings (CSV: time_s, length_m or displacement_mm, "
            "pressure_kPa/_Pa/_psi, force_N or tension_N). Estimates the dead band and resting braid "
            "angle from blocked forces (paper Sec. 4.3-4.4), then each stress law; prints the paper's "
            "Table 3 and Table 4 forms and held-out errors; writes a calibrated muscle file. Recordings "
            "are checked for physical plausibility first (see --allow)."
        ),
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="recording CSV files (only ever read)")
    p.add_argument("--muscle", required=True, help="preset (FAM1, FAM2) or muscle file: the geometry")
    p.add_argument("--stress", default="all", choices=(*LAW_NAMES, "all"), help="law to fit, or all")
    p.add_argument("--out", help="write the calibrated muscle file here (all laws, best as default)")
    p.add_argument("--json", help="write the JSON summary here")
    p.add_argument("--figures", metavar="PREFIX", help="write PREFIX_blocked/_strokes/_stress.png")
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
    add_recording_arguments(p)
    p.set_defaults(
        run=run,
        file_inputs=("files", "muscle"),
        file_outputs=("out", "json"),
        document_outputs={"out": MUSCLE_FORMAT},  # a JSON document: checked as one (cli._formatted_flags)
    )


def figure_paths(prefix) -> list[Path]:
    """The figures ``--figures PREFIX`` writes."""
    return [Path(f"{prefix}{suffix}") for suffix in FIGURE_SUFFIXES]


def run(args) -> int:
    """``efam calibrate``: read, check, fit, then write every output together."""
    if args.out is not None and Path(args.out).is_dir():  # a muscle file, refused before the fit
        raise OutputError(
            f"--out {args.out}: is a folder, not a file; give a file name (e.g. {Path(args.out) / 'muscle.json'})"
        )
    if args.figures is not None and not str(args.figures).strip():  # '' wrote no figure, silently
        raise OutputError("--figures: an empty file name (give the figures' path prefix, e.g. figs/fam1)")
    if args.figures:
        # a prefix, not a folder: '--figures figs/' wrote 'figs/_blocked.png', '--figures .' the
        # hidden '._blocked.png'
        if str(args.figures).endswith(("/", os.sep)) or Path(args.figures).is_dir():
            raise OutputError(
                f"--figures {args.figures}: is a folder; give a prefix the figure names are appended to "
                f"(e.g. {Path(args.figures) / 'fam1'} writes {Path(args.figures) / ('fam1' + FIGURE_SUFFIXES[0])})"
            )
        check_outputs(
            {"--figures": figure_paths(args.figures)}, {"FILE": args.files, "--muscle": [args.muscle]}
        )
        check_outputs({"--figures": figure_paths(args.figures), "--out": args.out, "--json": args.json}, {})
    muscle = load_uncalibrated(args.muscle)
    if args.tension_only:
        muscle = replace(muscle, tension_only=True)
        check_tension_only(muscle, f"--tension-only with --muscle {args.muscle}")
    recordings = read_for_fit(args, muscle, warn=lambda line: print(line, file=sys.stderr))
    laws = LAW_NAMES if args.stress == "all" else (args.stress,)
    try:
        cal = calibrate(
            recordings, muscle, laws, estimate_theta=not args.keep_theta, fit_deadband=args.fit_deadband,
            objective=args.objective, heldout=not args.no_heldout,
            allow="all",  # read_for_fit ran the checks and said what --allow let through
        )  # fmt: skip
    except ValueError as err:  # a fit that cannot be made from these data: say which data
        raise ValueError(f"{', '.join(str(f) for f in args.files)}: {err}") from None
    samples = cal.problem.samples
    mode = (
        f"isobaric strokes at {len(samples.levels_Pa)} pressure levels"
        if samples.isobaric
        else "pressure ramps / mixed data (no isobaric levels found)"
    )
    print(f"data: {len(samples)} samples, treated as {mode}")
    print(report.summary(cal))
    print("\nTable 3 form: Eq. 14 relative error (%) per comparison length")
    print(report.table3(cal.fits))
    print("\nTable 4 form: coefficients and errors")
    print(report.table4(cal))
    if args.baseline and cal.problem.points is None:
        print(
            "efam calibrate: warning: --baseline skipped: the paper's procedure needs isobaric strokes",
            file=sys.stderr,
        )
    if args.baseline and cal.problem.points is not None:
        base = paper_baseline(cal.fits[cal.best_law].muscle, cal.problem, list(cal.fits))
        print("\nthe paper's procedure (Nelder-Mead on Eq. 14) vs this calibration")
        print(report.baseline_table(cal.fits, base))
    outputs = OutputSet()
    try:
        if args.out:
            from ..musclefile import muscle_document

            outputs.json(args.out, _muscle_file_doc(cal, muscle_document))
        if args.json:
            outputs.json(args.json, cal.to_json())
        if args.figures:
            staged = [outputs.staging_path(path) for path in figure_paths(args.figures)]
            report.figure_blocked(cal, staged[0])
            report.figure_strokes(cal, staged[1])
            report.figure_stress(cal, staged[2])
        written = outputs.commit()
    finally:
        outputs.discard()
    for path in written:
        print(f"wrote {visible(str(path))}")
    return 0


def _muscle_file_doc(cal, muscle_document) -> dict:
    """The document ``Calibration.save_muscle`` writes, built in memory (written with the rest)."""
    import json
    import tempfile

    with tempfile.TemporaryDirectory(prefix="efam-muscle.") as folder:
        path = cal.save_muscle(Path(folder) / "muscle.json")
        return json.loads(path.read_text())
