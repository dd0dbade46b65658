"""Workspace of a one-section, three-muscle FAM1 bundle over a grid of muscle pressures.

Each pressure triple is held until the MuJoCo arm settles (gravity off, no pressure lag: the
quasi-static workspace); the constant-curvature equilibrium of the same triple is drawn beside
it. Triples whose equilibrium bends more than ``--max-bend-deg`` are left out (a 20 mm bundle
with very unequal pressures curls into a loop).

    python examples/arm_workspace.py [--levels 5] [--out docs/figures/arm_workspace.png]
"""

from __future__ import annotations

import argparse
import itertools
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from efam_mujoco import arm  # noqa: E402
from efam_mujoco.statics import solve_section  # noqa: E402

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"


def settle(model, data, pressures):
    mujoco.mj_resetData(model, data)
    arm.static_equilibrium(model, data, pressures)
    return arm.tip_in_base(model, data)


def workspace(levels: int, max_bend_deg: float):
    spec = arm.ArmSpec(sections=(arm.paper_section(),), gravity=False, pressure_tau_s=0.0)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    grid = np.linspace(arm.PAPER_PRESSURES_PA[0], arm.PAPER_PRESSURES_PA[-1], levels)
    rows = []
    for triple in itertools.product(grid, repeat=3):
        state, reference = solve_section(spec.sections[0], triple)
        if math.degrees(state.bend_angle_rad) > max_bend_deg:
            continue
        tip = settle(model, data, triple)
        rows.append((np.array(triple), tip, reference.tip_position_m, state.arc_length_m))
    return rows


def plot(rows, out: Path, max_bend_deg: float):
    mean_kpa = np.array([p.mean() / 1e3 for p, _, _, _ in rows])
    sim = np.array([t for _, t, _, _ in rows])
    cc = np.array([c for _, _, c, _ in rows])
    errors = np.array([np.linalg.norm(t - c) / s for _, t, c, s in rows])
    fig = plt.figure(figsize=(13, 5.6))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    ax3.scatter(*(sim * 1e3).T, c=mean_kpa, cmap="viridis", s=14)
    ax3.set_xlabel("x (mm)")
    ax3.set_ylabel("y (mm)")
    ax3.set_zlabel("z (mm)")
    ax3.set_title("tip positions (MuJoCo)")
    for k, (i, j, name) in enumerate(((0, 2, "xz"), (0, 1, "xy"))):
        ax = fig.add_subplot(1, 3, k + 2)
        ax.scatter(
            cc[:, i] * 1e3,
            cc[:, j] * 1e3,
            s=40,
            facecolors="none",
            edgecolors="0.6",
            label="continuum reference (CC, no load)",
        )
        points = ax.scatter(
            sim[:, i] * 1e3, sim[:, j] * 1e3, c=mean_kpa, cmap="viridis", s=12, label="MuJoCo"
        )
        ax.set_xlabel(f"{name[0]} (mm)")
        ax.set_ylabel(f"{name[1]} (mm)")
        ax.set_aspect("equal")
        ax.set_title(f"{name} projection")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), fontsize=8, frameon=False)
    fig.colorbar(points, ax=fig.axes[-1], label="mean pressure (kPa)")
    fig.suptitle(
        f"One-section FAM1 bundle (r = 18.2 mm, D = 16), {len(rows)} pressure triples, bend <= {max_bend_deg:.0f} deg\n"
        f"tip vs the continuum reference: max {errors.max():.2%}, mean {errors.mean():.2%} of section length",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return errors


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, default=5, help="pressure levels per muscle (103.4-517.1 kPa)")
    parser.add_argument("--max-bend-deg", type=float, default=360.0)
    parser.add_argument("--out", type=Path, default=FIGURES / "arm_workspace.png")
    args = parser.parse_args(argv)
    rows = workspace(args.levels, args.max_bend_deg)
    errors = plot(rows, args.out, args.max_bend_deg)
    print(
        f"{len(rows)} triples; tip vs CC: max {errors.max():.3%}, mean {errors.mean():.3%}; wrote {args.out}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
