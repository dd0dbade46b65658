"""No hidden dissipation and no numerical rest pose: energy balance of the released arm, and the
rest pose across time steps and solver settings. Everything at the default D, and (unless the
check is about the step) at the builder's own time step and integrator."""

import warnings
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from efam_mujoco import arm, load_muscle
from efam_mujoco.arm import energy, timestep

FAM1 = load_muscle("FAM1")
#: steps the undamped run may take in CI (the bench runs the full 10 s: bench/bench_arm.py energy)
STEP_BUDGET = 4000


def horizontal_arm(mode, damped=True, **kw):
    """The 1x3 arm at the default D, horizontal, no pressure lag, default or zero damping."""
    scale = 1.0 if damped else 0.0
    return arm.ArmSpec(
        sections=(arm.paper_section(arm.DEFAULT_DISKS),), orientation="horizontal", pressure_tau_s=0.0,
        axial_viscosity_N_s=6.8 * scale, bend_viscosity_N_m2_s=0.05 * scale, mode=mode, **kw,
    )  # fmt: skip


def released_arm(mode, damped):
    """The arm at rest at 400/250/250 kPa (found on the damped arm), pressures switched to
    300 kPa at once: it swings under gravity about its new rest pose. Returns (model, data,
    the muscles' potential at 300 kPa)."""
    rest_model = arm.build_model(horizontal_arm(mode))
    rest = mujoco.MjData(rest_model)
    assert arm.static_equilibrium(rest_model, rest, [400e3, 250e3, 250e3])
    spec = horizontal_arm(mode, damped)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    data.qpos[:] = rest.qpos
    data.ctrl[:] = 300e3
    mujoco.mj_forward(model, data)
    potential = energy.MusclePotential(model, arm.muscle_names(spec)[0], [FAM1] * 3, [300e3] * 3)
    return model, data, potential


@pytest.mark.parametrize("mode", ["segmented", "pcc"])
def test_undamped_arm_conserves_energy(mode):
    """Damping 0, fixed pressures, gravity on, released from a bent pose, at the default D and
    the builder's own step and integrator for the undamped arm (RK4, omega_max dt <= 0.71):
    kinetic + gravity + muscle potential (+ the PCC coupling springs) stays within 1 % of the
    motion's kinetic energy. CI runs the first ``STEP_BUDGET`` steps (the whole 10 s when D is
    small); bench/bench_arm.py energy runs 10 s."""
    model, data, potential = released_arm(mode, damped=False)
    choice = timestep.recorded_timestep(model)
    assert (
        not choice.given
        and choice.integrator == "RK4"
        and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    )
    assert choice.omega_max_rad_s * model.opt.timestep <= 2 * np.sqrt(2) / timestep.TIMESTEP_SAFETY["RK4"]
    assert not (model.dof_damping.any() or model.tendon_damping.any())
    duration = min(10.0, STEP_BUDGET * model.opt.timestep)
    run = energy.energy_balance(model, data, potential, duration, every=10)
    kinetic, drift = run.largest_kinetic_J, run.worst_imbalance_J
    assert kinetic > 0.01
    assert drift < 0.01 * kinetic, f"energy drift {drift:.3g} J = {drift / kinetic:.2%} of the kinetic energy"
    print(f"\n{mode}: {duration:.2f} s at {model.opt.timestep * 1e3:g} ms: energy drift {drift / kinetic:.3%} "
          f"of the largest kinetic energy {kinetic:.3f} J")  # fmt: skip


@pytest.mark.parametrize("mode", ["segmented", "pcc"])
def test_damped_arm_loses_exactly_the_damping_work(mode):
    """Default D, damping, time step and integrator (implicitfast), released as above: the energy
    lost equals the work of the joint (and PCC coupling) dampers, the only dissipation, within 2 %."""
    model, data, potential = released_arm(mode, damped=True)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert not timestep.recorded_timestep(model).given
    run = energy.energy_balance(model, data, potential, 3.0)
    lost, work = run.lost_J, run.damping_work_J
    assert lost > 0.1
    assert lost == pytest.approx(work, rel=0.02)
    print(f"\n{mode}: {model.opt.timestep * 1e3:g} ms: energy lost {lost:.4f} J, damping work {work:.4f} J")


