"""Everything the suite needs from the arm builder and its statics, in one place.

The suite acts on whatever arm :mod:`efam_mujoco.arm` builds. It relies on this much of it:

* ``arm.ArmSpec``, ``arm.SectionSpec``, ``arm.paper_section`` (the domains' arms), with the
  fields ``sections``, ``orientation``, ``pressure_tau_s``, ``max_pressure_Pa``, ``gravity``,
  ``timestep_s``, ``payload_kg``, ``name`` and, per section, ``muscles``, ``radius_m``,
  ``angles_rad``, ``disks``;
* ``arm.build_spec(spec) -> mujoco.MjSpec`` whose model has a fixed body ``base`` (z along the
  first section), per section j the disk bodies ``s{j}d{k}`` (k = 1..D, the last is the section's
  end plate), a site ``tip`` with sensor ``tip_pos``, and one actuator and one tendon per muscle,
  named by ``arm.muscle_names(spec)``, ctrl = gauge pressure in Pa, ctrlrange [0, rated];
* the pressure convention of ``arm.muscle_pressures(model, data)`` (activation = pressure),
  ``arm.ORIENTATIONS``;
* the continuum reference ``arm.solve_arm_spec(spec, pressures, tip_force_N=)`` (the arm's own
  weight, its payload and orientation) returning ``tip_position_m`` (base frame) and per
  section ``arc_length_m``, ``curvature_xy_per_m``: the reference the controllers invert, and
  ``statics.cc_frame`` (the unloaded arc).

Nothing here reads a joint name, so the joint structure inside the sections does not touch the
suite.
"""

from __future__ import annotations

import contextlib
import functools
import math
import re
import warnings
from dataclasses import replace

import mujoco
import numpy as np

from .. import arm as arm_builder
from .. import plugin, statics
from ..arm import timestep as arm_timestep

#: the paper's muscle preset every domain is built from
DOMAIN_MUSCLE = "FAM1"
#: spacer disks per section of the suite's domains: fewer than the arm's default (16) for
#: throughput; the tip error this costs against the continuum reference is in docs/suite.md
DOMAIN_DISKS = 4
#: physics step of the suite's domains, s: the suite's own choice (its control rates, rewards and
#: measured throughput are set at it), kept explicit whatever the builder derives (today also
#: 1 ms for these damped arms); stable thanks to the bundle's damping (the undamped arm's limit
#: at D = 4 is 0.37 ms)
DOMAIN_TIMESTEP_S = 1e-3


def bundle_spec(**overrides) -> arm_builder.ArmSpec:
    """One section of three FAM1 muscles at the default radius, upright (the ``bundle`` domain);
    ``disks`` (default :data:`DOMAIN_DISKS`) and any ``ArmSpec`` field can be overridden."""
    disks = overrides.pop("disks", DOMAIN_DISKS)
    options = {"orientation": "upright", "name": "efam_bundle", "timestep_s": DOMAIN_TIMESTEP_S}
    options.update(overrides)
    section = arm_builder.paper_section(disks=disks, muscle=DOMAIN_MUSCLE)
    return arm_builder.ArmSpec(sections=(section,), **options)


def arm_spec(**overrides) -> arm_builder.ArmSpec:
    """Three sections of three FAM1 muscles, hanging (the ``arm`` domain; upright it buckles
    under its own weight at low pressure); ``disks`` (default :data:`DOMAIN_DISKS`) and any
    ``ArmSpec`` field can be overridden."""
    disks = overrides.pop("disks", DOMAIN_DISKS)
    options = {"orientation": "hanging", "name": "efam_arm", "timestep_s": DOMAIN_TIMESTEP_S}
    options.update(overrides)
    section = arm_builder.paper_section(disks=disks, muscle=DOMAIN_MUSCLE)
    return arm_builder.ArmSpec(sections=(section,) * 3, **options)


def build_arm_spec(spec: arm_builder.ArmSpec) -> mujoco.MjSpec:
    """The builder's editable model of ``spec`` (plugin loaded), for the suite to add its scene."""
    plugin.load()
    with _domain_timestep():
        return arm_builder.build_spec(replace(spec, payload_kg=0.0))


