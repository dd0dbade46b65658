"""Test rigs: one muscle between a fixed base and an end plate, like the paper's MTS setup.

The muscle is a spatial tendon from a site on the base to a site on the plate, driven by the
``efam.muscle`` plugin (ctrl = gauge pressure in Pa). The plate moves along +z, away from the
base, so the tendon length is the muscle length. Three modes:

* ``stroke``: the plate is a mocap body whose position the test machine prescribes
  (displacement control, as the MTS strokes the muscle); at the resting length this is the
  blocked-force test. The load cell reads the muscle's force (push positive).
* ``free``: the plate slides freely (gravity off, damped): the muscle finds its free length.
* ``loaded``: as free, with a known axial load on the plate: ``load_N`` positive compresses the
  muscle (a weight on an upright EFAM), so at rest ``push(P, L) = load_N``.

``rig_xml`` returns the MJCF; ``models/rig_*.xml`` are these for FAM1. The measuring functions
below build a rig, run MuJoCo and return what a bench test would.

Effects identified by ``efam diagnose`` switch on with ``RigOptions(effects=[(name, parameters),
...])``: the actuator-force terms run inside the plugin (config keys ``effects`` and
``<effect>.<parameter>``, see efam_effects.h), ``pressure_lag`` on the actuator's own
``filterexact`` lag, and ``force_offset`` (a load-cell zero error) in the load-cell reading
(``load_cell_N``; the model file keeps it as ``<numeric name="load_cell_offset_N">``).
``replay`` drives the stroke rig with a recording's length and pressure, sample by sample.
"""

from __future__ import annotations

import math
import unicodedata
from dataclasses import dataclass

import mujoco
import numpy as np

from .muscle import MAX_PRESSURE_LAG_S, NEUTRAL_BRAID_ANGLE_DEG, Muscle
from .plugin import actuator_dynamics, effect_pairs, effects_config, instance_xml
from .plugin import load as load_plugin
from .units import check_pressure_Pa, check_within

MODES = ("stroke", "free", "loaded")
TIMESTEP_S = 1e-3
PLATE_MASS_KG = 0.05  # an aluminium end fitting and swage tube (paper Table 1): about 32 g
PLATE_DAMPING_NS_PER_M = 20.0
P_ATM = 101325.0  # a gauge pressure is never below -1 atm
LOAD_CELL_OFFSET = "load_cell_offset_N"  # <numeric> holding the force_offset effect


