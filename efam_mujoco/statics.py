"""Constant-curvature statics of parallel-bundled EFAM sections (the reference for the MuJoCo arm).

A section is M muscles in parallel between two plates, muscle i at radius r_i and angle alpha_i
in the section's base frame (z along the section). Under the constant-curvature (CC) assumption
the section's backbone is a circular arc of length s whose curvature vector k = (kx, ky) points
from the backbone to the centre of curvature (bend direction phi = atan2(ky, kx), curvature
kappa = |k|). A muscle follows the arc at its radius, so its length is

    L_i = s (1 - r_i (kx cos alpha_i + ky sin alpha_i)) = s (1 - kappa r_i cos(phi - alpha_i)).

Equilibrium. Cut the section at a point of its arc and look at everything beyond the cut. The
muscles cross the cut along the arc's tangent z_c and push the distal part with F_i = push(P_i,
L_i) (positive = pushes its ends apart) at r_i (cos alpha_i, sin alpha_i) in the cut frame. The
backbone (the plates and spacers) carries shear and twist but no axial force and no bending
moment: it is the muscles that hold the section open and bent. So, with the distal load's
force f and moment m about the cut point, both in the cut frame,

    sum_i F_i + f_z = 0
    sum_i F_i r_i sin(alpha_i) + m_x = 0,    -sum_i F_i r_i cos(alpha_i) + m_y = 0.

Without loads these say the muscle forces cancel and have no moment, whatever cut is used. With
loads the bending moment varies along the section and no single arc satisfies every cut; the
cut is made at the middle of the arc, the usual choice that makes the error of the CC
assumption second order. For a tip load along the section's axis, or a pure tip moment, every
cut gives the same answer.

Multi-section arms: section j's base frame is section j-1's tip frame. The load at a cut of
section j is the tip load plus the weight of every point mass beyond the cut (masses lumped on
the backbone at a fraction of their section's arc; a mass exactly at the cut counts half). All
sections are solved together (3 unknowns per section) with scipy.optimize.root.

Everything is in the arm's base frame: z along the first section at its base.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

FORCE_SCALE_N = 100.0  # residual scale: muscle forces are tens to hundreds of newtons
RESIDUAL_TOL = 1e-10  # on residuals in units of FORCE_SCALE_N (and FORCE_SCALE_N x radius)


class StaticsError(RuntimeError):
    """The equilibrium solve did not converge."""


@dataclass(frozen=True)
class SectionState:
    """A section's CC equilibrium, in the section's base frame."""

    arc_length_m: float
    curvature_xy_per_m: tuple[float, float]  # (kx, ky): towards the centre of curvature
    muscle_lengths_m: np.ndarray
    muscle_forces_N: np.ndarray  # push positive (MuJoCo sign)

    @property
    def curvature_per_m(self) -> float:
        return math.hypot(*self.curvature_xy_per_m)

    @property
    def bend_angle_rad(self) -> float:
        """Angle the tip tangent turns through: kappa s."""
        return self.curvature_per_m * self.arc_length_m

    @property
    def bend_direction_rad(self) -> float:
        """phi: the direction (in the base xy plane) the section bends towards."""
        return math.atan2(self.curvature_xy_per_m[1], self.curvature_xy_per_m[0])


@dataclass(frozen=True)
class ArmState:
    """A whole arm's CC equilibrium, in the arm's base frame."""

    sections: tuple[SectionState, ...]
    section_tip_positions_m: np.ndarray  # (S, 3)
    section_tip_rotations: np.ndarray  # (S, 3, 3), columns = tip frame axes

    @property
    def tip_position_m(self) -> np.ndarray:
        return self.section_tip_positions_m[-1]

    @property
    def tip_rotation(self) -> np.ndarray:
        return self.section_tip_rotations[-1]


# ------------------------------------------------------------------------------ geometry


def muscle_layout(section) -> tuple[np.ndarray, np.ndarray]:
    """Radii (M,) and angles (M,) in rad of a section's muscles. ``section`` needs ``muscles``,
    ``radius_m`` (a number or one per muscle) and ``angles_rad`` (one per muscle)."""
    count = len(section.muscles)
    radii = np.broadcast_to(np.asarray(section.radius_m, dtype=float), (count,)).copy()
    angles = np.asarray(section.angles_rad, dtype=float)
    if angles.shape != (count,):
        raise ValueError(f"section: {count} muscles but {angles.size} angles")
    return radii, angles


def muscle_lengths(section, arc_length_m: float, kx: float, ky: float) -> np.ndarray:
    """L_i = s (1 - r_i (kx cos alpha_i + ky sin alpha_i))."""
    radii, angles = muscle_layout(section)
    return arc_length_m * (1.0 - radii * (kx * np.cos(angles) + ky * np.sin(angles)))


def muscle_forces(section, pressures_Pa, lengths_m) -> np.ndarray:
    """Push (MuJoCo sign) of each muscle at its pressure and length."""
    return np.array([m.push(p, L) for m, p, L in zip(section.muscles, pressures_Pa, lengths_m)])


def _sinc(x: float) -> float:
    return 1.0 - x * x / 6.0 if abs(x) < 1e-4 else math.sin(x) / x


def _versinc(x: float) -> float:
    """(1 - cos x) / x^2."""
    return 0.5 - x * x / 24.0 if abs(x) < 1e-4 else (1.0 - math.cos(x)) / (x * x)


def _rotation(axis_angle: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    angle = float(np.linalg.norm(axis_angle))
    if angle < 1e-300:
        return np.eye(3)
    k = axis_angle / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def cc_frame(arc_length_m: float, kx: float, ky: float, fraction: float = 1.0):
    """Position and rotation of the backbone frame at ``fraction`` of a CC arc, in its base frame.

    The arc bends towards (kx, ky): the frame turns about the axis (-ky, kx, 0) by kappa s.
    """
    sigma = fraction * arc_length_m
    kappa = math.hypot(kx, ky)
    angle = kappa * sigma
    # p = [(1 - cos t)/kappa^2 (kx, ky), sin(t)/kappa] written to stay finite at kappa = 0
    lateral = sigma * sigma * _versinc(angle)
    pos = np.array([lateral * kx, lateral * ky, sigma * _sinc(angle)])
    rot = _rotation(sigma * np.array([-ky, kx, 0.0]))
    return pos, rot


# ------------------------------------------------------------------------------ equilibrium


@dataclass(frozen=True)
class PointMass:
    """A mass on a section's backbone at ``fraction`` (0 = section base, 1 = section tip)."""

    section: int
    fraction: float
    mass_kg: float


