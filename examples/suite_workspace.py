"""The reachable workspace the suite's targets are drawn from (docs/figures/suite_workspace.png):
rest tips of the reference statics (gravity on) at sampled reachable shapes, bundle and arm.

    python examples/suite_workspace.py [--samples 300] [--out docs/figures/suite_workspace.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from efam_mujoco.suite import arm as arm_domain  # noqa: E402
from efam_mujoco.suite import bundle as bundle_domain  # noqa: E402
from efam_mujoco.suite import workspace  # noqa: E402

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=300)
    parser.add_argument("--out", type=Path, default=FIGURES / "suite_workspace.png")
    args = parser.parse_args(argv)
    fig, axes = plt.subplots(1, 2, figsize=(9, 4))
    for ax, (name, domain) in zip(axes, (("bundle (upright)", bundle_domain), ("arm (hanging)", arm_domain))):
        ws = workspace.compute_workspace(
            domain.DOMAIN.make_arm(), samples=args.samples, seed=0, limits=domain.DOMAIN.limits
        )
        tips = ws.tips_m
        radial = np.hypot(tips[:, 0], tips[:, 1])
        sc = ax.scatter(
            radial * 1e3, tips[:, 2] * 1e3, c=ws.pressure_fractions.mean(axis=1), s=8, cmap="viridis"
        )
        ax.set(xlabel="distance from the axis, mm", ylabel="along the base axis, mm", aspect="equal")
        ax.set_title(
            f"{name}: {args.samples} targets, bends <= {domain.DOMAIN.limits.max_bend_deg:.0f} deg/section",
            fontsize=9,
        )
        fig.colorbar(sc, ax=ax, label="mean pressure fraction")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
