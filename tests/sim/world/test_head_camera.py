"""The head camera: images, projection consistent with them, a clear view, lighting."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import asdict, fields, replace

import numpy as np
import pybullet
import pytest

from perception.camera import PinholeCamera, RgbdFrame
from perception.interface import InvalidInputError as PerceptionInputError
from perception.objects.catalog import get_object_spec
from robots import get_robot
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.tasks.scene_specs import YUMI_SCENE
from sim.world.head_camera import FOCUS_BEFORE_RECORDED_PX, CameraConfig, HeadCamera, camera_config
from sim.world.lighting import Lighting
from sim.world.paper_world import PaperWorldConfig
from sim.world.yumi_world import World

MOUNT = YUMI.camera
"""The YuMi head camera's mount: the camera these tests render through."""
HEAD = camera_config(YUMI)
"""The YuMi head camera (its mount, the D435-like image)."""

# (how far an object reaches from its centre [m], at what height [m]): the mug's handle reaches
# 6.7 cm low down, its rim 4.5 cm at 9 cm; only the bottle (radius 1.9 cm) stands 17 cm tall.
OBJECT_EXTENTS_M = ((0.07, 0.0), (0.07, 0.07), (0.045, 0.09), (0.02, 0.17))


@pytest.fixture(scope="session")
def world() -> Iterator[World]:
    with World(robot=YUMI) as w:
        yield w


@pytest.fixture(scope="session")
def camera() -> HeadCamera:
    return HeadCamera(HEAD)


def _marker(world: World, position: list[float]) -> int:
    """A 1 cm magenta ball that only shows (no collision, no mass)."""
    visual = world.client.createVisualShape(
        pybullet.GEOM_SPHERE, radius=0.01, rgbaColor=[1.0, 0.0, 1.0, 1.0]
    )
    return int(world.client.createMultiBody(0.0, -1, visual, position))


def _magenta_centroid(image: np.ndarray) -> np.ndarray:
    rgb = image.astype(int)
    mask = (rgb[..., 0] > 80) & (rgb[..., 2] > 80) & (rgb[..., 1] < 0.3 * rgb[..., 0])
    v, u = np.nonzero(mask)
    assert u.size >= 3, "the marker is not in the image"
    return np.array([u.mean(), v.mean()])


def test_render_gives_uint8_rgb_of_the_configured_size(world: World, camera: HeadCamera) -> None:
    world.reset_scene()
    image = camera.render(world.client)
    assert image.dtype == np.uint8 and image.shape == (128, 128, 3)
    wide = HeadCamera(CameraConfig.for_mount(MOUNT, width_px=96, height_px=64)).render(world.client)
    assert wide.shape == (64, 96, 3)


@pytest.mark.parametrize(
    "point", [[0.30, 0.25, 0.05], [0.55, -0.25, 0.10], [0.42, 0.0, 0.02], [0.35, -0.2, 0.17]]
)
def test_projection_lands_on_the_rendered_point(
    world: World, camera: HeadCamera, point: list[float]
) -> None:
    world.reset_scene()
    marker = _marker(world, point)
    try:
        found = _magenta_centroid(camera.render(world.client))
    finally:
        world.client.removeBody(marker)
    np.testing.assert_allclose(camera.project(np.array([point]))[0], found, atol=0.35)


def test_image_axes_u_right_v_down(camera: HeadCamera) -> None:
    near, far, left = camera.project(np.array([[0.3, 0.0, 0.0], [0.55, 0.0, 0.0], [0.4, 0.2, 0]]))
    assert far[1] < near[1]  # farther away is higher up: row 0 is the top
    assert left[0] < near[0]  # the robot's left (+y) is the image's left
    assert np.isnan(camera.project(np.array([[-1.0, 0.0, 0.6]]))).all()  # behind the camera


def test_workspace_is_framed_and_not_hidden_by_the_arms_at_home(
    world: World, camera: HeadCamera
) -> None:
    world.reset_scene()
    points = np.array([  # every part of any object the scene may place
        [x + reach * np.cos(angle), y + reach * np.sin(angle), z]
        for x in np.linspace(*YUMI_SCENE.workspace_x_m, 7)
        for y in np.linspace(*YUMI_SCENE.workspace_y_m, 9)
        for angle in np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
        for reach, z in OBJECT_EXTENTS_M
    ])
    pixels = camera.project(points)
    assert pixels.min() >= 3 and pixels.max() <= 125  # inside the image, with a margin
    eye = list(camera.config.position_m)
    hits = world.client.rayTestBatch([eye] * len(points), points.tolist())
    assert not [p for p, hit in zip(points, hits, strict=True) if hit[0] == world.robot.body_id]


