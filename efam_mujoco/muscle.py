"""The force-balance model of a fluidic artificial muscle (Garbulinski et al. 2021, Sec. 4).

This is the reference implementation: the C plugin in ``efam_mujoco/plugin`` evaluates the same
expressions, in the same order, and a test holds the two to 1e-9.

Sign: ``Muscle.tension`` follows the paper's Eq. 2 (positive = the muscle pulls its ends
together). ``Muscle.push`` is its negative, the MuJoCo actuator convention of this package
(positive = the muscle pushes its ends apart).

Geometry (Sec. 4.1-4.5). A thread of fixed length B winds N turns round a cylinder of length L
and outer radius R_o: ``B^2 = L^2 + (2 pi N R_o)^2``. The braid angle theta is measured from the
radius to the thread, so ``L = B sin(theta)``; theta < 35.26 deg extends under pressure (EFAM),
theta > 35.26 deg contracts (McKibben). Eq. 2 holds for both.

Admissible lengths. The incompressible bladder (volume V_B) must fit inside the sleeve:
``pi R_o(L)^2 L >= V_B``, i.e. ``L (B^2 - L^2) >= 4 pi N^2 V_B``. The two roots of that cubic in
(0, B) bound the lengths at which the model is defined; at either bound the bladder fills the
sleeve (no gas left inside) and the threads cannot move further.

Outside those bounds, and for any input the model cannot take, the behaviour is fixed and
documented (the plugin does the same, so nothing non-finite ever reaches MuJoCo):

* a length beyond a bound: the force at the bound plus a stiff lock-out spring
  ``lock_stiffness * (L - L_bound)`` that pulls (or pushes) the muscle back inside;
* a pressure below zero is taken as zero (the model has no vacuum physics), and below the
  dead-band pressure the pressure term is zero, never negative (Sec. 4.3);
* a tension-only muscle (a contractile McKibben whose braid buckles) cannot push: tension < 0
  becomes 0;
* a non-finite length or pressure gives zero force.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import brentq

from .stress import StressLaw
from .units import as_floats, check_pressure_Pa

#: Braid angle at which the blocked force changes sign (paper Sec. 1, Eq. 1): atan(1/sqrt(2)).
NEUTRAL_BRAID_ANGLE_DEG = math.degrees(math.atan(1.0 / math.sqrt(2.0)))

#: Default lock-out stiffness beyond the admissible length range, N/m.
DEFAULT_LOCK_STIFFNESS = 2.0e4
#: What a muscle can be (the plugin's bounds in efam_muscle.c; the muscle-file reader refuses
#: the same with the key's unit in its words): a rest length or diameter (m), the largest dead
#: band (Pa: the package drives a muscle with at most 1000 kPa, so at or above it the muscle never
#: inflates) and the stiffest lock-out spring (N/m)
SIZE_RANGE_M = (1e-4, 10.0)
MAX_DEADBAND_PA = 1.0e6
MAX_LOCK_STIFFNESS_N_PER_M = 1e9
#: A dead band is the pressure that takes up the slack between bladder and sleeve: the paper's
#: are 34 kPa, and below 100 Pa (a thousandth of the pressures a muscle is driven with, under
#: what a bench's pressure sensor resolves) none can be told from 0. A typed dead band in
#: [ZERO_DEADBAND_PA, MIN_DEADBAND_PA) is a kPa value written as Pa (33.62 for 33.62 kPa) and is
#: refused at every boundary (muscle files, the plugin's config, efam_muscle.c); below
#: ZERO_DEADBAND_PA it is 0 for every purpose (under a millinewton on any muscle here), which is
#: what a fit bounded below by 0 returns, so it passes. The Muscle itself takes any value in
#: [0, MAX_DEADBAND_PA): the fits that build one (calibrate, diagnose) may land anywhere there.
MIN_DEADBAND_PA = 100.0
ZERO_DEADBAND_PA = 1.0
#: The longest first-order pressure lag (s) an actuator may have (MuJoCo ``dynprm[0]`` of a
#: filter): a valve and a tube fill a bladder in milliseconds to seconds (the pressure_lag
#: effect's bound is 3 s); a minute is twenty times that, and a longer one never fills in a run.
MAX_PRESSURE_LAG_S = 60.0
#: gauge pressures ``free_length`` searches at: from vacuum to 100 MPa (past any fluidic muscle)
ATMOSPHERE_PA = 101325.0
MAX_GAUGE_PRESSURE_PA = 100e6


class MuscleError(ValueError):
    """Impossible muscle geometry or constants."""


def deadband_problem(deadband_Pa: float) -> str:
    """Why a dead band typed at a boundary (a file, the plugin's config) cannot be physical, ''
    when it can: in [0, MAX_DEADBAND_PA), and not in [ZERO_DEADBAND_PA, MIN_DEADBAND_PA)."""
    if not 0.0 <= deadband_Pa < MAX_DEADBAND_PA:
        return f"must be in 0 .. {MAX_DEADBAND_PA:g} Pa: at {MAX_DEADBAND_PA / 1e3:g} kPa or more the muscle never inflates"
    if ZERO_DEADBAND_PA <= deadband_Pa < MIN_DEADBAND_PA:
        return (
            f"a dead band of {deadband_Pa:g} Pa is below {MIN_DEADBAND_PA:g} Pa, under what a pressure sensor "
            "tells from none (the paper's are 34 kPa): was it in kPa? Write 0 for no dead band"
        )
    return ""


def written_deadband_Pa(deadband_Pa: float) -> float:
    """The dead band as a muscle file or the plugin's config writes it: a fitted one (calibrate's
    and diagnose's fits are bounded at 0 only) in [ZERO_DEADBAND_PA, MIN_DEADBAND_PA), under what
    a bench tells from none, is written as none, since every reader refuses that band as a kPa
    value typed as Pa; any other value as it is."""
    return 0.0 if ZERO_DEADBAND_PA <= deadband_Pa < MIN_DEADBAND_PA else deadband_Pa


def _numbers(value, label: str, unit: str) -> np.ndarray:
    """``value`` as an array of floats (:func:`units.as_floats`); a ValueError saying ``label``
    must be numbers in ``unit`` for None, text, or anything else numpy cannot read as numbers."""
    array = as_floats(value)
    if array is None:
        raise ValueError(f"{label} must be numbers ({unit}), got {value!r}")
    return array


def _fluid_pressures(pressure_Pa, where: str) -> np.ndarray:
    """``pressure_Pa`` as an array of gauge pressures a fluid can have (ValueError naming
    ``where`` otherwise: not numbers, NaN, inf, below vacuum or above :data:`MAX_GAUGE_PRESSURE_PA`)."""
    P = _numbers(pressure_Pa, f"{where}: pressure_Pa", "Pa")
    bad = ~(np.isfinite(P) & (P >= -ATMOSPHERE_PA) & (P <= MAX_GAUGE_PRESSURE_PA))
    if bad.any():
        value = float(P.ravel()[int(np.argmax(bad.ravel()))])
        raise ValueError(
            f"{where}: pressure {value!r} Pa is outside the gauge pressures a fluid can have here "
            f"({-ATMOSPHERE_PA:g} .. {MAX_GAUGE_PRESSURE_PA:g} Pa)"
        )
    return P


def _lengths(length_m, what: str) -> np.ndarray:
    """``length_m`` as an array of lengths a muscle can have, finite and above 0 m (ValueError
    naming ``what``, the entry point and its argument, otherwise). One pass over the array: it
    guards public entry points only, the force itself takes any input (see :meth:`Muscle.tension`)."""
    L = _numbers(length_m, what, "m")
    # NaN fails L > 0 and inf fails L < inf: one reduction catches all three
    ok = (L > 0.0) & (L < math.inf)
    if not ok.all():
        value = float(L.ravel()[int(np.argmin(ok.ravel()))])
        raise ValueError(f"{what}: {value!r} m is not a finite length above 0 m")
    return L


@dataclass(frozen=True)
class Geometry:
    """What is measured while a muscle is made (paper Table 2), in SI.

    The sleeve is measured at a reference braid angle (the paper uses 45 deg) as a length and a
    diameter; the bladder before assembly; the end-fitting clamping channel (one per fitting) and
    the thread from the parts. ``rest_length_m`` and ``rest_diameter_m`` are measured on the
    finished, cycled muscle.
    """

    rest_length_m: float
    rest_diameter_m: float
    sleeve_length_ref_m: float
    sleeve_diameter_ref_m: float
    bladder_length_m: float
    bladder_inner_diameter_m: float
    bladder_outer_diameter_m: float
    clamp_length_m: float
    clamp_inner_diameter_m: float
    clamp_outer_diameter_m: float
    thread_thickness_m: float
    sleeve_angle_ref_deg: float = 45.0
    fittings: int = 2

    def __post_init__(self):
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise MuscleError(f"geometry: '{name}' must be a finite number, got {value!r}")
        for name in self.__dataclass_fields__:
            if name != "thread_thickness_m" and getattr(self, name) <= 0:
                raise MuscleError(f"geometry: '{name}' must be positive, got {getattr(self, name)}")
        if self.thread_thickness_m < 0:
            raise MuscleError("geometry: 'thread_thickness_m' must not be negative")
        if not 0 < self.sleeve_angle_ref_deg < 90:
            raise MuscleError("geometry: 'sleeve_angle_ref_deg' must be in (0, 90)")
        if self.bladder_inner_diameter_m >= self.bladder_outer_diameter_m:
            raise MuscleError("geometry: bladder inner diameter must be below its outer diameter")
        if self.clamp_outer_diameter_m - 2 * self.thread_thickness_m <= self.clamp_inner_diameter_m:
            raise MuscleError(
                "geometry: clamping channel has no room for the bladder "
                "(clamp outer diameter - 2 thread thickness <= clamp inner diameter)"
            )

    @property
    def turns(self) -> float:
        """Eq. 4 at the reference angle: N = L_ref / (pi D_ref tan(theta_ref))."""
        ref = math.radians(self.sleeve_angle_ref_deg)
        return self.sleeve_length_ref_m / (math.pi * self.sleeve_diameter_ref_m * math.tan(ref))

    @property
    def theta_rest_deg(self) -> float:
        """Eq. 5 (general reference angle): tan(theta_rest) = L_rest / (pi D_rest N)."""
        return math.degrees(math.atan(self.rest_length_m / (math.pi * self.rest_diameter_m * self.turns)))

    @property
    def clamp_volume_m3(self) -> float:
        """Eq. 6, for all fittings: the bladder volume squeezed into the clamping channels."""
        r_out = self.clamp_outer_diameter_m / 2 - self.thread_thickness_m
        r_in = self.clamp_inner_diameter_m / 2
        return math.pi * (r_out**2 - r_in**2) * self.clamp_length_m * self.fittings

    @property
    def bladder_section_m2(self) -> float:
        """Cross-section area of the bladder wall (m^2), from its outer and inner diameters."""
        return math.pi * ((self.bladder_outer_diameter_m / 2) ** 2 - (self.bladder_inner_diameter_m / 2) ** 2)

    @property
    def bladder_length_lost_m(self) -> float:
        """Eq. 7: the bladder length the end fittings take, Delta L_B,FIX."""
        return self.clamp_volume_m3 / self.bladder_section_m2

    @property
    def bladder_volume_m3(self) -> float:
        """Eq. 8: working bladder (wall material) volume V_B."""
        working = self.bladder_length_m - self.bladder_length_lost_m
        if working <= 0:
            raise MuscleError("geometry: the end fittings take the whole bladder length")
        return self.bladder_section_m2 * working


@dataclass(frozen=True)
class Muscle:
    """A muscle given by its derived constants; every length in m, pressure in Pa.

    Build one from a :class:`Geometry` with :meth:`from_geometry`, or directly from constants
    (for a bought muscle, or one calibrated from data).
    """

    rest_length_m: float
    rest_diameter_m: float
    theta_rest_deg: float
    bladder_volume_m3: float
    deadband_Pa: float
    stress: StressLaw
    tension_only: bool = False
    lock_stiffness_N_per_m: float = DEFAULT_LOCK_STIFFNESS
    name: str = ""
    # derived in __post_init__
    turns: float = field(init=False, repr=False)
    thread_length_m: float = field(init=False, repr=False)
    min_length_m: float = field(init=False, repr=False)
    max_length_m: float = field(init=False, repr=False)
    rest_outer_radius_m: float = field(init=False, repr=False)
    rest_wall_thickness_m: float = field(init=False, repr=False)

    def __post_init__(self):
        # types first: a string compares with nothing, and 'false' is a true string
        for key in ("rest_length_m", "rest_diameter_m", "theta_rest_deg", "bladder_volume_m3", "deadband_Pa",
                    "lock_stiffness_N_per_m"):  # fmt: skip
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise MuscleError(f"muscle constant '{key}' must be a number, got {value!r}")
        if not isinstance(self.tension_only, (bool, np.bool_)):
            raise MuscleError(f"muscle 'tension_only' must be True or False, got {self.tension_only!r}")
        if not isinstance(self.stress, StressLaw):
            raise MuscleError(f"muscle 'stress' must be a StressLaw, got {self.stress!r}")
        if not isinstance(self.name, str):
            raise MuscleError(f"muscle 'name' must be a string, got {self.name!r}")
        # the plugin's bounds (efam_muscle.c, and the muscle-file reader's): outside them a value
        # is a unit slip (a rest length of 170 m: mm written as m), not a muscle
        checks = {
            "rest_length_m": (
                SIZE_RANGE_M[0] <= self.rest_length_m <= SIZE_RANGE_M[1],
                "must be in 0.0001 .. 10 m (was it in mm?)",
            ),
            "rest_diameter_m": (
                SIZE_RANGE_M[0] <= self.rest_diameter_m <= SIZE_RANGE_M[1],
                "must be in 0.0001 .. 10 m (was it in mm?)",
            ),
            "theta_rest_deg": (0 < self.theta_rest_deg < 90, "must be in (0, 90) deg"),
            "bladder_volume_m3": (self.bladder_volume_m3 > 0, "must be positive"),
            "deadband_Pa": (
                0 <= self.deadband_Pa < MAX_DEADBAND_PA,
                "must be in 0 .. 1e6 Pa (was it in kPa?)",
            ),
            "lock_stiffness_N_per_m": (
                0 <= self.lock_stiffness_N_per_m <= MAX_LOCK_STIFFNESS_N_PER_M,
                "must be in 0 .. 1e9 N/m",
            ),
        }
        for key, (ok, rule) in checks.items():
            value = getattr(self, key)
            if not (math.isfinite(value) and ok):
                raise MuscleError(f"muscle constant '{key}' is invalid: {value!r} ({rule})")
        theta = math.radians(self.theta_rest_deg)
        turns = self.rest_length_m / (math.pi * self.rest_diameter_m * math.tan(theta))  # Eq. 4
        thread = self.rest_length_m / math.sin(theta)  # Eq. 3
        set_ = object.__setattr__
        set_(self, "turns", turns)
        set_(self, "thread_length_m", thread)
        set_(self, "rest_outer_radius_m", self.rest_diameter_m / 2)
        lo, hi = _admissible_lengths(thread, turns, self.bladder_volume_m3)
        if not lo < self.rest_length_m < hi:
            raise MuscleError(
                f"muscle '{self.name}': the bladder (V_B = {self.bladder_volume_m3:.4g} m^3) does not "
                f"fit inside the sleeve at its resting length {self.rest_length_m:.4g} m"
            )
        set_(self, "min_length_m", lo)
        set_(self, "max_length_m", hi)
        set_(self, "rest_wall_thickness_m", float(self._wall(self.rest_length_m, self.rest_outer_radius_m)))
        self.stress.check_stable(*self.strain_range())

    # ---------------------------------------------------------------------- construction
    @classmethod
    def from_geometry(cls, geometry: Geometry, deadband_Pa: float, stress: StressLaw, **kw) -> Muscle:
        """A muscle from measured :class:`Geometry` (paper Sec. 4.1-4.2), a dead band and a stress law;
        ``kw``: the other :class:`Muscle` fields (``name``, ``tension_only``...)."""
        return cls(
            rest_length_m=geometry.rest_length_m,
            rest_diameter_m=geometry.rest_diameter_m,
            theta_rest_deg=geometry.theta_rest_deg,
            bladder_volume_m3=geometry.bladder_volume_m3,
            deadband_Pa=deadband_Pa,
            stress=stress,
            **kw,
        )

    def with_stress(self, stress: StressLaw) -> Muscle:
        """The same muscle with another stress law."""
        return replace(self, stress=stress)

    # ------------------------------------------------------------------------- geometry
    @property
    def is_extensile(self) -> bool:
        """Whether the muscle extends when pressurised: its resting braid angle is below the
        neutral angle (35.26 deg in this model's convention)."""
        return self.theta_rest_deg < NEUTRAL_BRAID_ANGLE_DEG

    @property
    def kind(self) -> str:
        """``"extensile"`` or ``"contractile"``."""
        return "extensile" if self.is_extensile else "contractile"

    def outer_radius(self, length_m):
        """Eq. 10: R_o(L) = sqrt(B^2 - L^2) / (2 pi N), 0 m from the thread length on. Lengths in
        m; a NaN, an infinite or a length at or below 0 m is refused (it gave a radius)."""
        return self._outer_radius(_lengths(length_m, "Muscle.outer_radius: length_m"))

    def _outer_radius(self, L):
        # unchecked, for callers that clip their lengths into the admissible range first: the
        # force (a simulation's hot path) and the wall and strains (NaN in, NaN out, as before)
        L = np.asarray(L, dtype=float)
        return np.sqrt(np.maximum(self.thread_length_m**2 - L * L, 0.0)) / (2 * math.pi * self.turns)

    def _wall(self, L, r_out):
        inner_sq = np.maximum(r_out * r_out - self.bladder_volume_m3 / (math.pi * L), 0.0)
        return r_out - np.sqrt(inner_sq)

    def wall_thickness(self, length_m):
        """Eq. 11: t_B(L) = R_o - sqrt(R_o^2 - V_B / (pi L))."""
        L = np.clip(np.asarray(length_m, dtype=float), self.min_length_m, self.max_length_m)
        return self._wall(L, self._outer_radius(L))

    def strains(self, length_m):
        """Eqs. 12-13: longitudinal and circumferential (mid-wall) strains."""
        L = np.clip(np.asarray(length_m, dtype=float), self.min_length_m, self.max_length_m)
        r_out = self._outer_radius(L)
        t = self._wall(L, r_out)
        rest_mid = self.rest_outer_radius_m - self.rest_wall_thickness_m / 2
        return L / self.rest_length_m - 1.0, (r_out - t / 2) / rest_mid - 1.0

    def strain_range(self) -> tuple[float, float]:
        """The smallest and largest strain (either direction) over the admissible lengths."""
        L = np.linspace(self.min_length_m, self.max_length_m, 2001)
        ez, ec = self.strains(L)
        return float(min(ez.min(), ec.min())), float(max(ez.max(), ec.max()))

    # --------------------------------------------------------------------------- forces
    def tension(self, pressure_Pa, length_m):
        """Eq. 2: axial force in N, positive when the muscle pulls. Broadcasts its inputs.

        As in the C plugin (which this is the reference for), a pressure under zero gauge counts as
        zero, a length outside the admissible range meets the lock stiffness, and a non-finite
        pressure or length gives 0 N: a simulation step never hands MuJoCo a NaN. Code that reads
        measured data checks it first (``recordings``, ``check_pressure_Pa``)."""
        P_in, L_in = np.broadcast_arrays(
            np.asarray(pressure_Pa, dtype=float), np.asarray(length_m, dtype=float)
        )
        finite = np.isfinite(P_in) & np.isfinite(L_in)
        P = np.where(finite, np.maximum(P_in, 0.0), 0.0)
        L_raw = np.where(finite, L_in, self.rest_length_m)
        L = np.clip(L_raw, self.min_length_m, self.max_length_m)

        N, B, V = self.turns, self.thread_length_m, self.bladder_volume_m3
        r_out = self._outer_radius(L)
        t = self._wall(L, r_out)
        eps_z = L / self.rest_length_m - 1.0
        eps_c = (r_out - t / 2) / (self.rest_outer_radius_m - self.rest_wall_thickness_m / 2) - 1.0
        sigma_z = self.stress(eps_z, P)
        sigma_c = self.stress(eps_c, P)
        gauge = np.maximum(P - self.deadband_Pa, 0.0)
        force = (
            gauge / (4 * math.pi * N * N) * (3 * L * L - B * B)
            + sigma_z * V / L
            - sigma_c * t * L * L / (2 * math.pi * r_out * N * N)
        )
        force = force + self.lock_stiffness_N_per_m * (L_raw - L)
        if self.tension_only:
            force = np.maximum(force, 0.0)
        force = np.where(finite, force, 0.0)
        return force if force.ndim else float(force)

    def push(self, pressure_Pa, length_m):
        """MuJoCo sign: positive = pushes the ends apart (the negative of Eq. 2)."""
        return -self.tension(pressure_Pa, length_m)

    def blocked_tension(self, pressure_Pa):
        """Eq. 9 (Gaylord with dead band): the force at the resting length, paper sign
        (positive = pulls; an EFAM's is negative). Pressures in Pa (a warning below 1000 Pa)."""
        check_pressure_Pa(pressure_Pa, "Muscle.blocked_tension")
        return self._blocked_tension(pressure_Pa)

    def blocked_push(self, pressure_Pa):
        """Eq. 9 in the MuJoCo sign: the force at the resting length, positive = pushes (what
        ``rig.blocked_push`` measures). Pressures in Pa (a warning below 1000 Pa)."""
        check_pressure_Pa(pressure_Pa, "Muscle.blocked_push")
        return -self._blocked_tension(pressure_Pa, "Muscle.blocked_push")

    def blocked_force(self, pressure_Pa):
        """Deprecated: the paper-sign blocked force (= :meth:`blocked_tension`). Its name hid its
        sign (``rig.blocked_force`` was push positive); use ``blocked_tension`` or ``blocked_push``."""
        warnings.warn(
            "Muscle.blocked_force is the paper sign (positive = pulls); use Muscle.blocked_tension "
            "(same value) or Muscle.blocked_push (MuJoCo sign)",
            DeprecationWarning,
            stacklevel=2,
        )
        return self._blocked_tension(pressure_Pa)

    def _blocked_tension(self, pressure_Pa, where: str = "Muscle.blocked_tension"):
        # as free_length: a NaN gave NaN, 1e12 Pa a 5.8e8 N "blocked force"
        P = _fluid_pressures(pressure_Pa, where)
        P = np.maximum(P, 0.0)
        theta = math.radians(self.theta_rest_deg)
        gauge = np.maximum(P - self.deadband_Pa, 0.0)
        area = math.pi * self.rest_diameter_m**2 / 4
        force = gauge * area / math.cos(theta) ** 2 * (3 * math.sin(theta) ** 2 - 1)
        return force if force.ndim else float(force)

    def free_length(self, pressure_Pa, check_units: bool = True):
        """Length at which the muscle carries no force (Eq. 2 = 0), searched from rest length in
        the direction the pressure moves it. Vectorised over pressures (a loop of root finds).
        Pressures in Pa (a warning below 1000 Pa; ``check_units=False`` when the caller has
        checked a set these pressures belong to, e.g. one section's differential pressures)."""
        if check_units and not (pressure_Pa is None or isinstance(pressure_Pa, (str, bytes))):
            check_pressure_Pa(pressure_Pa, "Muscle.free_length")
        # a root search needs a pressure a fluid can have: a NaN found the rest length, 1e308 Pa
        # ended in scipy's "function value is NaN"
        P = _fluid_pressures(pressure_Pa, "Muscle.free_length")
        out = np.array([self._free_length_one(float(p)) for p in P.ravel()]).reshape(P.shape)
        return out if out.ndim else float(out)

    def free_extension(self, pressure_Pa):
        """Free length change as a fraction of resting length (paper Fig. 7b)."""
        return np.asarray(self.free_length(pressure_Pa)) / self.rest_length_m - 1.0

    def _free_length_one(self, p: float) -> float:
        f_rest = self.tension(p, self.rest_length_m)
        if f_rest == 0.0:
            return self.rest_length_m
        # a pushing muscle lengthens, a pulling one shortens
        end = self.max_length_m if f_rest < 0 else self.min_length_m
        grid = np.linspace(self.rest_length_m, end, 400)
        f = self.tension(p, grid)
        sign_change = np.nonzero(np.sign(f[1:]) != np.sign(f[0]))[0]
        if sign_change.size == 0:
            # no root inside: the muscle reaches its bound and the lock-out spring balances it
            if self.lock_stiffness_N_per_m == 0:
                return end
            return end - f[-1] / self.lock_stiffness_N_per_m
        i = sign_change[0]
        if f[i + 1] == 0.0:
            return float(grid[i + 1])
        return brentq(lambda L: self.tension(p, L), grid[i], grid[i + 1], xtol=1e-15, rtol=1e-14)

    def force_stroke(self, pressure_Pa: float, lengths_m):
        """Tension over a stroke at fixed pressure (paper Fig. 6), N, paper sign. Pressure in Pa
        (a warning below 1000 Pa), lengths in m; beyond the admissible lengths the lock-out
        spring acts, as in :meth:`tension`. Unlike :meth:`tension` (a simulation step's 0 N), a
        pressure no fluid can have or a length that is not finite and above 0 m is refused: a
        NaN gave a curve of 0 N, a negative length a lock-out force of millions of N."""
        P = _fluid_pressures(pressure_Pa, "Muscle.force_stroke")
        check_pressure_Pa(P, "Muscle.force_stroke")
        return self.tension(P, _lengths(lengths_m, "Muscle.force_stroke: lengths_m"))


def _admissible_lengths(thread: float, turns: float, volume: float) -> tuple[float, float]:
    """Roots in (0, B) of L^3 - B^2 L + 4 pi N^2 V = 0 (bladder exactly fills the sleeve)."""
    c = 4 * math.pi * turns**2 * volume
    peak = thread / math.sqrt(3.0)  # L (B^2 - L^2) is largest here
    if peak * (thread**2 - peak**2) <= c:
        raise MuscleError("the bladder does not fit inside the sleeve at any length")
    g = lambda L: L * (thread**2 - L * L) - c  # noqa: E731
    lo = brentq(g, 0.0, peak, xtol=1e-15, rtol=1e-15)
    hi = brentq(g, peak, thread, xtol=1e-15, rtol=1e-15)
    return lo, hi
