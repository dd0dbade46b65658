"""The arm's benchmarks: speed (plugin vs built-in affine actuators, segmented vs PCC vs the former
constrained arm), the random-pressure sweep, the D convergence table, the undamped energy run.

    python bench/bench_arm.py speed [--steps 3000] [--repeats 5]
    python bench/bench_arm.py sweep [--sets 200] [--disks D]  # gravity off, 3/4/6 muscles x 1/2/3 sections
    python bench/bench_arm.py convergence              # tip error vs the continuum reference, D = 4..32
    python bench/bench_arm.py energy [--arms 1x3 3x3] [--disks D] [--modes ...] [--duration 10]

Energy: each arm and mode at the builder's own step and integrator, undamped (RK4) for
``--duration`` and with the default damping (implicitfast) for 3 s; measured here: the 1x3 at
the default D and the 3x3 at D = 4 (the 3x3 at D = 16 undamped takes hours on one core).
Speed (steps/s and real-time factor) is measured side by side in one process, interleaved
repeats, medians, single thread; the
former constrained 3x3 arm (60 dof, 51 equality rows) is ``bench/reference/arm_3x3_constrained.xml``
(the shipped model before the physical arm). Each command updates its key of
``bench/results/arm.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
import warnings
from pathlib import Path

import mujoco
import numpy as np

from efam_mujoco import arm, load_muscle, plugin
from efam_mujoco.arm import continuum, timestep
from efam_mujoco.arm import energy as arm_energy
from efam_mujoco.files import write_json_atomic
from efam_mujoco.progress import progress

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "arm.json"
CONSTRAINED = HERE / "reference" / "arm_3x3_constrained.xml"


def pressure_schedule(
    nu: int, timestep: float, steps: int, max_pressure: float, per_muscle: int = 1
) -> np.ndarray:
    """(steps, nu) pressures: 0.5 Hz sinusoids between 20 % and 90 % of the range, each muscle
    phase-shifted (``per_muscle`` consecutive actuators share one muscle's pressure)."""
    t = np.arange(steps)[:, None] * timestep
    muscle = np.arange(nu)[None, :] // per_muscle
    return max_pressure * (0.55 + 0.35 * np.sin(2 * np.pi * 0.5 * t + muscle * (2 * np.pi / 3)))


def run(model: mujoco.MjModel, controls: np.ndarray) -> float:
    data = mujoco.MjData(model)
    start = time.perf_counter()
    for ctrl in controls:
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data)
    elapsed = time.perf_counter() - start
    if not np.all(np.isfinite(data.qpos)):
        raise RuntimeError("simulation diverged")
    return len(controls) / elapsed