def test_the_pandas_stand_camera_frames_the_workspace_as_densely_and_the_arm_hides_none():
    """The Panda's workcell camera (issue 39): every part of any object in view with a margin,
    none behind the arm at home, at 85-90 % of the head camera's pixels per cm."""
    panda = get_robot("panda")
    stand, head = HeadCamera(camera_config(panda)), HeadCamera(HEAD)
    points = np.array([[x + reach * np.cos(angle), y + reach * np.sin(angle), z]
                       for x in np.linspace(*YUMI_SCENE.workspace_x_m, 7)
                       for y in np.linspace(*YUMI_SCENE.workspace_y_m, 9)
                       for angle in np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
                       for reach, z in OBJECT_EXTENTS_M])
    pixels = stand.project(points)
    assert pixels.min() >= 3 and pixels.max() <= 125
    with World(robot=panda) as world:
        world.reset_scene()
        hits = world.client.rayTestBatch([list(stand.config.position_m)] * len(points),
                                         points.tolist())
        assert not [p for p, hit in zip(points, hits, strict=True)
                    if hit[0] == world.robot.body_id]
    centre = np.array([[0.475, 0.0, 0.0], [0.485, 0.0, 0.0], [0.475, 0.01, 0.0]])  # 1 cm steps
    density = [np.linalg.norm(np.diff(c.project(centre)[[0, k]], axis=0)) for c in (stand, head)
               for k in (1, 2)]
    assert 0.8 < density[0] / density[2] < 0.95 and 0.8 < density[1] / density[3] < 0.95


def test_each_object_shows_its_colours_where_it_stands(world: World, camera: HeadCamera) -> None:
    world.reset_scene()
    placed = {"sponge": (0.33, 0.15), "spray_bottle": (0.50, 0.0), "mug": (0.40, -0.17)}
    for name, xy in placed.items():
        world.add_object(get_object_spec(name), xy, 0.4)
    image = camera.render(world.client).astype(int)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    colour = {  # what each object shows from above
        "sponge": (g > r + 30) & (g > b + 30),  # the green scouring layer
        "spray_bottle": (b > r + 60) & (b > g + 30),  # the blue trigger head
        "mug": (r > 2 * g) & (r > 2 * b) & (r > 60),  # red ceramic
    }
    for name, (x, y) in placed.items():
        height = get_object_spec(name).height_m
        u, v = camera.project(np.array([[x, y, height / 2]]))[0].round().astype(int)
        window = colour[name][max(v - 12, 0):v + 13, max(u - 12, 0):u + 13]
        assert window.sum() >= 8, name  # at least 8 pixels of its colour near its centre


def test_darker_lighting_darkens_the_image(world: World, camera: HeadCamera) -> None:
    world.reset_scene()
    bright = camera.render(world.client).mean()
    dim = camera.render(world.client, Lighting(brightness=0.3)).mean()
    assert dim < 0.45 * bright


def test_a_crop_stretches_pixels_along_its_narrower_field() -> None:
    """A 2 : 1 crop of a square frame's field, rendered square, doubles horizontal distances."""
    square = HeadCamera(replace(HEAD, vertical_fov_deg=40.0, horizontal_fov_deg=None))
    fov_deg = 2 * np.degrees(np.arctan(0.5 * np.tan(np.radians(20.0))))  # half the tangent
    crop = HeadCamera(replace(HEAD, vertical_fov_deg=40.0, horizontal_fov_deg=fov_deg))
    points = np.array([[0.45, -0.1, 0.0], [0.45, 0.1, 0.0], [0.5, 0.0, 0.05]])
    centre = np.array([64.0, 63.0])  # the optical axis (see project's pixel-centre offsets)
    np.testing.assert_allclose(crop.project(points) - centre,
                               (square.project(points) - centre) * [2.0, 1.0], atol=1e-9)


