"""No hidden dissipation and no numerical rest pose: energy balance of the released arm, and the
rest pose across time steps and solver settings."""

import mujoco
import numpy as np
import pytest

from efam_mujoco import arm, load_muscle
from efam_mujoco.arm import energy

FAM1 = load_muscle("FAM1")


def released_arm(disks, timestep_s, viscosity_scale, integrator=None, mode="segmented"):
    """A horizontal 1x3 arm at rest at 400/250/250 kPa, pressures switched to 300 kPa at once:
    it swings under gravity about its new rest pose."""
    spec = arm.ArmSpec(
        sections=(arm.paper_section(disks),), orientation="horizontal", pressure_tau_s=0.0,
        axial_viscosity_N_s=6.8 * viscosity_scale, bend_viscosity_N_m2_s=0.05 * viscosity_scale,
        timestep_s=timestep_s, mode=mode,
    )  # fmt: skip
    model = arm.build_model(spec)
    if integrator is not None:
        model.opt.integrator = integrator
    model.tendon_damping[:] *= viscosity_scale  # the PCC coupling's dampers follow the viscosities
    data = mujoco.MjData(model)
    assert arm.static_equilibrium(model, data, [400e3, 250e3, 250e3])
    data.time, data.qvel[:] = 0.0, 0.0
    data.ctrl[:] = 300e3
    mujoco.mj_forward(model, data)
    potential = energy.MusclePotential(model, arm.muscle_names(spec)[0], [FAM1] * 3, [300e3] * 3)

    def total():
        return (
            energy.kinetic_energy(model, data)
            + energy.gravity_energy(model, data)
            + potential(data)
            + energy.spring_energy(model, data)
        )

    return model, data, total


def run_energy_balance(model, data, total, duration):
    """Step for ``duration``; returns (largest kinetic energy, largest |E(t) - E(0) + damping work|,
    energy lost, damping work)."""
    e0, work, worst, kinetic = total(), 0.0, 0.0, 0.0
    power = energy.damping_power(model, data)
    while data.time < duration - 1e-12:
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        new_power = energy.damping_power(model, data)
        work += 0.5 * (power + new_power) * model.opt.timestep
        power = new_power
        kinetic = max(kinetic, energy.kinetic_energy(model, data))
        worst = max(worst, abs(total() - e0 + work))
    return kinetic, worst, e0 - total(), work


@pytest.mark.parametrize("mode, timestep_s, duration_s", [("segmented", 2.5e-4, 10.0), ("pcc", 1e-4, 3.0)])
def test_undamped_arm_conserves_energy(mode, timestep_s, duration_s):
    """Damping 0, fixed pressures, gravity on, released from a bent pose for 10 s: kinetic +
    gravity + muscle potential (+ the PCC coupling springs) stays within 1 % of the motion's
    kinetic energy. Without damping the segments' stiff axial modes (about 1300 D rad/s) must be
    resolved by the time step (MuJoCo treats stiffness explicitly; the default 1 ms relies on the
    physical damping): D = 2, RK4 at 0.25 ms here (PCC: its stiffer coupling springs, 0.1 ms, 3 s);
    bench/bench_arm.py energy runs D = 4 at 0.1 ms for 10 s."""
    model, data, total = released_arm(2, timestep_s, 0.0, mujoco.mjtIntegrator.mjINT_RK4, mode)
    kinetic, drift, _, _ = run_energy_balance(model, data, total, duration_s)
    assert kinetic > 0.05
    assert drift < 0.01 * kinetic, f"energy drift {drift:.3g} J = {drift / kinetic:.2%} of the kinetic energy"
    print(f"\n{mode}: energy drift {drift / kinetic:.3%} of the largest kinetic energy {kinetic:.3f} J")


@pytest.mark.parametrize("mode", ["segmented", "pcc"])
def test_damped_arm_loses_exactly_the_damping_work(mode):
    """Default damping, time step and integrator (implicitfast), released as above: the energy
    lost equals the work of the joint dampers (the only dissipation) within 2 %."""
    model, data, total = released_arm(arm.DEFAULT_DISKS, 1e-3, 1.0, mode=mode)
    _, _, lost, work = run_energy_balance(model, data, total, 3.0)
    assert lost > 0.1
    assert lost == pytest.approx(work, rel=0.02)
    print(f"\n{mode}: energy lost {lost:.4f} J, damping work {work:.4f} J")


def rest_tip(timestep_s=1e-3, tune=None, mode="segmented"):
    spec = arm.ArmSpec(
        sections=(arm.paper_section(8),), orientation="horizontal", pressure_tau_s=0.0, timestep_s=timestep_s,
        mode=mode,
    )  # fmt: skip
    model = arm.build_model(spec)
    if tune:
        tune(model)
    data = mujoco.MjData(model)
    assert arm.settle(model, data, [300e3, 420e3, 420e3], t_max_s=20.0, vel_tol=1e-7)
    return arm.tip_in_base(model, data), spec.rest_length_m


@pytest.mark.parametrize("mode", ["segmented", "pcc"])
def test_rest_pose_is_independent_of_numerical_settings(mode):
    """The arm settled by simulation (not solved statically): the rest tip moves less than 0.05 %
    of the arm's length between time steps 0.25, 0.5, 1 and 2 ms and when the solver's
    parameters are halved or doubled (there is no constraint for them to act on)."""
    reference, length = rest_tip(mode=mode)
    variants = {f"dt {dt * 1e3} ms": dict(timestep_s=dt) for dt in (0.25e-3, 0.5e-3, 2e-3)}

    def scale(attr, factor):
        def tune(model):
            setattr(model.opt, attr, getattr(model.opt, attr) * factor)

        return tune

    for attr in ("tolerance", "impratio", "iterations"):
        for factor in (0.5, 2.0):
            variants[f"{attr} x{factor}"] = dict(
                tune=scale(attr, factor if attr != "iterations" else int(factor * 2))
            )
    worst = 0.0
    for label, kw in variants.items():
        tip, _ = rest_tip(mode=mode, **kw)
        moved = np.linalg.norm(tip - reference) / length
        worst = max(worst, moved)
        assert moved < 5e-4, f"{label}: rest tip moved {moved:.3%} of the arm's length"
    print(f"\n{mode}: rest tip moved at most {worst:.2e} of the arm's length")
