"""The plugin's pressure sensor: what each muscle of an instance acts with, in MuJoCo's sensordata."""

import math

import mujoco
import numpy as np
import pytest

import efam_mujoco  # noqa: F401  (registers efam.muscle)
from efam_mujoco import arm, load_muscle, rig
from efam_mujoco.plugin import instance_xml


def test_arm_pressure_sensor_follows_the_first_order_lag():
    spec = arm.arm_1x3(gravity=False, pressure_tau_s=0.05)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    command = np.array([4e5, 2.5e5, 1e5])
    data.ctrl[:] = command
    steps = 120
    for _ in range(steps):
        mujoco.mj_step(model, data)
    # the sensor is read at the position stage of the last step, before it integrated the lag:
    # filterexact after k steps of h is P (1 - exp(-k h / tau)) exactly
    elapsed = (steps - 1) * model.opt.timestep
    expected = command * (1 - math.exp(-elapsed / spec.pressure_tau_s))
    (sensor,) = [i for i in range(model.nsensor) if model.sensor(i).name.startswith("pressures_")]
    np.testing.assert_allclose(data.sensor(sensor).data, expected, rtol=1e-9)
    assert model.sensor(sensor).dim[0] == 3  # one value per actuator of the instance


def test_rig_pressure_sensor_reads_the_clamped_command():
    model, data = rig.build_rig(load_muscle("FAM1"), rig.RigOptions(mode="stroke", max_pressure_Pa=6e5))
    data.ctrl[0] = 9e5  # above the actuator's ctrlrange
    mujoco.mj_forward(model, data)
    assert data.sensor("pressure").data[0] == 6e5


def test_too_many_pressure_sensors_on_one_instance_are_rejected():
    muscle = load_muscle("FAM1")
    sensors = "".join(f'<plugin name="p{i}" instance="m"/>' for i in range(9))
    xml = f"""<mujoco>
  <extension><plugin plugin="efam.muscle">{instance_xml("m", muscle)}</plugin></extension>
  <worldbody><body><geom size="0.01" mass="1"/><joint name="j" type="slide"/></body></worldbody>
  <actuator><plugin instance="m" joint="j"/></actuator>
  <sensor>{sensors}</sensor>
</mujoco>"""
    with pytest.raises(ValueError, match="9 pressure sensors read this instance; at most 8"):
        mujoco.MjModel.from_xml_string(xml)