def test_config_errors_name_field_value_and_allowed() -> None:
    with pytest.raises(InvalidInputError, match=r"vertical_fov_deg = 0.5 .* in \[1, 170\] deg"):
        CameraConfig.for_mount(MOUNT, vertical_fov_deg=0.5)
    with pytest.raises(InvalidInputError, match=r"horizontal_fov_deg = 180.0 .* None or in \[1, "):
        CameraConfig.for_mount(MOUNT, horizontal_fov_deg=180.0)
    with pytest.raises(InvalidInputError, match=r"up = .* not along the optical axis"):
        CameraConfig.for_mount(MOUNT, position_m=(0.0, 0.0, 1.0), target_m=(0.0, 0.0, 0.0))
    with pytest.raises(InvalidInputError, match=r"brightness = 3.0 .* in \[0, 2\]"):
        Lighting(brightness=3.0)
    with pytest.raises(InvalidInputError, match=r"points_world = \(4,\) .* shape \(N, 3\)"):
        HeadCamera(HEAD).project(np.zeros(4))


@pytest.mark.parametrize("config", [HEAD, CameraConfig.for_mount(MOUNT, horizontal_fov_deg=None),
                                    PaperWorldConfig().camera])
def test_the_pinhole_geometry_agrees_with_pybullets_matrices(config: CameraConfig) -> None:
    camera = HeadCamera(config)
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(0.3, 0.6, 50), rng.uniform(-0.25, 0.25, 50),
                              rng.uniform(0.0, 0.2, 50)])  # (50, 3) on and above the table
    clip = np.hstack([points, np.ones((50, 1))]) @ camera.clip_from_world.T  # (50, 4)
    ndc = clip[:, :2] / clip[:, 3:]
    expected = np.column_stack([(ndc[:, 0] + 1) * 0.5 * config.width_px,
                                (1 - ndc[:, 1]) * 0.5 * config.height_px - 1])
    np.testing.assert_allclose(camera.project(points), expected, atol=1e-4)  # float32 matrices


def test_a_pixels_ray_passes_through_the_point_seen_there() -> None:
    pinhole = HEAD.pinhole
    points = np.array([[0.45, 0.1, 0.0], [0.5, -0.2, 0.15], [0.4, 0.0, 0.07]])
    rays = pinhole.rays(pinhole.project(points))  # (3, 3)
    along = points - np.asarray(pinhole.position_m)  # (3, 3)
    t = (along * rays).sum(axis=1) / (rays * rays).sum(axis=1)
    np.testing.assert_allclose(t[:, None] * rays, along, atol=1e-9)
    assert (t > 0).all()


def test_the_pinhole_camera_reads_back_from_a_datasets_record() -> None:
    record = asdict(replace(HEAD, lighting=Lighting(brightness=0.5)))  # as a dataset keeps it
    assert PinholeCamera.from_json(record) == HEAD.pinhole  # lighting is not geometry
    assert PinholeCamera.from_json(HEAD.pinhole.to_json()) == HEAD.pinhole
    with pytest.raises(PerceptionInputError, match=r"camera.*target_m"):
        PinholeCamera.from_json({"position_m": [0, 0, 1]})
    with pytest.raises(PerceptionInputError, match="vertical_fov_deg"):
        PinholeCamera.from_json(asdict(HEAD) | {"vertical_fov_deg": 190})


def test_a_camera_config_takes_its_mount_from_the_caller() -> None:
    """No robot is assumed: the mount's four fields are required, and for_mount fills them."""
    with pytest.raises(TypeError, match="position_m"):
        CameraConfig()  # type: ignore[call-arg]
    panda = get_robot("panda").camera
    config = CameraConfig.for_mount(panda, width_px=96)
    assert (config.position_m, config.target_m, config.focus_window_px, config.focus_box_px,
            config.width_px) == (panda.position_m, panda.target_m, panda.focus_window_px,
                                 panda.focus_box_px, 96)
    assert [f.name for f in fields(CameraConfig)] == [  # the order every record keeps
        "width_px", "height_px", "vertical_fov_deg", "horizontal_fov_deg", "position_m",
        "target_m", "up", "near_m", "far_m", "lighting", "focus_window_px", "focus_box_px"]


