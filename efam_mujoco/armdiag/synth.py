"""Blind test recordings: the arm model with one concealed effect, commands as a lab sends them.

The concealed effects are written here independently of the library (:mod:`efam_mujoco.armdiag.effects`,
:mod:`.replay`) and in other functional forms: a payload with an off-axis centre of mass added to
the tip body's inertia; a tilt as a rotated gravity and a rotated marker frame; hinge-only damping,
damping along the muscles (tendon damping) or a viscous medium; a second-order lag with a transport
delay; a leak through an orifice against the valve's flow (the pressure loss grows with the square root
of the pressure); a Dahl friction force in every muscle
(pre-sliding, rate-independent, applied as generalized forces through the muscles' own length
Jacobians, each muscle its own level); a one-way pneumatic coupling through a shared supply line
(the line follows one muscle's command with its own time constant and leaks into a neighbour's
valve through an orifice); a ball-jointed springy mount. Protocols: steps, ramps, sinusoids,
random sequences and a closed-loop tip controller; marker noise, dropouts in bursts, 30-200 Hz
sampling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .. import plugin
from .recording import ArmRecording

TRUTHS = (
    "none", "payload", "mount_tilt", "damping", "pressure_lag", "weak_muscle", "muscle_friction",
    "cross_talk", "compliant_mount",
)  # fmt: skip
PROTOCOLS = ("steps", "ramps", "sinusoids", "random", "closed_loop")
SETTLE_S = 3.0
#: rotational inertia of the springy mount's plate (kg m^2): with less, the stiff ball joint's own
#: mode outruns the arm's time step (the truth simulation blows up)
MOUNT_ARMATURE = 2e-3


@dataclass
class Truth:
    """The concealed effect of a recording: its name, parameters and the muscle it acts on."""

    name: str
    parameters: dict = field(default_factory=dict)
    muscle: str | None = None


def _commands(protocol, t, M, lo, hi, rng):
    """Open-loop commands (n, M), Pa."""
    n = len(t)
    if protocol == "steps":
        edges = np.cumsum(rng.uniform(0.8, 3.0, 64))
        levels = rng.uniform(lo, hi, (65, M))
        return levels[np.searchsorted(edges, t)]
    if protocol == "ramps":
        knots = np.concatenate([[0], np.cumsum(rng.uniform(1.0, 4.0, 64))])
        levels = rng.uniform(lo, hi, (65, M))
        return np.column_stack([np.interp(t, knots, levels[:, i]) for i in range(M)])
    if protocol == "sinusoids":
        f = rng.uniform(0.1, 1.2, M)
        ph = rng.uniform(0, 2 * np.pi, M)
        mid, amp = (lo + hi) / 2, (hi - lo) / 2 * rng.uniform(0.5, 1.0, M)
        return mid + amp * np.sin(2 * np.pi * f * t[:, None] + ph)
    if protocol == "random":  # band-limited random sequences (a random walk, reflected)
        steps = rng.normal(0, (hi - lo) * 0.08, (n, M)) * math.sqrt(max(t[1] - t[0], 1e-3) / 0.02)
        x = np.empty((n, M))
        x[0] = rng.uniform(lo, hi, M)
        for k in range(1, n):
            x[k] = x[k - 1] + steps[k]
            x[k] = np.where(x[k] > hi, 2 * hi - x[k], np.where(x[k] < lo, 2 * lo - x[k], x[k]))
        return x
    raise ValueError(protocol)


def _first_order(u, dt, tau):
    out = np.empty_like(u)
    a = 1 - math.exp(-dt / tau)
    y = u[0].copy()
    for k in range(len(u)):
        y = y + a * (u[k] - y)
        out[k] = y
    return out


def make_recording(spec: mujoco.MjSpec, truth: Truth, protocol: str, rng: np.random.Generator,
                   duration_s: float = 20.0, rate_Hz: float | None = None,
                   noise_m: float | None = None) -> ArmRecording:  # fmt: skip
    """One recording of the arm ``spec`` with ``truth`` concealed (see the module docstring)."""
    plugin.load()
    spec = spec.copy()
    muscles = [a.name for a in spec.actuators]
    M = len(muscles)
    tp = truth.parameters
    if truth.name == "compliant_mount":
        base = spec.body("base")
        base.add_joint(
            name="truth_ball",
            type=mujoco.mjtJoint.mjJNT_BALL,
            stiffness=tp["k"],
            damping=tp["c"],
            armature=MOUNT_ARMATURE,
        )
        if base.mass == 0:
            base.explicitinertial, base.mass, base.inertia = True, 5e-3, [1e-6] * 3
    model = spec.compile()
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)  # a diverging truth raises below
    data = mujoco.MjData(model)
    dt = model.opt.timestep
    rate = rate_Hz or float(rng.uniform(30, 200))
    noise = noise_m if noise_m is not None else float(rng.uniform(2e-4, 1e-3))
    n_settle = int(round(SETTLE_S / dt))
    n_run = int(round(duration_s / dt))
    t_step = np.arange(n_run) * dt
    hi_P = model.actuator_ctrlrange[:, 1]
    lo, hi = 0.1 * hi_P, 0.85 * hi_P
    t_samples = np.arange(0, duration_s - dt, 1.0 / rate)
    sample_of_step = np.searchsorted(t_samples, t_step + 1e-9, side="right") - 1
    rotation = np.eye(3)
    # -- concealed model edits
    if truth.name == "payload":
        b = model.nbody - 1
        m0, c0 = model.body_mass[b], model.body_ipos[b].copy()
        m, off = tp["mass_kg"], np.array([tp["offset_x_m"], tp["offset_y_m"], 0.01])
        com = (m0 * c0 + m * off) / (m0 + m)
        model.body_mass[b] = m0 + m
        model.body_ipos[b] = com
        model.body_inertia[b] = model.body_inertia[b] + m * 2e-4 + m * np.sum((off - com) ** 2) / 3
        mujoco.mj_setConst(model, data)
    elif truth.name == "mount_tilt":
        axis = np.array([math.cos(tp["azimuth_rad"]), math.sin(tp["azimuth_rad"]), 0.0])
        q = np.zeros(4)
        mujoco.mju_axisAngle2Quat(q, axis, tp["angle_rad"])
        r9 = np.zeros(9)
        mujoco.mju_quat2Mat(r9, q)
        rotation = r9.reshape(3, 3)
        model.opt.gravity[:] = rotation.T @ model.opt.gravity
    elif truth.name == "damping" and tp["form"] == "hinge":
        hinge = model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
        model.dof_damping[model.jnt_dofadr[hinge]] *= tp["factor"]
    elif truth.name == "damping" and tp["form"] == "tendon":  # viscous bladders: damping along each muscle
        model.tendon_damping[:] = tp["c_N_s_per_m"]
    elif truth.name == "muscle_friction":
        # each muscle's length Jacobian from its fixed tendon's joint coefficients
        muscle_jac = np.zeros((M, model.nv))
        for i, name in enumerate(muscles):
            t = model.tendon(name).id
            for w in range(model.tendon_adr[t], model.tendon_adr[t] + model.tendon_num[t]):
                muscle_jac[i, model.jnt_dofadr[model.wrap_objid[w]]] += model.wrap_prm[w]
        dahl_force = np.zeros(M)
        dahl_limit = tp["fc_N"] * np.asarray(tp["spread"])
    # -- commands (open loop now; closed loop inside the step loop)
    closed = protocol == "closed_loop"
    if not closed:
        cmd_samples = _commands(protocol, t_samples, M, lo, hi, rng)
    else:
        cmd_samples = np.tile((lo + hi) / 2, (len(t_samples), 1))
        targets_t = np.cumsum(rng.uniform(2.0, 4.0, 32))
        gain = tp_gain = rng.uniform(0.5, 1.5) * 2e6  # Pa per m of tip error (a P controller)
        del tp_gain
        angles = np.array([a for a in np.arange(M) * 2 * np.pi / M])
        target_xy = rng.uniform(-0.04, 0.04, (33, 2))
    tip_adr = model.sensor("tip_pos").adr[0]
    # settle under the first command
    mujoco.mj_resetData(model, data)
    tips = np.empty((n_run, 3))
    applied = np.empty((n_run, M))
    delay = int(round(tp.get("delay_s", 0.0) / dt))
    history = []
    lp_state = None
    drag_bodies = np.arange(2, model.nbody)
    measured_tip = None
    cmd_steps = np.empty((n_run, M))
    for k in range(-n_settle, n_run):
        s = sample_of_step[max(k, 0)]
        if closed and k > 0 and s >= 1 and sample_of_step[k - 1] != s:
            # the controller reads the (noisy) marker at its sample and commands the next pressures
            i_target = np.searchsorted(targets_t, t_samples[s])
            err = target_xy[i_target] - (measured_tip[:2] if measured_tip is not None else 0)
            push = -(err[0] * np.cos(angles) + err[1] * np.sin(angles))  # bend away from the high muscle
            cmd_samples[s] = np.clip((lo + hi) / 2 + gain * push, lo, hi)
        command = cmd_samples[max(s, 0)]
        cmd_steps[max(k, 0)] = command
        p = command.copy()
        if truth.name == "pressure_lag":
            idx = slice(None) if truth.muscle is None else muscles.index(truth.muscle)
            history.append(p.copy())
            delayed = history[max(0, len(history) - 1 - delay)]
            if lp_state is None:
                lp_state = [delayed.copy(), delayed.copy()]
            a = 1 - math.exp(-dt / (tp["tau_s"] / 2))
            lp_state[0] = lp_state[0] + a * (delayed - lp_state[0])
            lp_state[1] = lp_state[1] + a * (lp_state[0] - lp_state[1])
            p[idx] = lp_state[1][idx]
        elif truth.name == "weak_muscle":
            # orifice leak (flow ~ sqrt(P)) against the valve's flow (~ cmd - P): P = cmd - a sqrt(P);
            # the muscle's own pressure dynamics (the model's) follow
            i = muscles.index(truth.muscle)
            a = tp["leak_sqrt_Pa"]
            p[i] = ((-a + math.sqrt(a * a + 4 * command[i])) / 2) ** 2
        elif truth.name == "cross_talk":
            # a supply line shared with muscle `from` follows its command (own time constant) and
            # leaks into muscle `to`'s valve through an orifice (flow ~ sqrt of the pressure difference)
            i, j = muscles.index(tp["to"]), muscles.index(tp["from"])
            if lp_state is None:
                lp_state = command[j]
            lp_state += (1 - math.exp(-dt / tp["tau_line_s"])) * (command[j] - lp_state)
            gap = lp_state - command[i]
            p[i] = command[i] + tp["c"] * math.copysign(math.sqrt(abs(gap) * tp["ref_Pa"]), gap)
        data.ctrl[:] = np.clip(p, 0, hi_P)
        if k == -n_settle:
            data.act[:] = data.ctrl
        if truth.name == "damping" and tp["form"] == "medium":  # a viscous medium (linear drag on the disks)
            data.xfrc_applied[:] = 0
            for b in drag_bodies:
                v = np.zeros(6)
                mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, b, v, 0)
                lin = v[3:]
                data.xfrc_applied[b, :3] = -tp["c_N_s_per_m"] * lin
        if truth.name == "muscle_friction":  # Dahl: dF/dx = (Fc / x_slip) (1 - F/Fc sgn(dx)), exact per step
            dx = muscle_jac @ data.qvel * dt
            target = np.sign(dx) * dahl_limit
            dahl_force = target + (dahl_force - target) * np.exp(-np.abs(dx) / tp["slip_m"])
            data.qfrc_applied[:] = -muscle_jac.T @ dahl_force
        mujoco.mj_step(model, data)
        if k >= 0:
            tips[k] = rotation @ data.sensordata[tip_adr : tip_adr + 3]
            applied[k] = p
            if closed and s >= 0:
                measured_tip = tips[k] + rng.normal(0, noise, 3)
        if not np.all(np.isfinite(data.qpos)):
            raise FloatingPointError(f"truth simulation diverged ({truth})")
    pick = np.clip(np.round(t_samples / dt).astype(int), 0, n_run - 1)
    tip = tips[pick] + rng.normal(0, noise, (len(t_samples), 3))
    # dropouts in bursts (occlusions): about 1-4 % of the samples
    n = len(t_samples)
    for _ in range(int(rng.integers(1, 6))):
        start = int(rng.integers(0, n))
        tip[start : start + int(rng.integers(1, max(2, n // 60)))] = np.nan
    commands = cmd_samples  # what was sent at each sample (the controller filled it in as it ran)
    meta = {"truth": truth.name, "truth_parameters": truth.parameters, "truth_muscle": truth.muscle,
            "protocol": protocol, "rate_Hz": rate, "noise_m": noise}  # fmt: skip
    return ArmRecording(t_samples, muscles, commands, tip, meta=meta)


def random_truth(name: str, muscles: list[str], rng: np.random.Generator, max_Pa: float = 517e3) -> Truth:
    """A concealed effect of random magnitude (magnitudes a lab would notice, not beyond);
    ``max_Pa``: the muscles' top of range (sets the leak and coupling scales)."""
    groups: dict[str, list[str]] = {}
    for m in muscles:
        groups.setdefault(m.split("m")[0], []).append(m)
    if name == "none":
        return Truth("none")
    if name == "payload":
        return Truth(name, {"mass_kg": float(rng.uniform(0.03, 0.25)), "offset_x_m": float(rng.uniform(-0.02, 0.02)),
                            "offset_y_m": float(rng.uniform(-0.02, 0.02))})  # fmt: skip
    if name == "mount_tilt":
        return Truth(
            name,
            {
                "angle_rad": math.radians(rng.uniform(2.0, 8.0)),
                "azimuth_rad": float(rng.uniform(0, 2 * np.pi)),
            },
        )
    if name == "damping":
        form = str(rng.choice(["hinge", "tendon", "medium"]))
        if form == "hinge":
            return Truth(name, {"form": form, "factor": float(rng.uniform(3.0, 12.0))})
        if form == "tendon":
            return Truth(name, {"form": form, "c_N_s_per_m": float(rng.uniform(20.0, 100.0))})
        return Truth(name, {"form": form, "c_N_s_per_m": float(rng.uniform(0.5, 3.0))})
    if name == "pressure_lag":
        muscle = None if rng.random() < 0.3 else str(rng.choice(muscles))
        return Truth(
            name, {"tau_s": float(rng.uniform(0.15, 0.6)), "delay_s": float(rng.uniform(0.02, 0.06))}, muscle
        )
    if name == "weak_muscle":
        loss = float(rng.uniform(0.12, 0.4))  # pressure lost at half the range
        half = 0.5 * max_Pa
        return Truth(
            name,
            {"leak_sqrt_Pa": loss * half / math.sqrt((1 - loss) * half), "loss_at_half_range": loss},
            str(rng.choice(muscles)),
        )  # fmt: skip
    if name == "muscle_friction":
        return Truth(
            name,
            {"fc_N": float(rng.uniform(0.6, 3.0)), "spread": [float(x) for x in rng.uniform(0.7, 1.3, len(muscles))],
             "slip_m": float(rng.uniform(2e-4, 1e-3))},
        )  # fmt: skip
    if name == "cross_talk":
        group = groups[str(rng.choice(list(groups)))]
        to, frm = rng.choice(group, 2, replace=False)
        return Truth(
            name,
            {"c": float(rng.uniform(0.15, 0.4)), "to": str(to), "from": str(frm),
             "tau_line_s": float(rng.uniform(0.05, 0.3)), "ref_Pa": 0.2 * max_Pa},
            str(to),
        )  # fmt: skip
    if name == "compliant_mount":
        return Truth(name, {"k": float(rng.uniform(15.0, 200.0)), "c": float(rng.uniform(0.05, 1.0))})
    raise ValueError(name)
