"""``efam arm``: build an arm, write its MJCF, or put it at rest under pressures and compare the
MuJoCo tip with the continuum reference."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

import mujoco
import numpy as np

from ..files import OutputSet
from ..musclefile import load_muscle
from ..progress import progress
from ..units import as_floats, visible
from .builder import (
    MODELS_DIR,
    arm_xml,
    bend_in_base,
    build_model,
    static_equilibrium,
    tip_in_base,
    write_models,
)
from .continuum import ContinuumError, solve_arm_spec
from .spec import (
    DEFAULT_DISKS,
    MAX_MUSCLES_PER_SECTION,
    MAX_TESTED_PRESSURE_PA,
    ORIENTATIONS,
    ArmSpec,
    SectionSpec,
)
from .timestep import NUMERIC_NAME, recorded_timestep

#: Tip distance (% of the arm's rest length) within which the MuJoCo arm and the continuum
#: reference agree: the benchmark's worst case over random pressures is well under 1 % (gravity
#: off, docs/arms.md) and loaded arms within their validity agree to about 0.4 %; beyond 5 % the
#: two figures describe different shapes and ``efam arm`` says so.
AGREEMENT_PCT = 5.0
#: A tip moved farther than this share of the rest length by the loads (from the unloaded arm)
#: is a large deflection: past the range the two models are compared in.
LARGE_DEFLECTION = 0.5
#: ``efam arm`` refuses arms with more degrees of freedom than this (4 per spacer disk: two
#: slides and two hinges) unless ``--allow-large``: choosing the time step and finding the rest
#: state need the stiffness matrix (one MuJoCo evaluation per degree of freedom) and dense
#: eigen/least-squares solves (their cost grows as the cube), and MuJoCo's compiler, a single C
#: call that Ctrl-C and SIGTERM cannot interrupt, grows quickly too. 480 (e.g. 3 sections x 24
#: muscles x 40 disks) takes about a minute on one core; 20 x 24 x 40 (3200) took longer than 2
#: minutes in the compiler alone, deaf to SIGTERM.
MAX_DEGREES_OF_FREEDOM = 480


def degrees_of_freedom(arm: ArmSpec) -> int:
    """The arm model's degrees of freedom without building it: per spacer disk two slides and
    two hinges (segmented and PCC alike)."""
    return 4 * sum(section.disks for section in arm.sections)


def equilibrium(arm: ArmSpec, pressures_Pa: Sequence[Sequence[float]], tip_force_N=(0.0, 0.0, 0.0)) -> dict:
    """Tip position at rest under constant pressures, in the base frame: the MuJoCo arm
    (:func:`~efam_mujoco.arm.builder.static_equilibrium`) and the continuum reference with the
    arm's own weight and payload (``tip_force_N``: an extra load on the continuum only).

    A continuum reference that does not converge is reported (``continuum_error``, its tip
    ``None``), never raised; ``agreement`` says whether the two tips agree within
    :data:`AGREEMENT_PCT` and, when not, the likely reasons. A ``tip_force_N`` that is not 3
    finite numbers (x, y, z in N) is refused."""
    # checked before the MuJoCo work: (0, 0) ended in numpy's "could not be broadcast", a NaN in
    # scipy's "y0 must be finite", both from the continuum step after the arm was built and settled
    force = as_floats(tip_force_N)
    if force is None or force.shape != (3,) or not np.all(np.isfinite(force)):
        raise ValueError(
            f"equilibrium: tip_force_N must be 3 finite numbers (x, y, z in N, base frame), got {tip_force_N!r}"
        )
    pressures = [list(p) for p in pressures_Pa]
    steps = ("building the arm, choosing its time step", "MuJoCo rest state", "continuum reference")
    for step in progress(steps, "efam arm", total=len(steps)):
        if step == steps[0]:
            model = build_model(arm)
            data = mujoco.MjData(model)
            choice = recorded_timestep(model)
        elif step == steps[1]:
            settled = static_equilibrium(model, data, [p for section in pressures for p in section])
            simulated = tip_in_base(model, data)
        else:
            try:
                state, error = solve_arm_spec(arm, pressures, tip_force_N=tip_force_N), None
            except ContinuumError as err:
                state, error = None, str(err)
    result = {
        "settled": bool(settled),
        "tip_mujoco_m": simulated.tolist(),
        "bend_mujoco_deg": math.degrees(bend_in_base(model, data)),
        "timestep": {**asdict(choice), "description": choice.describe()},
    }
    if state is None:
        result.update(
            tip_continuum_m=None, tip_statics_m=None, difference_pct_of_rest_length=None,
            section_bend_deg=None, continuum_error=error,
        )  # fmt: skip
        result["agreement"] = {"tolerance_pct": AGREEMENT_PCT, "agree": False,
                               "reasons": [f"the continuum reference did not converge ({error})"]}  # fmt: skip
        return result
    predicted = np.asarray(state.tip_position_m)
    difference = float(100 * np.linalg.norm(simulated - predicted) / arm.rest_length_m)
    result.update(
        tip_continuum_m=predicted.tolist(),
        tip_statics_m=predicted.tolist(),  # the former name of tip_continuum_m
        difference_pct_of_rest_length=difference,
        section_bend_deg=[float(np.degrees(sec.bend_angle_rad)) for sec in state.sections],
    )
    agree = difference <= AGREEMENT_PCT
    reasons = [] if agree else _disagreement_reasons(arm, pressures, state, result)
    result["agreement"] = {"tolerance_pct": AGREEMENT_PCT, "agree": agree, "reasons": reasons}
    return result


def _disagreement_reasons(arm: ArmSpec, pressures, state, result: dict) -> list[str]:
    """Why the MuJoCo arm and the continuum reference likely disagree (most telling first)."""
    reasons = []
    coarse = [(j + 1, s.disks) for j, s in enumerate(arm.sections) if s.disks < DEFAULT_DISKS]
    if coarse:
        # first: with 2 disks a 279 deg curl is out of the MuJoCo arm's reach, and the reference,
        # which 8 disks meet within 0.04 %, was the one blamed
        j, d = coarse[0]
        reasons.append(
            f"the MuJoCo arm is coarse (section {j} has {d} spacer disk(s), the default is {DEFAULT_DISKS}): a "
            "section of few rigid links cannot take a strong curl, and its error grows as the disks fall; "
            "rerun with more --disks"
        )
    curled = [(j + 1, b) for j, b in enumerate(result["section_bend_deg"]) if b > 180.0]
    if curled and result["bend_mujoco_deg"] < max(b for _, b in curled) - 45.0:
        j, b = curled[0]
        reasons.append(
            f"the continuum reference curled past a half turn (section {j} bent {b:.0f} deg, MuJoCo's "
            f"whole arm {result['bend_mujoco_deg']:.0f} deg): under a load this large its shooting can "
            "converge to an unstable, curled-over equilibrium; "
            + (
                "or the coarse MuJoCo arm cannot curl that far"
                if coarse
                else "MuJoCo's arm settled into the stable one"
            )
        )
    for j, (section, sec_state) in enumerate(zip(arm.sections, state.sections)):
        lows = [m.min_length_m for m in section.muscles]
        highs = [m.max_length_m for m in section.muscles]
        lengths = np.asarray(sec_state.muscle_lengths_m)
        if np.any(lengths < np.array(lows) * 1.001) or np.any(lengths > np.array(highs) * 0.999):
            reasons.append(
                f"section {j + 1}'s muscles reach the end of their admissible lengths (lock-out) in the "
                "continuum reference: outside the muscle model's validity range"
            )
            break
    unloaded = solve_arm_spec(replace_loads(arm), pressures).tip_position_m
    moved = float(np.linalg.norm(np.asarray(result["tip_mujoco_m"]) - unloaded) / arm.rest_length_m)
    if moved > LARGE_DEFLECTION:
        reasons.append(
            f"large deflection: the loads move the MuJoCo tip {100 * moved:.0f} % of the rest length from the "
            "unloaded arm (buckling or bending far beyond the small-strain range the two models are compared in)"
        )
    if not result["settled"]:
        reasons.append("the MuJoCo arm's static equilibrium did not converge")
    return reasons or ["unknown: neither a large deflection, lock-out nor an unsettled MuJoCo arm"]


def replace_loads(arm: ArmSpec) -> ArmSpec:
    """``arm`` without gravity or payload (its unloaded, constant-curvature shape)."""
    from dataclasses import replace

    return replace(arm, gravity=False, payload_kg=0.0)


#: Bounds on ``efam arm``'s values (checked by efam_mujoco.cli before the command runs): sizes
#: that would exhaust the machine, and pressures MuJoCo would clamp silently to the actuators'
#: control range (the continuum column would not). ``dest: (low, high, unit)``.
ARGUMENT_BOUNDS = {
    "sections": (1, 20, ""),
    "muscles_per_section": (3, MAX_MUSCLES_PER_SECTION, ""),
    "disks": (1, 40, ""),
    "radius_mm": (1.0, 500.0, "mm"),
    "payload_kg": (0.0, 50.0, "kg"),
    "pressure_lag_s": (0.0, 10.0, "s"),
    "timestep_ms": (1e-4, 100.0, "ms"),
    "pressures_kPa": (0.0, MAX_TESTED_PRESSURE_PA / 1e3, "kPa"),
}


def _outputs(args) -> tuple[str, ...]:
    """The output flags of this invocation (the models folder only with --write-models)."""
    return ("xml", "json", "models_dir") if args.write_models else ("xml", "json")


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--write-models", action="store_true", help="regenerate models/arm_*.xml from the builder"
    )
    parser.add_argument("--models-dir", type=Path, default=MODELS_DIR, help="where --write-models writes")
    parser.add_argument(
        "--muscle", nargs="+", default=["FAM1"],
        help="preset or muscle file per muscle (one value: the same muscle everywhere)",
    )  # fmt: skip
    parser.add_argument("--stress", help="stress law (default: each file's default law)")
    parser.add_argument("--sections", type=int, default=1, help="number of sections (default 1)")
    parser.add_argument("--muscles-per-section", type=int, default=3, help="muscles per section (>= 3)")
    parser.add_argument(
        "--radius-mm", type=float, default=None,
        help="muscle placement radius, mm (default: from the muscles' diameters and count)",
    )  # fmt: skip
    parser.add_argument(
        "--disks", type=int, default=DEFAULT_DISKS, help=f"spacer disks per section (default {DEFAULT_DISKS})"
    )
    parser.add_argument(
        "--orientation",
        choices=sorted(ORIENTATIONS),
        default="upright",
        help="how the base is mounted: upright (arm points up), hanging (down) or horizontal",
    )
    parser.add_argument("--payload-kg", type=float, default=0.0, help="tip payload, kg")
    parser.add_argument("--no-gravity", action="store_true", help="switch gravity off")
    parser.add_argument(
        "--pressure-lag-s", type=float, default=0.05, help="valve/tube time constant, s (0: none)"
    )
    parser.add_argument(
        "--mode", choices=("segmented", "pcc"), default="segmented", help="arm model (default segmented)"
    )
    parser.add_argument(
        "--timestep-ms", type=float, default=None,
        help="physics time step, ms (default: derived from the arm's stiffness, masses and damping)",
    )  # fmt: skip
    parser.add_argument("--xml", help="write the arm's MJCF to this file")
    parser.add_argument(
        "--pressures-kPa", type=float, nargs="+",
        help="one pressure per muscle, base section first: print the tip at rest, MuJoCo vs continuum reference",
    )  # fmt: skip
    parser.add_argument("--json", help="write the equilibrium as JSON to this file")
    parser.add_argument(
        "--allow-large", action="store_true",
        help=f"build arms beyond {MAX_DEGREES_OF_FREEDOM} degrees of freedom (4 per spacer disk) even so: "
        "minutes to hours, and MuJoCo's compiler cannot be interrupted",
    )  # fmt: skip


def arm_from_args(args) -> ArmSpec:
    """The :class:`ArmSpec` the command line describes."""
    count = args.sections * args.muscles_per_section
    if args.sections < 1 or args.muscles_per_section < 3:
        raise ValueError("--sections must be >= 1 and --muscles-per-section >= 3")
    if len(args.muscle) not in (1, count):
        raise ValueError(f"--muscle: give 1 muscle or one per muscle ({count}), got {len(args.muscle)}")
    if args.radius_mm is not None and not args.radius_mm > 0:
        raise ValueError(f"--radius-mm must be positive, got {args.radius_mm}")
    names = args.muscle * count if len(args.muscle) == 1 else args.muscle
    loaded = {name: load_muscle(name, args.stress) for name in set(names)}
    m = args.muscles_per_section
    try:
        sections = tuple(
            SectionSpec(
                muscles=tuple(loaded[n] for n in names[j * m : (j + 1) * m]),
                radius_m=None if args.radius_mm is None else args.radius_mm / 1e3,
                disks=args.disks,
            )
            for j in range(args.sections)
        )
    except ValueError as err:  # the spec's words name its keys; here the flag is the user's
        raise ValueError(
            str(err).replace("raise radius_m or spread angles_deg", "raise --radius-mm")
        ) from None
    return ArmSpec(
        sections=sections,
        orientation=args.orientation,
        pressure_tau_s=args.pressure_lag_s,
        payload_kg=args.payload_kg,
        gravity=not args.no_gravity,
        mode=args.mode,
        name=f"arm_{args.sections}x{m}",
        timestep_s=None if args.timestep_ms is None else args.timestep_ms / 1e3,
    )


def _flags_given(args) -> list[str]:
    """The arm's flags this invocation sets to something else than their defaults."""
    parser = argparse.ArgumentParser(add_help=False)
    _add_arguments(parser)
    flags = {a.dest: a.option_strings[0] for a in parser._actions}
    defaults = vars(parser.parse_args([]))
    return [
        flags[k]
        for k, v in defaults.items()
        if k not in ("write_models", "models_dir") and getattr(args, k) != v
    ]


