"""The arm's time step, derived from its physics (:func:`choose_timestep`).

MuJoCo integrates stiffness explicitly: ``implicitfast`` treats only velocity damping
implicitly. A linear mode of angular frequency omega and damping c (per unit modal mass) is
then stable for

    dt^2 omega^2 < 4 + 2 dt c,   i.e.   dt < (c + sqrt(c^2 + 4 omega^2)) / omega^2,

which is the explicit limit 2 / omega without damping and about 2 c / omega^2 (twice the mode's
relaxation time c / k) for a strongly overdamped mode. The segments between the spacer disks
are stiff and light: without damping the arm's fastest mode (``omega_max``, about 1400 D rad/s
for FAM1 sections) sets the step; with the bundle's viscosity those modes are overdamped (modal
damping ratios of tens) and only their relaxation time (a few ms, independent of D) matters.

The builder linearises the compiled arm at rest (straight, every muscle at its rest length, at
zero and at the highest rated pressure): the stiffness K by finite differences of the net
generalized force at zero velocity, the mass matrix M (``mj_fullM``), the damping C (joint
damping plus the tendons' dampers). The modes (K phi = omega^2 M phi) and their modal damping
give each mode's limit; the step is the largest of :data:`ROUND_TIMESTEPS_S` that is stable at
:data:`TIMESTEP_SAFETY` times itself (checked once more on the full linearised step map), so the
stiffening of the muscles away from the straight rest pose has a margin. The integrator follows
the damping (:func:`default_integrator`): ``implicitfast`` with damping, RK4 without. An explicitly given
step beyond the arm's limit is refused; one beyond the undamped limit (stable only thanks to the
damping, or closer to the limit than the margin) gets a :class:`TimestepWarning`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import mujoco
import numpy as np
import scipy.linalg

#: the steps the builder chooses from, s (largest first). The largest, 1 ms, is a cap for
#: accuracy, not stability: the damped arm is stable at 2 ms too, but implicitfast is first
#: order, and the tip's path after a pressure step departs from a 0.1 ms reference by 2.2 % of
#: the arm's length at 2 ms, 1.0 % at 1 ms, 0.38 % at 0.5 ms (1x3, D = 16, lag 50 ms; docs/arms.md)
ROUND_TIMESTEPS_S = (1e-3, 5e-4, 2.5e-4, 2e-4, 1e-4, 5e-5, 2.5e-5, 2e-5, 1e-5, 5e-6, 2.5e-6, 2e-6, 1e-6)
#: the chosen step is stable (linearised at rest) at this multiple of itself, by integrator: a
#: margin for the muscles' stiffening away from the rest pose and for the nonlinear terms.
#: implicitfast (the damped arm): 2. RK4 (the undamped arm): 4, i.e. omega_max dt <= 0.71,
#: for energy rather than stability: RK4 damps a mode of frequency omega by about
#: (omega dt)^6 / 72 per step, and the released arm feeds its fastest modes; measured, the 3x3
#: arm at D = 4 over 10 s drifts 3.6 % of its kinetic energy at omega_max dt = 1.37 (see
#: docs/arms.md)
TIMESTEP_SAFETY = {"implicitfast": 2.0, "RK4": 4.0}
IMPLICITFAST = int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST)
RK4 = int(mujoco.mjtIntegrator.mjINT_RK4)
_NAMES = {IMPLICITFAST: "implicitfast", RK4: "RK4"}
#: name of the model's custom numeric holding (time step, omega_max, undamped limit, limit), SI
NUMERIC_NAME = "efam_timestep"


class TimestepWarning(UserWarning):
    """An explicitly chosen time step the arm tolerates only thanks to its damping, or with less
    margin than :data:`TIMESTEP_SAFETY` asks."""


@dataclass(frozen=True)
class TimestepChoice:
    """What the builder found about the arm's stable time steps.

    ``omega_max_rad_s``: the fastest undamped mode at rest; ``undamped_limit_s`` = 2 /
    omega_max (explicit stability without damping); ``limit_s``: the stability limit with the
    arm's damping under ``implicitfast``; ``timestep_s``: the step used; ``given``: whether it
    was given explicitly (``ArmSpec.timestep_s``) or chosen.
    """

    timestep_s: float
    omega_max_rad_s: float
    undamped_limit_s: float
    limit_s: float
    given: bool
    integrator: str = "implicitfast"
    #: a chosen step: whether the linearised arm is stable at the safety margin times it (False
    #: when no candidate down to the smallest is: the smallest is used, and said so)
    verified: bool = True

    def describe(self) -> str:
        """One line for people: the step, how it was found, and the limits."""
        margin = TIMESTEP_SAFETY.get(self.integrator, 2.0)
        if self.given:
            how = "given"
        elif self.verified:
            how = f"chosen: stable at {margin:g} x itself"
        else:
            how = f"chosen: the smallest candidate, and the linearised arm is not stable even at {margin:g} x it"
        return (
            f"time step {self.timestep_s * 1e3:g} ms, {self.integrator} ({how}); fastest mode omega_max = "
            f"{self.omega_max_rad_s:.0f} rad/s: undamped limit "
            f"{self.undamped_limit_s * 1e3:.3g} ms, with the arm's damping {self.limit_s * 1e3:.3g} ms"
        )


def generalized_force(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Net generalized force at zero velocity: passive (the muscle segments' extra forces) +
    actuators (whole muscles) - gravity. Calls mj_forward."""
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    return data.qfrc_passive + data.qfrc_actuator - data.qfrc_bias


