"""Render the YuMi's head camera over a sponge, a spray bottle and a mug, and save it as a PNG.

The world is headless PyBullet; the image comes from its CPU renderer (no GPU, no display). The
script also prints where each object's canonical grasp lands in the image, the pixel a
perception model learns to point at, and writes a dimly lit version of the same scene.

Run: python examples/03_render_head_camera.py [output folder, default: runs/renders/]
"""

import sys
import time
from pathlib import Path

import numpy as np

from perception.drawing import write_png
from perception.objects.catalog import get_object_spec
from perception.objects.grasps import grasp_pose
from robots.yumi import YUMI
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.lighting import Lighting
from sim.world.yumi_world import World

out = Path(sys.argv[1] if len(sys.argv) > 1 else "runs/renders")
placements = {  # object type: (x, y) on the table [m], yaw [rad]
    "sponge": ((0.34, 0.16), 0.5),
    "spray_bottle": ((0.48, 0.02), 1.2),
    "mug": ((0.40, -0.17), 2.2),
}

with World(robot=YUMI) as world:
    for name, (xy, yaw) in placements.items():
        world.add_object(get_object_spec(name), xy, yaw)
    world.step(round(0.25 / world.config.time_step_s))  # let them settle on the table

    camera = HeadCamera(camera_config(YUMI))  # the YuMi head camera
    start = time.perf_counter()
    image = camera.render(world.client)  # (128, 128, 3) uint8, row 0 at the top
    render_ms = (time.perf_counter() - start) * 1e3
    dim = camera.render(world.client, Lighting(brightness=0.35))

    print(f"{image.shape[1]} x {image.shape[0]} px in {render_ms:.1f} ms; camera at "
          f"{camera.config.position_m} m looking at {camera.config.target_m} m, "
          f"{camera.config.horizontal_fov_deg} x {camera.config.vertical_fov_deg} deg field of "
          "view")
    for body, spec in world.objects.items():
        grasp = grasp_pose(spec, world.object_pose(body))
        u, v = camera.project(grasp.position[None, :])[0]  # (2,) [px]
        approach = np.round(grasp.rotation[:, 2], 2)
        print(f"{spec.name:>12}: grasp TCP at {np.round(grasp.position, 3)} m, "
              f"approach {approach}, pixel (u {u:.1f}, v {v:.1f})")

for path, picture in [(out / "head_camera.png", image), (out / "head_camera_dim.png", dim)]:
    print(f"wrote {write_png(path, picture)}")
