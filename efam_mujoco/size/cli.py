"""``efam size --stroke FRACTION --force N --pressure kPa [...]``: size an EFAM or a bundle."""

from __future__ import annotations

import argparse
import math

from ..arm.spec import ARM_BOUNDS, MAX_MUSCLES_PER_SECTION
from ..cli import plain_float, plain_int
from ..files import OutputSet
from ..musclefile import MuscleFileError
from ..stress import LAW_NAMES, StressLawError
from ..units import visible
from . import report
from .catalogue import load_catalogue
from .design import Material
from .request import MAX_STROKE, Request
from .search import size


def _number(flag: str, unit: str, low: float, high: float, low_open: bool = True, hint: str = ""):
    """An argparse type: a finite number in its unit, inside (low, high]; the error names both."""

    def parse(text: str) -> float:
        # a plain ASCII decimal, as every other command's number flags: float() also reads
        # '5_00' and other scripts' digits ('５００'), which no user means as a pressure
        try:
            value = plain_float(text)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(
                f"{flag} takes a plain decimal number in {unit} (like 0.5 or 2e3), got {text!r}"
            ) from None
        below = value <= low if low_open else value < low
        if not math.isfinite(value) or below or value > high:
            bracket = "(" if low_open else "["
            raise argparse.ArgumentTypeError(
                f"{flag} must be in {bracket}{low:g}, {high:g}] {unit}, got {text}{hint}"
            )
        return value

    return parse


def _count(text: str) -> int:
    try:
        value = plain_int(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"--bundle takes a whole number of muscles, got {text!r}") from None
    if value < 3:
        raise argparse.ArgumentTypeError(f"--bundle needs at least 3 muscles in a section, got {value}")
    if value > MAX_MUSCLES_PER_SECTION:
        # the arm builder's own limit; a thousand took minutes to search
        raise argparse.ArgumentTypeError(
            f"--bundle takes at most {MAX_MUSCLES_PER_SECTION} muscles in a section, got {value}"
        )
    return value


def register_cli(subparsers) -> None:
    """``efam size`` (for efam_mujoco.cli.COMMAND_MODULES)."""
    p = subparsers.add_parser(
        "size",
        allow_abbrev=False,
        help="design an EFAM (or a bundle) for a stroke, a force and a pressure budget from catalogue parts",
        description=(
            "Search braided-sleeve and latex-tube sizes as sold (paper Table 2's manufacturing parameters) "
            "for EFAMs that, at the pressure, still push FORCE newtons when extended by STROKE (a fraction "
            "of the resting length). Ranked designs with every named constraint, verified in the MuJoCo "
            "rig; an infeasible request gets the closest point and what to relax. See docs/sizing.md."
        ),
    )
    p.add_argument("--stroke", required=True, metavar="FRACTION",
                   type=_number("--stroke", "(fraction of the resting length)", 0.0, MAX_STROKE,
                                hint=" (0.98 means 98 %)"),
                   help="required extension as a fraction of the resting length, e.g. 0.98 for 98 %% (required)")  # fmt: skip
    p.add_argument("--force", required=True, metavar="N", type=_number("--force", "N", 0.0, 1e5, low_open=False),
                   help="push still delivered at that stroke, N (the whole section's with --bundle; 0: a free "
                   "stroke) (required)")  # fmt: skip
    p.add_argument("--pressure", required=True, metavar="kPa", type=_number("--pressure", "kPa", 0.0, 1000.0),
                   help="pressure budget, gauge kPa (required)")  # fmt: skip
    p.add_argument("--length", metavar="m", type=_number("--length", "m", 0.005, 5.0), default=None,
                   help="resting length, m (default: the shortest the catalogue's aspect-ratio rule allows)")  # fmt: skip
    p.add_argument("--max-diameter", metavar="mm", type=_number("--max-diameter", "mm", 1.0, 1000.0, low_open=False,
                   hint=" (the flag is in mm: a muscle under 1 mm wide is no muscle; 28.7 mm is written 28.7, "
                   "not 0.0287 in metres)"), default=None,
                   help="largest resting diameter, mm (default: no limit)")  # fmt: skip
    p.add_argument("--blocked-force", metavar="N", type=_number("--blocked-force", "N", 0.0, 1e5), default=None,
                   help="also require this push at the resting length, N (default: none)")  # fmt: skip
    p.add_argument("--bundle", metavar="M", type=_count, default=None,
                   help="size the muscles of one section of M in parallel; report its tip force, stroke, bend "
                   "and payload deflection (default: one muscle)")  # fmt: skip
    p.add_argument("--payload", metavar="kg", type=_number("--payload", "kg", 0.0, ARM_BOUNDS["payload_kg"][1], low_open=False),
                   default=0.0, help="tip payload of the bundle, kg (default 0)")  # fmt: skip
    p.add_argument("--unguided", action="store_true", default=False,
                   help="the muscle pushes without a guide tube: Euler buckling limits it (default: guided)")  # fmt: skip
    p.add_argument("--stress-from", metavar="FILE", default="FAM1",
                   help="preset or calibrated muscle file whose stress law and dead band are the material "
                   "(default: FAM1, the paper's)")  # fmt: skip
    p.add_argument("--stress", metavar="LAW", choices=LAW_NAMES, default=None,
                   help=f"law from that file: {', '.join(LAW_NAMES)} (default: the file's default law)")  # fmt: skip
    p.add_argument("--catalogue", metavar="FILE", default=None,
                   help="a catalogue JSON in the built-in layout (default: the built-in catalogue)")  # fmt: skip
    p.add_argument("--top", metavar="K", type=plain_int, default=3,
                   help="designs to propose: listed, verified in MuJoCo, written and drawn (default 3)")  # fmt: skip
    p.add_argument(
        "--json", metavar="FILE", default=None, help="write the full result as JSON (default: none)"
    )
    p.add_argument("--figure", metavar="FILE", default=None,
                   help="write the force-stroke envelope figure (.png, .pdf, .svg, ...) (default: none)")  # fmt: skip
    p.set_defaults(
        run=run,
        file_inputs=("stress_from", "catalogue"),
        file_outputs=("json", "figure"),
        kpa_flags=("pressure",),
    )


def run(args) -> int:
    """Run ``efam size`` with parsed arguments; returns the exit status."""
    if args.payload and args.bundle is None:
        raise ValueError(
            "--payload (kg) applies to a bundle: add --bundle M, or add the payload's weight to --force"
        )
    if args.top < 1:
        raise ValueError(f"--top must be >= 1 (designs proposed), got {args.top}")
    try:
        material = Material.from_muscle(args.stress_from, args.stress)
    except (MuscleFileError, StressLawError) as err:
        raise ValueError(f"--stress-from: {err}") from None
    catalogue = load_catalogue(args.catalogue)
    request = Request(
        stroke=args.stroke,
        force_N=args.force,
        pressure_Pa=args.pressure * 1e3,
        length_m=args.length,
        max_diameter_m=None if args.max_diameter is None else args.max_diameter / 1e3,
        blocked_force_N=args.blocked_force,
        bundle=args.bundle,
        payload_kg=args.payload,
        unguided=args.unguided,
    )
    result = size(request, material, catalogue, verify=args.top)
    print(report.summary(result, top=args.top))
    outputs = OutputSet()  # written together: a figure that fails leaves the --json as it was
    if args.json:
        outputs.json(args.json, result.to_dict(top=args.top))
    if args.figure:
        report.envelope_figure(result, outputs.staging_path(args.figure), top=args.top)
    for path in outputs.commit():
        print(f"wrote {visible(str(path))}")
    return 0 if result.feasible else 1
