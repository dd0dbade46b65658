"""Calibration reports: the paper's Table 3 and Table 4 forms, and Figs. 8, 9 and 11 alike."""

from __future__ import annotations

import numpy as np

from ..files import save_figure
from ..stress import LAWS
from .core import Calibration
from .fit import LawFit

ROW_LABELS = {"blocked": "blocked force*", "eq14": "Eq. 14 (mean of k = 1..n)"}


def table3(fits: dict[str, LawFit]) -> str:
    """Eq. 14 relative error (%) per comparison length and law (paper Table 3 form), markdown."""
    laws = [law for law, fit in fits.items() if fit.eq14_by_k]
    if not laws:
        return "(Eq. 14 needs isobaric strokes: no Table 3 for these recordings)"
    rows = list(fits[laws[0]].eq14_by_k)
    lines = ["| comparison length | " + " | ".join(laws) + " |", "|---" * (len(laws) + 1) + "|"]
    for row in rows:
        label = ROW_LABELS.get(row, f"{row} dL_max")
        cells = [f"{fits[law].eq14_by_k.get(row, float('nan')):.2f}" for law in laws]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _coefficient(law: str, key: str, value: float) -> str:
    if key == "E1_Pa":
        return f"{value / 1e6:.4f}"
    if key.endswith("_Pa"):
        return f"{value:,.0f}"
    return f"{value:.4f}"