def _finite(value, what: str, *, low: float = -math.inf, unit: str = "") -> float:
    """``value`` as a float when it is a finite number not below ``low``; else an error naming it."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number, got {value!r}") from None
    if not (math.isfinite(number) and number >= low):
        bound = f" at least {low:g}{unit}" if low > -math.inf else ""
        raise ValueError(f"{what} must be a finite number{bound}, got {value!r}")
    return number


@dataclass(frozen=True)
class RigOptions:
    mode: str = "free"
    pressure_lag_s: float | None = None  # first-order valve/tube lag on the pressure, seconds
    max_pressure_Pa: float = 1.0e6
    plate_mass_kg: float = PLATE_MASS_KG
    damping_Ns_per_m: float = PLATE_DAMPING_NS_PER_M
    timestep_s: float = TIMESTEP_S
    # effects switched on: [(name, parameters), ...] as EffectModel / Diagnosis hold them
    effects: tuple = ()
    min_pressure_Pa: float = 0.0  # the control's lower bound (a replay passes noise below 0 through)

    def __post_init__(self):
        """Every option checked, each error naming it: MuJoCo would take a NaN mass as its
        default, and a negative timestep or damping runs a model nobody asked for."""
        if self.mode not in MODES:
            raise ValueError(f"rig mode '{self.mode}' unknown (known: {', '.join(MODES)})")
        if self.pressure_lag_s is not None:
            _finite(
                self.pressure_lag_s, "RigOptions.pressure_lag_s (or None for no lag)", low=1e-9, unit=" s"
            )
            if self.pressure_lag_s > MAX_PRESSURE_LAG_S:  # the plugin refuses such a dynprm too
                raise ValueError(
                    f"RigOptions.pressure_lag_s must be at most {MAX_PRESSURE_LAG_S:g} s (a valve and a tube "
                    f"fill a bladder in milliseconds to seconds; was it in ms?), got {self.pressure_lag_s!r}"
                )
        _finite(self.max_pressure_Pa, "RigOptions.max_pressure_Pa", low=1.0, unit=" Pa")
        _finite(self.min_pressure_Pa, "RigOptions.min_pressure_Pa", low=-P_ATM, unit=" Pa")
        if not self.min_pressure_Pa < self.max_pressure_Pa:
            raise ValueError(
                f"RigOptions.min_pressure_Pa ({self.min_pressure_Pa:g}) must be below max_pressure_Pa "
                f"({self.max_pressure_Pa:g})"
            )
        _finite(self.plate_mass_kg, "RigOptions.plate_mass_kg", low=1e-6, unit=" kg")
        _finite(self.damping_Ns_per_m, "RigOptions.damping_Ns_per_m", low=0.0, unit=" N s/m")
        _finite(self.timestep_s, "RigOptions.timestep_s", low=1e-7, unit=" s")
        if self.timestep_s > 0.01:
            raise ValueError(
                f"RigOptions.timestep_s must be at most 0.01 s (a muscle rig), got {self.timestep_s!r}"
            )
        effect_pairs(self.effects)  # only (name, parameters) pairs: tuple('friction') is its letters
        object.__setattr__(self, "effects", tuple(self.effects))
        actuator_dynamics(self.effects, self.pressure_lag_s)  # one lag, or an error
        load_cell_offset(self.effects)  # validates every effect's parameters


def load_cell_offset(effects) -> float:
    """The ``force_offset`` effect's ``offset_N`` (0 without it): what the load cell reads at zero
    force. Every effect is validated on the way (an error names the effect and key)."""
    effects_config(effects)
    for effect in effects or ():
        name, values = (effect["name"], effect["parameters"]) if isinstance(effect, dict) else effect
        if name == "force_offset":
            return float(values["offset_N"])
    return 0.0


def actuator_xml(
    name: str,
    instance: str,
    tendon: str,
    max_pressure_Pa: float,
    lag_s: float | None,
    effects=(),
    min_pressure_Pa: float = 0.0,
) -> str:
    """The ``<plugin>`` actuator element driving ``tendon`` with the plugin ``instance``."""
    dynamics = actuator_dynamics(effects, lag_s)
    low = repr(float(min_pressure_Pa)) if min_pressure_Pa else "0"
    return (
        f'    <plugin name="{name}" instance="{instance}" tendon="{tendon}" ctrllimited="true" '
        f'ctrlrange="{low} {max_pressure_Pa!r}"{dynamics}/>\n'
    )


def rig_xml(muscle: Muscle, options: RigOptions = RigOptions()) -> str:
    """The MJCF of a rig for ``muscle`` in ``options.mode`` (``stroke``, ``free`` or ``loaded``; see the
    module docstring), with the plugin's config, sensors and any effects switched on."""
    mode = options.mode
    L0 = muscle.rest_length_m
    radius = max(muscle.rest_diameter_m, 0.01)
    if mode == "stroke":
        plate_open, joint = f'<body name="plate" mocap="true" pos="0 0 {L0!r}">', ""
    else:
        plate_open = f'<body name="plate" pos="0 0 {L0!r}">'
        joint = (
            f'\n      <joint name="stroke" type="slide" axis="0 0 1" damping="{options.damping_Ns_per_m!r}"/>'
        )
    load_actuator = ""
    if mode == "loaded":
        # gear -1: ctrl = load in N, positive pushes the plate toward the base (compresses)
        load_actuator = '    <motor name="load" joint="stroke" gear="-1" ctrllimited="false"/>\n'
    sensors = (
        '    <actuatorfrc name="load_cell" actuator="muscle"/>\n'
        '    <tendonpos name="muscle_length" tendon="muscle_path"/>\n'
        '    <plugin name="pressure" instance="muscle"/>\n'
    )
    instance = instance_xml("muscle", muscle, "      ", options.effects)
    actuator = actuator_xml(
        "muscle", "muscle", "muscle_path", options.max_pressure_Pa, options.pressure_lag_s,
        options.effects, options.min_pressure_Pa,
    )  # fmt: skip
    offset = load_cell_offset(options.effects)
    custom = ""
    if offset:
        custom = (
            "  <!-- force_offset: the load cell reads this at zero force (rig.load_cell_N adds it) -->\n"
            f'  <custom>\n    <numeric name="{LOAD_CELL_OFFSET}" data="{offset!r}"/>\n  </custom>\n'
        )
    return f"""<mujoco model="efam_rig_{mode}">
  <!-- {_comment_text(muscle.name or "muscle")} on the {mode} rig; generated by efam_mujoco.rig -->
  <extension>
    <plugin plugin="efam.muscle">
{instance}
    </plugin>
  </extension>
  <option timestep="{options.timestep_s!r}" integrator="implicitfast" gravity="0 0 0"/>
  <worldbody>
    <light pos="0 -0.5 0.5" dir="0 1 -1"/>
    <geom name="base" type="cylinder" size="{radius!r} 0.005" pos="0 0 -0.005" rgba="0.6 0.6 0.6 1"/>
    <site name="base_anchor" pos="0 0 0" size="0.004"/>
    {plate_open}{joint}
      <geom name="plate" type="cylinder" size="{radius!r} 0.005" pos="0 0 0.005" mass="{options.plate_mass_kg!r}"
            rgba="0.7 0.7 0.75 1"/>
      <site name="plate_anchor" pos="0 0 0" size="0.004"/>
    </body>
  </worldbody>
  <tendon>
    <spatial name="muscle_path" width="{muscle.rest_diameter_m / 2!r}" rgba="0.9 0.6 0.2 0.6">
      <site site="base_anchor"/>
      <site site="plate_anchor"/>
    </spatial>
  </tendon>
  <actuator>
{actuator}{load_actuator}  </actuator>
  <sensor>
{sensors}  </sensor>
{custom}</mujoco>
"""