def force_jacobian(model: mujoco.MjModel, data: mujoco.MjData, q, f0, step: float) -> np.ndarray:
    """d(:func:`generalized_force`)/dq at ``q`` by forward differences of ``step`` (``f0``: the
    force at ``q``). The arm's joints are hinges and slides: qpos and qvel align. Leaves
    ``data`` at the last probe."""
    K = np.empty((model.nv, model.nv))
    for i in range(model.nv):
        data.qpos[:] = q
        data.qpos[i] += step
        K[:, i] = (generalized_force(model, data) - f0) / step
    return K


def linearise(model: mujoco.MjModel, pressure_Pa: float, qpos=None, step_m: float = 1e-7):
    """(K, M, C) of ``model`` at ``qpos`` (default: ``qpos0``), zero velocity, every muscle at
    ``pressure_Pa`` (control and pressure state): K = -d(qfrc_passive + qfrc_actuator -
    qfrc_bias)/dq by forward differences (symmetrised), M from ``mj_fullM``, C the joint damping
    plus J' c J of the tendons' dampers."""
    data = mujoco.MjData(model)
    if qpos is not None:
        data.qpos[:] = qpos
    data.ctrl[:] = pressure_Pa
    lagged = model.actuator_actadr >= 0
    data.act[model.actuator_actadr[lagged]] = data.ctrl[lagged]
    q0 = data.qpos.copy()
    K = -force_jacobian(model, data, q0, generalized_force(model, data), step_m)
    data.qpos[:] = q0
    generalized_force(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    C = np.diag(model.dof_damping.astype(float))
    if model.ntendon:
        J = np.zeros((model.ntendon, model.nv))
        mujoco.mju_sparse2dense(J, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
        C += J.T @ (model.tendon_damping[:, None] * J)
    return 0.5 * (K + K.T), M, C


def modal_limits(K, M, C, integrator: int = IMPLICITFAST):
    """Per mode with positive stiffness: (omega, modal damping c = phi' C phi with phi' M phi =
    1, the stability limit, s): implicitfast (c + sqrt(c^2 + 4 omega^2)) / omega^2; RK4
    2 sqrt(2) / omega (its limit on the imaginary axis; the builder uses RK4 only without
    damping)."""
    eigenvalues, modes = scipy.linalg.eigh(K, M)
    positive = eigenvalues > 0
    omega = np.sqrt(eigenvalues[positive])
    phi = modes[:, positive]
    c = np.einsum("im,ij,jm->m", phi, C, phi)
    if integrator == RK4:
        return omega, c, 2 * math.sqrt(2) / omega
    return omega, c, (c + np.sqrt(c**2 + 4 * omega**2)) / omega**2


def step_map_radius(K, M, C, timestep_s: float, integrator: int = IMPLICITFAST) -> float:
    """Spectral radius of one step of the linear system M a = -K q - C v (> 1: unstable).
    implicitfast: (M + dt C) v1 = M v0 - dt K q0, q1 = q0 + dt v1; RK4: the Taylor polynomial
    of degree 4 of exp(dt A), A = [[0, I], [-M^-1 K, -M^-1 C]]."""
    n = len(M)
    dt = timestep_s
    if integrator == RK4:
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
        hA = dt * A
        T, term = np.eye(2 * n), np.eye(2 * n)
        for order in range(1, 5):
            term = term @ hA / order
            T = T + term
    else:
        solved = np.linalg.solve(M + dt * C, np.hstack([M, -dt * K]))
        v_from_v, v_from_q = solved[:, :n], solved[:, n:]
        T = np.block([[np.eye(n) + dt * v_from_q, dt * v_from_v], [v_from_q, v_from_v]])
    return float(np.abs(np.linalg.eigvals(T)).max())


def default_integrator(damped: bool) -> int:
    """The arm's integrator: ``implicitfast`` when it has damping (the segments' overdamped
    modes are then integrated implicitly, at steps far beyond their explicit limit); RK4 without
    damping (implicitfast is first order and, on a chain, not energy conserving: a released
    undamped arm gains energy in proportion to the step; RK4 keeps it, see docs/arms.md)."""
    return IMPLICITFAST if damped else RK4


def choose_timestep(
    model: mujoco.MjModel, max_pressure_Pa: float, given_s: float | None = None
) -> TimestepChoice:
    """The arm's time step (see the module's docstring): linearised straight at rest at zero and at
    ``max_pressure_Pa``, for the model's integrator; ``given_s`` None chooses, a given step is
    checked (ValueError if the linearised arm is unstable at it, :class:`TimestepWarning` if it
    is stable only thanks to the damping or within the margin)."""
    integrator = int(model.opt.integrator)
    omega_max, limit, linear = 0.0, math.inf, []
    for pressure in (0.0, max_pressure_Pa):
        K, M, C = linearise(model, pressure)
        omega, _, limits = modal_limits(K, M, C, integrator)
        if omega.size:
            omega_max = max(omega_max, float(omega.max()))
            limit = min(limit, float(limits.min()))
        linear.append((K, M, C))

    def stable(dt):
        return all(step_map_radius(K, M, C, dt, integrator) <= 1 + 1e-9 for K, M, C in linear)

    explicit_limit = 2 * math.sqrt(2) if integrator == RK4 else 2.0
    undamped_limit = explicit_limit / omega_max if omega_max > 0 else math.inf
    safety = TIMESTEP_SAFETY[_NAMES[integrator]]
    if given_s is None:
        candidates = [dt for dt in ROUND_TIMESTEPS_S if safety * dt <= limit]
        candidates = candidates or [limit / safety]
        verified = [dt for dt in candidates if stable(safety * dt)][:1]
        chosen = verified[0] if verified else candidates[-1]
        choice = TimestepChoice(
            chosen, omega_max, undamped_limit, limit, False, _NAMES[integrator], bool(verified)
        )
        if not verified:  # never silent: the step is a guess, and the run may diverge or crawl
            warnings.warn(
                f"arm: no candidate time step is stable at {safety:g} x itself for the arm linearised straight "
                f"at rest ({choice.describe()}); a heavy load far from that pose is the usual cause",
                TimestepWarning,
                stacklevel=3,
            )
        return choice
    choice = TimestepChoice(float(given_s), omega_max, undamped_limit, limit, True, _NAMES[integrator])
    if given_s > limit or not stable(given_s):
        # under the per-mode limit the coupled step map can still grow (a heavy plate couples the
        # modes): say which test failed, or the message reads as '4 ms is above 9.11 ms'
        coupled = (
            ""
            if given_s > limit
            else f" (each mode alone allows up to {limit * 1e3:.3g} ms, but the step map of the modes together, "
            "linearised at rest and at the top pressure, grows at this step)"
        )
        raise ValueError(
            f"arm: timestep_s = {given_s * 1e3:g} ms is unstable for this arm{coupled}: {choice.describe()}; "
            "leave timestep_s unset (None) to let the builder choose"
        )
    if given_s > undamped_limit or safety * given_s > limit:
        warnings.warn(
            f"arm: timestep_s = {given_s * 1e3:g} ms is stable only thanks to the arm's damping or within "
            f"less than {safety:g} x margin ({choice.describe()}); with less damping it diverges",
            TimestepWarning,
            stacklevel=3,
        )
    return choice


def apply_timestep(spec: mujoco.MjSpec, max_pressure_Pa: float, given_s: float | None) -> TimestepChoice:
    """Compile ``spec`` (plugin loaded), choose or check its time step (:func:`choose_timestep`),
    set it, and record it in the custom numeric :data:`NUMERIC_NAME` (time step, omega_max,
    undamped limit, limit with damping, SI; 1 if the step was given)."""
    model = spec.compile()
    choice = choose_timestep(model, max_pressure_Pa, given_s)
    spec.option.timestep = choice.timestep_s
    spec.add_numeric(
        name=NUMERIC_NAME,
        data=[
            choice.timestep_s,
            choice.omega_max_rad_s,
            choice.undamped_limit_s,
            choice.limit_s,
            float(choice.given),
        ],
    )
    return choice


def recorded_timestep(model: mujoco.MjModel) -> TimestepChoice | None:
    """The :class:`TimestepChoice` the builder recorded in ``model`` (None for a model without it).
    A step changed after building (``model.opt.timestep``) is reported as given."""
    for i in range(model.nnumeric):
        if model.numeric(i).name == NUMERIC_NAME:
            dt, omega, undamped, limit, given = (float(v) for v in model.numeric(i).data[:5])
            current = float(model.opt.timestep)
            return TimestepChoice(
                current, omega, undamped, limit, bool(given) or current != dt,
                _NAMES.get(int(model.opt.integrator), str(model.opt.integrator)),
            )  # fmt: skip
    return None
