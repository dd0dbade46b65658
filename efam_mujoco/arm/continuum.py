"""The arm as a continuum: a Kirchhoff rod whose strains follow from the muscles, independent of MuJoCo.

Each section is a rod of reference length L (its muscles' mean resting length), parametrised
by the reference arc coordinate s. At s the cross-section has position p, rotation R (columns
d1, d2, d3; d3 the tangent) and strains: the stretch nu (d p / d s = nu d3, no shear) and the
curvature k = (k1, k2, 0) (d R / d s = R [k]x, no twist: the spacer disks and the muscles'
clamping keep the section from twisting; the twisting moment is a reaction). Muscle i at offset
y_i = (x_i, y_i, 0) in the cross-section then has the local stretch

    lambda_i = nu + k1 y_i - k2 x_i,

and, deformed uniformly at that stretch, it pushes (MuJoCo sign) with F_i = push(P_i, lambda_i L)
along d3 (paper Eq. 2 at the local length). Cut the rod at s: the distal part acts on the
proximal part with the force n and the moment m about p. The muscles carry the axial force and
the bending moment, the spacer structure the shear and the twist:

    n . d3 = -sum_i F_i,    m . d1 = -sum_i F_i y_i,    m . d2 = sum_i F_i x_i        (constitutive)

three equations that give (nu, k1, k2) from (n, m, R) (Newton, at every s). Balance:

    n(s) = F_tip + g * (mass beyond s),    d m / d s = -(d p / d s) x n,    m(L_arm) = M_tip,

with the muscles' spread mass as a line density and the end fittings, plates and payload as
point masses at the section ends. n is known in closed form; the moment at the base m(0) is found
by shooting (scipy ``solve_ivp`` along the arm, ``root`` on the three components of m(0)).

Without loads n = m = 0 everywhere, so every section has constant strains: the constant-curvature
(CC) arc, solved directly (:func:`solve_section_cc`), the special case that the loaded solution
reduces to.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import root

from ..units import check_pressure_Pa

FORCE_SCALE_N = 100.0
NEWTON_TOL = 1e-12  # on the constitutive residual, relative to FORCE_SCALE_N
#: Work bounds of the loaded rod (counted, never timed, so the outcome does not depend on the
#: machine). One evaluation = one constitutive (Newton) solve at one s, about 0.5 ms. A
#: section's integration takes 100-300 of them for the paper's arms, under gravity and payloads
#: alike; a load the section cannot carry pushes its muscles into lock-out, where the law is so
#: steep that the integrator's step collapses (thousands per section, seconds each): beyond
#: MAX_EVALUATIONS_PER_INTEGRATION that integration has failed (a step-size floor). The whole
#: solve (fixed-point steps, shooting, the load walked in from zero) stops at MAX_EVALUATIONS:
#: the heaviest known good case, the 1x3 paper arm horizontal with 1 kg, takes about 37 000.
MAX_EVALUATIONS_PER_INTEGRATION = 1000
MAX_EVALUATIONS = 60_000


class ContinuumError(RuntimeError):
    """The continuum equilibrium was not found (the reference did not converge)."""


class ContinuumBudgetError(ContinuumError):
    """The loaded rod's solve used up its work bound (:data:`MAX_EVALUATIONS`)."""


class _IntegrationTooStiff(ContinuumError):
    """One integration along a section needed more than :data:`MAX_EVALUATIONS_PER_INTEGRATION`."""


# ------------------------------------------------------------------------ the cross-section


