"""What an arm is: sections of parallel muscles (:class:`SectionSpec`) stacked into an
:class:`ArmSpec`, and the shipped arms."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..muscle import Muscle
from ..musclefile import load_muscle
from ..units import as_float, check_pressure_Pa
from .masses import muscle_part_masses

PSI = 6894.757293168361
#: the paper's test pressures (15..75 psi), Pa
PAPER_PRESSURES_PA = tuple(p * PSI for p in (15, 30, 45, 60, 75))
#: highest pressure the paper characterised the muscles at (75 psi), Pa
MAX_TESTED_PRESSURE_PA = 75 * PSI
#: gap between neighbouring muscles at the default placement radius, as a fraction of their
#: resting diameter (room for the sleeves' braid and for assembly)
DEFAULT_CLEARANCE = 0.1
#: spacer disks per section when none is given: from the convergence table in docs/arms.md
DEFAULT_DISKS = 8
#: the most muscles one section's bundle may hold (``efam arm`` and ``efam size --bundle``)
MAX_MUSCLES_PER_SECTION = 24

ORIENTATIONS = {
    # quaternion (w, x, y, z) turning the base frame's z (the arm axis) to the named direction
    "upright": (1.0, 0.0, 0.0, 0.0),
    "hanging": (0.0, 1.0, 0.0, 0.0),
    "horizontal": (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0),
}


def default_radius(muscles: tuple[Muscle, ...], clearance: float = DEFAULT_CLEARANCE) -> float:
    """Placement radius of M evenly spaced muscles: neighbours ``clearance`` x their diameter
    apart, i.e. r = max over neighbours of (d_a + d_b) / 2 (1 + clearance) / (2 sin(pi / M))."""
    count = len(muscles)
    widest = max(
        (muscles[i].rest_diameter_m + muscles[(i + 1) % count].rest_diameter_m) / 2 for i in range(count)
    )
    return widest * (1 + clearance) / (2 * math.sin(math.pi / count))


#: Physical ranges of a section's and an arm's values, ``key: (low, high, unit)``, as the
#: ``efam arm`` flags have them (``arm.cli.ARGUMENT_BOUNDS``), so that a spec file or a Python
#: constructor refuses what the command line refuses: a radius in mm written as metres (18.2 m),
#: a payload in grams as kilograms, a valve lag in ms as seconds. The masses allow any plate a
#: bench arm carries; the damping 1000 x the defaults (beyond, the arm takes hours to move).
SECTION_BOUNDS = {
    "radius_m": (1e-3, 0.5, "m"),
    "disks": (1, 200, ""),
    "end_mass_kg": (0.0, 50.0, "kg"),
    "body_mass_kg": (0.0, 50.0, "kg"),
    "plate_mass_kg": (0.0, 50.0, "kg"),
    "disk_mass_kg": (0.0, 50.0, "kg"),
}
#: a muscle's angular position around a section's axis, ``(low, high, unit)``: one turn either way
ANGLE_BOUNDS_DEG = (-360.0, 360.0, "deg")
ARM_BOUNDS = {
    "pressure_tau_s": (0.0, 10.0, "s"),
    "max_pressure_Pa": (1e-9, 10e6, "Pa"),
    "payload_kg": (0.0, 50.0, "kg"),
    "timestep_s": (1e-7, 0.1, "s"),
    "axial_viscosity_N_s": (0.0, 6.8e3, "N s"),
    "bend_viscosity_N_m2_s": (0.0, 50.0, "N m^2 s"),
}


def _within(value, key: str, bounds: dict, where: str) -> float:
    """``value`` as a finite float inside ``bounds[key]`` (ValueError naming ``where: key``)."""
    number = as_float(value)
    low, high, unit = bounds[key]
    if not (math.isfinite(number) and low <= number <= high):
        raise ValueError(f"{where}: {key} = {value!r} is outside {low:g} .. {high:g} {unit}".rstrip())
    return number


def _finite(value, key: str) -> float:
    """``value`` as a float, refused (ValueError naming ``section: key``) unless it is a finite real
    number (a numpy scalar, a 0-d array or a Decimal is one; a bool or a text is not): a NaN angle
    built an arm with a muscle nowhere, a text radius ended in a TypeError."""
    number = as_float(value)
    if not math.isfinite(number):
        raise ValueError(f"section: {key} must be a finite number, got {value!r}")
    return number


@dataclass(frozen=True)
class SectionSpec:
    """One bundle of M >= 3 muscles in parallel between two plates.

    ``radius_m`` default: :func:`default_radius` (neighbours 10 % of a diameter apart).
    ``angles_deg`` default: evenly spaced from 0 deg (the base frame's x axis). ``disks``: spacer
    disks per section, D (the last is the section's end plate). ``end_mass_kg`` (per muscle
    end) and ``body_mass_kg`` (per muscle, spread along it) default to the Table 1 estimate of
    :func:`muscle_part_masses`; ``plate_mass_kg`` is extra structure at the section's end plate
    and ``disk_mass_kg`` at every spacer disk (none in the paper).
    """

    muscles: tuple[Muscle, ...]
    radius_m: float | None = None
    angles_deg: tuple[float, ...] | None = None
    disks: int = DEFAULT_DISKS
    end_mass_kg: float | None = None
    body_mass_kg: float | None = None
    plate_mass_kg: float = 0.0
    disk_mass_kg: float = 0.0

    def __post_init__(self):
        muscles = tuple(self.muscles)
        object.__setattr__(self, "muscles", muscles)
        if len(muscles) < 3:
            raise ValueError(f"section: needs at least 3 muscles, got {len(muscles)}")
        for i, m in enumerate(muscles):
            if not isinstance(m, Muscle):
                raise ValueError(
                    f"section: muscles[{i}] is a {type(m).__name__}, not a Muscle (load one with load_muscle)"
                )
        if self.angles_deg is None:
            object.__setattr__(
                self, "angles_deg", tuple(360.0 * i / len(muscles) for i in range(len(muscles)))
            )
        angles = tuple(_finite(a, f"angles_deg[{i}]") for i, a in enumerate(self.angles_deg))
        low, high, unit = ANGLE_BOUNDS_DEG
        for i, a in enumerate(angles):  # 1e308 deg was read, then said to 'overlap'
            if not low <= a <= high:
                raise ValueError(
                    f"section: angles_deg[{i}] = {self.angles_deg[i]!r} is outside {low:g} .. {high:g} {unit} "
                    "(a muscle's angular position around the section's axis)"
                )
        object.__setattr__(self, "angles_deg", angles)
        if len(angles) != len(muscles):
            raise ValueError(f"section: {len(muscles)} muscles but {len(angles)} angles_deg")
        if self.radius_m is None:
            object.__setattr__(self, "radius_m", default_radius(muscles))
        if not (_finite(self.radius_m, "radius_m") > 0):
            raise ValueError(f"section: radius_m must be positive, got {self.radius_m}")
        object.__setattr__(self, "radius_m", _within(self.radius_m, "radius_m", SECTION_BOUNDS, "section"))
        if int(_finite(self.disks, "disks")) != _finite(self.disks, "disks") or self.disks < 1:
            raise ValueError(f"section: disks must be a positive integer, got {self.disks}")
        object.__setattr__(self, "disks", int(_within(self.disks, "disks", SECTION_BOUNDS, "section")))
        for key in ("end_mass_kg", "body_mass_kg", "plate_mass_kg", "disk_mass_kg"):
            value = getattr(self, key)
            if value is not None and not (_finite(value, key) >= 0):
                raise ValueError(f"section: {key} must be >= 0, got {value}")
            if value is not None:
                _within(value, key, SECTION_BOUNDS, "section")
        self._check_no_overlap()

    def _check_no_overlap(self):
        xy = self.radius_m * np.column_stack([np.cos(self.angles_rad), np.sin(self.angles_rad)])
        for a in range(len(self.muscles)):
            for b in range(a + 1, len(self.muscles)):
                gap = np.linalg.norm(xy[a] - xy[b])
                touch = self.muscles[a].rest_outer_radius_m + self.muscles[b].rest_outer_radius_m
                if gap < touch * (1 - 1e-9):
                    raise ValueError(
                        f"section: muscles {a} and {b} overlap at rest (centres {gap * 1e3:.1f} mm apart, "
                        f"need {touch * 1e3:.1f} mm): raise radius_m or spread angles_deg"
                    )

    @property
    def angles_rad(self) -> tuple[float, ...]:
        """Angular positions of the muscles around the section axis (rad)."""
        return tuple(math.radians(a) for a in self.angles_deg)

    @property
    def rest_length_m(self) -> float:
        """The section's reference length: its muscles' mean resting length (the spacing of the
        disks at qpos0 times D)."""
        return float(np.mean([m.rest_length_m for m in self.muscles]))

    def muscle_masses(self) -> tuple[float, float]:
        """(mass at each muscle end, mass along each muscle), kg."""
        end, body = muscle_part_masses()
        return (
            end if self.end_mass_kg is None else self.end_mass_kg,
            body if self.body_mass_kg is None else self.body_mass_kg,
        )

    def offsets_m(self) -> np.ndarray:
        """(M, 2): each muscle's position in the section's cross-section, m."""
        a = np.asarray(self.angles_rad)
        return self.radius_m * np.column_stack([np.cos(a), np.sin(a)])


@dataclass(frozen=True)
class ArmSpec:
    """A whole arm, base section first.

    Damping is a material property of the bundle, per unit length: ``axial_viscosity_N_s`` is
    the axial force per unit axial strain rate (a piece of length l extending at dl/dt resists
    with eta_a (dl/dt) / l), ``bend_viscosity_N_m2_s`` the bending moment per unit rate of
    curvature (a piece of length l bending at dtheta/dt resists with eta_b (dtheta/dt) / l). They
    are the only dissipation in the model. ``mode="segmented"`` (default) is the physical model;
    ``mode="pcc"`` holds every section at constant curvature (an approximation for model-based
    control; see docs/arms.md). ``timestep_s`` None (default): the builder derives the step from
    the arm's stiffness, masses and damping (:mod:`efam_mujoco.arm.timestep`); a given step is
    checked against the arm's stability limit.
    """

    sections: tuple[SectionSpec, ...]
    orientation: str = "upright"
    pressure_tau_s: float = 0.05
    max_pressure_Pa: float = MAX_TESTED_PRESSURE_PA
    payload_kg: float = 0.0
    gravity: bool = True
    timestep_s: float | None = None
    axial_viscosity_N_s: float = 6.8
    bend_viscosity_N_m2_s: float = 0.05
    hold_tip: bool = False  # weld the tip plate where it is at rest (blocked-force checks)
    mode: str = "segmented"
    name: str = "efam_arm"

    def __post_init__(self):
        object.__setattr__(self, "sections", tuple(self.sections))
        if not self.sections:
            raise ValueError("arm: needs at least one section")
        if self.orientation not in ORIENTATIONS:
            raise ValueError(
                f"arm: orientation must be one of {', '.join(ORIENTATIONS)}, got {self.orientation!r}"
            )
        if self.mode not in ("segmented", "pcc"):
            raise ValueError(f"arm: mode must be 'segmented' or 'pcc', got {self.mode!r}")
        checks = {  # key: (holds, what it must be)
            "pressure_tau_s": (self.pressure_tau_s >= 0, "a time constant >= 0 s"),
            "max_pressure_Pa": (self.max_pressure_Pa > 0, "a pressure > 0 Pa"),
            "payload_kg": (self.payload_kg >= 0, "a mass >= 0 kg"),
            "timestep_s": (self.timestep_s is None or self.timestep_s > 0, "a time step > 0 s"),
            "axial_viscosity_N_s": (self.axial_viscosity_N_s >= 0, "a damping >= 0 N s"),
            "bend_viscosity_N_m2_s": (self.bend_viscosity_N_m2_s >= 0, "a damping >= 0 N m^2 s"),
        }
        for key, (ok, what) in checks.items():
            value = getattr(self, key)
            if not ((value is None or math.isfinite(value)) and ok):
                raise ValueError(f"arm: {key} must be {what} (finite), got {float(value):g}")
            if value is not None:
                _within(value, key, ARM_BOUNDS, "arm")
        for key in ("gravity", "hold_tip"):
            # a text 'false' is true in Python: the spec-file reader refuses it, and so does this
            if not isinstance(getattr(self, key), (bool, np.bool_)):
                raise ValueError(f"arm: {key} must be True or False, got {getattr(self, key)!r}")
        check_pressure_Pa(self.max_pressure_Pa, "arm: max_pressure_Pa")
        # a control range that ends inside every muscle's dead band moves nothing: every command
        # replays as the arm at rest (517.1 under max_pressure_Pa, kPa written as Pa)
        lowest = min((m for s in self.sections for m in s.muscles), key=lambda m: m.deadband_Pa)
        if self.max_pressure_Pa <= lowest.deadband_Pa:
            raise ValueError(
                f"arm: max_pressure_Pa = {self.max_pressure_Pa:.10g} Pa is within every muscle's dead band "
                f"(the lowest, {lowest.name or 'a muscle'}'s, ends at {lowest.deadband_Pa / 1e3:.4g} kPa): no command could "
                "inflate a muscle; is it in kPa? (the key is in Pa)"
            )

    @property
    def rest_length_m(self) -> float:
        """Sum of the sections' resting lengths (m)."""
        return sum(s.rest_length_m for s in self.sections)


def paper_section(
    disks: int = DEFAULT_DISKS, law: str | None = None, muscle: str = "FAM1", **kw
) -> SectionSpec:
    """Three of the paper's muscles, evenly spaced at the default radius."""
    m = load_muscle(muscle, law)
    return SectionSpec(muscles=(m, m, m), disks=disks, **kw)


def arm_1x3(**kw) -> ArmSpec:
    """One section of three FAM1 muscles, upright."""
    disks = kw.pop("disks", DEFAULT_DISKS)
    return ArmSpec(sections=(paper_section(disks),), name="arm_1x3", **kw)


def arm_3x3(**kw) -> ArmSpec:
    """Three sections of three FAM1 muscles, hanging (upright it buckles under its own weight at
    low pressure)."""
    kw.setdefault("orientation", "hanging")
    disks = kw.pop("disks", DEFAULT_DISKS)
    return ArmSpec(sections=(paper_section(disks),) * 3, name="arm_3x3", **kw)
