"""``efam suite``: list the tasks, score the model-based controller and the random baseline,
and write an image strip of a solved episode.

    efam suite --list
    efam suite --domain bundle --task reach --episodes 50 --strip docs/figures/suite_bundle_reach.png
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..cli import bounded_int
from ..files import OutputSet, check_figure_path, save_figure
from ..units import visible

#: tasks the model-based controller acts on (those with a tip target)
CONTROLLED_TASKS = ("reach", "reach_payload", "track")
#: Episode i is seeded with seed + i, which numpy and dm_control take in 0 .. 2**32 - 1.
MAX_SEED = 2**32 - 1
#: Episodes per policy at most: about a second each, so hours of work; a score needs hundreds.
MAX_EPISODES = 10_000
#: the defaults of --episodes and --seed (``--list`` refuses a value other than these: it runs none)
DEFAULT_EPISODES = 10
DEFAULT_SEED = 0


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--list", action="store_true", help="list the domains and tasks")
    parser.add_argument(
        "--domain", default=None, help="bundle or arm (default bundle; with --list: only its tasks)"
    )
    parser.add_argument(
        "--task", default=None, help="task name (default reach; with --list: only tasks of that name)"
    )
    parser.add_argument(
        "--episodes", type=bounded_int(1, MAX_EPISODES), default=DEFAULT_EPISODES,
        help=f"seeded episodes per policy, 1 .. {MAX_EPISODES} (default {DEFAULT_EPISODES})",
    )  # fmt: skip
    parser.add_argument(
        "--seed", type=bounded_int(0, MAX_SEED, "numpy's seed range"), default=DEFAULT_SEED,
        help=f"seed of the first episode, 0 .. {MAX_SEED}; episode i uses seed + i (default {DEFAULT_SEED})",
    )  # fmt: skip
    parser.add_argument(
        "--strip",
        help="write an image strip of the controller's first episode (.png, .pdf, .svg, ...)",
    )
    parser.add_argument("--json", help="write the per-episode results as JSON")


def _summary(results) -> dict:
    errors = np.array([r.final_error for r in results])
    return {
        "episodes": len(results),
        "success_rate": float(np.mean([r.success for r in results])),
        "mean_return": float(np.mean([r.episode_return for r in results])),
        "median_final_error": float(np.median(errors)),
        "worst_final_error": float(errors.max()),
    }


def write_strip(domain: str, task: str, seed: int, path: Path, frames: int = 6) -> Path:
    """Render ``frames`` evenly spaced views of one controlled episode side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from . import controllers, load

    env = load(domain, task, task_kwargs={"random": seed})
    policy = controllers.InverseStaticsController(env)
    steps = int(round(env._step_limit))  # noqa: SLF001  (dm_control keeps it private)
    images: list = []
    env_frames_every = max(1, steps // frames)
    time_step = env.reset()
    policy.reset(time_step)
    images.append(env.physics.render(240, 320, camera_id="perspective"))
    count = 0
    while not time_step.last():
        time_step = env.step(policy(time_step))
        count += 1
        if count % env_frames_every == 0 and len(images) < frames:
            images.append(env.physics.render(240, 320, camera_id="perspective"))
    images[-1] = env.physics.render(240, 320, camera_id="perspective")
    dt = env.control_timestep()
    times = [i * env_frames_every * dt for i in range(len(images) - 1)] + [count * dt]
    fig, axes = plt.subplots(1, len(images), figsize=(2.4 * len(images), 2.2))
    for ax, image, t in zip(axes, images, times):
        ax.imshow(image)
        ax.set_title(f"t = {t:.1f} s", fontsize=9)
        ax.axis("off")
    error = controllers.final_error(env.task, env.physics)
    fig.suptitle(
        f"{domain}-{task}, seed {seed}: inverse statics + PI, final tip error {error * 1e3:.2f} mm",
        fontsize=10,
    )
    fig.tight_layout()
    save_figure(fig, path, dpi=110)  # a unique temporary, then a rename; the format from the suffix
    plt.close(fig)
    return path


def _run(args) -> int:
    from . import ALL_TASKS, BENCHMARKING, controllers

    if args.list:  # --domain/--task narrow the list (they were ignored without a word)
        ignored = [f for f, v in (("--json", args.json), ("--strip", args.strip)) if v is not None]
        ignored += [
            f
            for f, v, default in (
                ("--episodes", args.episodes, DEFAULT_EPISODES),
                ("--seed", args.seed, DEFAULT_SEED),
            )
            if v != default
        ]
        if ignored:  # a list runs no episode and writes nothing: said, not dropped without a word
            raise ValueError(
                f"--list only lists the tasks (narrowed by --domain/--task); {', '.join(ignored)} would be "
                "ignored: drop them, or run a task without --list"
            )
        shown = [(d, t) for d, t in ALL_TASKS if args.domain in (None, d) and args.task in (None, t)]
        if not shown:
            given = " ".join(
                f"--{k} {v}" for k, v in (("domain", args.domain), ("task", args.task)) if v is not None
            )
            raise ValueError(f"--list {given}: no such task; efam suite --list shows them all")
        for domain, task in shown:
            tag = "benchmarking" if (domain, task) in BENCHMARKING else "extra"
            print(f"{domain}-{task}  ({tag})")
        return 0
    for flag, value in (("--domain", args.domain), ("--task", args.task)):
        if value is not None and not value.strip():  # '' read as "the default" ran another task
            raise ValueError(
                f"{flag}: an empty name; give one (efam suite --list shows them) or drop the flag"
            )
    args.domain = "bundle" if args.domain is None else args.domain
    args.task = "reach" if args.task is None else args.task
    if (args.domain, args.task) not in ALL_TASKS:
        raise ValueError(f"--domain/--task: no task {args.domain}-{args.task}; see efam suite --list")
    if args.seed + args.episodes - 1 > MAX_SEED:  # the last episode's seed, before any episode runs
        raise ValueError(
            f"--seed {args.seed} with --episodes {args.episodes}: the last episode's seed "
            f"{args.seed + args.episodes - 1} is above {MAX_SEED} (numpy's seed range)"
        )
    policies = ["model", "random"] if args.task in CONTROLLED_TASKS else ["random"]
    if args.strip:  # before the episodes, not after them (also when run as a script)
        if "model" not in policies:
            raise ValueError(f"--strip: the controller acts on {', '.join(CONTROLLED_TASKS)} only")
        check_figure_path("--strip", args.strip)
    report = {"domain": args.domain, "task": args.task, "seed": args.seed}
    for name in policies:
        results = controllers.evaluate(args.domain, args.task, name, args.episodes, args.seed)
        summary = _summary(results)
        report[name] = {**summary, "per_episode": [r.__dict__ for r in results]}
        unit = "N" if args.task == "push" else "mm"
        scale = 1.0 if unit == "N" else 1e3
        label = "inverse statics + PI" if name == "model" else "random"
        print(
            f"{args.domain}-{args.task} {label:>20}: success {summary['success_rate'] * 100:5.1f} % of {args.episodes}, "
            f"mean return {summary['mean_return']:6.1f}, final error median {summary['median_final_error'] * scale:.2f} {unit}, "
            f"worst {summary['worst_final_error'] * scale:.2f} {unit}"
        )
    outputs = OutputSet()  # written together: a strip that fails leaves the --json as it was
    if args.json:
        outputs.json(args.json, report)
    if args.strip:  # checked above, before the episodes
        write_strip(args.domain, args.task, args.seed, outputs.staging_path(args.strip))
    for path in outputs.commit():
        print(f"wrote {visible(str(path))}")
    return 0


def register_cli(subparsers) -> None:
    """``efam suite`` (for efam_mujoco.cli.COMMAND_MODULES)."""
    parser = subparsers.add_parser(
        "suite",
        help="dm_control tasks on EFAM bundles and arms: score the controller and a random baseline",
        description=__doc__.split("\n\n")[0],  # the first paragraph: its first line ended mid-sentence
    )
    _add_arguments(parser)
    parser.set_defaults(run=_run, file_outputs=("json", "strip"))


def main(argv=None) -> int:
    """``python -m efam_mujoco.suite.cli ...`` = ``efam suite ...`` (the same checks of numbers,
    file names and output files, and the same one-line errors: the efam command line runs it)."""
    from ..cli import main as efam_main

    return efam_main(["suite", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