def _run(args) -> int:
    if args.write_models:
        # the package's fixed models come from the builder's presets: another arm's flags beside
        # them were dropped without a word (the models written were the presets all the same)
        given = _flags_given(args)
        if given:
            raise ValueError(
                f"--write-models regenerates the package's preset models (models/arm_*.xml) and takes no arm "
                f"flags; {', '.join(given)} would be ignored: drop them, or write this arm with --xml FILE"
            )
        if args.models_dir.exists() and not args.models_dir.is_dir():
            raise ValueError(f"--models-dir {args.models_dir}: is a file, not a folder")
        for path in write_models(args.models_dir):
            print(visible(str(path)))
        return 0
    spec = arm_from_args(args)
    dof = degrees_of_freedom(spec)
    if dof > MAX_DEGREES_OF_FREEDOM and not args.allow_large:
        raise ValueError(
            f"--sections {args.sections} x --disks {args.disks}: {dof} degrees of freedom (4 per spacer "
            f"disk), beyond the {MAX_DEGREES_OF_FREEDOM} this command builds in about a minute (the cost grows "
            "as the cube: minutes to hours, in calls Ctrl-C cannot interrupt); use fewer disks (the continuum "
            "reference does not depend on them) or sections, or pass --allow-large"
        )
    # every argument is checked before anything is written: a refused --pressures-kPa had
    # already replaced the user's --xml file
    if args.pressures_kPa:
        count = sum(len(s.muscles) for s in spec.sections)
        pressures = np.asarray(args.pressures_kPa) * 1e3
        if pressures.size != count or not np.all(np.isfinite(pressures)) or np.any(pressures < 0):
            raise ValueError(f"--pressures-kPa: need {count} finite pressures >= 0, got {args.pressures_kPa}")
    outputs = OutputSet()  # written together at the end: a failed equilibrium leaves the --xml as it was
    if args.xml:
        outputs.text(args.xml, arm_xml(spec))
    if args.pressures_kPa:
        sizes = np.cumsum([len(s.muscles) for s in spec.sections])[:-1]
        result = equilibrium(spec, np.split(pressures, sizes))
        # '+ 0.0': a coordinate a hair below zero is shown as 0, not '-0.'
        mujoco_mm = np.round(1e3 * np.array(result["tip_mujoco_m"]), 2) + 0.0
        if result["tip_continuum_m"] is None:
            print(f"tip at rest, base frame (mm): MuJoCo {mujoco_mm}, continuum reference: did not converge")
            _warn(str(result["continuum_error"]))
        else:
            print(
                f"tip at rest, base frame (mm): MuJoCo {mujoco_mm}, "
                f"continuum reference {np.round(1e3 * np.array(result['tip_continuum_m']), 2) + 0.0}; "
                f"difference {result['difference_pct_of_rest_length']:.2f} % of the arm's rest length"
            )
            if not result["agreement"]["agree"]:
                _warn(
                    f"the MuJoCo arm and the continuum reference disagree: their tips are "
                    f"{result['difference_pct_of_rest_length']:.1f} % of the arm's rest length apart (they agree "
                    f"within {AGREEMENT_PCT:g} % in the models' validity range); likely: "
                    + "; ".join(result["agreement"]["reasons"])
                )
        print(result["timestep"]["description"])
        if not result["settled"]:
            _warn("the MuJoCo arm's static equilibrium did not converge")
        if args.json:
            outputs.json(args.json, result)
    for path in outputs.commit():
        shown = visible(str(path))
        print(
            f"wrote {shown} (its time step: custom numeric {NUMERIC_NAME!r})"
            if args.xml and path == Path(args.xml)
            else f"wrote {shown}"
        )
    if not (args.xml or args.pressures_kPa):
        print(
            "efam arm: error: nothing to do: pass --xml FILE, --pressures-kPa ..., or --write-models",
            file=sys.stderr,
        )
        return 2
    return 0


def _warn(message: str) -> None:
    """One warning line on standard error, as every command's: ``efam arm: warning: ...``."""
    print(f"efam arm: warning: {visible(' '.join(message.split()))}", file=sys.stderr)


def register_cli(subparsers) -> None:
    """``efam arm`` (for efam_mujoco.cli.COMMAND_MODULES)."""
    parser = subparsers.add_parser(
        "arm",
        help="build a continuum arm; its tip at rest under pressures, MuJoCo vs continuum reference",
        description=__doc__.split("\n\n")[0],  # the first paragraph: its first line ended mid-sentence
    )
    _add_arguments(parser)
    parser.set_defaults(
        run=_run, file_inputs=("muscle",), file_outputs=_outputs, argument_bounds=ARGUMENT_BOUNDS
    )


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m efam_mujoco.arm ...`` = ``efam arm ...`` (the same checks and error handling)."""
    from ..cli import main as efam_main

    return efam_main(["arm", *(sys.argv[1:] if argv is None else argv)])
