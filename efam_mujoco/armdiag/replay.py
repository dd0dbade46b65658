"""Replay a recording's commands in MuJoCo, for many model variants at once (``mujoco.rollout``).

A model variant is the arm model plus a :class:`Knobs` setting: the calibration the model already
has (per-muscle pressure gain and offset, damping, pressure lag) and the effect terms of the
library (tip payload, base tilt, compliant mount, muscle friction, pressure cross-talk). Every
knob is applied as a post-build edit of the :class:`mujoco.MjSpec` (a body, a joint, a quaternion,
joint friction, damping, ``dynprm``) or as the command-to-ctrl map, so the arm builder's
internals are never touched.

Muscle friction, two forms. The plugin refuses effect terms on segmented muscles (the default
physical arm), so there the muscle's dry friction force ``f0`` is put on the muscle itself, as
MuJoCo's dry friction of the muscle's whole-length tendon (``frictionloss = f0`` on tendon
``s{j}m{i}``, the fixed tendon whose length is the muscle's): the friction force acts along the
muscle, through its own length Jacobian, on every joint it spans, whatever the number of disks D.
MuJoCo's frictionloss is a dry-friction constraint, made near-hard (``solimpfriction`` 0.9999,
``solreffriction`` two time steps) because at MuJoCo's default impedance the light links creep
through it (the soft default fits a friction recording no better than no friction). An earlier
form put ``f0 sum_i |dL_i/dq|`` on every joint separately; it fits worse (each joint sticks on
its own, while a muscle's friction couples the joints it spans). Only an unsegmented model (one
tendon per muscle, ``mode="pcc"`` or a plain MJCF) gets the plugin's muscle-level friction term,
config keys ``effects=friction, friction.f0_N``. ``Replayer.tips`` rolls a batch of variants out in one call
(threads where there are cores) and returns the tip at the recording's sample times.

Timing: the arm starts at rest under the first command (``settle_s`` of simulated time at the
first row before t0); commands are held from one sample to the next (zero-order hold, as a valve
controller sends them); sample k is compared with the tip at the step that starts at its time.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
from mujoco import rollout

from .. import plugin

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
#: custom numerics that carry the command map in an MJCF (per muscle; mix: one value)
CTRL_GAIN, CTRL_OFFSET, CTRL_MIX = "efam_ctrl_gain", "efam_ctrl_offset_Pa", "efam_ctrl_mix"
#: one-way couplings in an MJCF: (receiving muscle index, source muscle index, c) triples, flattened
CTRL_COUPLING = "efam_ctrl_coupling"
#: friction term lifted from the muscle level: a fixed pre-sliding strain, a fitted amplitude; the
#: arm's strokes slide it (no pressure slip, no relaxation)
FRICTION_SLIP_STRAIN = 3e-3
#: impedance of the tendon form of muscle friction: MuJoCo's default soft frictionloss lets the light
#: links creep through it within a few steps (no visible friction), so it is made near-hard
FRICTION_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
FRICTION_SOLREF_STEPS = 2.0  # solref time constant, in time steps (the stiffest MuJoCo advises)
#: a replayed tip farther than this from the origin (m) has diverged; diverged variants get
#: FAILED_TIP_M everywhere, so that they fit nothing
UNSTABLE_M, FAILED_TIP_M = 100.0, 1e3
#: joint speed (m/s or rad/s) no arm reaches under pressure: beyond it a variant has diverged
UNSTABLE_SPEED = 1e4
#: simulated time at the first command before the recording's first sample, s (the arm at rest)
SETTLE_S = 3.0
#: rotational inertia of the compliant mount's hinges (kg m^2, a mount plate): less lets the
#: stiffer mounts of the search range outrun the time step
MOUNT_ARMATURE = 1e-3


@dataclass(frozen=True)
class Knobs:
    """Everything a variant changes, SI. ``None`` arrays mean 'as the model has it'."""

    gain: tuple = ()  # per muscle, effective pressure = gain * mixed command - offset
    offset_Pa: tuple = ()  # per muscle
    cross_talk: float = 0.0  # mixed_i = (1 - c) p_i + c mean(p_j, j neighbours in the section)
    coupling: tuple = ()  # one-way leaks (i, j, c): mixed_i += c (p_j - p_i), after the mixing above
    lag_s: tuple = ()  # per muscle pressure time constant (filterexact)
    damping_axial: float = 1.0  # multiplier on the slide joints' damping
    damping_bend: float = 1.0  # multiplier on the hinge joints' damping
    medium_viscosity_Pa_s: float = 0.0  # MuJoCo's fluid model (inertia boxes) in a viscous medium
    payload_kg: float = 0.0
    tilt_rad: tuple = (0.0, 0.0)  # base turned about the world x, then y axis
    mount_stiffness_N_m_per_rad: float = 0.0  # 0: rigid mount
    mount_damping_N_m_s_per_rad: float = 0.0
    friction_N: float = 0.0  # muscle dry friction f0 on every muscle (joint or plugin form)

    def structure(self) -> tuple:
        """Variants with the same structure can share one rollout batch."""
        return (self.payload_kg > 0, self.mount_stiffness_N_m_per_rad > 0, self.friction_N > 0)


def sections_of(muscles: list[str]) -> list[list[int]]:
    """Muscle indices grouped by section (names ``s{j}m{i}``; any other naming: one group)."""
    groups: dict[str, list[int]] = {}
    for i, name in enumerate(muscles):
        m = re.fullmatch(r"(s\d+)m\d+", name)
        groups.setdefault(m.group(1) if m else "all", []).append(i)
    return list(groups.values())


@dataclass
class Replayer:
    """Replays one recording's commands on variants of one arm model."""

    spec: mujoco.MjSpec
    time_s: np.ndarray
    command_Pa: np.ndarray
    settle_s: float = SETTLE_S
    threads: int = 1
    muscles: list[str] = field(init=False)
    nominal: Knobs = field(init=False)

    def __post_init__(self):
        plugin.load()
        self.spec = self.spec.copy()
        for act in self.spec.actuators:  # every muscle gets a pressure state (lag ~0 if it had none)
            if act.dyntype == mujoco.mjtDyn.mjDYN_NONE:
                act.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
                act.dynprm[0] = 1e-4
                act.actdim = 1
        self.muscles = [a.name for a in self.spec.actuators]
        self.groups = sections_of(self.muscles)
        base = self.spec.compile()
        self.dt = float(base.opt.timestep)
        self.max_Pa = base.actuator_ctrlrange[:, 1].copy()
        self._damping0 = {j.name: j.damping for j in self.spec.joints}
        self.segmented = any(
            int(float(dict(p.config).get("segments", 1))) > 1
            for p in self.spec.plugins
            if p.plugin_name == plugin.PLUGIN_NAME
        )
        self.nominal = Knobs(
            gain=(1.0,) * base.nu, offset_Pa=(0.0,) * base.nu, lag_s=tuple(base.actuator_dynprm[:, 0])
        )
        stored = {n.name: list(n.data) for n in self.spec.numerics}  # a command map written with the model
        if CTRL_GAIN in stored:
            self.nominal = with_values(
                self.nominal, gain=stored[CTRL_GAIN], offset_Pa=stored.get(CTRL_OFFSET, [0.0] * base.nu),
                cross_talk=float(stored.get(CTRL_MIX, [0.0])[0]),
            )  # fmt: skip
        if CTRL_COUPLING in stored:
            flat = stored[CTRL_COUPLING]
            self.nominal = with_values(
                self.nominal,
                coupling=tuple(
                    (int(flat[n]), int(flat[n + 1]), float(flat[n + 2])) for n in range(0, len(flat), 3)
                ),
            )
        t0 = self.time_s[0]
        self.n_settle = int(round(self.settle_s / self.dt))
        n_run = int(math.floor((self.time_s[-1] - t0) / self.dt)) + 1
        grid = t0 + self.dt * np.arange(n_run)
        held = np.searchsorted(self.time_s, grid + 1e-9, side="right") - 1
        self.step_command = np.vstack(
            [np.repeat(self.command_Pa[:1], self.n_settle, 0), self.command_Pa[held]]
        )
        self.sample_step = self.n_settle + np.minimum(
            np.round((self.time_s - t0) / self.dt).astype(int), n_run - 1
        )
        self._datas = None
        self.rollouts = 0
        self.simulated_s = 0.0  # simulated time over all rollouts (settling included), s
        self.unstable = 0  # variants that diverged (scored as failed, never printed)
        self.warnings = 0  # MuJoCo warnings caught during the rollouts
        self._cut_from: Replayer | None = None  # a head's whole replayer: counts there too
        self._heads: dict[int, Replayer] = {}

    def head(self, until_s: float) -> Replayer:
        """The same replayer on the recording's rows up to ``until_s`` after its start (a
        shorter, cheaper replay for screening; ``self`` when that is the whole recording). Built
        once per length; its rollouts count in this replayer's counters too."""
        n = int(np.searchsorted(self.time_s, self.time_s[0] + until_s, side="right"))
        if n >= len(self.time_s):
            return self
        if n not in self._heads:
            head = Replayer(self.spec, self.time_s[:n], self.command_Pa[:n], self.settle_s, self.threads)
            head._cut_from = self
            self._heads[n] = head
        return self._heads[n]

    def _count(self, rollouts: int, simulated_s: float, unstable: int, warnings: int) -> None:
        """Add to the rollout counters, here and in the replayer this one was cut from."""
        self.rollouts += rollouts
        self.simulated_s += simulated_s
        self.unstable += unstable
        self.warnings += warnings
        if self._cut_from is not None:
            self._cut_from._count(rollouts, simulated_s, unstable, warnings)

    # ------------------------------------------------------------------ variants as models

    def edited_spec(self, k: Knobs) -> mujoco.MjSpec:
        """The arm model with ``k``'s model terms switched on (the command map is separate)."""
        spec = self.spec.copy()
        base = spec.body("base")
        for j in spec.joints:
            if j.type == mujoco.mjtJoint.mjJNT_SLIDE:
                j.damping = self._damping0[j.name] * k.damping_axial
            elif j.type == mujoco.mjtJoint.mjJNT_HINGE:
                j.damping = self._damping0[j.name] * k.damping_bend
        if k.medium_viscosity_Pa_s > 0:
            spec.option.viscosity = k.medium_viscosity_Pa_s
        for act, tau in zip(spec.actuators, k.lag_s):
            act.dynprm[0] = tau
        if any(k.tilt_rad):
            q = np.zeros(4)
            qx = np.array([math.cos(k.tilt_rad[0] / 2), math.sin(k.tilt_rad[0] / 2), 0, 0])
            qy = np.array([math.cos(k.tilt_rad[1] / 2), 0, math.sin(k.tilt_rad[1] / 2), 0])
            mujoco.mju_mulQuat(q, qy, qx)
            out = np.zeros(4)
            mujoco.mju_mulQuat(out, q, np.asarray(base.quat, float))
            base.quat = out
        if k.payload_kg > 0:
            tip_body = next(b for b in spec.bodies if "tip" in [s.name for s in b.sites])
            tip = next(s for s in tip_body.sites if s.name == "tip")
            r = 0.015
            # the mass on the geom (not an explicit <inertial>) so that it survives the MJCF round trip
            load = tip_body.add_body(name="payload", pos=list(tip.pos))
            load.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0], contype=0, conaffinity=0,
                          group=2, mass=k.payload_kg)  # fmt: skip
        if k.mount_stiffness_N_m_per_rad > 0:
            for name, axis in (("mount_x", [1, 0, 0]), ("mount_y", [0, 1, 0])):
                base.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                               stiffness=k.mount_stiffness_N_m_per_rad,
                               damping=k.mount_damping_N_m_s_per_rad, armature=MOUNT_ARMATURE)  # fmt: skip
            base.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.005, 0, 0], contype=0, conaffinity=0,
                          group=2, mass=1e-3)  # fmt: skip
        if k.friction_N > 0 and self.segmented:
            for t in spec.tendons:
                if t.name in self.muscles:  # the whole muscle's tendon (its length = the muscle's)
                    t.frictionloss = k.friction_N
                    t.solref_friction = [FRICTION_SOLREF_STEPS * self.dt, 1.0]
                    t.solimp_friction = list(FRICTION_SOLIMP)
        elif k.friction_N > 0:
            for instance in spec.plugins:
                if instance.plugin_name == plugin.PLUGIN_NAME:
                    cfg = dict(instance.config)
                    cfg.update(plugin.effects_config([("friction", self.friction_values(k.friction_N))]))
                    instance.config = cfg
        return spec

    @staticmethod
    def friction_values(f0_N: float) -> dict:
        """The plugin's friction config (unsegmented muscles): amplitude f0, a fixed slip strain."""
        return {"f0_N": f0_N, "f1_N_per_MPa": 0.0, "slip_strain": FRICTION_SLIP_STRAIN,
                "slip_kPa": 0.0, "relax_per_s": 0.0}  # fmt: skip

    def model_with(self, k: Knobs) -> mujoco.MjSpec:
        """``edited_spec(k)`` plus ``k``'s command map stored as custom numerics (an MJCF that a
        :class:`Replayer` replays as it was identified)."""
        spec = self.edited_spec(k)
        for n in list(spec.numerics):
            if n.name in (CTRL_GAIN, CTRL_OFFSET, CTRL_MIX, CTRL_COUPLING):
                spec.delete(n)
        spec.add_numeric(name=CTRL_GAIN, data=list(k.gain), size=len(k.gain))
        spec.add_numeric(name=CTRL_OFFSET, data=list(k.offset_Pa), size=len(k.offset_Pa))
        spec.add_numeric(name=CTRL_MIX, data=[k.cross_talk], size=1)
        if k.coupling:
            flat = [float(x) for triple in k.coupling for x in triple]
            spec.add_numeric(name=CTRL_COUPLING, data=flat, size=len(flat))
        return spec

    def controls(self, k: Knobs, command_Pa: np.ndarray | None = None) -> np.ndarray:
        """Commands -> ctrl (effective pressures, Pa) through ``k``'s command map."""
        p = self.step_command if command_Pa is None else command_Pa
        mixed = p.copy()
        if k.cross_talk:
            for group in self.groups:
                if len(group) > 1:
                    sub = p[:, group]
                    others = (sub.sum(1, keepdims=True) - sub) / (len(group) - 1)
                    mixed[:, group] = (1 - k.cross_talk) * sub + k.cross_talk * others
        for i, j, c in k.coupling:
            mixed[:, i] += c * (p[:, j] - p[:, i])
        out = np.asarray(k.gain) * mixed - np.asarray(k.offset_Pa)
        return np.clip(out, 0.0, self.max_Pa)

    # ------------------------------------------------------------------------- rolling out

    def tips(self, variants: list[Knobs], command_Pa: np.ndarray | None = None, samples=None) -> np.ndarray:
        """Tip positions (variants, samples, 3) at the recording's sample times (or every step
        of ``command_Pa`` when given, then ``samples`` picks steps)."""
        out = [None] * len(variants)
        by_structure: dict[tuple, list[int]] = {}
        for i, k in enumerate(variants):
            by_structure.setdefault(k.structure(), []).append(i)
        for idx in by_structure.values():
            models = [self.edited_spec(variants[i]).compile() for i in idx]
            ctrl = np.stack([self.controls(variants[i], command_Pa) for i in idx])
            tip = self._rollout(models, ctrl)
            pick = (
                self.sample_step if command_Pa is None else (samples if samples is not None else slice(None))
            )
            for n, i in enumerate(idx):
                out[i] = tip[n][pick]
        return np.stack(out)

    def _rollout(self, models, ctrl) -> np.ndarray:
        for m in models:  # an unstable variant keeps its NaNs (no silent reset to the rest pose)
            m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        m0 = models[0]
        datas = [mujoco.MjData(m0) for _ in range(max(1, min(self.threads, len(models))))]
        init = np.empty((len(models), mujoco.mj_stateSize(m0, _STATE)))
        for n, m in enumerate(models):
            d = datas[0]
            mujoco.mj_resetData(m, d)
            d.act[:] = ctrl[n, 0][m.actuator_actadr >= 0] if m.na == m.nu else d.act
            mujoco.mj_getState(m, d, init[n], _STATE)
        adr = m0.sensor("tip_pos").adr[0]
        with _quiet_warnings() as caught:
            state, sensordata = rollout.rollout(models, datas, init, ctrl, persistent_pool=False)
        tips = sensordata[:, :, adr : adr + 3].copy()
        bad = ~np.all(np.isfinite(tips) & (np.abs(tips) < UNSTABLE_M), axis=(1, 2))
        # a diverged arm can keep a bounded, frozen tip (its angles wrap, its sensors stop
        # updating once MuJoCo flags the bad accelerations): judge the joint speeds too
        # (FULLPHYSICS state = time, qpos, qvel, ...)
        speeds = state[:, :, 1 + m0.nq : 1 + m0.nq + m0.nv]
        bad |= ~np.all(np.isfinite(speeds) & (np.abs(speeds) < UNSTABLE_SPEED), axis=(1, 2))
        tips[bad] = FAILED_TIP_M  # a variant that blew up fits nothing: scored as a failed candidate
        self._count(len(models), len(models) * ctrl.shape[1] * self.dt, int(bad.sum()), len(caught))
        return tips


@contextlib.contextmanager
def _quiet_warnings():
    """MuJoCo's warnings (an unstable candidate's "Nan, Inf or huge value in QACC") collected
    instead of printed; the previous handler is restored afterwards."""
    caught: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(caught.append)
    try:
        yield caught
    finally:
        mujoco.set_mju_user_warning(previous)


def with_values(k: Knobs, **changes) -> Knobs:
    """``k`` with some knobs changed (tuples for per-muscle knobs)."""
    return replace(
        k, **{key: tuple(v) if isinstance(v, (list, np.ndarray)) else v for key, v in changes.items()}
    )


def default_threads() -> int:
    """Threads for the rollouts: the cores this process may use (at most 8)."""
    try:
        return max(1, min(8, len(os.sched_getaffinity(0))))
    except AttributeError:
        return max(1, min(8, os.cpu_count() or 1))
