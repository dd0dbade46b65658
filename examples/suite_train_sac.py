"""Train an off-the-shelf RL agent (Stable-Baselines3 SAC, default hyperparameters) on
``bundle-reach`` through the Gymnasium adapter, and plot its learning curve beside the
model-based controller and the random baseline. Optional: needs ``pip install -e ".[rl]"``
(gymnasium, stable-baselines3 and its PyTorch); not part of CI.

    python examples/suite_train_sac.py [--steps 100000] [--max-wall-s 3600] [--seed 0]
    python examples/suite_train_sac.py --plot-only      # redraw the figure from the CSV log

Every ``--eval-every`` environment steps the current policy (deterministic) runs
``--eval-episodes`` seeded evaluation episodes (seeds 1000, 1001, ...: targets and starts
the agent never trained on) and the point is appended to a CSV log (``--run-dir``, default
``out/suite_sac/``) next to a checkpoint of the agent, and the figure is redrawn: a run stopped
early (``--max-wall-s``, or killed) still leaves its curve. ``--resume`` continues from the
checkpoint. The controller and random baselines are run once on the same evaluation seeds.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FIGURES = ROOT / "docs" / "figures"
FIELDS = ("steps", "wall_s", "mean_return", "std_return", "success_rate", "median_final_error_m")


def evaluate(model, env, seeds) -> dict:
    """Mean/std return, success rate and median final tip error of ``model`` (deterministic)
    over one episode per seed."""
    returns, successes, errors = [], [], []
    for seed in seeds:
        observation, _ = env.reset(seed=int(seed))
        total, done, info = 0.0, False, {}
        while not done:
            action, _ = model.predict(observation, deterministic=True)
            observation, reward, terminated, truncated, info = env.step(action)
            total += reward
            done = terminated or truncated
        returns.append(total)
        successes.append(info["success"])
        errors.append(env.env.physics.tip_to_target_distance())
    return {
        "mean_return": float(np.mean(returns)),
        "std_return": float(np.std(returns)),
        "success_rate": float(np.mean(successes)),
        "median_final_error_m": float(np.median(errors)),
    }


def baselines(seeds) -> dict:
    """The model-based controller's and random actions' mean return and success rate on the
    evaluation seeds (the same targets and starts the agent is evaluated on)."""
    from efam_mujoco import suite
    from efam_mujoco.suite import controllers

    out = {}
    for name in ("model", "random"):
        returns, successes, errors = [], [], []
        for seed in seeds:
            env = suite.load("bundle", "reach", task_kwargs={"random": int(seed)})
            policy = (
                controllers.InverseStaticsController(env)
                if name == "model"
                else controllers.RandomPolicy(env, int(seed))
            )
            total, success, error = controllers.run_episode(env, policy)
            returns.append(total)
            successes.append(success)
            errors.append(error)
        out[name] = {
            "mean_return": float(np.mean(returns)),
            "success_rate": float(np.mean(successes)),
            "median_final_error_m": float(np.median(errors)),
        }
    return out


def read_log(path: Path) -> list[dict]:
    """The evaluation points of a CSV log (empty when there is none)."""
    if not path.exists():
        return []
    with path.open(newline="") as handle:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(handle)]


def append_log(path: Path, row: dict) -> None:
    """Append one evaluation point to the CSV log (header on a new file)."""
    new = not path.exists()
    with path.open("a", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=FIELDS)
        if new:
            writer.writeheader()
        writer.writerow({k: row[k] for k in FIELDS})


def plot(curve: list[dict], reference: dict, out: Path, title: str) -> None:
    """Return and success rate against environment steps, the baselines as horizontal lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from efam_mujoco.files import save_figure

    steps = np.array([p["steps"] for p in curve]) / 1000
    returns = np.array([p["mean_return"] for p in curve])
    spread = np.array([p["std_return"] for p in curve])
    success = np.array([p["success_rate"] for p in curve]) * 100
    error_mm = np.array([p["median_final_error_m"] for p in curve]) * 1000
    fig, (ax_r, ax_s, ax_e) = plt.subplots(1, 3, figsize=(12.5, 3.5))
    ax_r.fill_between(steps, returns - spread, returns + spread, alpha=0.2, color="C0", lw=0)
    ax_r.plot(steps, returns, "o-", ms=3, color="C0", label="SAC (mean, +-1 std)")
    ax_s.plot(steps, success, "o-", ms=3, color="C0", label="SAC")
    ax_e.plot(steps, error_mm, "o-", ms=3, color="C0", label="SAC")
    for name, style, label in (("model", "--", "inverse statics + PI"), ("random", ":", "random actions")):
        ax_r.axhline(reference[name]["mean_return"], ls=style, color="k", label=label)
        ax_s.axhline(reference[name]["success_rate"] * 100, ls=style, color="k", label=label)
        if "median_final_error_m" in reference[name]:
            ax_e.axhline(reference[name]["median_final_error_m"] * 1000, ls=style, color="k", label=label)
    ax_e.axhline(10.0, color="C3", lw=0.8, label="success radius")
    ax_r.set(ylabel="episode return (max 100)", title=title)
    ax_s.set(
        ylabel="success: tip within 1 cm at the end, %",
        ylim=(-3, 103),
        title="deterministic policy, seeded evaluation episodes",
    )
    ax_e.set(ylabel="median final tip error, mm", yscale="log")
    ax_r.legend(fontsize=8, loc="center right")
    ax_e.legend(fontsize=8, loc="upper right")
    for ax in (ax_r, ax_s, ax_e):
        ax.set_xlabel("environment steps (thousands)")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, out, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="training environment steps")
    parser.add_argument(
        "--max-wall-s", type=float, default=float("inf"), help="stop after this much training time"
    )
    parser.add_argument("--eval-every", type=int, default=5_000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--hidden", type=int, nargs="+", default=[128, 128],
        help="hidden layer widths of the actor and critics (SB3's default is 256 256: twice the CPU time per update)",
    )  # fmt: skip
    parser.add_argument("--run-dir", type=Path, default=ROOT / "out" / "suite_sac")
    parser.add_argument("--out", type=Path, default=FIGURES / "suite_learning_curve.png")
    parser.add_argument("--resume", action="store_true", help="continue from the run directory's checkpoint")
    parser.add_argument("--plot-only", action="store_true", help="redraw the figure from the run's CSV log")
    args = parser.parse_args(argv)
    if args.steps <= 0 or args.eval_every <= 0 or args.eval_episodes <= 0:
        parser.error("--steps, --eval-every and --eval-episodes must be positive")
    log, checkpoint = args.run_dir / "curve.csv", args.run_dir / "sac_bundle_reach.zip"
    meta_path = args.run_dir / "run.json"
    eval_seeds = range(1000, 1000 + args.eval_episodes)
    title = f"bundle-reach, SAC seed {args.seed}"

    if args.plot_only:
        curve = read_log(log)
        if not curve or not meta_path.exists():
            print(f"no log in {args.run_dir}: train first")
            return 2
        plot(curve, json.loads(meta_path.read_text())["baselines"], args.out, title)
        print(f"wrote {args.out}")
        return 0
    try:
        import torch
        from stable_baselines3 import SAC
    except ImportError:
        print('needs stable-baselines3 and PyTorch: pip install -e ".[rl]"')
        return 2
    torch.set_num_threads(1)  # a small MLP: threads only contend (and the machine is shared)
    os.environ.setdefault("OMP_NUM_THREADS", "1")

    from efam_mujoco.progress import progress
    from efam_mujoco.suite.gym import SuiteEnv

    args.run_dir.mkdir(parents=True, exist_ok=True)
    train_env, eval_env = SuiteEnv("bundle", "reach"), SuiteEnv("bundle", "reach")
    if args.resume and checkpoint.exists():
        model = SAC.load(checkpoint, env=train_env)
        curve = read_log(log)
        meta = json.loads(meta_path.read_text())
    else:
        for stale in (log, checkpoint):
            stale.unlink(missing_ok=True)
        train_env.reset(seed=args.seed)
        policy_kwargs = {"net_arch": list(args.hidden)}
        model = SAC("MlpPolicy", train_env, seed=args.seed, verbose=0, policy_kwargs=policy_kwargs)
        curve = []
        started = time.perf_counter()
        meta = {
            "seed": args.seed, "sac": {"policy_kwargs": policy_kwargs, "other": "stable-baselines3 defaults"},
            "eval_seeds": list(eval_seeds), "baselines": baselines(eval_seeds),
        }  # fmt: skip
        meta["baseline_wall_s"] = time.perf_counter() - started
        meta_path.write_text(json.dumps(meta, indent=1))
        print(f"baselines on the evaluation seeds: {meta['baselines']}", flush=True)
    done = int(curve[-1]["steps"]) if curve else 0
    wall = curve[-1]["wall_s"] if curve else 0.0
    chunks = range(done, args.steps, args.eval_every)
    for _ in progress(chunks, "SAC bundle-reach", total=len(chunks)):
        chunk = min(args.eval_every, args.steps - done)
        started = time.perf_counter()
        model.learn(total_timesteps=chunk, reset_num_timesteps=False)
        wall += time.perf_counter() - started  # training time only (evaluation not counted)
        done += chunk
        point = {"steps": done, "wall_s": wall, **evaluate(model, eval_env, eval_seeds)}
        curve.append(point)
        append_log(log, point)
        model.save(checkpoint)
        plot(curve, meta["baselines"], args.out, title)
        print(
            f"{done:7d} steps ({wall / 60:5.1f} min): return {point['mean_return']:6.1f}, "
            f"success {point['success_rate'] * 100:5.1f} %, median error "
            f"{point['median_final_error_m'] * 1000:6.1f} mm",
            flush=True,
        )
        if wall >= args.max_wall_s:
            print(f"stopping: {wall:.0f} s of training >= --max-wall-s {args.max_wall_s:.0f}")
            break
    print(f"wrote {args.out}; log {log}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