def test_a_record_from_before_the_focus_reads_back_with_the_focus_then_in_force() -> None:
    record = json.loads(json.dumps(asdict(HEAD)))
    assert CameraConfig.from_json(record) == HEAD
    old = {k: v for k, v in record.items() if not k.startswith("focus_")}
    assert CameraConfig.from_json(old) == HEAD  # the YuMi head camera's, as before issue 39
    assert FOCUS_BEFORE_RECORDED_PX == (MOUNT.focus_window_px, MOUNT.focus_box_px)


def test_depth_reads_back_the_table_and_an_objects_top_where_they_are(
    world: World, camera: HeadCamera
) -> None:
    world.reset_scene()
    mug = get_object_spec("mug")
    world.add_object(mug, (0.45, 0.1), 0.0)
    frame = camera.render_rgbd(world.client)
    assert frame.depth_m.dtype == np.float32 and frame.depth_m.shape == (128, 128)
    np.testing.assert_array_equal(frame.rgb, camera.render(world.client))
    points = frame.points_world()  # (H, W, 3)
    assert points.shape == (128, 128, 3)
    table = points[np.abs(points[..., 1] - 0.1) > 0.1]  # away from the mug: the table top
    assert np.abs(table[..., 2]).max() < 2e-3  # depth-buffer precision at ~0.6 m
    rim = camera.project(np.array([[0.45 - 0.0375, 0.1, mug.height_m]]))[0]  # the near rim
    seen = points[round(rim[1]), round(rim[0])]
    assert abs(seen[2] - mug.height_m) < 5e-3 and abs(seen[0] - 0.4125) < 5e-3


def test_points_from_depth_inverts_the_projection() -> None:
    camera = HEAD.pinhole
    rng = np.random.default_rng(0)
    flat = rng.choice(camera.width_px * camera.height_px, 50, replace=False)
    v, u = np.unravel_index(flat, (camera.height_px, camera.width_px))
    depth = np.full((camera.height_px, camera.width_px), np.inf)
    depth[v, u] = rng.uniform(0.3, 0.8, 50)
    points = camera.points_from_depth(depth)  # (H, W, 3)
    seen = points[v, u]  # (50, 3)
    np.testing.assert_allclose(camera.project(seen), np.column_stack([u, v]), atol=1e-9)
    along = (seen - np.asarray(camera.position_m)) @ -camera.world_from_camera[:, 2]
    np.testing.assert_allclose(along, depth[v, u])  # depth is along the optical axis
    assert np.isnan(np.delete(points.reshape(-1, 3), flat, axis=0)).all()  # no depth: NaN
    with pytest.raises(PerceptionInputError, match=r"depth_m = 'shape \(4, 4\)' is not allowed"):
        camera.points_from_depth(np.zeros((4, 4)))


def test_a_frame_s_robot_mask_is_a_bool_image_of_its_size() -> None:
    camera = HEAD.pinhole
    size = (camera.height_px, camera.width_px)
    rgb, depth = np.zeros((*size, 3), np.uint8), np.full(size, np.inf, np.float32)
    assert RgbdFrame(rgb, depth, camera).robot_mask is None
    assert RgbdFrame(rgb, depth, camera, robot_mask=np.zeros(size, bool)).robot_mask.shape == size
    for wrong in (np.zeros(size, np.uint8), np.zeros((4, 4), bool)):
        with pytest.raises(PerceptionInputError, match=r"robot_mask = .* is not allowed: None or "
                                                       r"bool of shape \(128, 128\)"):
            RgbdFrame(rgb, depth, camera, robot_mask=wrong)


@pytest.mark.parametrize("config", [HEAD, CameraConfig.for_mount(MOUNT, horizontal_fov_deg=None)])
def test_k_and_the_optical_frame_project_as_the_camera_does(config: CameraConfig) -> None:
    camera = config.pinhole
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(0.3, 0.6, 20), rng.uniform(-0.25, 0.25, 20),
                              rng.uniform(0.0, 0.2, 20)])  # (20, 3)
    T = camera.T_world_camera
    local = (points - T[:3, 3]) @ T[:3, :3]  # (20, 3) in the optical frame: z forward
    assert (local[:, 2] > 0).all()
    pixels = local @ camera.K.T  # (20, 3)
    np.testing.assert_allclose(pixels[:, :2] / pixels[:, 2:], camera.project(points), atol=1e-9)
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    assert camera.image_size_px == (config.width_px, config.height_px)