def speed(args) -> dict:
    """Steps/s and real-time factor (simulated s per wall s) of the 3x3 arm: segmented and PCC at
    the default D and at D = 4, each at the builder's time step; the built-in affine actuators
    (one per segment) at the same step as the plugin; the former constrained arm at its 1 ms."""
    plugin.load()
    D = arm.DEFAULT_DISKS

    def pair(**kw):
        model = arm.build_model(arm.arm_3x3(**kw))
        with warnings.catch_warnings():  # the plugin arm's step, given explicitly to the affine arm
            warnings.simplefilter("ignore", timestep.TimestepWarning)
            affine = arm.build_model(arm.arm_3x3(timestep_s=model.opt.timestep, **kw), muscles="affine")
        return model, affine

    plugin_D, affine_D = pair(disks=D)
    plugin_4, affine_4 = pair(disks=4)
    variants = {
        f"segmented D={D} plugin": (plugin_D, 1),
        f"segmented D={D} affine": (affine_D, 2 * D),
        "segmented D=4 plugin": (plugin_4, 1),
        "segmented D=4 affine": (affine_4, 8),
        f"pcc D={D} plugin": (arm.build_model(arm.arm_3x3(mode="pcc", disks=D)), 1),
        "pcc D=4 plugin": (arm.build_model(arm.arm_3x3(mode="pcc", disks=4)), 1),
        "constrained (former arm_3x3, D=4)": (mujoco.MjModel.from_xml_path(str(CONSTRAINED)), 1),
    }
    controls = {
        name: pressure_schedule(m.nu, m.opt.timestep, args.steps, arm.MAX_TESTED_PRESSURE_PA, per)
        for name, (m, per) in variants.items()
    }
    for name, (m, _) in variants.items():  # warm up
        run(m, controls[name][:200])
    rates = {name: [] for name in variants}
    for repeat in progress(range(args.repeats), "speed"):
        order = list(variants) if repeat % 2 == 0 else list(variants)[::-1]
        for name in order:
            rates[name].append(run(variants[name][0], controls[name]))
    median = {name: statistics.median(r) for name, r in rates.items()}
    step = {name: float(m.opt.timestep) for name, (m, _) in variants.items()}
    realtime = {name: median[name] * step[name] for name in variants}
    ratio = {
        f"D={D}": median[f"segmented D={D} plugin"] / median[f"segmented D={D} affine"],
        "D=4": median["segmented D=4 plugin"] / median["segmented D=4 affine"],
    }
    old = "constrained (former arm_3x3, D=4)"
    for name, rate in median.items():
        m = variants[name][0]
        print(
            f"{name:36s} nv {m.nv:3d}  neq {m.neq:2d}  dt {step[name] * 1e3:g} ms  {rate:8.0f} steps/s "
            f"({rate / median[old]:.2f} x the constrained arm)  real time x {realtime[name]:.2f} "
            f"({realtime[name] / realtime[old]:.2f} x the constrained arm)"
        )
    for key, value in ratio.items():
        print(f"plugin / built-in affine at {key}: {value:.3f} (goal >= 0.95)")
    return {
        "model": "3x3 FAM1 arm, hanging, gravity on, pressure lag, default damping, each at the builder's "
        "time step (implicitfast); affine at the plugin's step; the constrained arm at its 1 ms",
        "steps_per_run": args.steps,
        "repeats": args.repeats,
        "threads": 1,
        "steps_per_s": median,
        "steps_per_s_all": rates,
        "timestep_s": step,
        "real_time_factor": realtime,
        "nv": {name: int(m.nv) for name, (m, _) in variants.items()},
        "ratio_plugin_over_affine": ratio,
        "ratio_to_constrained": {name: rate / median[old] for name, rate in median.items()},
        "real_time_ratio_to_constrained": {name: rt / realtime[old] for name, rt in realtime.items()},
        "goal_ratio": 0.95,
        "meets_goal": all(v >= 0.95 for v in ratio.values()),
    }


def random_pressures(rng, count, strong):
    if not strong:
        return rng.uniform(0.0, arm.MAX_TESTED_PRESSURE_PA, count)
    p = rng.uniform(0.0, 0.1, count)
    p[rng.choice(count, size=rng.integers(1, count), replace=False)] = rng.uniform(0.85, 1.0)
    return p * arm.MAX_TESTED_PRESSURE_PA


def sweep(args) -> dict:
    """Gravity off, random pressure sets (every second strongly differential) per layout: worst
    tip error vs the continuum reference (CC here), and how far any segment got outside its
    muscle's admissible lengths (no other limit exists)."""
    fam1 = load_muscle("FAM1")
    out = {}
    for muscles in (3, 4, 6):
        for sections in (1, 2, 3):
            rng = np.random.default_rng(100 * muscles + sections)
            spec = arm.ArmSpec(
                sections=(arm.SectionSpec(muscles=(fam1,) * muscles, disks=args.disks),) * sections,
                gravity=False,
                pressure_tau_s=0.0,
            )
            model = arm.build_model(spec)
            names = [n for s in arm.muscle_names(spec) for n in s]
            geometry = arm.SegmentLengths(model, names)  # the segment lengths the plugin uses
            errors, beyond, failed = [], 0, 0
            for case in progress(range(args.sets), f"{muscles} muscles x {sections}"):
                pressures = [random_pressures(rng, muscles, case % 2 == 1) for _ in range(sections)]
                data = mujoco.MjData(model)
                failed += not arm.static_equilibrium(model, data, np.concatenate(pressures))
                reference = continuum.solve_arm(spec.sections, pressures)
                errors.append(
                    np.linalg.norm(arm.tip_in_base(model, data) - reference.tip_position_m)
                    / spec.rest_length_m
                )
                N = 2 * spec.sections[0].disks
                for lengths in N * geometry(data).reshape(len(names), N):
                    beyond += int(np.any((lengths < fam1.min_length_m) | (lengths > fam1.max_length_m)))
            key = f"{muscles}x{sections}"
            out[key] = {
                "sets": args.sets,
                "disks": args.disks,
                "worst_tip_error_pct": 100 * max(errors),
                "median_tip_error_pct": 100 * float(np.median(errors)),
                "muscles_beyond_admissible": beyond,
                "not_converged": failed,
            }
            print(f"{muscles} muscles x {sections} sections, D = {args.disks}: {args.sets} sets, worst tip error {100 * max(errors):.3g} % "
                  f"of rest length (median {100 * np.median(errors):.3g} %), {beyond} muscles beyond admissible, "
                  f"{failed} not converged")  # fmt: skip
    return out


