"""Steps per second of the 3x3 EFAM arm: plugin muscles vs MuJoCo's built-in affine actuators.

Both models are the same arm from the same builder (``arm.arm_3x3()``: hanging, gravity on,
pressure lag, the shipped time step); only the actuators differ (``muscles="affine"``: the muscle
model linearised, MuJoCo's speed limit for a tendon actuator). Both follow the same pressure
schedule (slow sinusoids, phase-shifted per muscle). Measured side by side in one process,
interleaved repeats, medians; single thread. Writes ``bench/results/arm.json``.

    python bench/bench_arm.py [--steps 4000] [--repeats 9]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from efam_mujoco import arm
from efam_mujoco.files import write_json_atomic

RESULTS = Path(__file__).resolve().parent / "results" / "arm.json"


def pressure_schedule(model: mujoco.MjModel, steps: int, max_pressure: float) -> np.ndarray:
    """(steps, nu) pressures: 0.5 Hz sinusoids between 20 % and 90 % of the range, each muscle
    phase-shifted so the arm extends and bends."""
    t = np.arange(steps)[:, None] * model.opt.timestep
    phase = np.arange(model.nu)[None, :] * (2 * np.pi / 3)
    return max_pressure * (0.55 + 0.35 * np.sin(2 * np.pi * 0.5 * t + phase))


def run(model: mujoco.MjModel, controls: np.ndarray) -> tuple[float, float]:
    """Steps per second over the schedule, and mean solver iterations (a check that both arms
    did comparable work)."""
    data = mujoco.MjData(model)
    iterations = 0
    start = time.perf_counter()
    for ctrl in controls:
        data.ctrl[:] = ctrl
        mujoco.mj_step(model, data)
        iterations += data.solver_niter[0]
    elapsed = time.perf_counter() - start
    if not np.all(np.isfinite(data.qpos)):
        raise RuntimeError("simulation diverged")
    return len(controls) / elapsed, iterations / len(controls)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000, help="steps per timed run")
    parser.add_argument("--repeats", type=int, default=9, help="interleaved repeats per variant")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)

    spec = arm.arm_3x3()
    models = {name: arm.build_model(spec, muscles=name) for name in ("plugin", "affine")}
    controls = pressure_schedule(models["plugin"], args.steps, spec.max_pressure_Pa)
    for model in models.values():  # warm up caches and the plugin
        run(model, controls[:500])

    rates = {name: [] for name in models}
    iterations = {name: [] for name in models}
    for repeat in range(args.repeats):
        order = list(models) if repeat % 2 == 0 else list(models)[::-1]  # alternate who goes first
        for name in order:
            rate, iters = run(models[name], controls)
            rates[name].append(rate)
            iterations[name].append(iters)

    median = {name: statistics.median(r) for name, r in rates.items()}
    ratio = median["plugin"] / median["affine"]
    model = models["plugin"]
    result = {
        "benchmark": "3x3 EFAM arm, plugin muscles vs built-in affine actuators",
        "model": "arm_3x3 (hanging, gravity on, pressure lag)",
        "nq": int(model.nq),
        "nv": int(model.nv),
        "nu": int(model.nu),
        "neq": int(model.neq),
        "timestep_s": float(model.opt.timestep),
        "steps_per_run": args.steps,
        "repeats": args.repeats,
        "threads": 1,
        "steps_per_s": {"plugin": median["plugin"], "affine": median["affine"]},
        "steps_per_s_all": rates,
        "mean_solver_iterations": {k: statistics.mean(v) for k, v in iterations.items()},
        "ratio_plugin_over_affine": ratio,
        "goal_ratio": 0.95,
        "meets_goal": ratio >= 0.95,
        "mujoco": mujoco.__version__,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    write_json_atomic(args.out, result)
    print(
        f"3x3 arm ({model.nv} dof, {model.nu} muscles): plugin {median['plugin']:.0f} steps/s, "
        f"affine {median['affine']:.0f} steps/s, ratio {ratio:.3f} (goal >= 0.95)"
    )
    print(f"solver iterations/step: plugin {result['mean_solver_iterations']['plugin']:.2f}, "
          f"affine {result['mean_solver_iterations']['affine']:.2f}")  # fmt: skip
    print(f"wrote {args.out}")
    return 0 if ratio >= 0.95 else 1


if __name__ == "__main__":
    sys.exit(main())
