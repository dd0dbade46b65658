"""The EFAM suite: environment throughput against raw physics, and the controller's success.

1. **Throughput.** For every task, environment steps per second (``env.step`` with random
   actions, resets excluded) against the raw physics of the same compiled model
   (``mujoco.mj_step(model, data, nstep=substeps)`` with the same pressures, no Python per
   substep), divided by the control substeps. Goal: env >= 0.9 x raw / substeps. Interleaved
   repeats, medians, single thread, one process.
   Env and raw are timed in alternating blocks of 10 control steps (the same machine load
   for both), single thread, one process.
2. **Controller.** The model-based controller (inverse statics of the reference plus PI
   feedback) and the random baseline on 50 seeded ``bundle-reach`` and ``arm-reach`` episodes
   (seeds 0..49). Goals: within 1 cm at the end of >= 90 % of bundle episodes, within 2 cm
   at the end of >= 80 % of arm episodes. Also printed for ``reach_payload`` (payload unknown
   to the controller).

3. **Random steps.** Every task, 1000 control steps of uniform random actions (across
   episode ends): no MuJoCo warning, finite observations, rewards in [0, 1] (the unit tests
   run 1000 steps on the bundle tasks, 200 on the slower arm).

4. **Reference** (``--reference-episodes N``, off by default: the continuum takes seconds per
   solve). The controller's feed-forward solved on the suite's statics (the domain's own model)
   against the same solve on the continuum reference, on ``bundle-reach`` seeds 0..N-1: CPU
   time, the feed-forward's rest tip in the domain's model against the target, closed-loop
   final error.

Writes ``bench/results/suite.json`` (``--update`` keeps the sections not run).

    python bench/bench_suite.py [--episodes 50] [--steps 2000] [--skip-throughput] [--skip-control]
                                [--skip-random-steps] [--reference-episodes 0] [--update]
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from efam_mujoco import suite
from efam_mujoco.files import write_json_atomic
from efam_mujoco.progress import progress
from efam_mujoco.suite import controllers

RESULTS = Path(__file__).resolve().parent / "results" / "suite.json"
GOALS = {"bundle": 0.9, "arm": 0.8}  # reach success rate


# CPU time of this thread: on a shared machine, wall time counts the other jobs' time slices
_clock = time.thread_time


def _state(model, data, kind):
    state = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, data, state, kind)
    return state


def throughput(domain: str, task: str, steps: int, block: int = 20, repeats: int = 3) -> dict:
    """Env steps/s and raw physics steps/s in thread CPU time, block by block: every block of
    ``block`` control steps runs ``repeats`` times through the environment and ``repeats`` times
    as raw ``mj_step`` calls, each run from the block's starting state (the same physics work),
    and the fastest run of each counts (as ``timeit``: the other jobs on a shared machine only
    ever add time). Resets are not timed."""
    env = suite.load(domain, task, task_kwargs={"random": 0})
    physics = env.physics
    substeps = int(round(env.control_timestep() / physics.timestep()))
    actions = np.random.RandomState(0).uniform(0.0, 1.0, size=(steps, physics.model.nu))
    pressures = actions * physics.rated_pressures_Pa()
    model = physics.model.ptr
    data = mujoco.MjData(model)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    env.reset()
    env_time = raw_time = 0.0
    env_time_first = raw_time_first = 0.0
    for first in range(0, steps, block):
        state = _state(model, physics.data.ptr, kind)
        step_count = env._step_count  # noqa: SLF001  (dm_control keeps the episode's step count private)
        env_runs, raw_runs = [], []
        for _ in range(repeats):
            mujoco.mj_setState(model, physics.data.ptr, state, kind)
            mujoco.mj_forward(model, physics.data.ptr)
            env._step_count = step_count  # noqa: SLF001
            start = _clock()
            for action in actions[first : first + block]:
                last = env.step(action).last()
            env_runs.append(_clock() - start)
            mujoco.mj_setState(model, data, state, kind)
            mujoco.mj_forward(model, data)
            start = _clock()
            for ctrl in pressures[first : first + block]:
                data.ctrl[:] = ctrl
                mujoco.mj_step(model, data, substeps)
            raw_runs.append(_clock() - start)
        env_time += min(env_runs)
        raw_time += min(raw_runs)
        env_time_first += env_runs[0]
        raw_time_first += raw_runs[0]
        if last:
            env.reset()
    env_rate, raw_rate = steps / env_time, steps * substeps / raw_time
    return {
        "substeps": substeps,
        "control_steps": steps,
        "repeats_per_block": repeats,
        "env_steps_per_s": env_rate,
        "raw_physics_steps_per_s": raw_rate,
        "ratio_env_to_raw_over_substeps": env_rate / (raw_rate / substeps),
        "ratio_first_runs_only": raw_time_first / env_time_first,
    }


def random_steps(domain: str, task: str, steps: int = 1000, seed: int = 0) -> dict:
    """``steps`` control steps of uniform random actions (across episode ends): MuJoCo's warning
    counters, finite observations, rewards in [0, 1]."""
    env = suite.load(domain, task, task_kwargs={"random": seed})
    policy = controllers.RandomPolicy(env, seed)  # the suite's own random baseline
    time_step = env.reset()
    episodes, finite, rewards_ok = 1, True, True
    for _ in range(steps):
        if time_step.last():
            time_step = env.reset()
            episodes += 1
        time_step = env.step(policy(time_step))
        finite &= all(np.all(np.isfinite(v)) for v in time_step.observation.values())
        rewards_ok &= 0.0 <= time_step.reward <= 1.0
    warnings = {
        name: int(env.physics.data.warning.number[int(value)])
        for name, value in mujoco.mjtWarning.__members__.items()
        if name != "mjNWARNING" and env.physics.data.warning.number[int(value)]
    }
    return {
        "steps": steps,
        "episodes": episodes,
        "mujoco_warnings": warnings,
        "finite": bool(finite),
        "rewards_in_0_1": bool(rewards_ok),
    }


def control(domain: str, task: str, episodes: int) -> dict:
    out = {}
    for name in ("model", "random"):
        results = controllers.evaluate(domain, task, name, episodes, seed=0)
        errors = np.array([r.final_error for r in results])
        out[name] = {
            "success_rate": float(np.mean([r.success for r in results])),
            "final_error_m_median": float(np.median(errors)),
            "final_error_m_90th_percentile": float(np.percentile(errors, 90)),
            "final_error_m_worst": float(errors.max()),
            "mean_return": float(np.mean([r.episode_return for r in results])),
        }
    return out


def reference_comparison(episodes: int) -> dict:
    """The controller's feed-forward from the suite's statics (the domain's own MuJoCo model at
    rest) against the same inverse statics on the continuum (Kirchhoff rod) reference, on
    ``bundle-reach`` seeds 0..episodes-1: CPU time and forward solves of the inverse, the
    feed-forward's rest tip in the domain's model against the target, and the closed-loop
    episode's final error."""
    from efam_mujoco.suite import arm_glue

    out = {"episodes": episodes, "seeds": f"0..{episodes - 1}"}
    for name, reference in (("suite_statics", None), ("continuum", _continuum)):
        rows = []
        for seed in progress(range(episodes), f"bundle-reach feed-forward from {name}", total=episodes):
            env = suite.load("bundle", "reach", task_kwargs={"random": seed})
            policy = controllers.InverseStaticsController(env, reference=reference)
            started = _clock()
            policy.reset(env.reset())
            solve_s = _clock() - started
            spec, target = env.task.arm_spec, env.task.target_in_base
            plant_tip, _ = arm_glue.reference_tip(spec, policy.solution.fractions * spec.max_pressure_Pa)
            _, success, error = controllers.run_episode(env, policy)
            rows.append(
                (solve_s, policy.solution.forward_solves, np.linalg.norm(plant_tip - target), error, success)
            )
        solve_s, solves, feedforward, final, success = (np.array(c, dtype=float) for c in zip(*rows))
        out[name] = {
            "inverse_statics_cpu_s_median": float(np.median(solve_s)),
            "inverse_statics_cpu_s_worst": float(solve_s.max()),
            "forward_solves_median": float(np.median(solves)),
            "feedforward_error_in_domain_model_m_median": float(np.median(feedforward)),
            "feedforward_error_in_domain_model_m_worst": float(feedforward.max()),
            "final_error_m_median": float(np.median(final)),
            "final_error_m_worst": float(final.max()),
            "success_rate": float(success.mean()),
        }
    return out


