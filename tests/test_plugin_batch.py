"""The plugin's batched force path: one instance driving many actuators (as the rig and arm
builders write it) must give the Python reference's forces, like the single-actuator path."""

import math

import mujoco
import numpy as np
import pytest
from test_plugin import MUSCLES, probe_lengths, probe_pressures

import efam_mujoco  # noqa: F401  (registers efam.muscle)
from efam_mujoco import StressLaw, load_muscle
from efam_mujoco.plugin import instance_xml

ACTUATORS = 70  # more than one pass of the batch (64) and a remainder


def shared_instance_model(muscle, count: int = ACTUATORS) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """``count`` bodies on slide joints (qpos = muscle length), all driven by one plugin instance."""
    bodies = "".join(
        f'<body><geom size="0.01" mass="1"/><joint name="j{i}" type="slide" axis="0 0 1"/></body>'
        for i in range(count)
    )
    actuators = "".join(
        f'<plugin instance="shared" joint="j{i}" ctrllimited="true" ctrlrange="-1e5 2e6"/>'
        for i in range(count)
    )
    xml = f"""<mujoco>
  <extension><plugin plugin="efam.muscle">{instance_xml("shared", muscle)}</plugin></extension>
  <worldbody>{bodies}</worldbody>
  <actuator>{actuators}</actuator>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def batched_forces(model, data, pressures, lengths) -> np.ndarray:
    data.qpos[:] = lengths
    data.ctrl[:] = pressures
    mujoco.mj_forward(model, data)
    return data.actuator_force.copy()


@pytest.mark.parametrize("case", sorted(MUSCLES))
def test_batched_forces_equal_python_reference(case):
    muscle = MUSCLES[case]
    model, data = shared_instance_model(muscle)
    # every (pressure, length) probe of the single-actuator test, 70 at a time, shuffled so that
    # each pass mixes pressures, strain signs and out-of-range lengths
    pairs = np.array([(p, L) for p in probe_pressures(muscle) for L in probe_lengths(muscle)])
    np.random.default_rng(0).shuffle(pairs)
    worst = 0.0
    for first in range(0, len(pairs), ACTUATORS):
        chunk = pairs[first : first + ACTUATORS]
        chunk = np.vstack([chunk, np.tile(chunk[-1], (ACTUATORS - len(chunk), 1))])
        forces = batched_forces(model, data, chunk[:, 0], chunk[:, 1])
        clamped = np.clip(chunk[:, 0], -1e5, 2e6)
        reference = muscle.push(clamped, chunk[:, 1])
        error = np.abs(forces - reference) / np.maximum(1.0, np.abs(reference))
        worst = max(worst, float(error.max()))
    assert worst <= 1e-9, (case, worst)


def test_batched_non_finite_inputs_give_zero_and_do_not_spoil_neighbours():
    muscle = load_muscle("FAM1")
    model, data = shared_instance_model(muscle)
    lengths = np.full(ACTUATORS, 0.25)
    pressures = np.full(ACTUATORS, 3e5)
    lengths[5], lengths[66] = np.nan, np.inf
    forces = batched_forces(model, data, pressures, lengths)
    assert forces[5] == 0.0 and forces[66] == 0.0
    good = np.ones(ACTUATORS, bool)
    good[[5, 66]] = False
    np.testing.assert_allclose(forces[good], muscle.push(3e5, 0.25), rtol=1e-12)


def test_batched_overflowing_law_gives_finite_force():
    muscle = load_muscle("FAM1").with_stress(StressLaw("exponential_decay", (1.5e6, 2.0, 1e5, 2000.0)))
    model, data = shared_instance_model(muscle)
    lengths = np.linspace(0.5 * muscle.min_length_m, 1.2 * muscle.max_length_m, ACTUATORS)
    forces = batched_forces(model, data, np.full(ACTUATORS, 3e5), lengths)
    assert all(math.isfinite(f) for f in forces)
    with np.errstate(over="ignore", invalid="ignore"):
        reference = muscle.push(3e5, lengths)
    finite = np.isfinite(reference)
    assert finite.any() and (~finite).any()  # the probe reaches both regimes
    np.testing.assert_allclose(forces[finite], reference[finite], rtol=1e-9, atol=1e-9)
    assert np.all(forces[~finite] == 0.0)  # documented: a non-finite force becomes 0
