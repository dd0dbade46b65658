"""A hanging and a horizontal arm under gravity: the MuJoCo arm's disks over the continuum
reference's backbone (the Kirchhoff rod of muscles, not a constant-curvature arc).

    python examples/arm_gravity.py [--out docs/figures/arm_gravity.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from efam_mujoco import arm  # noqa: E402
from efam_mujoco.arm import continuum  # noqa: E402
from efam_mujoco.files import save_figure  # noqa: E402

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"
CASES = (
    ("hanging, 2 sections, 200/300/300 kPa, 0.5 kg", "hanging", [200e3, 300e3, 300e3], 0.5),
    ("horizontal, 2 sections, 300/400/400 kPa, 0.5 kg", "horizontal", [300e3, 400e3, 400e3], 0.5),
    ("horizontal, 2 sections, 300 kPa, no payload", "horizontal", [300e3] * 3, 0.0),
)


def world(spec, points):
    """Base-frame points to the world (x, z) plane of the figure."""
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(arm.ORIENTATIONS[spec.orientation]))
    out = np.asarray(points) @ rotation.reshape(3, 3).T
    return out[:, 0], out[:, 2]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=FIGURES / "arm_gravity.png")
    args = parser.parse_args(argv)
    fig, ax = plt.subplots(figsize=(7.0, 8.0))
    colours = ("tab:blue", "tab:orange", "tab:green")
    for (label, orientation, pressures, payload), colour in zip(CASES, colours):
        spec = arm.ArmSpec(
            sections=(arm.paper_section(),) * 2,
            orientation=orientation,
            payload_kg=payload,
            pressure_tau_s=0.0,
        )
        model = arm.build_model(spec)
        data = mujoco.MjData(model)
        arm.static_equilibrium(model, data, pressures * 2)
        disks = [data.xpos[model.body("base").id]] + [
            data.xpos[model.body(f"s{j}d{k}").id]
            for j in (1, 2)
            for k in range(1, spec.sections[0].disks + 1)
        ]
        reference = continuum.solve_arm_spec(spec, [pressures] * 2)
        x, z = world(spec, reference.backbone_m)
        error = np.linalg.norm(arm.tip_in_base(model, data) - reference.tip_position_m) / spec.rest_length_m
        ax.plot(x, z, "-", color=colour, lw=2.5, alpha=0.45, label=f"{label}: continuum reference")
        disks = np.array(disks)
        ax.plot(disks[:, 0], disks[:, 2], "o", ms=3.5, color=colour,
                label=f"MuJoCo, D = {spec.sections[0].disks} disks per section (tip off by {100 * error:.2f} % "
                      "of length)")  # fmt: skip
    ax.plot([0], [0], "ks", ms=8, label="base")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("world x (m)")
    ax.set_ylabel("world z (m)")
    ax.set_title("FAM1 arms under their own weight and a payload (gravity along -z)", fontsize=10)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=1, frameon=False)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, args.out, dpi=130)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
