"""The arm's mechanical energy: kinetic, gravitational, and the muscles' potential at fixed
pressure (each segment's force integrated over its length), and the power of its damping.

At fixed pressures every muscle segment is a nonlinear spring (its force depends on its length
only), so kinetic + gravity + muscle potential is conserved without damping; with damping it
falls by exactly the work of the damping forces. Used by the tests and benchmarks to show that
the model has no hidden dissipation.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..progress import progress
from .builder import SegmentLengths, segment_tendons

_GRID = 200_001  # samples of the force-length table per (muscle, pressure)


class MusclePotential:
    """V(l) = -int_{l0}^{l} push(P, N x) dx for every segment of every muscle of an arm model at
    fixed pressures (tabulated once; l0 = the segment's resting length, V = 0 there), at the
    segment lengths the plugin uses (:class:`.builder.SegmentLengths`: the arc lengths)."""

    def __init__(self, model: mujoco.MjModel, names: list[str], muscles: list, pressures_Pa):
        segmented = [n for n in names if segment_tendons(model, n).size]
        self.lengths = SegmentLengths(model, segmented)
        self.entries = []
        start = 0
        for name, muscle, p in zip(names, muscles, np.ravel(pressures_Pa)):
            N = segment_tendons(model, name).size
            segmented_muscle = N > 0
            if segmented_muscle:  # the muscle's segments, in the order SegmentLengths gives them
                where = slice(start, start + N)
                start += N
            else:  # PCC: the whole muscle is one segment (its tendon)
                where = int(model.tendon(name).id)
                N = 1
            lengths = np.linspace(0.5 * muscle.min_length_m, 1.5 * muscle.max_length_m, _GRID) / N
            force = muscle.push(float(p), N * lengths)
            work = np.concatenate([[0.0], np.cumsum((force[1:] + force[:-1]) / 2 * np.diff(lengths))])
            rest = muscle.rest_length_m / N
            work -= np.interp(rest, lengths, work)
            self.entries.append((segmented_muscle, where, lengths, -work))

    def __call__(self, data: mujoco.MjData) -> float:
        """The muscles' potential in state ``data`` (J; tendon lengths from its last mj_forward)."""
        segments = self.lengths(data)
        return float(
            sum(
                np.interp(segments[where] if segmented else data.ten_length[where], grid, V).sum()
                for segmented, where, grid, V in self.entries
            )
        )


def kinetic_energy(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """1/2 qvel' M qvel (mass matrix from the current positions; call after mj_forward/mj_step)."""
    out = np.zeros(model.nv)
    mujoco.mj_mulM(model, data, out, data.qvel)
    return 0.5 * float(data.qvel @ out)


def gravity_energy(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """-sum_b m_b g . x_b over all bodies (world frame)."""
    return -float(np.sum(model.body_mass[:, None] * data.xipos * model.opt.gravity[None, :]))


def damping_power(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Power the dampers dissipate, W (>= 0): sum_j c_j qdot_j^2 over the joints plus
    sum_t c_t (d l_t / dt)^2 over the tendons (the PCC coupling)."""
    return float(
        np.sum(model.dof_damping * data.qvel**2) + np.sum(model.tendon_damping * data.ten_velocity**2)
    )


def spring_energy(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Energy in the joint and tendon springs (the PCC mode's coupling springs; none in the
    segmented arm). Hinge and slide joints only (the arm has no others)."""
    stretch = data.ten_length - model.tendon_lengthspring[:, 0]
    joints = model.jnt_qposadr
    turn = data.qpos[joints] - model.qpos_spring[joints]
    return 0.5 * float(np.sum(model.tendon_stiffness * stretch**2) + np.sum(model.jnt_stiffness * turn**2))


def mechanical_energy(model: mujoco.MjModel, data: mujoco.MjData, potential: MusclePotential) -> float:
    """Kinetic + gravity + the muscles' potential at fixed pressure + the springs' energy, J."""
    return (
        kinetic_energy(model, data)
        + gravity_energy(model, data)
        + potential(data)
        + spring_energy(model, data)
    )


@dataclass(frozen=True)
class EnergyBalance:
    """What :func:`energy_balance` measured over a run, J."""

    largest_kinetic_J: float  # the motion's largest kinetic energy
    worst_imbalance_J: float  # largest |E(t) - E(0) + damping work so far|
    lost_J: float  # E(0) - E(end)
    damping_work_J: float  # the dampers' work (trapezoidal in time)


def energy_balance(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    potential: MusclePotential,
    duration_s: float,
    every: int = 1,
    label: str | None = None,
) -> EnergyBalance:
    """Step for ``duration_s`` at fixed controls and book the mechanical energy against the
    dampers' work, every ``every`` steps (1 with damping: the work is integrated step by step).
    ``label``: show a progress bar. Raises if the state stops being finite."""
    e0, work, worst, kinetic = mechanical_energy(model, data, potential), 0.0, 0.0, 0.0
    power = damping_power(model, data)
    steps = int(round(duration_s / model.opt.timestep))
    numbers = range(1, steps + 1)
    for step in numbers if label is None else progress(numbers, label, total=steps):
        mujoco.mj_step(model, data)
        if step % every and step != steps:
            continue
        mujoco.mj_forward(model, data)
        new_power = damping_power(model, data)
        work += 0.5 * (power + new_power) * model.opt.timestep * every
        power = new_power
        kinetic = max(kinetic, kinetic_energy(model, data))
        worst = max(worst, abs(mechanical_energy(model, data, potential) - e0 + work))
    if not np.all(np.isfinite(data.qpos)):
        raise FloatingPointError(f"{label or 'energy balance'}: the arm's state is not finite (diverged)")
    return EnergyBalance(kinetic, worst, e0 - mechanical_energy(model, data, potential), work)