@contextlib.contextmanager
def _domain_timestep():
    """Silence the builder's warning about :data:`DOMAIN_TIMESTEP_S` (a deliberate choice above
    the undamped arm's limit, stable with the damping; a step the damped arm cannot take is
    still refused)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", arm_timestep.TimestepWarning)
        yield


def muscle_names(spec: arm_builder.ArmSpec) -> list[str]:
    """Actuator (and tendon) names of all muscles, base section first."""
    return [name for section in arm_builder.muscle_names(spec) for name in section]


def muscle_pressures_Pa(act_adr, act, ctrl, rated_Pa) -> np.ndarray:
    """The pressure each muscle acts with, Pa, in actuator order: as
    ``arm.muscle_pressures(model, data)`` (the activation of an actuator with pressure
    dynamics, else its ctrl clamped to [0, rated]), vectorised for a per-step observation."""
    out = np.clip(ctrl, 0.0, rated_Pa)
    lagged = act_adr >= 0
    out[lagged] = act[act_adr[lagged]]
    return out


def base_quaternion(spec: arm_builder.ArmSpec) -> np.ndarray:
    """Orientation (w, x, y, z) of the arm's base frame in the world."""
    return np.asarray(arm_builder.ORIENTATIONS[spec.orientation], dtype=float)


def rest_length_m(spec: arm_builder.ArmSpec) -> float:
    """The arm's length at rest (sum of its sections' muscle rest lengths)."""
    return float(sum(section.rest_length_m for section in spec.sections))


def section_muscles(spec: arm_builder.ArmSpec):
    """Per section: (muscles, radii (M,), angles (M,) in rad)."""
    out = []
    for section in spec.sections:
        angles = np.asarray(section.angles_rad, dtype=float)
        radii = np.full(angles.shape, float(section.radius_m))
        out.append((tuple(section.muscles), radii, angles))
    return out


# ---------------------------------------------------------------- the reference (statics)


