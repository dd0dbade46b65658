"""EFAM bundles and arms as a dm_control suite: ``load(domain_name, task_name)``.

```python
from efam_mujoco import suite
env = suite.load("bundle", "reach", task_kwargs={"random": 0})
```

Domains: ``bundle`` (one section of three muscles) and ``arm`` (three sections of three).
Tasks: ``reach``, ``track``, ``extend``, ``push`` and ``reach_payload``. Actions are pressure
fractions of each muscle's rated pressure in [0, 1] (action spec ``pressure_fraction_of_rated``),
applied through the arm's pressure lag (50 ms by default). On a Linux machine without a display
the suite renders with ``MUJOCO_GL=egl`` unless ``MUJOCO_GL`` is set before the import.
"""

from __future__ import annotations

import inspect
import os
import sys

import numpy as np

if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")  # headless: dm_control would try GLFW first

from . import arm, bundle  # noqa: E402  (after the rendering backend is chosen)

_DOMAINS = {name: module for name, module in (("arm", arm), ("bundle", bundle)) if hasattr(module, "SUITE")}


def _get_tasks(tag=None):
    result = []
    for domain_name in sorted(_DOMAINS):
        tasks = _DOMAINS[domain_name].SUITE
        for task_name in tasks if tag is None else tasks.tagged(tag):
            result.append((domain_name, task_name))
    return tuple(result)


#: every (domain, task) pair
ALL_TASKS = _get_tasks()
#: the tasks tagged for benchmarking
BENCHMARKING = _get_tasks("benchmarking")
#: the others
EXTRA = tuple(sorted(set(ALL_TASKS) - set(BENCHMARKING)))
#: domain name -> its task names
TASKS_BY_DOMAIN = {d: tuple(t for dd, t in ALL_TASKS if dd == d) for d in _DOMAINS}


def _check_random(random) -> None:
    """``task_kwargs['random']``: None, a ``numpy.random.RandomState`` or a whole-number seed in
    0 .. 2**32 - 1 (numpy's own messages name neither the key nor the rule: "Cannot cast scalar
    from dtype('float64')")."""
    if random is None or isinstance(random, np.random.RandomState):
        return
    if isinstance(random, bool) or not isinstance(random, (int, np.integer)) or not 0 <= random < 2**32:
        raise ValueError(
            f"task_kwargs['random'] must be a whole-number seed in 0 .. 2**32 - 1 or a numpy RandomState, "
            f"got {random!r}"
        )


def load(domain_name, task_name, task_kwargs=None, environment_kwargs=None, visualize_reward=False):
    """An environment of the suite, as ``dm_control.suite.load``.

    ``task_kwargs``: ``random`` (seed or ``RandomState``), ``time_limit`` (s), ``arm_options``
    (fields of ``efam_mujoco.arm.ArmSpec``, e.g. ``{"pressure_tau_s": 0.1}``).
    ``environment_kwargs``: passed to ``dm_control.rl.control.Environment``.
    """
    if domain_name not in _DOMAINS:
        raise ValueError(f"unknown domain {domain_name!r}; the domains are {', '.join(sorted(_DOMAINS))}")
    suite = _DOMAINS[domain_name].SUITE
    if task_name not in suite:
        raise ValueError(
            f"unknown task {task_name!r} in domain {domain_name!r}; its tasks are {', '.join(suite)}"
        )
    if task_kwargs is not None and not isinstance(task_kwargs, dict):
        raise TypeError(f"task_kwargs must be a dict of keyword arguments, got {type(task_kwargs).__name__}")
    if environment_kwargs is not None and not isinstance(environment_kwargs, dict):
        raise TypeError(
            f"environment_kwargs must be a dict of keyword arguments, got {type(environment_kwargs).__name__}"
        )
    task_kwargs = dict(task_kwargs or {})
    _check_random(task_kwargs.get("random"))
    fixed = sorted({"control_timestep", "n_sub_steps", "time_limit"} & set(environment_kwargs or {}))
    if fixed:  # dm_control said "got multiple values for keyword argument", or both were supplied
        raise ValueError(
            f"environment_kwargs: {', '.join(fixed)} are set by the task (the control step is the suite's; "
            "the episode length is task_kwargs['time_limit'])"
        )
    accepted = inspect.signature(suite[task_name]).parameters
    unknown = sorted(set(task_kwargs) - set(accepted))
    if unknown:
        raise ValueError(
            f"{domain_name}-{task_name}: unknown task_kwargs {unknown}; accepted: {sorted(accepted)}"
        )
    if environment_kwargs is not None:
        task_kwargs["environment_kwargs"] = environment_kwargs
    env = suite[task_name](**task_kwargs)
    env.task.visualize_reward = visualize_reward
    return env