def _comment_text(text: str) -> str:
    """``text`` safe inside an XML comment: one line, no ``--``, no character XML cannot hold
    (controls, half surrogate pairs): a muscle's name is user input."""
    text = "".join(ch for ch in str(text) if unicodedata.category(ch) not in ("Cc", "Cs") or ch in "\t\n")
    text = " ".join(text.split())
    while "--" in text:
        text = text.replace("--", "- -")
    return text.rstrip("-")[:200]


def build_rig(muscle: Muscle, options: RigOptions = RigOptions()) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Compile :func:`rig_xml` (plugin loaded first); returns ``(model, data)``."""
    load_plugin()
    model = mujoco.MjModel.from_xml_string(rig_xml(muscle, options))
    return model, mujoco.MjData(model)


# ------------------------------------------------------------------------------- measurements
def load_cell_N(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """What the rig's load cell reads (push positive): the muscle's force plus the load cell's
    zero error (the ``force_offset`` effect, kept in the model as a ``<numeric>``)."""
    return float(data.sensordata[model.sensor("load_cell").adr[0]]) + _zero_error(model)


def _zero_error(model: mujoco.MjModel) -> float:
    try:
        return float(model.numeric(LOAD_CELL_OFFSET).data[0])
    except KeyError:
        return 0.0


#: How far (a share of the resting length) a length may lie beyond the muscle's admissible
#: lengths and still be asked about: the lock spring (20 kN/m) holds a muscle a few mm past its
#: braid's lock-out under tens of newtons, never a tenth of its length (``efam view --check``
#: calls a model whose muscle goes further one whose geometry does not fit the muscle)
ADMISSIBLE_SLACK = 0.1


def check_lengths(muscle: Muscle, lengths_m, what: str) -> np.ndarray:
    """``lengths_m`` as an array, refused (naming ``what``) when a length is not finite or lies
    beyond the muscle's admissible lengths by more than ``ADMISSIBLE_SLACK`` of its rest length."""
    lengths = np.atleast_1d(np.asarray(lengths_m, dtype=float))
    if lengths.ndim != 1:
        raise ValueError(
            f"{what} must be a number or a 1-D sequence of lengths in m, got shape {lengths.shape}"
        )
    slack = ADMISSIBLE_SLACK * muscle.rest_length_m
    check_within(lengths, muscle.min_length_m - slack, muscle.max_length_m + slack, what=what, unit="m")
    return lengths


