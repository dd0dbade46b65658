"""The next experiment: which short test would tell two fitted hypotheses apart.

Candidate protocols a lab can run in a minute (each 12 s, from the recording's first command):
a slow pressure ramp of all muscles, a step of all muscles to high pressure and back, each
muscle stepped alone in turn, a fast sinusoid per muscle (2 Hz, phases 120 deg apart), and a
long hold of a strong bend. Both hypotheses are replayed on each; the recommendation is the one
with the largest RMS tip difference, stated against the marker noise.
"""

from __future__ import annotations

import numpy as np

from .replay import Knobs, Replayer

DURATION_S = 12.0


def protocols(replayer: Replayer) -> dict[str, np.ndarray]:
    """Per-step commands (steps, muscles) of each candidate protocol, Pa."""
    dt = replayer.dt
    t = np.arange(int(DURATION_S / dt)) * dt
    M = len(replayer.muscles)
    hi = 0.8 * replayer.max_Pa
    lo = np.full(M, 0.15) * replayer.max_Pa
    out = {}
    out["slow ramp of all muscles, 0.15 to 0.8 of the range and back"] = (
        lo + (hi - lo) * np.interp(t, [0, DURATION_S / 2, DURATION_S], [0, 1, 0])[:, None]
    )
    step = ((t > 1) & (t < 6))[:, None]
    out["step of all muscles to 0.8 of the range, hold 5 s, vent"] = np.where(step, hi, lo)
    k = np.minimum((t // (DURATION_S / M)).astype(int), M - 1)
    alone = np.tile(lo, (len(t), 1))
    alone[np.arange(len(t)), k] = hi[k]
    out["each muscle stepped alone in turn"] = alone
    phase = 2 * np.pi * np.arange(M) / M
    out["fast sinusoid, 2 Hz, phases spread over the muscles"] = (lo + hi) / 2 + (hi - lo) / 2 * np.sin(
        2 * np.pi * 2.0 * t[:, None] + phase
    )
    bend = np.tile(lo, (len(t), 1))
    bend[t > 1, 0] = hi[0]
    out["hold a strong bend (first muscle high) for 11 s"] = bend
    return out


def recommend(replayer: Replayer, hypotheses: dict[str, Knobs], noise_m: float) -> dict:
    """The protocol that separates the two ``hypotheses`` best (a dict for the report)."""
    names = list(hypotheses)
    settle = np.repeat(replayer.step_command[:1], replayer.n_settle, 0)
    table = []
    for label, commands in protocols(replayer).items():
        commands = np.vstack([settle, commands])
        tips = replayer.tips(
            [hypotheses[n] for n in names], command_Pa=commands, samples=slice(replayer.n_settle, None)
        )
        diff = float(np.sqrt(np.mean((tips[0] - tips[1]) ** 2)))
        table.append(
            {
                "protocol": label,
                "predicted_rms_difference_m": diff,
                "over_noise": diff / noise_m if noise_m else None,
            }
        )
    table.sort(key=lambda r: -r["predicted_rms_difference_m"])
    return {"between": names, "recommended": table[0]["protocol"], "candidates": table}
