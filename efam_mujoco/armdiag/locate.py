"""Where the replayed tip departs from the recorded one: in time, in pressure space, by muscle and
section. Plain statistics of the residual of the re-fitted model against the noise floor."""

from __future__ import annotations

import numpy as np


def noise_floor(time_s: np.ndarray, tip_m: np.ndarray) -> float:
    """Marker noise (m, per coordinate): a robust scale of the tip's second differences, which
    white noise of std s gives with std s sqrt(6) and smooth motion hardly touches."""
    ok = np.all(np.isfinite(tip_m), axis=1)
    d2 = tip_m[2:] - 2 * tip_m[1:-1] + tip_m[:-2]
    keep = ok[2:] & ok[1:-1] & ok[:-2]
    d2 = d2[keep]
    if len(d2) < 10:  # dropouts leave few runs of three: the marked samples in a row, gaps closed
        # (a regular pattern, every other sample say, keeps the differences those of a finer grid)
        marked = tip_m[ok]
        d2 = marked[2:] - 2 * marked[1:-1] + marked[:-2]
    if len(d2) < 10:
        return float("nan")
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) * 1.4826
    return float(np.sqrt(np.mean(mad**2)) / np.sqrt(6.0))


def _rms(x) -> float | None:
    """RMS of the rows ``x``; None when there are none (a bin the test never visited: a muscle
    never commanded above the others, a pressure level every row shares with the next)."""
    return float(np.sqrt(np.mean(x**2))) if x.size else None


def _mm(v: float | None) -> str:
    return "no samples" if v is None else f"{v * 1e3:.2f} mm"


def locate(
    time_s,
    command_Pa,
    muscles,
    groups,
    residual,
    valid,
    noise,
    directions: dict[str, np.ndarray],
    blocks: int = 10,
) -> dict:
    """``residual`` (n, 3) of the re-fitted model; ``directions``: per muscle, the change of the
    replayed tip when that muscle's pressure is scaled or delayed (n, 3; NaN rows where it was not
    replayed), to attribute the residual (over the rows it covers)."""
    r = np.where(valid[:, None], residual, 0.0)
    edges = np.linspace(time_s[0], time_s[-1], blocks + 1)
    in_time = []
    for a, b in zip(edges[:-1], edges[1:]):
        rows = valid & (time_s >= a) & (time_s <= b)
        in_time.append({"from_s": float(a), "to_s": float(b), "rms_m": _rms(residual[rows])})
    mean_p = command_Pa.mean(axis=1)
    cuts = np.quantile(mean_p, [1 / 3, 2 / 3])
    level = np.digitize(mean_p, cuts)
    by_level = {}
    for k, name in enumerate(("low", "mid", "high")):
        rows = valid & (level == k)
        by_level[name] = {
            "mean_pressure_kPa": float(mean_p[rows].mean() / 1e3) if rows.any() else None,
            "rms_m": _rms(residual[rows]),
        }
    # the muscle commanded furthest above the others; none where the commands are (nearly) all
    # equal (within 1 % of the test's top command), which would credit every such row to muscle 0
    spread = command_Pa - command_Pa.mean(1, keepdims=True)
    dominant = np.argmax(spread, axis=1)
    dominant[spread.max(axis=1) <= 0.01 * max(float(np.max(command_Pa)), 1e-300)] = -1
    by_dominant = {muscles[i]: _rms(residual[valid & (dominant == i)]) for i in range(len(muscles))}
    explained = {}
    for name, d in directions.items():
        known = np.all(np.isfinite(d), axis=1)  # a direction may cover only the first rows
        d = np.where((valid & known)[:, None], d, 0.0)
        rk = np.where(known[:, None], r, 0.0)
        nd = float(np.sum(d**2))
        energy = float(np.sum(rk**2)) or 1.0
        explained[name] = float(np.sum(rk * d) ** 2 / (nd * energy)) if nd > 0 else 0.0
    by_muscle = {m: max(explained.get(f"{m}:{kind}", 0.0) for kind in ("gain", "lag")) for m in muscles}
    by_section = {f"section {j + 1}": max(by_muscle[muscles[i]] for i in g) for j, g in enumerate(groups)}
    worst = max((b for b in in_time if b["rms_m"] is not None), key=lambda b: b["rms_m"], default=None)
    top_muscle = max(by_muscle, key=by_muscle.get) if by_muscle else None
    summary = [f"residual RMS {_mm(_rms(residual[valid]))} against a marker noise of {noise * 1e3:.2f} mm"]
    if worst is not None:
        summary.append(f"largest in {worst['from_s']:.1f}-{worst['to_s']:.1f} s ({_mm(worst['rms_m'])})")
    # a level no row falls in (every command equal, or the low third all vented) is left out
    levels = [f"{k} {_mm(v['rms_m'])}" for k, v in by_level.items() if v["rms_m"] is not None]
    summary.append("by mean pressure: " + ", ".join(levels))
    if top_muscle is not None and by_muscle[top_muscle] < 0.005:
        summary.append("no muscle's pressure or lag direction explains any of it")
    elif top_muscle is not None:
        summary.append(
            f"best explained by muscle {top_muscle} ({by_muscle[top_muscle]:.0%} of the residual energy "
            f"along its pressure or lag direction); by section: "
            + ", ".join(f"{k} {v:.0%}" for k, v in by_section.items())
        )
    return {
        "in_time": in_time, "by_pressure_level": by_level, "by_dominant_muscle_m": by_dominant,
        "by_muscle_explained": by_muscle, "by_section_explained": by_section, "summary": summary,
    }  # fmt: skip
