"""Controllers for the suite: a model-based one (inverse statics plus feedback) and a random
baseline, and the episode runner that scores them.

Model-based reach (:class:`InverseStaticsController`):

1. **Feed-forward, inverse statics.** The target (base frame) is first met by one constant-
   curvature arc through it (every section the same arc length, bend and direction: closed
   form), whose muscle lengths give unloaded pressures through the inverse of the muscles' free
   length. These seed a bounded Gauss-Newton solve (Broyden updates) of the suite's statics
   (:func:`.arm_glue.reference_tip`: the domain's model at rest; the arm's own weight included; no payload: the controller does not know it) for pressure fractions
   ``u*`` whose rest tip is the target, with a small pull towards the seed that settles the
   redundancy of a multi-section arm. Finite differences at the solution give the Jacobian
   ``J`` of the rest tip with respect to the fractions (the solve's Broyden estimate can be
   wrong in a weak direction).
2. **Feedback.** Each control step, with the tip error ``e`` (base frame) and its integral,
   ``u = u* + a J+ (kp e + ki int e dt)``, J+ the damped pseudo-inverse, the correction
   shortened (a <= 1) until u is inside [0, 1] (the integral stops growing while a < 1). The integral removes what the
   statics does not know (an unknown payload) and the slow creep of a lightly damped arm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import arm_glue

# ------------------------------------------------------------------------- inverse statics


def cc_arc_shape(spec, target_in_base) -> np.ndarray:
    """Per section ``(s, kx, ky)`` of one constant-curvature arc from the base through
    ``target_in_base``, every section an equal share of it: (S, 3)."""
    x, y, z = (float(v) for v in target_in_base)
    lateral = math.hypot(x, y)
    bend = 2.0 * math.atan2(lateral, z)  # the chord leaves the base at half the bend
    chord = math.hypot(lateral, z)
    half = bend / 2
    arc = chord * (half / math.sin(half) if half > 1e-9 else 1.0)
    direction = math.atan2(y, x)
    kappa = bend / arc if arc > 0 else 0.0
    count = len(spec.sections)
    return np.tile([arc / count, kappa * math.cos(direction), kappa * math.sin(direction)], (count, 1))


def cc_arc_pressures(spec, target_in_base) -> np.ndarray:
    """Pressure fractions that hold the arm unloaded as one constant-curvature arc through
    ``target_in_base`` (:func:`cc_arc_shape`), clipped to [0, 1]."""
    fractions = []
    for (s, kx, ky), (muscles, radii, angles) in zip(
        cc_arc_shape(spec, target_in_base), arm_glue.section_muscles(spec)
    ):
        lengths = s * (1.0 - radii * (kx * np.cos(angles) + ky * np.sin(angles)))
        fractions.append(
            [
                arm_glue.pressure_for_free_length(m, L, spec.max_pressure_Pa) / spec.max_pressure_Pa
                for m, L in zip(muscles, lengths)
            ]
        )
    return np.clip(np.concatenate(fractions), 0.0, 1.0)


@dataclass(frozen=True)
class InverseStatics:
    """Pressure fractions whose rest tip (the suite's statics) is a target."""

    fractions: np.ndarray  # (muscles,)
    jacobian_m: np.ndarray  # (3, muscles): d tip / d fraction, base frame
    tip_m: np.ndarray  # the reference's rest tip at ``fractions``
    seed: np.ndarray  # the one-arc seed
    forward_solves: int = 0  # statics solves the inverse took

    def error_m(self, target_in_base) -> float:
        """Distance (m) from the reference tip of this solution to ``target_in_base``."""
        return float(np.linalg.norm(self.tip_m - np.asarray(target_in_base)))


def inverse_statics(
    spec,
    target_in_base,
    payload_kg: float = 0.0,
    tolerance_m: float = 1e-5,
    max_iterations: int = 20,
    regularisation: float = 1e-4,
    reference=None,
) -> InverseStatics:
    """Solve the suite's statics for pressure fractions in [0, 1] that put the rest tip on
    the target: Gauss-Newton from :func:`cc_arc_pressures` with one finite-difference Jacobian
    and Broyden updates after it (each evaluation is a statics solve, the costly part),
    minimising ``|tip(u) - target|^2 + regularisation^2 |u - seed|^2`` (m^2): the pull to the
    seed only acts along the directions the tip does not see (a multi-section arm's
    redundancy). Stops within ``tolerance_m`` of the target.

    ``reference(spec, pressures_Pa, payload_kg) -> tip`` replaces the suite's statics as the
    forward map, e.g. :func:`.arm_glue.continuum_tip` (docs/suite.md compares the two)."""
    target = np.asarray(target_in_base, dtype=float)
    seed = cc_arc_pressures(spec, target)

    calls = []

    def tip(u):  # the first solve from rest, the others from the previous rest state
        calls.append(None)
        if reference is not None:
            return np.asarray(reference(spec, u * spec.max_pressure_Pa, payload_kg), dtype=float)
        return arm_glue.reference_tip(
            spec, u * spec.max_pressure_Pa, payload_kg=payload_kg, warm=len(calls) > 1
        )[0]

    def jacobian_at(u, x, step=1e-4):  # one-sided differences, inwards from the bounds
        jacobian = np.empty((3, u.size))
        for i in range(u.size):
            h = step if u[i] + step <= 1.0 else -step
            probe = u.copy()
            probe[i] += h
            jacobian[:, i] = (tip(probe) - x) / h
        return jacobian

    u = np.clip(seed, 0.0, 1.0)
    x = tip(u)
    jacobian = jacobian_at(u, x)
    mu = regularisation**2
    identity = np.eye(u.size)
    for _ in range(max_iterations):
        error = x - target
        if np.linalg.norm(error) <= tolerance_m:
            break
        delta = -np.linalg.solve(jacobian.T @ jacobian + mu * identity, jacobian.T @ error + mu * (u - seed))
        u_new = np.clip(u + delta, 0.0, 1.0)
        delta = u_new - u
        if not np.any(delta):
            break  # pinned on the bounds
        x_new = tip(u_new)
        # Broyden: the Jacobian takes the step's observed change
        jacobian += np.outer((x_new - x) - jacobian @ delta, delta) / (delta @ delta)
        u, x = u_new, x_new
    # the feedback's Jacobian measured at the solution: the Broyden estimate is only good along
    # the steps taken, and a weak direction can come out with the wrong sign (the feedback
    # then drove bundle-reach seed 18 away from its target: 201 mm off at the end)
    return InverseStatics(u, jacobian_at(u, x), x, seed, len(calls))


def damped_pinv(jacobian, damping: float = 1e-3) -> np.ndarray:
    """J^T (J J^T + damping^2 I)^-1."""
    J = np.asarray(jacobian)
    return J.T @ np.linalg.inv(J @ J.T + damping**2 * np.eye(J.shape[0]))


# --------------------------------------------------------------------------- the policies


class RandomPolicy:
    """Uniform random pressure fractions in the action spec's bounds (seeded)."""

    name = "random"

    def __init__(self, env, seed: int | None = None):
        self.spec = env.action_spec()
        self.random = np.random.RandomState(seed)

    def reset(self, time_step) -> None:
        """Nothing to prepare."""

    def __call__(self, time_step) -> np.ndarray:
        # one draw per muscle: dm_env keeps the bounds as scalars, and uniform(0, 1) alone is one
        # number that the old step spread over every muscle (all pressures equal: never a bend)
        return self.random.uniform(self.spec.minimum, self.spec.maximum, size=self.spec.shape)


#: feedback gains (kp, ki in 1/s) by number of sections, tuned on the suite's domains: the
#: hanging 3-section arm swings slowly (a ~1 Hz pendulum mode) and needs a gentler integral
GAINS = {1: (0.3, 3.0), 2: (0.1, 0.5)}


class InverseStaticsController:
    """Model-based tip control: inverse statics of the reference plus PI feedback (module doc).

    Works on the tasks whose observation has ``target_position`` (reach, reach_payload, track).
    It is built for a fixed target: on ``track`` the feed-forward is the loop's starting point
    and the feedback lags the moving target (bundle-track seeds 0-5: 1 of 6 within the radius
    at the end, 1-84 mm; docs/suite.md).
    """

    name = "inverse statics + PI"

    def __init__(
        self,
        env,
        kp: float | None = None,
        ki: float | None = None,
        damping_m_per_fraction: float = 0.01,
        reference=None,
    ):
        """``reference``: the forward statics the feed-forward inverts (see
        :func:`inverse_statics`; by default the suite's statics, the domain's own model)."""
        self.env = env
        self.reference = reference
        sections = len(env.task.arm_spec.sections)
        default_kp, default_ki = GAINS[min(sections, max(GAINS))]
        self.kp = default_kp if kp is None else kp
        self.ki = default_ki if ki is None else ki
        self.damping = damping_m_per_fraction
        self.dt = env.control_timestep()
        self.solution: InverseStatics | None = None
        self._integral = np.zeros(3)
        self._pinv = None

    def reset(self, time_step) -> None:
        """Solve the inverse statics for the episode's target."""
        physics = self.env.physics
        target = physics.to_base(time_step.observation["target_position"])
        self.solution = inverse_statics(self.env.task.arm_spec, target, reference=self.reference)
        self._pinv = damped_pinv(self.solution.jacobian_m, self.damping)
        self._integral = np.zeros(3)

    def __call__(self, time_step) -> np.ndarray:
        physics = self.env.physics
        target = physics.to_base(time_step.observation["target_position"])
        error = target - physics.to_base(time_step.observation["tip_position"])
        feedforward = self.solution.fractions
        correction = self._pinv @ (self.kp * error + self.ki * (self._integral + error * self.dt))
        # shorten the correction until the command is inside [0, 1] (clipping muscle by muscle
        # would drop its differential part: all muscles at the rail straighten the arm); a
        # muscle whose feed-forward is already on a bound is clipped instead
        scale = 1.0
        for u, d in zip(feedforward.tolist(), correction.tolist()):
            if (u >= 1.0 and d > 0) or (u <= 0.0 and d < 0):
                continue
            if u + scale * d > 1.0:
                scale = (1.0 - u) / d
            elif u + scale * d < 0.0:
                scale = -u / d
        if scale >= 1.0:  # no integration while saturated (anti-windup)
            self._integral += error * self.dt
        return np.clip(feedforward + max(scale, 0.0) * correction, 0.0, 1.0)


# ------------------------------------------------------------------------------- episodes


@dataclass(frozen=True)
class EpisodeResult:
    """One episode: the return, the final success, and the task's final error."""

    seed: int
    episode_return: float
    success: bool
    final_error: (
        float  # reach/track: tip-target distance, m; extend: worst length error, m; push: |F - F*|, N
    )


def final_error(task, physics) -> float:
    """The task's error at the end of an episode (the quantity its success is judged on)."""
    if hasattr(task, "length_errors"):
        return float(np.max(np.abs(task.length_errors(physics))))
    if hasattr(task, "target_force_N"):
        return abs(physics.plate_force() - task.target_force_N)
    return physics.tip_to_target_distance()


def run_episode(env, policy, frames: list | None = None, camera="perspective", frame_every: int = 0):
    """Run one episode of ``policy`` (after ``env.reset()``); optionally collect rendered
    frames every ``frame_every`` steps. Returns (return, success, final error)."""
    time_step = env.reset()
    policy.reset(time_step)
    total = 0.0
    step = 0
    while not time_step.last():
        time_step = env.step(policy(time_step))
        total += time_step.reward
        step += 1
        if frames is not None and frame_every and step % frame_every == 0:
            frames.append(env.physics.render(240, 320, camera_id=camera))
    return total, bool(env.task.success(env.physics)), final_error(env.task, env.physics)


def evaluate(domain: str, task: str, policy_name: str, episodes: int, seed: int = 0):
    """Run ``episodes`` seeded episodes of a policy (``"model"`` or ``"random"``) on a task;
    episode i uses task seed ``seed + i`` (a progress bar on a terminal). Returns a list of
    :class:`EpisodeResult`."""
    from ..progress import progress
    from . import load

    results = []
    for i in progress(range(episodes), f"{domain}-{task} {policy_name}", total=episodes):
        env = load(domain, task, task_kwargs={"random": seed + i})
        policy = InverseStaticsController(env) if policy_name == "model" else RandomPolicy(env, seed=seed + i)
        ret, ok, err = run_episode(env, policy)
        results.append(EpisodeResult(seed + i, ret, ok, err))
    return results
