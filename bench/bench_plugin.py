"""Speed of the native efam.muscle plugin, side by side in one process.

A chain of N bodies on slide joints, one spatial-tendon muscle per link, in three variants of
the same model:

* ``plugin``   the efam.muscle plugin (FAM1, its default stress law), one plugin instance per
               muscle (the config inside each actuator element);
* ``plugin_shared`` the same, all actuators sharing one ``<instance>`` (identical muscles): MuJoCo
               visits every plugin instance in several stages of a step, so fewer instances cost less;
* ``affine``   MuJoCo's built-in ``general`` actuators with affine gain and bias on the same
               tendons (the muscle linearised at its resting length): the speed limit;
* ``callback`` ``general`` actuators whose force a Python ``mjcb_act_bias`` callback computes
               with the same muscle model (a scalar ``math`` port of Eq. 2: the fastest Python).

Single-thread steps per second are measured in thread CPU time with the repeats of the variants
interleaved (medians), then ``mujoco.rollout`` of the plugin models with 2 threads vs 1 in wall
time (and the affine model beside them, which shows what the machine allows at that moment: on a
2-core machine other jobs take the second core, and no model can speed up). Ratios are printed and written to
bench/results/plugin.json.

Goals (issue 2): plugin/affine >= 0.95, rollout 2-thread/1-thread >= 1.7.

    python bench/bench_plugin.py [--links 12] [--repeats 15] [--steps 2000]
"""

from __future__ import annotations

import os

# before numpy loads: idle OpenBLAS threads spin on the second core, which the rollout needs
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import math
import platform
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

import efam_mujoco  # noqa: F401  (registers efam.muscle)
from efam_mujoco import Muscle, load_muscle
from efam_mujoco.files import write_json_atomic
from efam_mujoco.plugin import instance_xml, plugin_config
from efam_mujoco.progress import progress

RESULTS = Path(__file__).resolve().parent / "results" / "plugin.json"
TIMESTEP = 0.001
PRESSURE_Pa = 2.5e5  # mean command; each muscle gets a different phase of a slow sine


# ---------------------------------------------------------------------------------- models
def chain_xml(muscle: Muscle, links: int, actuator: str, extension: str = "") -> str:
    """N plates stacked along z, each on a slide joint in its parent; muscle i spans link i."""
    L0 = muscle.rest_length_m
    bodies, closes, tendons, actuators = [], [], [], []
    for i in range(links):
        parent_site = "base" if i == 0 else f"top{i - 1}"
        bodies.append(
            f'<body name="plate{i}" pos="0 0 {L0!r}">'
            f'<joint name="j{i}" type="slide" axis="0 0 1" damping="5"/>'
            f'<geom type="cylinder" size="0.02 0.002" mass="0.2"/><site name="top{i}"/>'
        )
        closes.append("</body>")
        tendons.append(f'<spatial name="t{i}"><site site="{parent_site}"/><site site="top{i}"/></spatial>')
        actuators.append(actuator.format(i=i))
    return f"""<mujoco model="efam_chain_{links}">
  <option timestep="{TIMESTEP}" gravity="0 0 0"/>
  <extension><plugin plugin="efam.muscle">{extension}</plugin></extension>
  <worldbody><site name="base"/>{"".join(bodies)}{"".join(closes)}</worldbody>
  <tendon>{"".join(tendons)}</tendon>
  <actuator>{"".join(actuators)}</actuator>
</mujoco>"""


def plugin_actuator(muscle: Muscle) -> str:
    config = "".join(f'<config key="{k}" value="{v}"/>' for k, v in plugin_config(muscle).items())
    return '<plugin name="m{i}" plugin="efam.muscle" tendon="t{i}">' + config + "</plugin>"


def affine_actuator(muscle: Muscle) -> str:
    """force = gain ctrl + bias, gain and bias linear in length: Eq. 2 linearised at rest."""
    L0, dL, P = muscle.rest_length_m, 1e-5, PRESSURE_Pa
    gain = (muscle.push(P, L0) - muscle.push(0.0, L0)) / P
    gain_slope = ((muscle.push(P, L0 + dL) - muscle.push(0.0, L0 + dL)) / P - gain) / dL
    stiffness = (muscle.push(0.0, L0 + dL) - muscle.push(0.0, L0 - dL)) / (2 * dL)
    bias0 = muscle.push(0.0, L0) - stiffness * L0
    return (
        '<general name="m{i}" tendon="t{i}" gaintype="affine" biastype="affine" '
        f'gainprm="{gain - gain_slope * L0!r} {gain_slope!r} 0" biasprm="{bias0!r} {stiffness!r} 0"/>'
    )


SHARED_ACTUATOR = '<plugin name="m{i}" instance="muscle" tendon="t{i}"/>'
CALLBACK_ACTUATOR = '<general name="m{i}" tendon="t{i}" gainprm="0" biastype="user"/>'