class _Statics:
    """The domain's own MuJoCo model held at rest: settle, then Newton on qpos (finite-difference
    stiffness) until the net generalized force vanishes. Warm-started from the last equilibrium
    (the inverse statics probes nearby pressures)."""

    def __init__(self, spec: arm_builder.ArmSpec):
        plugin.load()
        with _domain_timestep():
            self.model = arm_builder.build_model(replace(spec, payload_kg=0.0))
        self.data = mujoco.MjData(self.model)
        self.lagged = np.flatnonzero(self.model.actuator_actadr >= 0)
        self.tip_site = self.model.site("tip").id
        self.tip_body = self.model.site_bodyid[self.tip_site]
        self.base = self.model.body("base").id
        self.chains = section_body_chains(self.model)
        self.warm: np.ndarray | None = None

    def _residual(self, qpos, applied):
        m, d = self.model, self.data
        d.qpos[:] = qpos
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        return d.qfrc_passive + d.qfrc_actuator - d.qfrc_bias + applied

    def _applied(self, force_world):
        d = self.data
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)
        out = np.zeros(self.model.nv)
        if np.any(force_world):
            point = d.site_xpos[self.tip_site].copy()
            mujoco.mj_applyFT(self.model, d, force_world, np.zeros(3), point, self.tip_body, out)
        return out

    def solve(self, pressures_Pa, force_base, warm: bool = False, settle_s: float = 1.5, tol_N: float = 1e-8):
        """Rest state under ``pressures_Pa`` and a tip force (base frame), from rest (or with
        ``warm`` from the last rest state found); returns whether the Newton iteration converged
        (the state is left in ``self.data``)."""
        m, d = self.model, self.data
        if not warm:
            self.warm = None
        d.ctrl[:] = pressures_Pa
        d.act[m.actuator_actadr[self.lagged]] = d.ctrl[self.lagged]
        R = d.xmat[self.base].reshape(3, 3) if self.warm is not None else None
        if self.warm is None:
            mujoco.mj_resetData(m, d)
            d.ctrl[:] = pressures_Pa
            d.act[m.actuator_actadr[self.lagged]] = d.ctrl[self.lagged]
            mujoco.mj_forward(m, d)
            R = d.xmat[self.base].reshape(3, 3).copy()
        force_world = R @ np.asarray(force_base, dtype=float)
        q = self.data.qpos.copy() if self.warm is None else self.warm.copy()
        if self.warm is None:
            self._settle(settle_s, force_world)
            q = d.qpos.copy()
        converged = self._newton(q, force_world, tol_N)
        if not converged:  # far from the last rest state: settle from rest and try again
            mujoco.mj_resetData(m, d)
            d.ctrl[:] = pressures_Pa
            d.act[m.actuator_actadr[self.lagged]] = d.ctrl[self.lagged]
            self._settle(settle_s, force_world)
            converged = self._newton(d.qpos.copy(), force_world, tol_N)
        self.warm = d.qpos.copy() if converged else None
        return converged

    def _settle(self, seconds, force_world):
        m, d = self.model, self.data
        for _ in range(int(round(seconds / m.opt.timestep))):
            d.qfrc_applied[:] = self._applied(force_world)
            mujoco.mj_step(m, d)
        if not np.all(np.isfinite(d.qpos)):
            raise FloatingPointError("suite statics: the arm's state is not finite while settling")

    def _newton(self, q, force_world, tol_N, iterations: int = 30):
        m = self.model
        self.data.qpos[:] = q
        applied = self._applied(force_world)
        r = self._residual(q, applied)
        h = 1e-7
        for _ in range(iterations):
            if np.max(np.abs(r)) < tol_N:
                break
            K = np.empty((m.nv, m.nv))
            for i in range(m.nv):
                probe = q.copy()
                probe[i] += h
                self.data.qpos[:] = probe
                K[:, i] = (self._residual(probe, self._applied(force_world)) - r) / h
            step = np.linalg.lstsq(K, -r, rcond=None)[0]
            for scale in (1.0, 0.5, 0.25, 0.1, 0.03):
                trial_q = q + scale * step
                self.data.qpos[:] = trial_q
                trial = self._residual(trial_q, self._applied(force_world))
                if np.linalg.norm(trial) < np.linalg.norm(r):
                    q, r = trial_q, trial
                    break
            else:
                break
        self.data.qpos[:] = q
        self._residual(q, self._applied(force_world))
        return bool(np.max(np.abs(r)) < tol_N)

    def tip_and_lengths(self):
        """Tip (base frame) and section backbone lengths of the current state."""
        d = self.data
        p0, R0 = d.xpos[self.base], d.xmat[self.base].reshape(3, 3)
        tip = R0.T @ (d.site_xpos[self.tip_site] - p0)
        return tip, np.array(backbone_lengths(d.xpos.tolist(), self.chains))


_DISK_BODY = re.compile(r"^s(\d+)d(\d+)$")


def section_chains(body_names) -> list[list[str]]:
    """Per section, the names of the bodies along its backbone: its base plate (the arm's
    ``base`` or the previous section's end plate), then its disks ``s{j}d{k}`` in order."""
    disks: dict[int, dict[int, str]] = {}
    for name in body_names:
        match = _DISK_BODY.match(name or "")
        if match:
            disks.setdefault(int(match[1]), {})[int(match[2])] = name
    if not disks:
        raise ValueError("model: no disk bodies named s{j}d{k}")
    chains, start = [], "base"
    for j in sorted(disks):
        chains.append([start] + [disks[j][k] for k in sorted(disks[j])])
        start = chains[-1][-1]
    return chains


def section_body_chains(model) -> list[list[int]]:
    """:func:`section_chains` of a compiled model, as body ids."""
    names = [model.body(b).name for b in range(model.nbody)]
    return [[names.index(name) for name in chain] for chain in section_chains(names)]


def backbone_lengths(xpos, chains) -> list[float]:
    """Per section, the backbone length (m): the polyline through its bodies' centres.
    ``xpos``: every body's position as a list of [x, y, z] (``data.xpos.tolist()``: plain
    floats, faster than numpy at this size); ``chains``: :func:`section_body_chains`."""
    lengths = []
    for chain in chains:
        points = [xpos[i] for i in chain]
        lengths.append(sum(map(math.dist, points[:-1], points[1:])))
    return lengths


_STATICS: dict = {}