def _continuum(spec, pressures_Pa, payload_kg):
    from efam_mujoco.suite import arm_glue

    return arm_glue.continuum_tip(spec, pressures_Pa, payload_kg)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument(
        "--steps", type=int, default=2000, help="timed control steps per bundle task (arm: 1/5)"
    )
    parser.add_argument("--skip-throughput", action="store_true")
    parser.add_argument("--skip-control", action="store_true")
    parser.add_argument("--skip-random-steps", action="store_true")
    parser.add_argument(
        "--reference-episodes", type=int, default=0,
        help="bundle-reach episodes comparing the feed-forward from the suite's statics and from the continuum (slow: seconds per solve)",
    )  # fmt: skip
    parser.add_argument("--update", action="store_true", help="keep the sections of --out that are not run")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    report = {
        "benchmark": "EFAM dm_control suite: env vs raw physics throughput; controller success",
        "machine": {
            "python": sys.version.split()[0],
            "platform": platform.platform(),
            "mujoco": mujoco.__version__,
        },
        "threads": 1,
    }
    if args.update and args.out.exists():
        import json

        report = {**json.loads(args.out.read_text()), **report}
    ok = True
    if not args.skip_random_steps:
        report["random_steps"] = {}
        for domain, task in progress(suite.ALL_TASKS, "random steps per task"):
            result = random_steps(domain, task)
            report["random_steps"][f"{domain}-{task}"] = result
            clean = not result["mujoco_warnings"] and result["finite"] and result["rewards_in_0_1"]
            ok &= clean
            print(
                f"{domain}-{task:14s} {result['steps']} random steps ({result['episodes']} episodes): "
                f"MuJoCo warnings {result['mujoco_warnings'] or 'none'}, finite {result['finite']}, "
                f"rewards in [0, 1] {result['rewards_in_0_1']}",
                flush=True,
            )
    if not args.skip_throughput:
        report["throughput"] = {}
        for domain, task in progress(suite.ALL_TASKS, "throughput per task"):
            steps = args.steps if domain == "bundle" else args.steps // 5
            result = throughput(domain, task, steps)
            report["throughput"][f"{domain}-{task}"] = result
            ratio = result["ratio_env_to_raw_over_substeps"]
            ok &= ratio >= 0.9
            print(
                f"{domain}-{task:14s} env {result['env_steps_per_s']:8.0f} steps/s, raw physics "
                f"{result['raw_physics_steps_per_s']:8.0f} steps/s / {result['substeps']} substeps = "
                f"{result['raw_physics_steps_per_s'] / result['substeps']:8.0f}: ratio {ratio:.3f} "
                f"(first runs only {result['ratio_first_runs_only']:.3f}) (goal >= 0.9)",
                flush=True,
            )
    if not args.skip_control:
        report["control"] = {"episodes": args.episodes, "seeds": f"0..{args.episodes - 1}"}
        evaluated = (
            ("bundle", "reach"),
            ("arm", "reach"),
            ("bundle", "reach_payload"),
            ("arm", "reach_payload"),
        )
        for domain, task in progress(evaluated, "controller evaluations"):
            result = control(domain, task, args.episodes)
            report["control"][f"{domain}-{task}"] = result
            radius = 0.01 if domain == "bundle" else 0.02
            for name, label in (("model", "inverse statics + PI"), ("random", "random")):
                r = result[name]
                print(
                    f"{domain}-{task:14s} {label:>20s}: within {radius * 100:.0f} cm at the end of "
                    f"{r['success_rate'] * 100:5.1f} % of {args.episodes} episodes; final error median "
                    f"{r['final_error_m_median'] * 1e3:.2f} mm, 90th pct {r['final_error_m_90th_percentile'] * 1e3:.2f} mm, "
                    f"worst {r['final_error_m_worst'] * 1e3:.2f} mm",
                    flush=True,
                )
            if task == "reach":
                ok &= result["model"]["success_rate"] >= GOALS[domain]
    if args.reference_episodes > 0:
        result = report["reference_comparison"] = reference_comparison(args.reference_episodes)
        for name in ("suite_statics", "continuum"):
            r = result[name]
            print(
                f"bundle-reach feed-forward from {name:13s}: inverse statics {r['inverse_statics_cpu_s_median']:.2f} s CPU "
                f"median (worst {r['inverse_statics_cpu_s_worst']:.2f} s, {r['forward_solves_median']:.0f} solves); "
                f"its rest tip in the domain's model {r['feedforward_error_in_domain_model_m_median'] * 1e3:.2f} mm "
                f"from the target (worst {r['feedforward_error_in_domain_model_m_worst'] * 1e3:.2f} mm); closed loop: "
                f"final error median {r['final_error_m_median'] * 1e3:.2f} mm, worst {r['final_error_m_worst'] * 1e3:.2f} mm, "
                f"success {r['success_rate'] * 100:.0f} % of {args.reference_episodes}",
                flush=True,
            )
    write_json_atomic(args.out, report)
    print(f"wrote {args.out}; goals {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