def rest_tip(mode, start_qpos, timestep_s=None, tune=None):
    """The tip at rest at 300/420/420 kPa, settled by simulation from ``start_qpos``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", timestep.TimestepWarning)  # steps above the undamped limit
        model = arm.build_model(horizontal_arm(mode, timestep_s=timestep_s))
    if tune:
        tune(model)
    data = mujoco.MjData(model)
    data.qpos[:] = start_qpos
    assert arm.settle(model, data, [300e3, 420e3, 420e3], t_max_s=20.0, vel_tol=3e-5)
    assert data.nefc == 0  # no constraint rows: no solver parameter enters the dynamics
    return arm.tip_in_base(model, data)


@pytest.mark.parametrize("mode", ["segmented", "pcc"])
def test_rest_pose_is_independent_of_numerical_settings(mode):
    """The arm settled by simulation (not solved statically), from its rest pose under nearby
    pressures: the rest tip moves less than 0.05 % of the arm's length between time steps 0.25,
    0.5, 1 and 2 ms and when the solver's parameters are halved or doubled (there is no
    constraint for them to act on: no constraint row is ever made)."""
    start_model = arm.build_model(horizontal_arm(mode))
    start = mujoco.MjData(start_model)
    assert arm.static_equilibrium(start_model, start, [310e3, 415e3, 415e3])
    length = horizontal_arm(mode).rest_length_m
    variants = {f"dt {dt * 1e3:g} ms": dict(timestep_s=dt) for dt in (0.25e-3, 0.5e-3, 1e-3, 2e-3)}

    def scale(attr, factor):
        def tune(model):
            setattr(model.opt, attr, type(getattr(model.opt, attr))(getattr(model.opt, attr) * factor))

        return tune

    for attr, factor in (("tolerance", 2.0), ("iterations", 0.5)):
        variants[f"{attr} x{factor}"] = dict(tune=scale(attr, factor))
    tips = {label: rest_tip(mode, start.qpos, **kw) for label, kw in variants.items()}
    worst = max(np.linalg.norm(a - b) for a in tips.values() for b in tips.values()) / length
    assert worst < 5e-4, f"rest tip moved {worst:.3%} of the arm's length: {tips}"
    print(f"\n{mode}: rest tip moved at most {worst:.2e} of the arm's length")


def grows(model, steps=400):
    """Start straight at rest (gravity off, zero pressure: qpos0 is the equilibrium) with a tiny
    random disturbance (1e-6 m/s, rad/s): whether it grows a thousandfold (an unstable
    step's growth saturates in the muscles' nonlinearity or ends in MuJoCo's reset) within
    ``steps``."""
    data = mujoco.MjData(model)
    data.qvel[:] = 1e-6 * np.random.default_rng(0).standard_normal(model.nv)
    for _ in range(steps):
        mujoco.mj_step(model, data)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number or np.abs(data.qvel).max() > 1e-3:
            return True  # (MuJoCo resets a diverged state and counts a warning)
    return False


@pytest.mark.parametrize("damped", [True, False])
def test_stability_limit_matches_simulation(damped):
    """The linearised stability limit (undamped: RK4, 2 sqrt(2) / omega_max; damped: implicitfast,
    from each mode's frequency and damping) is where the simulated arm starts to diverge: stable
    at 0.8 x the limit, diverging at 1.25 x (at rest, zero pressure). The builder's limit (the
    smaller of zero and the highest pressure) is at most this one; a step beyond it is refused
    when given, and a damped step above the undamped limit warns."""
    spec = arm.ArmSpec(
        sections=(arm.paper_section(arm.DEFAULT_DISKS),), gravity=False, pressure_tau_s=0.0,
        axial_viscosity_N_s=6.8 * damped, bend_viscosity_N_m2_s=0.05 * damped,
    )  # fmt: skip
    model = arm.build_model(spec)
    choice = timestep.recorded_timestep(model)
    assert choice.integrator == ("implicitfast" if damped else "RK4")
    _, _, limits = timestep.modal_limits(*timestep.linearise(model, 0.0), int(model.opt.integrator))
    limit = float(limits.min())
    assert choice.limit_s <= limit * (1 + 1e-9)
    model.opt.timestep = 0.8 * limit
    assert not grows(model)
    model.opt.timestep = 1.25 * limit
    assert grows(model)
    with pytest.raises(ValueError, match="omega_max"):
        arm.build_spec(replace(spec, timestep_s=1.25 * choice.limit_s))
    if damped:
        with pytest.warns(timestep.TimestepWarning, match="undamped limit"):
            arm.build_spec(replace(spec, timestep_s=2e-3))
