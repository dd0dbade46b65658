"""What ``efam size`` prints, and the force-stroke envelope figure of the best designs."""

from __future__ import annotations

import numpy as np

from .search import SizingResult


def _mm(x):
    return f"{x * 1e3:.1f}"


def summary(result: SizingResult, top: int = 3) -> str:
    """The request, the ranked designs (Table 2 parameters, mass, binding constraint), MuJoCo beside
    the analytic values, the bundle, or the closest point and what to relax."""
    r = result.request
    who = f"a bundle of {r.bundle} muscles" if r.bundle else "one muscle"
    lines = [
        f"sizing {who}: stroke {r.stroke:g} (x resting length) with {r.force_N:g} N at {r.pressure_Pa / 1e3:g} kPa"
        + (f", blocked force >= {r.blocked_force_N:g} N" if r.blocked_force_N else "")
        + (f", resting length {r.length_m * 1e3:g} mm" if r.length_m else "")
        + (f", diameter <= {r.max_diameter_m * 1e3:g} mm" if r.max_diameter_m else "")
        + (", unguided" if r.unguided and not r.bundle else ""),
        f"material: {result.material.source}; {result.catalogue}; {result.candidates} designs checked "
        f"in {result.seconds:.2f} s",
    ]
    lines += [f"note: {n}" for n in result.notes]
    if not result.feasible:
        lines.append("\nno catalogue design meets the request.")
        c = result.closest
        if c is not None:
            lines.append(
                f"closest achievable point: stroke {c.stroke:.3g} with {c.force_N:.4g} N "
                f"({100 * c.fraction:.1f} % of the way to the request; {c.tubing}, braid angle {c.theta_rest_deg:.2f} deg)"
            )
        for x in result.relax:
            lines.append(f"  to meet it, {x.message}")
        if not result.relax:
            lines.append("  no single requirement can be relaxed within the catalogue's limits")
        return "\n".join(lines)
    lines.append(
        f"\n{len(result.designs)} feasible designs; the best {min(top, len(result.designs))}, proposed:"
    )
    head = (
        f"{'#':>2} {'tube (bladder)':<26} {'sleeve':<28} {'L_45 mm':>8} {'L_B mm':>7} {'L_rest':>7} "
        f"{'D_rest':>6} {'theta':>6} {'mass g':>7} {'F@stroke N':>10} {'blocked N':>9} {'free':>6}  binding (margin)"
    )
    lines.append(head)
    for i, d in enumerate(result.designs[:top], start=1):
        g, p, b = d.geometry, d.performance, d.binding
        lines.append(
            f"{i:>2} {d.tubing.name:<26} {d.sleeve.name:<28} {_mm(g.sleeve_length_ref_m):>8} "
            f"{_mm(g.bladder_length_m):>7} {_mm(g.rest_length_m):>7} {_mm(g.rest_diameter_m):>6} "
            f"{d.muscle.theta_rest_deg:>6.2f} {d.mass_kg * 1e3:>7.1f} {p.force_at_stroke_N:>10.2f} "
            f"{p.blocked_force_N:>9.1f} {p.free_stroke:>6.3f}  {b.name} ({100 * b.margin:+.2f} %)"
        )
    best = result.designs[0]
    lines.append(f"\nbest design, every constraint ({best.tubing.name} in {best.sleeve.name}):")
    for c in best.checks:
        margin = "" if c.margin is None else f"margin {100 * c.margin:+.1f} %"
        lines.append(f"  {c.name:<16} {c.status:<4} {margin:<18} {c.note}")
    f = best.geometry
    lines.append(
        f"  end fittings: core {_mm(f.clamp_inner_diameter_m)} mm, channel bore {_mm(f.clamp_outer_diameter_m)} mm, "
        f"length {_mm(f.clamp_length_m)} mm; thread {f.thread_thickness_m * 1e3:.4g} mm"
    )
    verified = [d for d in result.designs if d.verification is not None]
    if verified:
        lines.append("\nMuJoCo rig (efam.muscle plugin) beside the analytic model, per design:")
        lines.append(f"{'#':>2} {'quantity':<18} {'analytic':>12} {'MuJoCo':>12} {'rel. diff':>10}")
        for i, d in enumerate(result.designs, start=1):
            if d.verification is None:
                continue
            for name, pair in d.verification.pairs().items():
                lines.append(
                    f"{i:>2} {name:<18} {pair.analytic:>12.5g} {pair.mujoco:>12.5g} {pair.relative_difference:>10.1e}"
                )
            verdict = {True: "meets", False: "DOES NOT meet"}.get(d.verification.meets_request)
            if verdict is None:
                lines.append("   -> not checked: the free or loaded rig did not come to rest within 60 s")
            else:
                lines.append(f"   -> in MuJoCo the design {verdict} the request (2 % tolerance)")
    if result.bundle is not None:
        b = result.bundle
        lines.append(
            f"\nbundle: {b.muscles} x the best muscle at radius {_mm(b.radius_m)} mm, {b.pressure_Pa / 1e3:g} kPa "
            f"(continuum reference beside MuJoCo)"
        )
        lines.append(
            f"  tip force, held at rest    {b.tip_force_N.analytic:10.1f} N   MuJoCo {b.tip_force_N.mujoco:10.1f} N"
        )
        lines.append(
            f"  stroke, all at P           {b.stroke.analytic:10.3f}     MuJoCo {b.stroke.mujoco:10.3f}"
        )
        lines.append(f"  bend range, muscle 1 vented {b.bend_range_deg:9.1f} deg (reference)")
        lines.append(
            f"  bend, muscle 1 at {b.bend_check_Pa / 1e3:.0f} kPa {b.bend_deg.analytic:9.1f} deg MuJoCo {b.bend_deg.mujoco:9.1f} deg"
        )
        lines.append(
            f"  tip deflection, horizontal, payload {b.payload_kg:g} kg {b.tip_deflection_m.analytic * 1e3:8.1f} mm "
            f"MuJoCo {b.tip_deflection_m.mujoco * 1e3:8.1f} mm"
        )
        lines += [f"  note: {n}" for n in b.notes]
    return "\n".join(lines)