CASES = {
    # label: (orientation, sections, pressures kPa per section, payload kg, gravity)
    "oblique bend 333 deg (517/0/300 kPa), gravity off": ("upright", 1, [517, 0, 300], 0.0, False),
    "bend 185 deg (300/200/100 kPa), gravity off": ("upright", 1, [300, 200, 100], 0.0, False),
    "hanging 2x3, 200/300/300 kPa": ("hanging", 2, [200, 300, 300], 0.0, True),
    "horizontal 1x3, 300/450/450 kPa, 1 kg": ("horizontal", 1, [300, 450, 450], 1.0, True),
    "horizontal 2x3, 300/400/400 kPa, 0.5 kg": ("horizontal", 2, [300, 400, 400], 0.5, True),
    "upright 1x3, 517/480/480 kPa, 0.2 kg": ("upright", 1, [517, 480, 480], 0.2, True),
}


def convergence(args) -> dict:
    """Tip error vs the continuum reference, % of the arm's rest length, for D = 4, 8, 16, 32."""
    out = {}
    for label, (orientation, sections, kpa, payload, gravity) in CASES.items():
        row = {}
        pressures = [np.array(kpa) * 1e3] * sections
        for D in args.disks:
            spec = arm.ArmSpec(
                sections=(arm.paper_section(D),) * sections, orientation=orientation, payload_kg=payload,
                gravity=gravity, pressure_tau_s=0.0,
            )  # fmt: skip
            model = arm.build_model(spec)
            data = mujoco.MjData(model)
            arm.static_equilibrium(model, data, np.concatenate(pressures))
            if D == args.disks[0]:
                reference = continuum.solve_arm_spec(spec, pressures)
            row[D] = 100 * float(
                np.linalg.norm(arm.tip_in_base(model, data) - reference.tip_position_m) / spec.rest_length_m
            )
        out[label] = row
        print(f"{label:48s} " + "  ".join(f"D={D}: {e:.3f} %" for D, e in row.items()))
    return out


ENERGY_ARMS = {  # label: (sections, orientation, D (None: the default))
    "1x3": (1, "horizontal", None),
    "3x3": (3, "hanging", None),
}


def released(sections, orientation, disks, mode, damped):
    """The arm at rest at 400/250/250 kPa per section (found with damping), pressures switched to
    300 kPa: it swings under gravity. Built at the builder's own step and integrator for its
    damping (the undamped arm: RK4). Returns (spec, model, data, the muscles' potential)."""

    def make(scale):
        return arm.ArmSpec(
            sections=(arm.paper_section(disks),) * sections, orientation=orientation, pressure_tau_s=0.0,
            axial_viscosity_N_s=6.8 * scale, bend_viscosity_N_m2_s=0.05 * scale, mode=mode,
        )  # fmt: skip

    rest_model = arm.build_model(make(1.0))
    rest = mujoco.MjData(rest_model)
    arm.static_equilibrium(rest_model, rest, [400e3, 250e3, 250e3] * sections)
    spec = make(1.0 if damped else 0.0)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    data.qpos[:] = rest.qpos
    data.ctrl[:] = 300e3
    mujoco.mj_forward(model, data)
    names = [n for section in arm.muscle_names(spec) for n in section]
    potential = arm_energy.MusclePotential(
        model, names, [load_muscle("FAM1")] * len(names), [300e3] * len(names)
    )

    return spec, model, data, potential