def _section_frames(sections, unknowns):
    """Base frame (p, R) of every section and the CC parameters, in the arm base frame."""
    frames, p, R = [], np.zeros(3), np.eye(3)
    for j in range(len(sections)):
        s, kx, ky = unknowns[3 * j : 3 * j + 3]
        frames.append((p, R, s, kx, ky))
        dp, dR = cc_frame(s, kx, ky)
        p, R = p + R @ dp, R @ dR
    return frames, (p, R)


def _point(frames, section: int, fraction: float):
    p, R, s, kx, ky = frames[section]
    dp, dR = cc_frame(s, kx, ky, fraction)
    return p + R @ dp, R @ dR


def _residuals(sections, pressures, unknowns, scales, tip_force, tip_moment, gravity, masses):
    frames, (tip_p, _) = _section_frames(sections, unknowns)
    mass_points = [(_point(frames, pm.section, pm.fraction)[0], pm) for pm in masses]
    out = []
    for j, section in enumerate(sections):
        s, kx, ky = unknowns[3 * j : 3 * j + 3]
        cut_p, cut_R = _point(frames, j, 0.5)
        force = np.array(tip_force, dtype=float)
        moment = np.array(tip_moment, dtype=float) + np.cross(tip_p - cut_p, force)
        for x, pm in mass_points:
            if pm.section < j or (pm.section == j and pm.fraction < 0.5):
                continue
            share = 0.5 if pm.section == j and pm.fraction == 0.5 else 1.0
            weight = share * pm.mass_kg * np.asarray(gravity, dtype=float)
            force = force + weight
            moment = moment + np.cross(x - cut_p, weight)
        f_local, m_local = cut_R.T @ force, cut_R.T @ moment
        radii, angles = muscle_layout(section)
        F = muscle_forces(section, pressures[j], muscle_lengths(section, s, kx, ky))
        r_scale = scales[j]
        out += [
            (F.sum() + f_local[2]) / FORCE_SCALE_N,
            (np.sum(F * radii * np.sin(angles)) + m_local[0]) / (FORCE_SCALE_N * r_scale),
            (-np.sum(F * radii * np.cos(angles)) + m_local[1]) / (FORCE_SCALE_N * r_scale),
        ]
    return np.array(out)


def _free_arc_guess(section, pressures) -> float:
    return float(np.mean([m.free_length(p) for m, p in zip(section.muscles, pressures)]))