class ScalarMuscle:
    """Eq. 2 for one (pressure, length), with ``math`` instead of numpy: what a Python callback
    can do at best. Exponential-decay law only (FAM1's default)."""

    def __init__(self, muscle: Muscle):
        if muscle.stress.name != "exponential_decay":
            raise ValueError("the callback benchmark implements the exponential_decay law only")
        self.m = muscle
        self.c = muscle.stress.coefficients
        self.rest_mid = muscle.rest_outer_radius_m - muscle.rest_wall_thickness_m / 2

    def push(self, pressure: float, length: float) -> float:
        m, c = self.m, self.c
        if not (math.isfinite(pressure) and math.isfinite(length)):
            return 0.0
        P = max(pressure, 0.0)
        L = min(max(length, m.min_length_m), m.max_length_m)
        N, B, V = m.turns, m.thread_length_m, m.bladder_volume_m3
        r_out = math.sqrt(max(B**2 - L * L, 0.0)) / (2 * math.pi * N)
        t = r_out - math.sqrt(max(r_out * r_out - V / (math.pi * L), 0.0))
        eps_z = L / m.rest_length_m - 1.0
        eps_c = (r_out - t / 2) / self.rest_mid - 1.0
        sigma_z = (c[0] + c[1] * P) * eps_z + c[2] * (1.0 - math.exp(-c[3] * eps_z))
        sigma_c = (c[0] + c[1] * P) * eps_c + c[2] * (1.0 - math.exp(-c[3] * eps_c))
        gauge = max(P - m.deadband_Pa, 0.0)
        force = (
            gauge / (4 * math.pi * N * N) * (3 * L * L - B * B)
            + sigma_z * V / L
            - sigma_c * t * L * L / (2 * math.pi * r_out * N * N)
        )
        force += m.lock_stiffness_N_per_m * (length - L)
        return -force


# ----------------------------------------------------------------------------- measurement
def commands(model: mujoco.MjModel, steps: int) -> np.ndarray:
    """Slow sine pressures, a different phase per muscle (steps x nu)."""
    t = np.arange(steps)[:, None] * TIMESTEP
    phase = np.arange(model.nu)[None, :]
    return PRESSURE_Pa * (1.0 + 0.6 * np.sin(2 * math.pi * 2.0 * t + phase))


def steps_per_second(model, data, controls: np.ndarray, chunk: int = 100) -> float:
    """Step the model through ``controls``, ``chunk`` steps per Python call.

    Timed in this thread's CPU time: on a machine shared with other jobs, wall time also counts
    the time slices the scheduler gave to them, which is noise here."""
    mujoco.mj_resetData(model, data)
    start = time.thread_time()
    for k in range(0, len(controls), chunk):
        data.ctrl[:] = controls[k]
        mujoco.mj_step(model, data, nstep=chunk)
    elapsed = time.thread_time() - start
    if not np.all(np.isfinite(data.qpos)):
        raise RuntimeError(f"{model.names[:20]!r}: the simulation diverged")
    return len(controls) / elapsed


