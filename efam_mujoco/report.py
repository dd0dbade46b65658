"""``efam muscle`` and ``efam demo``: a muscle's constants and its analytic vs MuJoCo behaviour."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import rig
from .files import (
    check_replaceable_folder,
    replace_folder,
    safe_name,
    save_figure,
    strict_json,
    write_text_atomic,
)
from .muscle import NEUTRAL_BRAID_ANGLE_DEG, Muscle
from .musclefile import load_muscle
from .stress import LAW_NAMES

PSI_TO_PA = 6894.757293168361
PAPER_PRESSURES_PA = tuple(p * PSI_TO_PA for p in (15, 30, 45, 60, 75))  # 103.4 ... 517.1 kPa


@dataclass(frozen=True)
class PressureRow:
    """One pressure of ``efam muscle``: blocked force (push positive, N) and free extension
    (fraction of the resting length), analytic and MuJoCo."""

    pressure_Pa: float
    blocked_analytic_N: float  # push positive
    blocked_mujoco_N: float
    extension_analytic: float  # fraction of resting length
    extension_mujoco: float


def compare(muscle: Muscle, pressures_Pa=PAPER_PRESSURES_PA) -> list[PressureRow]:
    """Blocked force (Eq. 9) and free extension (root of Eq. 2) beside the MuJoCo rig's, push
    positive. Pressures (Pa) outside the rig's control range are refused: MuJoCo would clamp
    them while the analytic column would not, and the difference would read as a model error."""
    rig.check_control_range(pressures_Pa, rig.RigOptions(), "pressures_Pa")
    return [
        PressureRow(
            pressure_Pa=p,
            blocked_analytic_N=float(muscle.blocked_push(p)),
            blocked_mujoco_N=rig.blocked_push(muscle, p),
            extension_analytic=float(muscle.free_extension(p)),
            extension_mujoco=rig.free_extension(muscle, p),
        )
        for p in pressures_Pa
    ]


def constants_dict(muscle: Muscle) -> dict:
    """A muscle's derived constants (SI, units in the keys), for the table and the JSON."""
    return {
        "name": muscle.name,
        "kind": muscle.kind,
        "stress_law": muscle.stress.name,
        "stress_coefficients": muscle.stress.to_dict(),
        "rest_length_m": muscle.rest_length_m,
        "rest_diameter_m": muscle.rest_diameter_m,
        "theta_rest_deg": muscle.theta_rest_deg,
        "turns": muscle.turns,
        "thread_length_m": muscle.thread_length_m,
        "bladder_volume_m3": muscle.bladder_volume_m3,
        "rest_wall_thickness_m": muscle.rest_wall_thickness_m,
        "deadband_kPa": muscle.deadband_Pa / 1e3,
        "admissible_length_m": [muscle.min_length_m, muscle.max_length_m],
    }


def report_dict(muscle: Muscle, rows: list[PressureRow]) -> dict:
    """``efam muscle --json``: the constants and each pressure's analytic and MuJoCo values."""
    doc = constants_dict(muscle)
    doc["sign"] = (
        "blocked_force_N positive = the muscle pushes its ends apart (blocked_push_N: the same "
        "values under the package's push/tension naming)"
    )
    doc["rows"] = [
        {
            "pressure_kPa": r.pressure_Pa / 1e3,
            "blocked_force_N": {"analytic": r.blocked_analytic_N, "mujoco": r.blocked_mujoco_N},
            "blocked_push_N": {"analytic": r.blocked_analytic_N, "mujoco": r.blocked_mujoco_N},
            "free_extension": {"analytic": r.extension_analytic, "mujoco": r.extension_mujoco},
        }
        for r in rows
    ]
    return doc