def solve_arm(
    sections: Sequence,
    pressures_Pa: Sequence[Sequence[float]],
    tip_force_N=(0.0, 0.0, 0.0),
    tip_moment_N_m=(0.0, 0.0, 0.0),
    gravity_m_s2=(0.0, 0.0, 0.0),
    point_masses: Sequence[PointMass] = (),
    initial=None,
) -> ArmState:
    """CC equilibrium of an arm of ``sections`` (base first) at the given muscle pressures.

    Loads are in the arm's base frame: a force and a moment at the arm's tip, and gravity acting
    on ``point_masses`` (see :class:`PointMass`). ``initial`` (3 per section: s, kx, ky) seeds
    the solve; by default each section starts straight at its muscles' mean free length.
    """
    if len(pressures_Pa) != len(sections):
        raise ValueError(f"{len(sections)} sections but {len(pressures_Pa)} pressure lists")
    pressures = [np.asarray(p, dtype=float) for p in pressures_Pa]
    for j, (section, p) in enumerate(zip(sections, pressures)):
        if p.shape != (len(section.muscles),):
            raise ValueError(f"section {j}: {len(section.muscles)} muscles but {p.size} pressures")
    scales = [float(np.mean(muscle_layout(sec)[0])) for sec in sections]
    if initial is None:
        initial = np.concatenate([[_free_arc_guess(sec, p), 0.0, 0.0] for sec, p in zip(sections, pressures)])
    # unknowns scaled to order one: s, and the curvature as kappa * r (a strain)
    scale_vec = np.concatenate([[1.0, 1.0 / r, 1.0 / r] for r in scales])
    loads = (tip_force_N, tip_moment_N_m, gravity_m_s2, point_masses)

    def fun(z):
        return _residuals(sections, pressures, z * scale_vec, scales, *loads)

    z0 = np.asarray(initial, dtype=float) / scale_vec
    result = root(fun, z0, method="hybr", options={"xtol": 1e-13})
    if not _converged(result):
        result = _continuation(fun, z0, sections, pressures, scale_vec, scales, loads)
    unknowns = result.x * scale_vec
    return _arm_state(sections, pressures, unknowns)


def _converged(result) -> bool:
    # hybr reports "no progress" when it reaches round-off before xtol: judge by the residual
    return bool(np.all(np.isfinite(result.x)) and np.max(np.abs(result.fun)) < RESIDUAL_TOL)


def _continuation(fun, z0, sections, pressures, scale_vec, scales, loads):
    """Walk the loads and the pressure differences in from an easy problem when a direct solve fails."""
    mean = [np.full_like(p, p.mean()) for p in pressures]
    z, result = z0, None
    for t in np.linspace(0.0, 1.0, 21)[1:]:
        step_p = [m + t * (p - m) for m, p in zip(mean, pressures)]
        step_loads = (
            t * np.asarray(loads[0], dtype=float),
            t * np.asarray(loads[1], dtype=float),
            t * np.asarray(loads[2], dtype=float),
            loads[3],
        )

        def step_fun(x, step_p=step_p, step_loads=step_loads):
            return _residuals(sections, step_p, x * scale_vec, scales, *step_loads)

        result = root(step_fun, z, method="hybr", options={"xtol": 1e-13})
        if not _converged(result):
            break
        z = result.x
    if result is None or not _converged(result):
        msg = "no constant-curvature equilibrium found"
        raise StaticsError(f"{msg}: {result.message if result is not None else ''}")
    return result


def _arm_state(sections, pressures, unknowns) -> ArmState:
    states, tip_ps, tip_Rs = [], [], []
    p, R = np.zeros(3), np.eye(3)
    for j, section in enumerate(sections):
        s, kx, ky = (float(v) for v in unknowns[3 * j : 3 * j + 3])
        lengths = muscle_lengths(section, s, kx, ky)
        states.append(SectionState(s, (kx, ky), lengths, muscle_forces(section, pressures[j], lengths)))
        dp, dR = cc_frame(s, kx, ky)
        p, R = p + R @ dp, R @ dR
        tip_ps.append(p)
        tip_Rs.append(R)
    return ArmState(tuple(states), np.array(tip_ps), np.array(tip_Rs))


def solve_section(section, pressures_Pa, tip_force_N=(0.0, 0.0, 0.0), tip_moment_N_m=(0.0, 0.0, 0.0)):
    """One section with a load at its tip (in its base frame): its :class:`SectionState` and the
    :class:`ArmState` holding its tip pose."""
    arm = solve_arm([section], [pressures_Pa], tip_force_N, tip_moment_N_m)
    return arm.sections[0], arm