def stroke_forces(
    muscle: Muscle, pressure_Pa: float, lengths_m, settle_s: float = 0.0, effects=()
) -> np.ndarray:
    """Displacement-controlled test: the load cell (push positive) at each prescribed length.
    ``pressure_Pa`` in Pa, inside the rig's control range (else an error, never a clamp);
    ``lengths_m`` inside the muscle's admissible lengths (give or take ``ADMISSIBLE_SLACK``)."""
    options = RigOptions(mode="stroke", effects=effects)
    check_control_range(pressure_Pa, options, "stroke_forces: pressure_Pa")
    lengths_m = check_lengths(muscle, lengths_m, "stroke_forces: lengths_m")
    settle_s = _finite(settle_s, "stroke_forces: settle_s", low=0.0, unit=" s")
    model, data = build_rig(muscle, options)
    forces = []
    for length in np.atleast_1d(lengths_m):
        data.mocap_pos[0] = (0.0, 0.0, float(length))
        data.ctrl[0] = pressure_Pa
        for _ in range(max(1, int(round(settle_s / model.opt.timestep)))):
            mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        forces.append(load_cell_N(model, data))
    return np.asarray(forces)


def replay(recording, muscle: Muscle, effects=()) -> np.ndarray:
    """The stroke rig driven by a recording, sample by sample (:func:`replay_rig`, :func:`drive`):
    what the load cell reads at each sample (N, push positive), with ``effects`` switched on."""
    model, data = replay_rig(recording, muscle, effects)
    return drive(model, data, recording)


def replay_rig(recording, muscle: Muscle, effects=()) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The stroke rig ready to replay ``recording``: its control range passes every recorded
    pressure through (noise below zero gauge included, as the recording has it), and a filtered
    pressure (``pressure_lag``) starts at the first sample's, as ``effects.lag`` does."""
    P = np.asarray(recording.pressure_Pa, dtype=float)
    check_pressure_Pa(P, "rig.replay: recording.pressure_Pa")
    options = RigOptions(
        mode="stroke",
        effects=effects,
        min_pressure_Pa=-P_ATM,
        max_pressure_Pa=max(RigOptions.max_pressure_Pa, float(np.max(P))),
    )
    model, data = build_rig(muscle, options)
    if model.na:
        data.act[:] = P[0]
    for i in range(model.nu):
        if model.actuator_history[i, 0]:  # a delayed pressure: the line held at the first sample's
            n = int(model.actuator_history[i, 0])
            times = -model.opt.timestep * np.arange(n, 0, -1, dtype=float)
            mujoco.mj_initCtrlHistory(model, data, i, times.reshape(n, 1), np.full((n, 1), P[0]))
    return model, data


