"""Bladder stress-strain laws sigma(epsilon, P) (Garbulinski et al. 2021, Sec. 4.7).

Every law is ``(E1 + E2 P) eps`` (the pressure-stiffened linear term, Eq. 15) plus at most one
non-linear term:

=================  =======================================  ======================================
name               sigma(eps, P)                            coefficients (SI, unit in the name)
=================  =======================================  ======================================
linear             (E1 + E2 P) eps                          E1_Pa, E2                     Eq. 15
polynomial         ... + E3 eps^2 + E4 eps^3                E1_Pa, E2, E3_Pa, E4_Pa       Eq. 16
exponential_decay  ... + E3 (1 - exp(-E4 eps))              E1_Pa, E2, E3_Pa, E4          Eq. 19
exponent           ... + E1 (s(eps)^E3 + s(eps)^E4)         E1_Pa, E2, E3, E4             Eq. 21
sigmoid            ... + E3 tanh(E4 eps)                    E1_Pa, E2, E3_Pa, E4          Sec. 7
arccot             ... + E3 (2/pi)(pi/2 - arccot(E4 eps))   E1_Pa, E2, E3_Pa, E4          Sec. 7
=================  =======================================  ======================================

``s(eps)^p`` is ``sign(eps)|eps|^p`` (the paper's rule for negative strain). The two laws the
paper's Future Work proposes are written so that E3 is the stress the transient saturates at
and E4 sets how fast it does, like the exponential-decay law, but odd in strain: they stay
bounded in compression where ``1 - exp(-E4 eps)`` grows exponentially. ``pi/2 - arccot(x)`` is
``atan(x)``.

Drucker stability (d sigma / d eps > 0): for every law but the polynomial one it follows from
one-coefficient bounds (paper Table 5), so ``check`` tests those; the polynomial law's slope is a
quadratic in strain whose minimum over the strain range is found exactly (Eq. 18). E2 >= 0 for
every law, so the slope is smallest at zero pressure and that is where the check is made.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LAW_NAMES = ("linear", "polynomial", "exponential_decay", "exponent", "sigmoid", "arccot")


class StressLawError(ValueError):
    """Unknown law, missing or out-of-bounds coefficient, or a Drucker-unstable law."""


def _signed_power(eps, p):
    return np.sign(eps) * np.abs(eps) ** p


def _signed_power_slope(eps, p):
    # d/d eps of sign(eps)|eps|^p = p |eps|^(p-1); infinite at 0 for p < 1 (the paper's transient)
    with np.errstate(divide="ignore"):
        return p * np.abs(eps) ** (p - 1.0)


# Non-linear terms and their strain derivatives, given c = (E1, E2, E3, E4).
_TERMS = {
    "linear": (lambda e, c: 0.0 * e, lambda e, c: 0.0 * e),
    "polynomial": (
        lambda e, c: c[2] * e**2 + c[3] * e**3,
        lambda e, c: 2.0 * c[2] * e + 3.0 * c[3] * e**2,
    ),
    "exponential_decay": (
        lambda e, c: c[2] * (1.0 - np.exp(-c[3] * e)),
        lambda e, c: c[2] * c[3] * np.exp(-c[3] * e),
    ),
    "exponent": (
        lambda e, c: c[0] * (_signed_power(e, c[2]) + _signed_power(e, c[3])),
        lambda e, c: c[0] * (_signed_power_slope(e, c[2]) + _signed_power_slope(e, c[3])),
    ),
    "sigmoid": (
        lambda e, c: c[2] * np.tanh(c[3] * e),
        lambda e, c: c[2] * c[3] / np.cosh(c[3] * e) ** 2,
    ),
    "arccot": (
        lambda e, c: c[2] * (2.0 / np.pi) * np.arctan(c[3] * e),
        lambda e, c: c[2] * (2.0 / np.pi) * c[3] / (1.0 + (c[3] * e) ** 2),
    ),
}


@dataclass(frozen=True)
class LawSpec:
    """What a law needs: coefficient names (unit in the name), hard bounds, a search box."""

    name: str
    params: tuple[str, ...]
    # Hard physical bounds: (low, high, low_open, high_open). Violating one is an error.
    bounds: tuple[tuple[float, float, bool, bool], ...]
    # Finite box for calibration searches (inside the hard bounds).
    search: tuple[tuple[float, float], ...]
    equation: str


_INF = math.inf
_E1 = (0.0, _INF, True, False)  # E1 > 0: a Young's-modulus-like stiffness (paper: 1-5 MPa)
_E2 = (0.0, _INF, False, False)  # E2 >= 0: pressure stiffens the bladder (paper Sec. 4.7)
#: the bladder moduli a muscle can have (Pa): soft silicone to stiff rubber; the calibration
#: searches inside it, and a muscle file's E1 outside it is refused (an MPa value written as Pa)
E1_PLAUSIBLE_PA = (1e4, 5e7)
#: the largest strain-stiffening exponent E4 of the exponent law a rubber bladder can have: the
#: paper's are 1.35 and 1.52 (Table 4) and Ogden's exponents for rubber reach about 5 (Treloar's
#: data: 1.3, 5, -2); a muscle file's or the plugin's E4 above it is refused (700 had loaded,
#: its stress a muscle's strain of 1.5 to the power 700)
EXPONENT_E4_MAX = 10.0
_E1_SEARCH = E1_PLAUSIBLE_PA
_E2_SEARCH = (0.0, 20.0)

LAWS: dict[str, LawSpec] = {
    "linear": LawSpec("linear", ("E1_Pa", "E2"), (_E1, _E2), (_E1_SEARCH, _E2_SEARCH), "(E1 + E2 P) eps"),
    "polynomial": LawSpec(
        "polynomial",
        ("E1_Pa", "E2", "E3_Pa", "E4_Pa"),
        (_E1, _E2, (-_INF, _INF, False, False), (-_INF, _INF, False, False)),
        (_E1_SEARCH, _E2_SEARCH, (-2e7, 2e7), (-2e7, 2e7)),
        "(E1 + E2 P) eps + E3 eps^2 + E4 eps^3",
    ),
    "exponential_decay": LawSpec(
        "exponential_decay",
        ("E1_Pa", "E2", "E3_Pa", "E4"),
        (_E1, _E2, (0.0, _INF, False, False), (0.0, _INF, True, False)),
        (_E1_SEARCH, _E2_SEARCH, (0.0, 2e7), (0.5, 200.0)),
        "(E1 + E2 P) eps + E3 (1 - exp(-E4 eps))",
    ),
    "exponent": LawSpec(
        "exponent",
        ("E1_Pa", "E2", "E3", "E4"),
        (_E1, _E2, (0.0, 1.0, True, True), (1.0, _INF, True, False)),
        (_E1_SEARCH, _E2_SEARCH, (0.05, 0.99), (1.01, 4.0)),
        "(E1 + E2 P) eps + E1 (sign(eps)|eps|^E3 + sign(eps)|eps|^E4)",
    ),
    "sigmoid": LawSpec(
        "sigmoid",
        ("E1_Pa", "E2", "E3_Pa", "E4"),
        (_E1, _E2, (0.0, _INF, False, False), (0.0, _INF, True, False)),
        (_E1_SEARCH, _E2_SEARCH, (0.0, 2e7), (0.5, 200.0)),
        "(E1 + E2 P) eps + E3 tanh(E4 eps)",
    ),
    "arccot": LawSpec(
        "arccot",
        ("E1_Pa", "E2", "E3_Pa", "E4"),
        (_E1, _E2, (0.0, _INF, False, False), (0.0, _INF, True, False)),
        (_E1_SEARCH, _E2_SEARCH, (0.0, 2e7), (0.5, 200.0)),
        "(E1 + E2 P) eps + E3 (2/pi) (pi/2 - arccot(E4 eps))",
    ),
}


def spec(name: str) -> LawSpec:
    """The :class:`LawSpec` of the law ``name`` (coefficients, bounds); unknown names raise."""
    if name not in LAWS:
        raise StressLawError(f"unknown stress law '{name}' (known: {', '.join(LAW_NAMES)})")
    return LAWS[name]


@dataclass(frozen=True)
class StressLaw:
    """A stress law with its coefficients, in SI and in ``LAWS[name].params`` order."""

    name: str
    coefficients: tuple[float, ...]

    def __post_init__(self):
        law = spec(self.name)
        if len(self.coefficients) != len(law.params):
            raise StressLawError(
                f"stress law '{self.name}' takes {len(law.params)} coefficients "
                f"({', '.join(law.params)}), got {len(self.coefficients)}"
            )
        object.__setattr__(self, "coefficients", tuple(float(c) for c in self.coefficients))
        self.check_bounds()

    # ----------------------------------------------------------------- construction / files
    @classmethod
    def from_dict(cls, name: str, coefficients: dict, where: str = "stress law") -> StressLaw:
        """From ``{"E1_Pa": ..., "E2": ...}``; every key must be known and present."""
        law = spec(name)
        unknown = sorted(set(coefficients) - set(law.params))
        if unknown:
            raise StressLawError(
                f"{where}: unknown coefficient key '{unknown[0]}' for law '{name}' "
                f"(expected {', '.join(law.params)})"
            )
        values = []
        for key in law.params:
            if key not in coefficients:
                raise StressLawError(f"{where}: missing coefficient key '{key}' for law '{name}'")
            value = coefficients[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise StressLawError(f"{where}: coefficient '{key}' must be a number, got {value!r}")
            values.append(float(value))
        return cls(name, tuple(values))

    def to_dict(self) -> dict[str, float]:
        """The coefficients by name, e.g. ``{"E1_Pa": ..., "E2": ...}``."""
        return dict(zip(spec(self.name).params, self.coefficients))

    # ----------------------------------------------------------------------- evaluation
    def __call__(self, strain, pressure_Pa):
        """Stress in Pa; broadcasts over strain and pressure arrays."""
        e = np.asarray(strain, dtype=float)
        c = self.coefficients
        return (c[0] + c[1] * np.asarray(pressure_Pa, dtype=float)) * e + _TERMS[self.name][0](e, _pad(c))

    def slope(self, strain, pressure_Pa):
        """d sigma / d eps in Pa (Eqs. 17, 20, 22 and their kin)."""
        e = np.asarray(strain, dtype=float)
        c = self.coefficients
        return (c[0] + c[1] * np.asarray(pressure_Pa, dtype=float)) + _TERMS[self.name][1](e, _pad(c))

    # ------------------------------------------------------------------------ stability
    def check_bounds(self) -> None:
        """Raise naming the coefficient when a hard bound (paper Table 5) is violated."""
        law = spec(self.name)
        for key, value, (lo, hi, lo_open, hi_open) in zip(law.params, self.coefficients, law.bounds):
            if not math.isfinite(value):
                raise StressLawError(f"stress law '{self.name}': coefficient '{key}' is not finite")
            too_low = value <= lo if lo_open else value < lo
            too_high = value >= hi if hi_open else value > hi
            if too_low or too_high:
                raise StressLawError(
                    f"stress law '{self.name}': coefficient '{key}' = {value:g} is outside "
                    f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
                )

    def min_slope(self, strain_lo: float, strain_hi: float) -> float:
        """Smallest d sigma / d eps over [strain_lo, strain_hi] at P = 0 (the worst pressure)."""
        c = self.coefficients
        if self.name == "polynomial":
            # slope = E1 + 2 E3 e + 3 E4 e^2: check both ends and the vertex if it is inside
            candidates = [strain_lo, strain_hi]
            if c[3] != 0.0:
                vertex = -c[2] / (3.0 * c[3])
                if strain_lo < vertex < strain_hi:
                    candidates.append(vertex)
            return min(c[0] + 2.0 * c[2] * e + 3.0 * c[3] * e * e for e in candidates)
        # Every other law: E1 plus non-negative terms once its bounds hold. The infimum of those
        # terms over a finite range is positive, so E1 is a safe lower bound.
        return c[0]

    def check_stable(self, strain_lo: float, strain_hi: float) -> None:
        """Drucker: raise when d sigma / d eps <= 0 anywhere in the strain range."""
        worst = self.min_slope(strain_lo, strain_hi)
        if not worst > 0.0:
            raise StressLawError(
                f"stress law '{self.name}' is not Drucker-stable: d sigma/d eps = {worst:.4g} Pa "
                f"<= 0 for strains in [{strain_lo:.3g}, {strain_hi:.3g}] (coefficients "
                f"{self.to_dict()})"
            )


def _pad(c: tuple[float, ...]) -> tuple[float, ...]:
    return c + (0.0,) * (4 - len(c))