def _statics(spec: arm_builder.ArmSpec) -> _Statics:
    key = replace(spec, payload_kg=0.0)
    if key not in _STATICS:
        if len(_STATICS) > 8:
            _STATICS.clear()
        _STATICS[key] = _Statics(key)
    return _STATICS[key]


def reference_tip(
    spec: arm_builder.ArmSpec,
    pressures_Pa,
    payload_kg: float = 0.0,
    tip_force_N=(0.0, 0.0, 0.0),
    warm: bool = False,
):
    """Tip position (base frame, m) of the arm at rest under ``pressures_Pa`` (one per muscle,
    base section first), with the arm's own weight, a payload of ``payload_kg`` at the tip and a
    tip force (base frame). Returns ``(tip, section_lengths_m)`` (each section's backbone: the
    polyline through its plates, as :meth:`EfamPhysics.section_lengths` measures it). Each solve
    starts from the model at rest (a pure function of its inputs); ``warm=True`` starts from the
    previous solve's rest state instead (faster for a sequence of nearby solves that itself
    began cold).

    The suite's statics is the domain's own MuJoCo model held at rest (:class:`_Statics`): every
    target is then reachable by the simulated arm, and a solve takes milliseconds (the
    continuum reference, :func:`continuum_tip`, takes 0.5-10 s; its distance to this one is
    stated in docs/suite.md)."""
    statics_ = _statics(spec)
    force = np.asarray(tip_force_N, dtype=float) + float(payload_kg) * arm_builder.gravity_in_base(spec)
    if not statics_.solve(np.asarray(pressures_Pa, dtype=float), force, warm=warm):
        raise RuntimeError(f"suite statics: no rest state found for pressures {np.round(pressures_Pa, 1)} Pa")
    return statics_.tip_and_lengths()


def continuum_tip(spec: arm_builder.ArmSpec, pressures_Pa, payload_kg: float = 0.0) -> np.ndarray:
    """Tip (base frame, m) by the continuum (Kirchhoff rod) reference of :mod:`efam_mujoco.arm`:
    independent of MuJoCo and of the disk count, slow (seconds for the 3-section arm)."""
    pressures = np.asarray(pressures_Pa, dtype=float)
    counts = np.cumsum([len(s.muscles) for s in spec.sections])[:-1]
    state = arm_builder.solve_arm_spec(
        replace(spec, payload_kg=float(payload_kg)), np.split(pressures, counts)
    )
    return np.asarray(state.tip_position_m, dtype=float)


# ----------------------------------------------------- unloaded constant-curvature geometry


@functools.lru_cache(maxsize=32)
def _free_length_table(muscle, max_pressure_Pa: float):
    pressures = np.linspace(0.0, max_pressure_Pa, 513)
    lengths = np.array([muscle.free_length(p) for p in pressures])
    # below the muscle's dead band the free length stays at rest: keep the last such point
    first = int(np.searchsorted(lengths, lengths[0], side="right")) - 1
    pressures, lengths = pressures[first:], lengths[first:]
    if np.any(np.diff(lengths) <= 0):
        raise ValueError(f"muscle {muscle.name}: free length not increasing with pressure")
    return pressures, lengths


def free_length_m(muscle, pressure_Pa, max_pressure_Pa: float):
    """The muscle's free length at ``pressure_Pa`` (interpolated table; vectorised)."""
    pressures, lengths = _free_length_table(muscle, float(max_pressure_Pa))
    return np.interp(pressure_Pa, pressures, lengths)


def pressure_for_free_length(muscle, length_m, max_pressure_Pa: float):
    """Inverse of :func:`free_length_m`: the pressure at which the muscle's free length is
    ``length_m`` (clamped to [0, max_pressure_Pa])."""
    pressures, lengths = _free_length_table(muscle, float(max_pressure_Pa))
    return np.interp(length_m, lengths, pressures)


def cc_tip(sections_params, spec: arm_builder.ArmSpec) -> np.ndarray:
    """Tip (base frame) of an arm whose sections are the arcs ``(s, kx, ky)`` (no load)."""
    p, R = np.zeros(3), np.eye(3)
    for s, kx, ky in sections_params:
        dp, dR = statics.cc_frame(s, kx, ky)
        p, R = p + R @ dp, R @ dR
    return p
