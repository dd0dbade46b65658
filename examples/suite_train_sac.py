"""Train an off-the-shelf RL agent (Stable-Baselines3 SAC) on ``bundle-reach`` through the
Gymnasium adapter, and plot its learning curve beside the model-based controller and the random
baseline. Optional: needs ``pip install -e ".[rl]"`` (gymnasium, stable-baselines3 and its
PyTorch); not part of CI.

    python examples/suite_train_sac.py [--steps 100000] [--out docs/figures/suite_learning_curve.png]

Every ``--eval-every`` environment steps the current policy (deterministic) runs 10 seeded
evaluation episodes (seeds 1000..1009); the figure shows their mean return and success rate.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"
EVAL_SEEDS = range(1000, 1010)


def evaluate(model, env) -> tuple[float, float]:
    """Mean return and success rate of ``model`` over the evaluation seeds."""
    returns, successes = [], []
    for seed in EVAL_SEEDS:
        observation, _ = env.reset(seed=seed)
        total, done, info = 0.0, False, {}
        while not done:
            action, _ = model.predict(observation, deterministic=True)
            observation, reward, terminated, truncated, info = env.step(action)
            total += reward
            done = terminated or truncated
        returns.append(total)
        successes.append(info["success"])
    return float(np.mean(returns)), float(np.mean(successes))


def baselines() -> dict:
    """Mean return and success of the controller and of random actions on the same seeds."""
    from efam_mujoco import suite
    from efam_mujoco.suite import controllers

    out = {}
    for name in ("model", "random"):
        returns, successes = [], []
        for seed in EVAL_SEEDS:
            env = suite.load("bundle", "reach", task_kwargs={"random": seed})
            policy = (
                controllers.InverseStaticsController(env)
                if name == "model"
                else controllers.RandomPolicy(env, seed)
            )
            total, success, _ = controllers.run_episode(env, policy)
            returns.append(total)
            successes.append(success)
        out[name] = (float(np.mean(returns)), float(np.mean(successes)))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="training environment steps")
    parser.add_argument("--eval-every", type=int, default=5_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=FIGURES / "suite_learning_curve.png")
    args = parser.parse_args(argv)
    try:
        from stable_baselines3 import SAC
    except ImportError:
        print('needs stable-baselines3: pip install -e ".[rl]"')
        return 2
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from efam_mujoco.suite.gym import SuiteEnv

    train_env, eval_env = SuiteEnv("bundle", "reach"), SuiteEnv("bundle", "reach")
    train_env.reset(seed=args.seed)
    model = SAC("MlpPolicy", train_env, seed=args.seed, verbose=0)
    curve = []
    for done in range(0, args.steps, args.eval_every):
        model.learn(total_timesteps=args.eval_every, reset_num_timesteps=False)
        mean_return, success = evaluate(model, eval_env)
        curve.append((done + args.eval_every, mean_return, success))
        print(
            f"{done + args.eval_every:7d} steps: return {mean_return:6.1f}, success {success * 100:5.1f} %",
            flush=True,
        )
    reference = baselines()
    steps, returns, successes = (np.array(c) for c in zip(*curve))
    fig, (ax_r, ax_s) = plt.subplots(1, 2, figsize=(9, 3.2))
    ax_r.plot(steps, returns, "o-", label="SAC")
    ax_s.plot(steps, successes * 100, "o-", label="SAC")
    for name, style in (("model", "--"), ("random", ":")):
        label = "inverse statics + PI" if name == "model" else "random"
        ax_r.axhline(reference[name][0], ls=style, color="k", label=label)
        ax_s.axhline(reference[name][1] * 100, ls=style, color="k", label=label)
    ax_r.set(xlabel="environment steps", ylabel="mean return (10 episodes)", title="bundle-reach")
    ax_s.set(xlabel="environment steps", ylabel="within 1 cm at the end, %")
    ax_r.legend(fontsize=8)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