def table4(cal: Calibration) -> str:
    """Coefficients (paper Table 4 form: E1 in MPa, E3/E4 in Pa or plain) and the errors."""
    lines = [
        "| law | E1 (x10^6 Pa) | E2 | E3 | E4 | RMS (N) | held-out RMS (N) | Eq. 14 (%) | stable | fit (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for law, fit in cal.fits.items():
        params = LAWS[law].params
        cells = [_coefficient(law, p, fit.coefficients[p]) for p in params] + [""] * (4 - len(params))
        held = cal.heldout_rms_N.get(law)
        eq14 = "-" if fit.eq14_error_pct is None else f"{fit.eq14_error_pct:.2f}"
        lines.append(
            f"| {law} | " + " | ".join(cells) + f" | {fit.rms_N:.3f} | "
            f"{'-' if held is None else f'{held:.3f}'} | {eq14} | {'yes' if fit.stable else 'NO'} | "
            f"{fit.seconds:.3f} |"
        )
    return "\n".join(lines)


def baseline_table(ours: dict[str, LawFit], baseline: dict[str, LawFit]) -> str:
    """A Markdown table: our fit beside the paper's Nelder-Mead procedure, per law (Eq. 14, RMS, time)."""
    lines = [
        "| law | ours: Eq. 14 (%) | ours: RMS (N) | ours: s | Nelder-Mead: Eq. 14 (%) | NM: RMS (N) | NM: s |",
        "|---|---|---|---|---|---|---|",
    ]
    for law, fit in ours.items():
        nm = baseline.get(law)
        if nm is None:
            continue
        lines.append(
            f"| {law} | {fit.eq14_error_pct:.3f} | {fit.rms_N:.3f} | {fit.seconds:.3f} | "
            f"{nm.eq14_error_pct:.3f} | {nm.rms_N:.3f} | {nm.seconds:.3f} |"
        )
    return "\n".join(lines)


def summary(cal: Calibration) -> str:
    """The text report of a calibration: data, blocked-force fit, each law's errors and coefficients."""
    s = cal.problem.samples
    b = cal.blocked
    rejected = [f"{p / 1e3:.1f} kPa" for p, ok in zip(b.pressure_Pa, b.inlier) if not ok]
    levels = ", ".join(f"{p / 1e3:.1f}" for p in s.levels_Pa) if s.isobaric else "none (pressure ramps)"
    return "\n".join(
        [
            f"recordings: {len(cal.problem.recordings)}, samples: {len(s)}, isobaric levels (kPa): {levels}",
            f"blocked force (Sec. 4.3-4.4): {len(b.pressure_Pa)} point(s), dead band "
            f"{cal.deadband_Pa / 1e3:.2f} kPa, theta_rest {cal.theta_rest_deg:.3f} deg (muscle file had "
            f"{cal.geometry_theta_rest_deg:.3f} deg), line RMS {b.rms_N:.3f} N, outliers rejected: "
            f"{', '.join(rejected) if rejected else 'none'}",
            *(
                [
                    f"dead band fitted with the laws (--fit-deadband): {cal.muscle.deadband_Pa / 1e3:.2f} kPa, the value written"
                ]
                if abs(cal.muscle.deadband_Pa - cal.deadband_Pa) > 1e-3 * max(cal.deadband_Pa, 1.0)
                else []
            ),
            f"best law (smallest held-out RMS; fewest coefficients within 1 %): {cal.best_law}; "
            f"calibration took {cal.seconds:.2f} s",
        ]
    )


# ---------------------------------------------------------------------------------- figures
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figure_blocked(cal: Calibration, path) -> None:
    """Fig. 8 alike: blocked force vs pressure, the fitted line, Eq. 9 with the muscle's angle."""
    plt = _plt()
    b = cal.blocked
    fig, ax = plt.subplots(figsize=(5.5, 4))
    P = np.linspace(0, max(b.pressure_Pa.max(), 1.0) * 1.05, 200)
    ax.plot(b.pressure_Pa[b.inlier] / 1e3, -b.tension_N[b.inlier], "o", label="data (blocked force)")
    if (~b.inlier).any():
        ax.plot(b.pressure_Pa[~b.inlier] / 1e3, -b.tension_N[~b.inlier], "x", ms=9, label="rejected outlier")
    ax.plot(P / 1e3, -b.predict(P), "-", label=f"fit: dead band {b.deadband_Pa / 1e3:.1f} kPa, "
            f"theta {cal.theta_rest_deg:.2f} deg")  # fmt: skip
    theta = np.radians(cal.geometry_theta_rest_deg)
    area = np.pi * cal.problem.muscle.rest_diameter_m**2 / 4
    before = np.maximum(P - b.deadband_Pa, 0) * area * (2 * np.tan(theta) ** 2 - 1)  # Eq. 9
    ax.plot(P / 1e3, -before, "--", label=f"Eq. 9, geometric theta {cal.geometry_theta_rest_deg:.2f} deg")
    ax.set_xlabel("pressure (kPa)")
    ax.set_ylabel("blocked force, push positive (N)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def figure_strokes(cal: Calibration, path, laws=None) -> None:
    """Fig. 9 alike: force vs stroke, data (grey) and each law's model per pressure (black)."""
    plt = _plt()
    laws = list(laws or cal.fits)
    s = cal.problem.samples
    cols = min(3, len(laws))
    rows = int(np.ceil(len(laws) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows), squeeze=False, sharey=True)
    rest = cal.problem.muscle.rest_length_m
    step = max(1, len(s) // 6000)
    cmap = plt.get_cmap("viridis")
    for ax, law in zip(axes.flat, laws):
        muscle = cal.fits[law].muscle
        if not s.isobaric:
            ax.scatter(s.length_m[::step] / rest - 1, -s.tension_N[::step], s=1, c="0.6", rasterized=True)
        for j, p in enumerate(s.levels_Pa if s.isobaric else []):
            at = np.nonzero(s.level == j)[0][::step]
            color = cmap(j / max(len(s.levels_Pa) - 1, 1))
            ax.scatter(s.length_m[at] / rest - 1, -s.tension_N[at], s=1, color=color, rasterized=True,
                       label=f"{p / 1e3:.0f} kPa")  # fmt: skip
            L = np.linspace(s.length_m[at].min(), s.length_m[at].max(), 200)
            ax.plot(L / rest - 1, muscle.push(p, L), color="k", lw=1.0)
        fit = cal.fits[law]
        eq14 = "" if fit.eq14_error_pct is None else f", Eq. 14 {fit.eq14_error_pct:.2f} %"
        ax.set_title(f"{law}: RMS {fit.rms_N:.2f} N{eq14}", fontsize=9)
        ax.set_xlabel("length change / rest length")
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("force, push positive (N)")
    if s.isobaric:
        axes.flat[0].legend(fontsize=7, markerscale=6, title="data; black: model", title_fontsize=7)
    for ax in list(axes.flat)[len(laws) :]:
        ax.axis("off")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def figure_stress(cal: Calibration, path) -> None:
    """Fig. 11 alike: sigma(eps, P = 0) of every fitted law, small strains and the whole range."""
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    lo, hi = cal.problem.strain_range
    for law, fit in cal.fits.items():
        e_small = np.linspace(0, 0.10, 300)
        e_all = np.linspace(0.0, 4.0, 600)
        a.plot(e_small * 100, fit.stress(e_small, 0.0) / 1e6, label=law)
        b.plot(e_all * 100, fit.stress(e_all, 0.0) / 1e6, label=law)
    a.set_title("strain 0-10 %")
    b.set_title("strain 0-400 % (paper Fig. 11b)")
    for ax in (a, b):
        ax.set_xlabel("strain (%)")
        ax.set_ylabel("stress at P = 0 (MPa)")
        ax.grid(alpha=0.3)
    a.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def write_figures(cal: Calibration, prefix) -> list[str]:
    """Write ``PREFIX_blocked.png``, ``PREFIX_strokes.png`` and ``PREFIX_stress.png``; returns the paths."""
    paths = [f"{prefix}_blocked.png", f"{prefix}_strokes.png", f"{prefix}_stress.png"]
    figure_blocked(cal, paths[0])
    figure_strokes(cal, paths[1])
    figure_stress(cal, paths[2])
    return paths