def envelope_figure(result: SizingResult, path, top: int = 3):
    """Force-stroke curves at the request's pressure of the best designs (Eq. 2 lines, MuJoCo rig
    points for the verified ones), the request, and the best design's curves at lower pressures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .. import rig
    from ..files import save_figure

    r = result.request
    P = r.pressure_Pa
    fig, ax = plt.subplots(figsize=(7.2, 4.6), dpi=120)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    designs, seen = [], set()
    for d in result.designs:  # the best design of each tube: sleeves alone do not change the curve
        if d.tubing.name not in seen and len(designs) < top:
            seen.add(d.tubing.name)
            designs.append(d)
    if designs:
        best = designs[0].muscle
        for frac in (0.25, 0.5, 0.75):
            top_stroke = max(float(best.free_extension(frac * P)), 0.01)
            s = np.linspace(0, top_stroke, 80)
            ax.plot(s, best.push(frac * P, best.rest_length_m * (1 + s)), color="0.75", lw=1, zorder=1)
            ax.annotate(f"{frac * P / 1e3:.0f} kPa", (s[len(s) // 3], best.push(frac * P, best.rest_length_m * (1 + s[len(s) // 3]))),
                        fontsize=7, color="0.5")  # fmt: skip
    for i, d in enumerate(designs):
        m = d.muscle
        free = float(m.free_extension(P))
        s = np.linspace(0, free, 120)
        rank = result.designs.index(d) + 1
        label = f"#{rank} {d.tubing.name.removeprefix('latex ')}, {d.muscle.theta_rest_deg:.2f} deg, {d.mass_kg * 1e3:.0f} g"
        ax.plot(s, m.push(P, m.rest_length_m * (1 + s)), color=colours[i % len(colours)], lw=2, label=label)
        if d.verification is not None or i == 0:
            pts = np.linspace(0, free, 7)
            sim = rig.stroke_forces(m, P, m.rest_length_m * (1 + pts))
            ax.plot(pts, sim, "o", mfc="none", color=colours[i % len(colours)], ms=6)
    ax.plot(
        [r.stroke],
        [r.muscle_force_N],
        "k*",
        ms=14,
        label=f"request: {r.muscle_force_N:.4g} N at stroke {r.stroke:g}",
    )
    if r.muscle_blocked_force_N:
        ax.plot(
            [0],
            [r.muscle_blocked_force_N],
            "kP",
            ms=10,
            label=f"request: blocked {r.muscle_blocked_force_N:.4g} N",
        )
    if result.closest is not None:
        c = result.closest
        if c.muscle is not None:
            m = c.muscle
            s = np.linspace(0, max(float(m.free_extension(P)), 0.01), 120)
            ax.plot(s, m.push(P, m.rest_length_m * (1 + s)), color="tab:red", lw=1.5,
                    label=f"most capable: {c.tubing.removeprefix('latex ')}, {c.theta_rest_deg:.2f} deg")  # fmt: skip
        ax.plot([c.stroke], [c.force_N / r.muscles], "rx", ms=12, mew=2, label="closest achievable point")
    per = " per muscle" if r.bundle else ""
    ax.set_xlabel("stroke (extension / resting length)")
    ax.set_ylabel(f"push force{per}, N")
    ax.set_title(f"force-stroke envelope at {P / 1e3:g} kPa (lines: Eq. 2; circles: MuJoCo rig)", fontsize=10)
    ax.set_ylim(bottom=0)
    ax.set_xlim(left=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    save_figure(fig, path)  # a unique temporary, then a rename; the format from the suffix
    plt.close(fig)
    return path