def drive(model: mujoco.MjModel, data: mujoco.MjData, recording, samples=None) -> np.ndarray:
    """Step a stroke rig through ``recording`` (or its ``samples``, a range of indices), one
    mj_step per sample: the plate (mocap) at the recorded length, the control at the recorded
    pressure, MuJoCo's time the recording's (from its first sample) and the step's timestep the
    interval since the previous sample -- what the plugin's effect states and a ``filterexact``
    pressure lag integrate over, as ``EffectModel.push_stepwise`` does. Returns the load-cell
    readings; each is read in the forward pass of its step, at that sample's inputs."""
    time = np.asarray(recording.time_s, dtype=float)
    if len(time) > 1 and not np.all(np.diff(time) > 0):
        raise ValueError("replay: the recording's time must increase strictly")
    t0 = float(time[0])
    sensor = model.sensor("load_cell").adr[0]
    indices = range(len(time)) if samples is None else samples
    out = np.empty(len(indices))
    for j, k in enumerate(indices):
        if k:
            model.opt.timestep = float(time[k] - time[k - 1])
        data.time = float(time[k]) - t0
        data.mocap_pos[0, 2] = recording.length_m[k]
        data.ctrl[0] = recording.pressure_Pa[k]
        mujoco.mj_step(model, data)
        out[j] = data.sensordata[sensor]
    return out + _zero_error(model)


def blocked_push(muscle: Muscle, pressure_Pa: float) -> float:
    """Load-cell force with the plate held at the resting length, push positive (the MuJoCo
    sign; ``Muscle.blocked_push`` is its analytic counterpart)."""
    return float(stroke_forces(muscle, pressure_Pa, [muscle.rest_length_m])[0])


def blocked_tension(muscle: Muscle, pressure_Pa: float) -> float:
    """As :func:`blocked_push` in the paper's sign (positive = pulls; ``Muscle.blocked_tension``)."""
    return -blocked_push(muscle, pressure_Pa)


def blocked_force(muscle: Muscle, pressure_Pa: float) -> float:
    """Deprecated: push positive (= :func:`blocked_push`), while ``Muscle.blocked_force`` was the
    paper sign; use ``blocked_push`` or ``blocked_tension``."""
    import warnings

    warnings.warn(
        "rig.blocked_force is push positive; use rig.blocked_push (same value) or rig.blocked_tension",
        DeprecationWarning,
        stacklevel=2,
    )
    return blocked_push(muscle, pressure_Pa)


def check_control_range(pressures_Pa, options: RigOptions = RigOptions(), what: str = "pressure_Pa") -> None:
    """Refuse pressures outside the rig's control range (MuJoCo would clamp them silently, and
    the analytic and MuJoCo columns would no longer use the same input); warn below 1000 Pa."""
    check_pressure_Pa(pressures_Pa, what, stacklevel=4)
    check_within(pressures_Pa, options.min_pressure_Pa, options.max_pressure_Pa, what=what, unit="Pa")


def _unsettled(muscle: Muscle, pressure_Pa: float, max_time_s: float) -> str:
    """Why the rig's plate did not come to rest, naming the muscle and what in it to check."""
    text = (
        f"muscle '{muscle.name}': the rig did not settle within {max_time_s:g} s at {pressure_Pa / 1e3:g} kPa"
    )
    theta = muscle.theta_rest_deg
    if not muscle.is_extensile:  # a geometry typed wrong turns an EFAM into a McKibben
        text += (
            f": its braid angle at rest is {theta:.1f} deg, above {NEUTRAL_BRAID_ANGLE_DEG:.2f} deg, so it "
            "contracts under pressure; check its geometry (sleeve diameter and length, units), or mark a "
            "contractile muscle tension_only"
        )
    return text