def single_thread(models: dict, steps: int, repeats: int) -> dict[str, float]:
    datas = {name: mujoco.MjData(model) for name, model in models.items()}
    controls = commands(next(iter(models.values())), steps)
    rates: dict[str, list[float]] = {name: [] for name in models}
    for name, model in models.items():  # warm-up
        steps_per_second(model, datas[name], controls[: steps // 4])
    for r in progress(range(repeats), "single-thread repeats", total=repeats):
        order = list(models) if r % 2 == 0 else list(reversed(models))  # interleave, alternate order
        for name in order:
            rates[name].append(steps_per_second(models[name], datas[name], controls))
    return {name: statistics.median(values) for name, values in rates.items()}


def rollout_rate(model, threads: int, nbatch: int, nstep: int, repeats: int) -> list[float]:
    datas = [mujoco.MjData(model) for _ in range(threads)]
    state_size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    initial = np.zeros((nbatch, state_size))
    for i in range(nbatch):
        mujoco.mj_getState(model, datas[0], initial[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    control = np.broadcast_to(commands(model, nstep), (nbatch, nstep, model.nu)).copy()
    state = np.empty((nbatch, nstep, state_size))
    sensordata = np.empty((nbatch, nstep, model.nsensordata))
    rates = []
    with rollout.Rollout(nthread=threads) as runner:
        for _ in range(repeats):
            start = time.perf_counter()
            runner.rollout(model, datas, initial, control, state=state, sensordata=sensordata)
            rates.append(nbatch * nstep / (time.perf_counter() - start))
    if not np.all(np.isfinite(state)):
        raise RuntimeError("rollout diverged")
    return rates


def threaded(models: dict, nbatch: int, nstep: int, repeats: int) -> dict[str, dict[str, float]]:
    rates: dict[tuple[str, int], list[float]] = {}
    for name in models:
        rollout_rate(models[name], 2, nbatch, nstep, 1)  # warm-up
    for _ in progress(range(repeats), "rollout repeats", total=repeats):
        for name in models:
            for threads in (1, 2):
                rates.setdefault((name, threads), []).extend(
                    rollout_rate(models[name], threads, nbatch, nstep, 1)
                )
    return {
        name: {
            f"{threads}_thread_steps_per_s": statistics.median(rates[(name, threads)]) for threads in (1, 2)
        }
        for name in models
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--links", type=int, default=12, help="muscles in the chain (default 12)")
    parser.add_argument("--steps", type=int, default=2000, help="steps per single-thread repeat")
    parser.add_argument("--repeats", type=int, default=15, help="interleaved repeats (medians)")
    parser.add_argument("--rollouts", type=int, default=32, help="rollouts per mujoco.rollout call")
    parser.add_argument("--rollout-steps", type=int, default=1000, help="steps per rollout")
    parser.add_argument("--rollout-repeats", type=int, default=7, help="interleaved rollout repeats")
    parser.add_argument("--out", type=Path, default=RESULTS, help="JSON results file")
    args = parser.parse_args(argv)

    load_before = os.getloadavg()[0]
    muscle = load_muscle("FAM1")
    scalar = ScalarMuscle(muscle)
    for length in (0.1, muscle.rest_length_m, 0.3):  # the callback computes the same model
        assert math.isclose(scalar.push(3e5, length), muscle.push(3e5, length), rel_tol=1e-12)
    models = {
        "plugin": mujoco.MjModel.from_xml_string(chain_xml(muscle, args.links, plugin_actuator(muscle))),
        "plugin_shared": mujoco.MjModel.from_xml_string(
            chain_xml(muscle, args.links, SHARED_ACTUATOR, instance_xml("muscle", muscle))
        ),
        "affine": mujoco.MjModel.from_xml_string(chain_xml(muscle, args.links, affine_actuator(muscle))),
        "callback": mujoco.MjModel.from_xml_string(chain_xml(muscle, args.links, CALLBACK_ACTUATOR)),
    }

    def bias(m, d, i):
        return scalar.push(d.ctrl[i], d.actuator_length[i])

    mujoco.set_mjcb_act_bias(bias)
    try:
        rates = single_thread(models, args.steps, args.repeats)
    finally:
        mujoco.set_mjcb_act_bias(None)

    rollouts = threaded(
        {name: models[name] for name in ("plugin", "plugin_shared", "affine")},
        args.rollouts,
        args.rollout_steps,
        args.rollout_repeats,
    )

    def speedup(name):
        r = rollouts[name]
        return r["2_thread_steps_per_s"] / r["1_thread_steps_per_s"]

    ratios = {
        "plugin_over_affine": rates["plugin"] / rates["affine"],
        "plugin_shared_over_affine": rates["plugin_shared"] / rates["affine"],
        "rollout_2_over_1_thread_plugin": speedup("plugin"),
        "rollout_2_over_1_thread_plugin_shared": speedup("plugin_shared"),
        "rollout_2_over_1_thread_affine": speedup("affine"),
        "python_callback_over_affine": rates["callback"] / rates["affine"],
    }
    # The goal applies to the model as efam_mujoco's builders write it (rig, arm: one instance
    # per distinct muscle, its actuators evaluated as a vectorised batch). One instance per
    # actuator is measured beside it: MuJoCo itself spends ~30 ns visiting each instance per step.
    goals = {
        "plugin_shared_over_affine": 0.95,
        "rollout_2_over_1_thread_plugin_shared": 1.7,
    }
    doc = {
        "benchmark": "bench/bench_plugin.py",
        "model": f"chain of {args.links} slide-joint links, one spatial-tendon FAM1 muscle each "
        f"({muscle.stress.name}), timestep {TIMESTEP} s",
        "machine": {
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
            "mujoco": mujoco.__version__,
            "load_average_1min_before": load_before,
            "load_average_1min_after": os.getloadavg()[0],
        },
        "settings": vars(args) | {"out": args.out.name},  # no machine path in the results
        "single_thread_steps_per_s": rates,
        "rollout": rollouts,
        "ratios": ratios,
        "goals": goals,
        "goals_met": {key: ratios[key] >= goal for key, goal in goals.items()},
    }
    write_json_atomic(args.out, doc)

    print("plugin_shared: one plugin instance for the identical muscles (as the efam builders write it)")
    print("plugin:        one plugin instance per actuator (inline <config> on each actuator)")
    print(f"single thread, {args.links} muscles (median of {args.repeats} interleaved repeats):")
    for name, rate in rates.items():
        print(f"  {name:13s} {rate:12,.0f} steps/s")
    print(f"mujoco.rollout, {args.rollouts} rollouts x {args.rollout_steps} steps:")
    for name, r in rollouts.items():
        print(
            f"  {name:13s} 1 thread {r['1_thread_steps_per_s']:12,.0f}   "
            f"2 threads {r['2_thread_steps_per_s']:12,.0f} steps/s"
        )
    print("ratios:")
    for key, value in ratios.items():
        goal = f"  (goal >= {goals[key]})" if key in goals else ""
        print(f"  {key:41s} {value:6.3f}{goal}")
    if load_before > 0.5:
        print(
            f"note: the machine was busy (1-min load average {load_before:.2f} before the run); the "
            "rollout speed-up needs an idle second core, see the affine row for what it allowed"
        )
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