@dataclass(frozen=True)
class _Section:
    """What the rod needs of a section: its muscles, offsets, pressures, reference length."""

    muscles: tuple
    offsets: np.ndarray  # (M, 2)
    pressures: np.ndarray  # (M,)
    length: float
    groups: tuple  # (muscle, index array) per distinct muscle object: one vectorised push each

    @classmethod
    def of(cls, section, pressures) -> _Section:
        pressures = np.asarray(pressures, dtype=float)
        if pressures.shape != (len(section.muscles),):
            raise ValueError(f"section: {len(section.muscles)} muscles but {pressures.size} pressures")
        if not np.all(np.isfinite(pressures)):
            raise ValueError(f"section: pressures must be finite, got {pressures}")
        groups = {}
        for i, m in enumerate(section.muscles):
            groups.setdefault(id(m), (m, []))[1].append(i)
        groups = tuple((m, np.array(idx)) for m, idx in groups.values())
        a = np.asarray(section.angles_rad, dtype=float)
        radii = np.broadcast_to(np.asarray(section.radius_m, dtype=float), a.shape)
        offsets = np.column_stack([radii * np.cos(a), radii * np.sin(a)])
        length = float(np.mean([m.rest_length_m for m in section.muscles]))
        return cls(tuple(section.muscles), offsets, pressures, length, groups)

    def stretches(self, strains) -> np.ndarray:
        nu, k1, k2 = strains
        return nu + k1 * self.offsets[:, 1] - k2 * self.offsets[:, 0]

    def forces(self, stretches) -> np.ndarray:
        """Push of every muscle at its local stretch (its whole length deformed like this)."""
        out = np.empty(len(self.muscles))
        for muscle, idx in self.groups:
            out[idx] = muscle.push(self.pressures[idx], stretches[idx] * self.length)
        return out

    def _forces_and_slopes(self, stretches, h=1e-7):
        L = stretches * self.length
        out, slope = np.empty(L.size), np.empty(L.size)
        for muscle, idx in self.groups:
            both = muscle.push(
                np.tile(self.pressures[idx], 3), np.concatenate([L[idx], L[idx] + h, L[idx] - h])
            )
            n = idx.size
            out[idx] = both[:n]
            slope[idx] = (both[n : 2 * n] - both[2 * n :]) / (2 * h) * self.length
        return out, slope

    def resultants(self, forces) -> np.ndarray:
        """(sum F, sum F y, -sum F x): minus the axial force and the bending moments in d1, d2."""
        return np.array([forces.sum(), forces @ self.offsets[:, 1], -(forces @ self.offsets[:, 0])])

    def strains(self, target, guess) -> np.ndarray:
        """(nu, k1, k2) at which the muscles' resultants equal ``target`` (Newton from ``guess``)."""
        z = np.array(guess, dtype=float)
        rows = np.column_stack([np.ones(len(self.muscles)), self.offsets[:, 1], -self.offsets[:, 0]])
        for _ in range(60):
            F, dF = self._forces_and_slopes(self.stretches(z))
            residual = self.resultants(F) - target
            scale = np.array([1.0, 1.0 / 0.02, 1.0 / 0.02]) / FORCE_SCALE_N
            if np.max(np.abs(residual * scale)) < NEWTON_TOL:
                return z
            jac = rows.T @ (dF[:, None] * rows)
            step = np.linalg.solve(jac, -residual)
            # a damped step keeps the stretch positive where the law is steep (lock-out)
            limit = 0.2 / max(1e-12, np.max(np.abs(rows @ step)))
            z = z + step * min(1.0, limit)
        raise ContinuumError(f"constitutive solve did not converge (residual {residual})")


# ---------------------------------------------------------------------------- CC (no load)