def format_report(muscle: Muscle, rows: list[PressureRow]) -> str:
    """The table ``efam muscle`` prints."""
    c = constants_dict(muscle)
    lines = [
        f"{muscle.name or 'muscle'} ({c['kind']}), stress law {c['stress_law']}",
        f"  resting length {c['rest_length_m'] * 100:.3f} cm, resting diameter {c['rest_diameter_m'] * 100:.3f} cm",
        f"  resting braid angle {c['theta_rest_deg']:.3f} deg, turns N {c['turns']:.4f}, "
        f"thread length B {c['thread_length_m'] * 100:.3f} cm",
        f"  bladder volume V_B {c['bladder_volume_m3'] * 1e3:.5f} L, wall at rest "
        f"{c['rest_wall_thickness_m'] * 1e3:.3f} mm, dead band {c['deadband_kPa']:.2f} kPa",
        f"  admissible length {c['admissible_length_m'][0] * 100:.2f} .. {c['admissible_length_m'][1] * 100:.2f} cm",
        "",
        "  pressure   blocked force (push +), N       free extension, % of rest length",
        "      kPa   analytic    MuJoCo   diff %     analytic   MuJoCo   diff %",
    ]
    for r in rows:
        lines.append(
            f"  {r.pressure_Pa / 1e3:7.1f}  {r.blocked_analytic_N:9.2f} {r.blocked_mujoco_N:9.2f}"
            f" {_pct(r.blocked_mujoco_N, r.blocked_analytic_N):8.3f}"
            f"   {100 * r.extension_analytic:9.2f} {100 * r.extension_mujoco:8.2f}"
            f" {_pct(r.extension_mujoco, r.extension_analytic):8.3f}"
        )
    return "\n".join(lines)


def _pct(value: float, reference: float) -> float:
    return 100.0 * (value - reference) / reference if reference else 0.0


