"""Pressure step response of the shipped 3x3 arm (models/arm_3x3.xml: hanging, gravity on).

All nine muscles step from 0 to 310 kPa at t = 0.5 s (the arm extends), then at t = 3 s the
first muscle of every section steps to full pressure in one time step (the arm bends away from
it). The valve/tube lag of the shipped model (tau = 50 ms) filters each step. Plotted: the
commanded and acting pressures, and the tip position against time, with the continuum reference
equilibrium under gravity (arm.continuum.solve_arm_spec: the rod with the arm's masses) for each hold.

    python examples/arm_step_response.py [--out docs/figures/arm_step_response.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from efam_mujoco import arm, plugin  # noqa: E402
from efam_mujoco.arm.continuum import solve_arm_spec  # noqa: E402
from efam_mujoco.files import save_figure  # noqa: E402

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"
STEPS = ((0.5, "all", 310e3), (3.0, "first", 517.1e3))  # (time, which muscles, pressure)


def command(t: float, nu: int) -> np.ndarray:
    ctrl = np.zeros(nu)
    for start, which, pressure in STEPS:
        if t >= start:
            if which == "all":
                ctrl[:] = pressure
            else:
                ctrl[::3] = pressure
    return ctrl


def simulate(model, duration):
    data = mujoco.MjData(model)
    times, tips, ctrls, acting = [], [], [], []
    while data.time < duration:
        data.ctrl[:] = command(data.time, model.nu)
        mujoco.mj_step(model, data)
        times.append(data.time)
        tips.append(data.sensor("tip_pos").data.copy())
        ctrls.append(data.ctrl.copy())
        acting.append(arm.muscle_pressures(model, data))
    if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
        raise RuntimeError("the simulation went unstable")
    return np.array(times), np.array(tips), np.array(ctrls), np.array(acting)


def static_tip(spec, model, pressures):
    """The continuum reference at rest under gravity, as a world position."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    base = model.body("base").id
    rot, origin = data.xmat[base].reshape(3, 3), data.xpos[base]
    gravity = rot.T @ model.opt.gravity
    del gravity  # the spec's orientation gives the same gravity in the base frame
    state = solve_arm_spec(spec, np.reshape(pressures, (len(spec.sections), 3)))
    return origin + rot @ state.tip_position_m


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--out", type=Path, default=FIGURES / "arm_step_response.png")
    args = parser.parse_args(argv)

    plugin.load()
    model = mujoco.MjModel.from_xml_path(str(arm.MODELS_DIR / "arm_3x3.xml"))
    spec = arm.arm_3x3()  # the spec the shipped model was built from (for the statics)
    t, tip, ctrl, acting = simulate(model, args.duration)

    fig, (ax_p, ax_x) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for index, label in ((0, "muscle 1 of each section"), (1, "muscles 2, 3")):
        ax_p.plot(t, ctrl[:, index] / 1e3, "--", lw=1, color=f"C{index}", label=f"command, {label}")
        ax_p.plot(t, acting[:, index] / 1e3, lw=1.8, color=f"C{index}", label=f"acting (lag), {label}")
    ax_p.set_ylabel("pressure (kPa)")
    ax_p.legend(fontsize=8)
    for axis, name in enumerate("xyz"):
        ax_x.plot(t, tip[:, axis] * 1e3, color=f"C{axis + 2}", label=f"tip {name}")
    holds = [(STEPS[0][0], STEPS[1][0]), (STEPS[1][0], args.duration)]
    for (start, end), pressures in zip(
        holds, (command(STEPS[0][0], model.nu), command(STEPS[1][0], model.nu))
    ):
        expected = static_tip(spec, model, pressures)
        for axis in range(3):
            ax_x.hlines(expected[axis] * 1e3, start, end, colors=f"C{axis + 2}", linestyles=":", lw=1.2)
    ax_x.plot([], [], "k:", label="continuum reference at rest (hold value)")
    ax_x.set_xlabel("time (s)")
    ax_x.set_ylabel("tip position (mm)")
    ax_x.legend(fontsize=8, loc="center", bbox_to_anchor=(0.38, 0.55))
    fig.suptitle(
        f"3x3 FAM1 arm, hanging: pressure steps (tau = 50 ms, dt = {model.opt.timestep * 1e3:g} ms)",
        fontsize=11,
    )
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, args.out, dpi=110)
    print(f"final tip {np.round(tip[-1] * 1e3, 1)} mm; wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