def _hat(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rotation(axis_angle) -> np.ndarray:
    angle = float(np.linalg.norm(axis_angle))
    if angle < 1e-300:
        return np.eye(3)
    K = _hat(np.asarray(axis_angle) / angle)
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _sinc(x: float) -> float:
    return 1.0 - x * x / 6.0 if abs(x) < 1e-4 else math.sin(x) / x


def _versinc(x: float) -> float:
    return 0.5 - x * x / 24.0 if abs(x) < 1e-4 else (1.0 - math.cos(x)) / (x * x)


def cc_frame(arc_length_m: float, kx: float, ky: float, fraction: float = 1.0):
    """Position and rotation of the backbone frame at ``fraction`` of a CC arc of length
    ``arc_length_m`` bending towards (kx, ky) (curvature per unit arc length), in its base frame."""
    sigma = fraction * arc_length_m
    kappa = math.hypot(kx, ky)
    angle = kappa * sigma
    lateral = sigma * sigma * _versinc(angle)
    pos = np.array([lateral * kx, lateral * ky, sigma * _sinc(angle)])
    return pos, _rotation(sigma * np.array([-ky, kx, 0.0]))


@dataclass(frozen=True)
class SectionState:
    """A section at equilibrium, in its base frame. ``curvature_xy_per_m`` (towards the centre
    of curvature, per unit deformed arc length), ``muscle_forces_N`` (push positive) and
    ``muscle_lengths_m`` are the section's mean (CC: exact) values."""

    arc_length_m: float
    curvature_xy_per_m: tuple[float, float]
    muscle_lengths_m: np.ndarray
    muscle_forces_N: np.ndarray

    @property
    def curvature_per_m(self) -> float:
        """Magnitude of the section curvature (1/m)."""
        return math.hypot(*self.curvature_xy_per_m)

    @property
    def bend_angle_rad(self) -> float:
        """Total bend of the section (rad): curvature times arc length."""
        return self.curvature_per_m * self.arc_length_m

    @property
    def bend_direction_rad(self) -> float:
        """Direction of the curvature vector in the base plane of the section (rad from x)."""
        return math.atan2(self.curvature_xy_per_m[1], self.curvature_xy_per_m[0])


@dataclass(frozen=True)
class ArmState:
    """A whole arm at equilibrium, in the arm's base frame: per section its state and tip pose,
    and the backbone sampled along the reference arc (``backbone_m``, (K, 3), base to tip)."""

    sections: tuple[SectionState, ...]
    section_tip_positions_m: np.ndarray  # (S, 3)
    section_tip_rotations: np.ndarray  # (S, 3, 3), columns = tip frame axes
    backbone_m: np.ndarray

    @property
    def tip_position_m(self) -> np.ndarray:
        """Tip position of the last section in the arm's base frame (m)."""
        return self.section_tip_positions_m[-1]

    @property
    def tip_rotation(self) -> np.ndarray:
        """Tip orientation of the last section (3x3 rotation in the arm's base frame)."""
        return self.section_tip_rotations[-1]


def _cc_state(sec: _Section, strains) -> SectionState:
    nu, k1, k2 = strains
    stretch = sec.stretches(strains)
    # curvature per unit deformed length, towards the centre: rotation about d2 by k2 turns d3
    # towards +x, about d1 by k1 towards -y
    return SectionState(nu * sec.length, (k2 / nu, -k1 / nu), stretch * sec.length, sec.forces(stretch))


def solve_section_cc(section, pressures_Pa) -> SectionState:
    """The unloaded section: the muscles' forces cancel and have no moment (CC arc)."""
    sec = _Section.of(section, pressures_Pa)
    # the unit check looks at the section's pressure set once: one muscle of a strongly differential
    # set may well be at a few hundred Pa, which Muscle.free_length alone would take for kPa
    check_pressure_Pa(sec.pressures, "continuum.solve_section_cc")
    nu0 = (
        float(
            np.mean([m.free_length(float(p), check_units=False) for m, p in zip(sec.muscles, sec.pressures)])
        )
        / sec.length
    )
    return _cc_state(sec, sec.strains(np.zeros(3), [nu0, 0.0, 0.0]))


def _cc_pose(state: SectionState):
    return cc_frame(state.arc_length_m, *state.curvature_xy_per_m)


# -------------------------------------------------------------------------- the loaded rod


@dataclass(frozen=True)
class PointMass:
    """A mass on a section's backbone at ``fraction`` of its reference length (0 base, 1 tip)."""

    section: int
    fraction: float
    mass_kg: float


def solve_arm(
    sections: Sequence,
    pressures_Pa: Sequence[Sequence[float]],
    tip_force_N=(0.0, 0.0, 0.0),
    tip_moment_N_m=(0.0, 0.0, 0.0),
    gravity_m_s2=(0.0, 0.0, 0.0),
    point_masses: Sequence[PointMass] = (),
    line_densities_kg_per_m: Sequence[float] | None = None,
    samples_per_section: int = 41,
    max_evaluations: int = MAX_EVALUATIONS,
) -> ArmState:
    """Equilibrium of the rod of ``sections`` (base first) at the given pressures.

    Loads in the arm's base frame: a force and a moment at the tip; gravity on the point masses
    and on each section's line density (kg per m of reference length). Without loads (no tip
    load, or no gravity and masses) the result is the CC solution of each section.

    The loaded solve is bounded by ``max_evaluations`` constitutive solves (and each integration
    along a section by :data:`MAX_EVALUATIONS_PER_INTEGRATION`); a solve that does not converge
    within them raises :class:`ContinuumError` saying so (the reference did not converge).
    """
    if len(pressures_Pa) != len(sections):
        raise ValueError(f"{len(sections)} sections but {len(pressures_Pa)} pressure lists")
    secs = [_Section.of(s, p) for s, p in zip(sections, pressures_Pa)]
    densities = (
        np.zeros(len(secs)) if line_densities_kg_per_m is None else np.asarray(line_densities_kg_per_m, float)
    )
    if densities.shape != (len(secs),) or np.any(densities < 0):
        raise ValueError(
            f"line_densities_kg_per_m: need {len(secs)} values >= 0, got {line_densities_kg_per_m}"
        )
    for pm in point_masses:
        if not (0 <= pm.section < len(secs) and 0.0 <= pm.fraction <= 1.0 and pm.mass_kg >= 0):
            raise ValueError(f"point mass {pm} is not on the arm")
    F_tip, M_tip, g = (np.asarray(v, dtype=float) for v in (tip_force_N, tip_moment_N_m, gravity_m_s2))
    weights = [pm for pm in point_masses if pm.mass_kg > 0]
    loaded = np.any(F_tip) or np.any(M_tip) or (np.any(g) and (weights or np.any(densities)))
    cc = [solve_section_cc(s, p) for s, p in zip(sections, pressures_Pa)]
    if not loaded:
        return _cc_arm(cc, samples_per_section)
    rod = _Rod(secs, densities, weights, F_tip, M_tip, g, max_evaluations)
    return rod.solve(cc, samples_per_section)


def _cc_arm(states, samples) -> ArmState:
    tips, rots, backbone = [], [], []
    p, R = np.zeros(3), np.eye(3)
    for state in states:
        for f in np.linspace(0.0, 1.0, samples)[(1 if backbone else 0) :]:
            dp, _ = cc_frame(state.arc_length_m, *state.curvature_xy_per_m, fraction=f)
            backbone.append(p + R @ dp)
        dp, dR = _cc_pose(state)
        p, R = p + R @ dp, R @ dR
        tips.append(p)
        rots.append(R)
    return ArmState(tuple(states), np.array(tips), np.array(rots), np.array(backbone))


class _Rod:
    def __init__(self, secs, densities, weights, F_tip, M_tip, g, max_evaluations=MAX_EVALUATIONS):
        self.secs, self.densities, self.g = secs, densities, g
        self.evaluations, self.max_evaluations = 0, int(max_evaluations)
        self.F_tip, self.M_tip = F_tip, M_tip
        # mass beyond each section's start (tip side), for n(s) in closed form
        self.point = [
            [(pm.fraction * s.length, pm.mass_kg) for pm in weights if pm.section == j]
            for j, s in enumerate(secs)
        ]
        beyond, after = [], 0.0
        for j in reversed(range(len(secs))):
            beyond.append(after)
            after += densities[j] * secs[j].length + sum(m for _, m in self.point[j])
        self.mass_after = beyond[::-1]  # mass of the sections after j

    def force(self, j, s):
        """n(s) in section j: tip force plus the weight of everything beyond s (a point mass
        exactly at s counts as beyond, except at the section's start)."""
        mass = self.mass_after[j] + self.densities[j] * (self.secs[j].length - s)
        mass += sum(m for pos, m in self.point[j] if pos > s or (pos == s and s > 0))
        return self.F_tip + mass * self.g

    def _integrate(self, m0, samples=None):
        """Integrate p, R and m from the base moment ``m0`` to the tip; the strains at every s
        from the constitutive equations (Newton, warm-started)."""
        p, R, m = np.zeros(3), np.eye(3), np.asarray(m0, dtype=float)
        memo = {"guess": np.array([1.0, 0.0, 0.0])}
        tips, rots, backbone, states = [], [], [], []

        def strains_at(j, sec, s, y):
            self.evaluations += 1
            if self.evaluations > self.max_evaluations:
                raise ContinuumBudgetError(
                    f"the continuum reference did not converge within {self.max_evaluations} "
                    "constitutive solves (a load the arm cannot carry: its muscles in lock-out?)"
                )
            R_ = y[3:12].reshape(3, 3)
            n = self.force(j, s)
            target = np.array([-(n @ R_[:, 2]), -(y[12:] @ R_[:, 0]), -(y[12:] @ R_[:, 1])])
            memo["guess"] = sec.strains(target, memo["guess"])
            return memo["guess"], n

        for j, sec in enumerate(self.secs):
            calls = [0]  # evaluations of the integration under way (reset for each)

            def rhs(s, y, j=j, sec=sec, calls=calls):
                calls[0] += 1
                if calls[0] > MAX_EVALUATIONS_PER_INTEGRATION:  # the step has collapsed: stiff
                    raise _IntegrationTooStiff(
                        f"integration in section {j + 1} needed more than {MAX_EVALUATIONS_PER_INTEGRATION} "
                        "steps (stiff: muscles at their lock-out?)"
                    )
                z, n = strains_at(j, sec, s, y)
                R_ = y[3:12].reshape(3, 3)
                dp = z[0] * R_[:, 2]
                return np.concatenate([dp, (R_ @ _hat([z[1], z[2], 0.0])).ravel(), -np.cross(dp, n)])

            cuts = sorted({0.0, sec.length, *[pos for pos, _ in self.point[j] if 0 < pos < sec.length]})
            lengths = np.zeros(len(sec.muscles))
            y = np.concatenate([p, R.ravel(), m])
            for a, b in zip(cuts[:-1], cuts[1:]):
                grid = np.linspace(a, b, samples) if samples else None
                calls[0] = 0
                sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-9, atol=1e-12, t_eval=grid)
                if not sol.success:
                    raise ContinuumError(f"integration failed in section {j + 1}: {sol.message}")
                y = sol.y[:, -1]
                if samples:
                    backbone.extend(sol.y[:3].T[(1 if backbone else 0) :])
                    stretch = [sec.stretches(strains_at(j, sec, s, col)[0]) for col, s in zip(sol.y.T, sol.t)]
                    lengths += np.trapezoid(np.array(stretch), sol.t, axis=0)
            p, R, m = y[:3], y[3:12].reshape(3, 3), y[12:]
            u, _, vt = np.linalg.svd(R)  # orthonormalise against integration drift
            R = u @ vt
            tips.append(p.copy())
            rots.append(R.copy())
            if samples:
                states.append(lengths)
        return m, tips, rots, backbone, states

    def solve(self, cc_states, samples) -> ArmState:
        # start from the moment the loads would have on the unloaded (CC) shape
        guess_arm = _cc_arm(cc_states, samples)
        m0 = self.M_tip + np.cross(guess_arm.tip_position_m, self.F_tip)
        for j, sec in enumerate(self.secs):
            pts = guess_arm.backbone_m[j * (samples - 1) : (j + 1) * (samples - 1) + 1]
            w = self.densities[j] * sec.length / (samples - 1)
            for x in pts[1:]:
                m0 = m0 + np.cross(x, w * self.g)
        scale = FORCE_SCALE_N * 0.02
        full = (self.F_tip, self.M_tip, self.g)

        def attempt(fraction, start):
            self.F_tip, self.M_tip, self.g = (fraction * v for v in full)

            def residual(z):
                try:
                    m_end = self._integrate(z * scale)[0]
                except ContinuumBudgetError:
                    raise
                except ContinuumError:
                    return np.full(3, 1e3)
                return (m_end - self.M_tip) / scale

            result = root(residual, start, method="hybr", options={"xtol": 1e-12})
            ok = np.all(np.isfinite(result.x)) and np.max(np.abs(result.fun)) < 1e-9
            return result, ok

        # a few fixed-point steps first: m(L) = m(0) - (moment of the loads on the current shape)
        for _ in range(4):
            try:
                m0 = m0 - (self._integrate(m0)[0] - self.M_tip)
            except ContinuumBudgetError:
                raise
            except ContinuumError:
                break

        def walk_in():
            """The loads walked in from the unloaded arm (each step from the last solution):
            the branch the real arm follows as it is loaded."""
            z = np.zeros(3)
            for fraction in np.linspace(0.0, 1.0, 11)[1:]:
                result, ok = attempt(fraction, z)
                if not ok:
                    break
                z = result.x
            return result, ok

        result, ok = attempt(1.0, m0 / scale)
        walked = not ok
        if not ok:
            result, ok = walk_in()
        self.F_tip, self.M_tip, self.g = full
        if not ok:
            raise ContinuumError(
                f"no rod equilibrium found: {result.message} (residual {np.max(np.abs(result.fun)):.2e})"
            )
        state = self._state(result.x * scale, samples)
        # the direct shot can land on a far branch: a section curled past a half turn that the
        # unloaded arm does not have (measured: the 1x3 arm horizontal with 2 kg, 246 deg, where
        # the walked-in load gives the arm's own 87 deg). Walk the loads in and keep that branch.
        curled = [
            st.bend_angle_rad > math.pi and cc.bend_angle_rad < math.pi
            for st, cc in zip(state.sections, cc_states)
        ]
        if any(curled) and not walked:
            try:
                again, ok = walk_in()
                self.F_tip, self.M_tip, self.g = full
                if ok:
                    other = self._state(again.x * scale, samples)
                    if max(st.bend_angle_rad for st in other.sections) < max(
                        st.bend_angle_rad for st in state.sections
                    ):
                        state = other
            except ContinuumBudgetError:  # no budget left to check: the direct solution stands
                pass
            finally:
                self.F_tip, self.M_tip, self.g = full
        return state

    def _state(self, m0, samples) -> ArmState:
        """The :class:`ArmState` of the rod shot from the base moment ``m0`` (sampled)."""
        _, tips, rots, backbone, lengths = self._integrate(m0, samples)
        states = []
        for sec, L in zip(self.secs, lengths):
            mean_stretch = L / sec.length
            # mean strains of the section from its muscles' mean stretches (least squares)
            rows = np.column_stack([np.ones(len(sec.muscles)), sec.offsets[:, 1], -sec.offsets[:, 0]])
            nu, k1, k2 = np.linalg.lstsq(rows, mean_stretch, rcond=None)[0]
            states.append(SectionState(nu * sec.length, (k2 / nu, -k1 / nu), L, sec.forces(mean_stretch)))
        return ArmState(tuple(states), np.array(tips), np.array(rots), np.array(backbone))


