"""A thin Gymnasium adapter for the EFAM suite (optional: ``pip install gymnasium``, or the
``rl`` extra).

    from efam_mujoco.suite.gym import SuiteEnv
    env = SuiteEnv("bundle", "reach")
    observation, info = env.reset(seed=0)

Observations: the suite's observation dict flattened in its spec's order into one ``float32``
vector (``SuiteEnv.observation_keys`` names the slices). Actions: ``Box(0, 1)``, the pressure
fractions of rated. An episode ends by truncation at the suite's time limit (the suite's
tasks never terminate); ``info["success"]`` is the task's success test at that step.
``register_all()`` registers ``efam/<domain>-<task>-v0`` for every task.
"""

from __future__ import annotations

import warnings

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError as error:  # pragma: no cover - the message is the point
    raise ImportError(
        "efam_mujoco.suite.gym needs gymnasium: pip install gymnasium (or pip install -e '.[rl]')"
    ) from error

from . import ALL_TASKS, common, load


class SuiteEnv(gymnasium.Env):
    """One task of the EFAM suite as a ``gymnasium.Env``."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        domain: str,
        task: str,
        task_kwargs=None,
        render_mode=None,
        camera="perspective",
        size=(240, 320),
    ):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if isinstance(size, (str, bytes)) or np.ndim(size) != 1 or len(size) != 2:
            raise ValueError(f"size must be (height, width) in pixels, got {size!r}")
        common.check_image_size(*size, "size (height, width)")  # now, not at the first render()
        self.domain, self.task = domain, task
        self.task_kwargs = dict(task_kwargs or {})
        self.render_mode, self.camera, self.size = render_mode, camera, size
        self.env = load(domain, task, task_kwargs=self.task_kwargs)
        spec = self.env.observation_spec()
        self.observation_keys = list(spec)
        count = sum(int(np.prod(s.shape)) for s in spec.values())
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(count,), dtype=np.float32)
        action = self.env.action_spec()
        self.action_space = spaces.Box(
            np.broadcast_to(action.minimum, action.shape).astype(np.float32),
            np.broadcast_to(action.maximum, action.shape).astype(np.float32),
            dtype=np.float32,
        )
        self.metadata = {**self.metadata, "render_fps": int(round(1 / self.env.control_timestep()))}
        self._ended = False  # the last step ended the episode: the next needs a reset first
        self._started = False  # reset() was called: a step before it read no observation
        self._told_clipped = False

    def _flat(self, observation) -> np.ndarray:
        return np.concatenate([np.ravel(observation[k]) for k in self.observation_keys]).astype(np.float32)

    def reset(self, *, seed=None, options=None):
        """Start an episode (a seed reloads the task with that seed); returns (observation, info)."""
        super().reset(seed=seed)
        if options:  # gymnasium passes options through; this task takes none
            raise ValueError(f"reset: this environment takes no options, got {sorted(options)}")
        if seed is not None:  # a seeded task: its targets and starts follow the seed
            self.env = load(self.domain, self.task, task_kwargs={**self.task_kwargs, "random": int(seed)})
        time_step = self.env.reset()
        self._ended = False
        self._started = True
        return self._flat(time_step.observation), {}

    def step(self, action):
        """Apply ``action`` (pressure fractions in [0, 1]) for one control step; returns
        (observation, reward, terminated, truncated, info) with ``info["success"]``. Actions
        outside [0, 1] are clipped (a warning says so, once per environment); a non-finite
        action, a wrong shape, or a step after the episode ended (call ``reset``) is an error."""
        if not self._started:  # dm_control's first step would read a None reward
            raise RuntimeError("step() before reset(): call reset() to start an episode")
        if self._ended:
            raise RuntimeError(
                "the episode has ended (truncated at its time limit): call reset() before step()"
            )
        # before the float cast: complex was cast with a warning, text parsed
        common.refuse_unreal_action(action)
        action = np.asarray(action, dtype=np.float64)
        if action.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {action.shape}")
        if not np.all(np.isfinite(action)):
            raise ValueError(f"action must be finite pressure fractions in [0, 1], got {action.tolist()}")
        outside = (action < self.action_space.low) | (action > self.action_space.high)
        if outside.any() and not self._told_clipped:
            self._told_clipped = True
            warnings.warn(
                f"action {action.tolist()} is outside [0, 1]: clipped to the muscles' pressure range (said once "
                "per environment)",
                RuntimeWarning,
                stacklevel=2,
            )
        time_step = self.env.step(np.clip(action, self.action_space.low, self.action_space.high))
        self._ended = bool(time_step.last())
        info = {"success": bool(self.env.task.success(self.env.physics))}
        return self._flat(time_step.observation), float(time_step.reward), False, self._ended, info

    def render(self):
        """An RGB frame from the named camera when ``render_mode="rgb_array"``, else None."""
        if self.render_mode != "rgb_array":
            return None
        return self.env.physics.render(*self.size, camera_id=self.camera)

    def close(self):
        """Release the dm_control environment."""
        self.env.close()


def register_all() -> list[str]:
    """Register ``efam/<domain>-<task>-v0`` with Gymnasium for every task; returns the ids."""
    ids = []
    for domain, task in ALL_TASKS:
        env_id = f"efam/{domain}-{task}-v0"
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=SuiteEnv, kwargs={"domain": domain, "task": task})
        ids.append(env_id)
    return ids
