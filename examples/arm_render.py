"""An offscreen rendered image of the 3x3 EFAM arm, bent by unequal pressures.

MuJoCo picks its OpenGL backend when it is imported (``MUJOCO_GL``), so each backend is tried in
a fresh process: EGL (GPU, headless), then OSMesa (software). Where neither works the example
says so and exits cleanly (status 0): there is nothing to render with.

    python examples/arm_render.py [--out docs/figures/arm_render.png]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"
BACKENDS = ("egl", "osmesa")


def render(out: Path) -> None:
    """Runs in the child process, with MUJOCO_GL already set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import mujoco
    import numpy as np

    from efam_mujoco import arm, plugin

    plugin.load()
    mj_spec = arm.build_spec(arm.arm_3x3(orientation="upright", gravity=False))
    _add_scenery(mj_spec, mujoco)
    model = mj_spec.compile()
    data = mujoco.MjData(model)
    # per section: a different muscle low, so the arm bends in three directions
    data.ctrl[:] = np.array([[250e3, 400e3, 400e3], [400e3, 250e3, 400e3], [400e3, 400e3, 250e3]]).ravel()
    while data.time < 3.0:
        mujoco.mj_step(model, data)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = data.xpos[model.body("s2d2").id]
    camera.distance, camera.azimuth, camera.elevation = 1.5, 135.0, -18.0
    with mujoco.Renderer(model, height=720, width=960) as renderer:
        renderer.update_scene(data, camera)
        image = renderer.render()
    out.parent.mkdir(parents=True, exist_ok=True)
    plt.imsave(out, image)


def _add_scenery(spec, mujoco) -> None:
    """A sky gradient and a checkered floor under the base (visual only)."""
    spec.add_texture(
        name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[0.55, 0.7, 0.85], rgb2=[0.05, 0.08, 0.12], width=256, height=256,
    )  # fmt: skip
    spec.add_texture(
        name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=[0.82, 0.82, 0.8], rgb2=[0.68, 0.68, 0.66], width=256, height=256,
    )  # fmt: skip
    floor = spec.add_material(name="floor", texrepeat=[8, 8], reflectance=0.0)
    floor.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1.2, 1.2, 0.05], pos=[0, 0, -0.004], material="floor",
        contype=0, conaffinity=0,
    )  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=FIGURES / "arm_render.png")
    parser.add_argument("--backend", choices=BACKENDS, help=argparse.SUPPRESS)  # the child's own run
    args = parser.parse_args(argv)
    if args.backend:
        render(args.out)
        return 0
    failures = []
    for backend in BACKENDS:
        env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
        child = subprocess.run(
            [sys.executable, __file__, "--backend", backend, "--out", str(args.out)],
            env=env,
            capture_output=True,
            text=True,
        )
        if child.returncode == 0:
            print(f"rendered with MUJOCO_GL={backend}; wrote {args.out}")
            return 0
        last = (child.stderr.strip().splitlines() or ["(no message)"])[-1]
        failures.append(f"{backend}: {last}")
    print("skipped: no OpenGL backend available for offscreen rendering (" + "; ".join(failures) + ")")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
