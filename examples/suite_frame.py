"""A rendered frame of each EFAM suite domain (docs/figures/suite_frame.png).

MUJOCO_GL=egl python examples/suite_frame.py [--out docs/figures/suite_frame.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from efam_mujoco import suite  # noqa: E402

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=FIGURES / "suite_frame.png")
    args = parser.parse_args(argv)
    images = []
    for domain, task in (("bundle", "reach"), ("arm", "reach"), ("bundle", "push")):
        env = suite.load(domain, task, task_kwargs={"random": 2})
        env.reset()
        for _ in range(20):
            env.step(np.full(env.action_spec().shape, 0.45))
        images.append(env.physics.render(360, 480, camera_id="perspective"))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    plt.imsave(args.out, np.concatenate(images, axis=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