def equilibrium_length(
    muscle: Muscle,
    pressure_Pa: float,
    load_N: float = 0.0,
    max_time_s: float = 20.0,
    tol_m_per_s: float = 1e-7,
) -> float:
    """Let the plate settle under pressure (and a compressive load); return the muscle length.
    ``pressure_Pa`` in Pa, inside the rig's control range (else an error, never a clamp). A load
    the muscle cannot hold (MuJoCo's simulation blows up and resets) is an error, not the
    reset's resting length."""
    from .files import mujoco_warnings

    load_N = _finite(load_N, "equilibrium_length: load_N")
    max_time_s = _finite(max_time_s, "equilibrium_length: max_time_s", low=1e-3, unit=" s")
    tol_m_per_s = _finite(tol_m_per_s, "equilibrium_length: tol_m_per_s", low=1e-15, unit=" m/s")
    options = RigOptions(mode="loaded" if load_N else "free")
    check_control_range(pressure_Pa, options, "equilibrium_length: pressure_Pa")
    model, data = build_rig(muscle, options)
    data.ctrl[0] = pressure_Pa
    if load_N:
        data.ctrl[1] = load_N
    length = model.sensor("muscle_length").adr[0]
    steps_per_check = max(1, int(0.05 / model.opt.timestep))
    # a law infinitely stiff at zero strain (exponent, E3 < 1) keeps the plate in a limit cycle of
    # tens of nm about its rest: it never stops, but it has settled when, at the end, a window's
    # whole swing (and its drift from the window before) is under a millionth of the resting
    # length; only then, so that every other muscle still settles to the velocity tolerance
    still_m = 1e-6 * muscle.rest_length_m
    mid, previous_mid, swing = math.inf, math.inf, math.inf
    with mujoco_warnings() as warned:
        for _ in range(max(1, int(max_time_s / 0.05))):
            low, high = math.inf, -math.inf
            for _ in range(steps_per_check):
                mujoco.mj_step(model, data)
                low, high = min(low, data.qpos[0]), max(high, data.qpos[0])
            if warned:
                # with no load, a load is not the cause: the muscle's own constants are (a braid
                # angle near 90 deg, a diameter far from its length: the probe's muscles blamed a load)
                cause = (
                    f"under a load of {load_N:g} N (MuJoCo: {warned[0]}): more than the muscle can hold, or a "
                    "load in the wrong unit"
                    if load_N
                    else f"with no load (MuJoCo: {warned[0]}): the muscle's own constants give a force MuJoCo "
                    f"cannot integrate (braid angle {muscle.theta_rest_deg:.4g} deg, resting diameter "
                    f"{muscle.rest_diameter_m:.4g} m, length {muscle.rest_length_m:.4g} m: are they the muscle's?)"
                )
                raise RuntimeError(f"the rig went unstable at {pressure_Pa:g} Pa {cause}")
            if abs(data.qvel[0]) < tol_m_per_s and abs(data.qacc[0]) * 0.05 < tol_m_per_s:
                break
            previous_mid, mid, swing = mid, 0.5 * (low + high), high - low
        else:
            if not (swing < still_m and abs(mid - previous_mid) < still_m):
                raise RuntimeError(_unsettled(muscle, pressure_Pa, max_time_s))
    mujoco.mj_forward(model, data)
    return float(data.sensordata[length])


def free_extension(muscle: Muscle, pressure_Pa: float) -> float:
    """Free length change from MuJoCo, as a fraction of the resting length."""
    return equilibrium_length(muscle, pressure_Pa) / muscle.rest_length_m - 1.0


def write_models(folder: str = "models") -> list[str]:
    """Regenerate ``models/rig_<mode>_fam1.xml`` (a test checks they equal the builder's output)."""
    from pathlib import Path

    from .files import check_outputs, write_text_atomic
    from .musclefile import load_muscle

    muscle = load_muscle("FAM1")
    check_outputs({"folder": folder}, {})  # never into site-packages
    paths = []
    for mode in MODES:
        path = Path(folder) / f"rig_{mode}_fam1.xml"
        write_text_atomic(path, rig_xml(muscle, RigOptions(mode=mode)))
        paths.append(str(path))
    return paths


if __name__ == "__main__":
    print("\n".join(write_models()))