def solve_section(section, pressures_Pa, tip_force_N=(0.0, 0.0, 0.0), tip_moment_N_m=(0.0, 0.0, 0.0)):
    """One section with a load at its tip (in its base frame): its :class:`SectionState` and the
    :class:`ArmState` holding its tip pose."""
    arm = solve_arm([section], [pressures_Pa], tip_force_N, tip_moment_N_m)
    return arm.sections[0], arm


# ---------------------------------------------------------------- the MuJoCo arm's loads


def arm_loads(arm) -> dict:
    """The continuum loads of an :class:`~efam_mujoco.arm.ArmSpec` (base frame): gravity, point
    masses (end fittings, plates, spacer disks spread as a line density, payload) and each
    section's line density (the muscles' spread mass)."""
    from .builder import gravity_in_base

    masses, densities = [], []
    for j, section in enumerate(arm.sections):
        end, body = section.muscle_masses()
        M = len(section.muscles)
        densities.append((M * body + (section.disks - 1) * section.disk_mass_kg) / section.rest_length_m)
        if j > 0:
            masses.append(PointMass(j, 0.0, M * end))
        masses.append(PointMass(j, 1.0, M * end + section.plate_mass_kg))
    if arm.payload_kg > 0:
        masses.append(PointMass(len(arm.sections) - 1, 1.0, arm.payload_kg))
    return {
        "gravity_m_s2": gravity_in_base(arm),
        "point_masses": masses,
        "line_densities_kg_per_m": densities,
    }


def solve_arm_spec(arm, pressures_Pa, tip_force_N=(0.0, 0.0, 0.0), **kw) -> ArmState:
    """:func:`solve_arm` with the loads of an :class:`~efam_mujoco.arm.ArmSpec` (its own weight,
    payload and orientation), plus a tip force in the base frame."""
    return solve_arm(arm.sections, pressures_Pa, tip_force_N=tip_force_N, **arm_loads(arm), **kw)