def balance(model, data, potential, duration, every, label):
    """:func:`efam_mujoco.arm.energy.energy_balance` with a progress bar, and its wall time."""
    start = time.perf_counter()
    result = arm_energy.energy_balance(model, data, potential, duration, every, label)
    return result, time.perf_counter() - start


def energy(args) -> dict:
    """Damping 0, fixed pressures, gravity on, released from a bent pose, 10 s at the builder's
    step and integrator: energy drift vs the largest kinetic energy; with the default damping,
    3 s: energy lost vs the dampers' work."""
    out = {}
    for label in args.arms:
        sections, orientation, disks = ENERGY_ARMS[label]
        D = args.disks or disks or arm.DEFAULT_DISKS
        for mode in args.modes:
            key = f"{label} {orientation} D={D} {mode}"
            spec, model, data, potential = released(sections, orientation, D, mode, damped=False)
            choice = timestep.recorded_timestep(model)
            run, wall = balance(model, data, potential, args.duration, 10, key + " undamped")
            kinetic, drift = run.largest_kinetic_J, run.worst_imbalance_J
            row = {
                "undamped_integrator": choice.integrator,
                "undamped_timestep_s": model.opt.timestep,
                "omega_max_rad_s": choice.omega_max_rad_s,
                "omega_max_dt": choice.omega_max_rad_s * model.opt.timestep,
                "duration_s": args.duration,
                "largest_kinetic_J": kinetic,
                "drift_J": drift,
                "drift_pct_of_kinetic": 100 * drift / kinetic,
                "undamped_wall_s": wall,
            }
            print(
                f"{key}: undamped, {choice.integrator} {model.opt.timestep * 1e3:g} ms (omega_max dt "
                f"{row['omega_max_dt']:.2f}), {args.duration:g} s: drift {row['drift_pct_of_kinetic']:.3f} % of "
                f"{kinetic:.3f} J ({wall:.0f} s wall)", flush=True,
            )  # fmt: skip
            spec, model, data, potential = released(sections, orientation, D, mode, damped=True)
            run, _ = balance(model, data, potential, 3.0, 1, key + " damped")
            lost, work = run.lost_J, run.damping_work_J
            row.update({
                "damped_integrator": timestep.recorded_timestep(model).integrator,
                "damped_timestep_s": model.opt.timestep, "damped_lost_J": lost, "damped_work_J": work,
                "damped_lost_over_work_minus_1_pct": 100 * (lost / work - 1),
            })  # fmt: skip
            print(f"{key}: default damping, {row['damped_integrator']} {model.opt.timestep * 1e3:g} ms, 3 s: "
                  f"lost {lost:.5f} J, damping work {work:.5f} J ({row['damped_lost_over_work_minus_1_pct']:+.3f} %)",
                  flush=True)  # fmt: skip
            out[key] = row
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("speed")
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--repeats", type=int, default=5)
    p = sub.add_parser("sweep")
    p.add_argument("--sets", type=int, default=200)
    p.add_argument("--disks", type=int, default=arm.DEFAULT_DISKS)
    p = sub.add_parser("convergence")
    p.add_argument("--disks", type=int, nargs="+", default=[4, 8, 16, 32])
    p = sub.add_parser("energy")
    p.add_argument("--arms", nargs="+", choices=sorted(ENERGY_ARMS), default=list(ENERGY_ARMS))
    p.add_argument("--modes", nargs="+", choices=("segmented", "pcc"), default=["segmented", "pcc"])
    p.add_argument("--disks", type=int, default=None, help="D (default: the arm's default)")
    p.add_argument("--duration", type=float, default=10.0, help="undamped run, simulated s")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    result = {"speed": speed, "sweep": sweep, "convergence": convergence, "energy": energy}[args.command](
        args
    )
    doc = json.loads(args.out.read_text()) if args.out.exists() else {}
    if "benchmark" in doc:  # the former single-benchmark layout
        doc = {}
    if args.command == "energy":  # one key per arm, kept across runs of different arms
        kept = {k: v for k, v in doc.get("energy", {}).items() if k not in ("segmented", "pcc")}  # old layout
        result = {**kept, **result}
    doc[args.command] = result
    doc["environment"] = {
        "mujoco": mujoco.__version__,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    write_json_atomic(args.out, doc)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