def force_stroke_figure(muscle: Muscle, path: Path, pressures_Pa=PAPER_PRESSURES_PA) -> Path:
    """Force-stroke curves at each pressure: analytic lines, MuJoCo rig points (paper Fig. 6)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    stroke_line = np.linspace(0.0, 1.05, 200)
    stroke_points = np.linspace(0.0, 1.05, 15)
    for p, color in zip(pressures_Pa, plt.cm.viridis(np.linspace(0.1, 0.9, len(pressures_Pa)))):
        L = muscle.rest_length_m * (1 + stroke_line)
        ax.plot(100 * stroke_line, muscle.push(p, L), color=color, label=f"{p / 1e3:.1f} kPa")
        sim = rig.stroke_forces(muscle, p, muscle.rest_length_m * (1 + stroke_points))
        ax.plot(100 * stroke_points, sim, "o", color=color, markersize=4)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("length change, % of resting length")
    ax.set_ylabel("axial force, N (push +)")
    ax.set_title(f"{muscle.name}: force-stroke, {muscle.stress.name} law (lines: Eq. 2, dots: MuJoCo rig)")
    ax.legend(title="gauge pressure", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=120)
    finally:
        plt.close(fig)
    return path


# ------------------------------------------------------------------------------------ CLI
def _pressures(args) -> tuple[float, ...]:
    if not args.pressures_kPa:
        return PAPER_PRESSURES_PA
    high = rig.RigOptions().max_pressure_Pa
    for p in args.pressures_kPa:
        if not (np.isfinite(p) and 0 <= p * 1e3 <= high):
            raise ValueError(
                f"--pressures-kPa: {p:.10g} kPa is outside the rig's control range 0 .. {high / 1e3:g} kPa "
                "(MuJoCo would clamp it, the analytic column would not)"
            )
    if len(args.pressures_kPa) > MAX_PRESSURES:
        raise ValueError(f"--pressures-kPa: at most {MAX_PRESSURES} pressures, got {len(args.pressures_kPa)}")
    # a value below 1 kPa is warned of once, in kPa, by the command line (cli._small_kilopascal_flags)
    return tuple(p * 1e3 for p in args.pressures_kPa)


#: ``efam muscle --pressures-kPa`` takes at most this many pressures (each runs the MuJoCo rig).
MAX_PRESSURES = 50


def run_muscle(args) -> int:
    """``efam muscle``: the table on standard output, and as JSON with ``--json``."""
    muscle = load_muscle(args.muscle, args.stress)
    # a pressure flag under 1 kPa is said once, in kPa, by the command line, which then quiets
    # the Pa-level checks of the functions it feeds (cli._small_kilopascal_flags)
    try:
        rows = compare(muscle, _pressures(args))
    except RuntimeError as err:  # the rig could not hold this muscle: name the file it came from
        raise RuntimeError(f"{args.muscle}: {err}") from None
    doc = report_dict(muscle, rows)
    text = strict_json(doc)  # before printing: a non-finite value is an error, not a bad file
    print(format_report(muscle, rows))
    if args.json:
        write_text_atomic(Path(args.json), text)
    return 0


def run_demo(args) -> int:
    """``efam demo``: the table and a force-stroke figure in the ``--out`` folder (replaced as a
    whole: it holds only what the demo writes)."""
    check_replaceable_folder(args.out, "--out", "demo")  # before the work, not after it
    muscle = load_muscle(args.muscle, args.stress)
    if muscle.theta_rest_deg >= NEUTRAL_BRAID_ANGLE_DEG:
        # the figure is the paper's Fig. 6, 0-105 % extension: a contractile muscle only shortens
        # (before: the table printed, then the rig refused 'stroke_forces: lengths_m: ...')
        raise ValueError(
            f"{args.muscle}: the muscle is contractile (braid angle {muscle.theta_rest_deg:.4g} deg, above the "
            f"neutral {NEUTRAL_BRAID_ANGLE_DEG:.2f} deg): efam demo draws an extensile muscle's force over "
            "0-105 % extension; `efam muscle` gives this one's table"
        )
    rows = compare(muscle)
    doc = report_dict(muscle, rows)
    text = strict_json(doc)
    print(format_report(muscle, rows))
    out = Path(args.out)
    figure_name = f"force_stroke_{safe_name(muscle.name.lower(), 'muscle')}.png"
    with replace_folder(out, "--out", "demo") as staging:
        force_stroke_figure(muscle, staging / figure_name)
        (staging / "demo.json").write_text(text)
    print(f"\nfigure: {out / figure_name}\ntable:  {out / 'demo.json'}")
    return 0


def register_cli(sub) -> None:
    """Add ``efam muscle`` and ``efam demo`` to the ``efam`` command line."""
    p = sub.add_parser(
        "muscle",
        help="derived constants; blocked force and free extension, analytic vs MuJoCo",
        description="Derived constants of a muscle, and per pressure the blocked force (Eq. 9) and "
        "free extension (Eq. 2 = 0) from the analytic model beside the MuJoCo rig's.",
    )
    p.add_argument("muscle", help="preset (FAM1, FAM2) or muscle file (JSON)")
    p.add_argument("--stress", choices=LAW_NAMES, help="stress law (default: the file's default law)")
    p.add_argument(
        "--pressures-kPa",
        type=float,
        nargs="+",
        help="gauge pressures in kPa, within the rig's 0 .. 1000 kPa (default: the paper's five)",
    )
    p.add_argument("--json", help="write the table as JSON to this file")
    p.set_defaults(
        run=run_muscle, file_inputs=("muscle",), file_outputs=("json",), file_positionals=("muscle",)
    )

    d = sub.add_parser(
        "demo",
        help="the FAM1 table and a force-stroke figure (analytic lines over MuJoCo points)",
        description="Runs the main job: the analytic vs MuJoCo table for a muscle at the paper's five "
        "pressures and a figure of its force-stroke curves.",
    )
    d.add_argument("--muscle", default="FAM1", help="preset or muscle file (default FAM1)")
    d.add_argument("--stress", choices=LAW_NAMES, help="stress law (default: the file's default law)")
    d.add_argument(
        "--out",
        default="efam_demo",
        help="output folder, replaced as a whole (a new, empty or previous demo folder; default ./efam_demo)",
    )
    d.set_defaults(run=run_demo, file_inputs=("muscle",), file_outputs=("out",))
