"""Writes ``yumi.urdf`` and ``yumi.srdf`` from the numbers in :mod:`robots.yumi.specs`.

Run ``python -m robots.yumi.generate`` after changing a number; ``tests/robots/test_yumi.py`` fails
while the committed files differ from what this writes. The SRDF's disabled collision pairs are
found the way MoveIt's setup assistant does: adjacent links, and pairs whose primitive shapes
overlap in nearly every sampled configuration (their overlap is an artefact of the boxes, not a
real collision).
"""

from __future__ import annotations

import itertools
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from robots.yumi import specs
from robots.yumi.specs import Box, Cylinder

HERE = Path(__file__).resolve().parent
URDF_PATH = HERE / "yumi.urdf"
SRDF_PATH = HERE / "yumi.srdf"

_COLORS = {
    "body": (0.85, 0.85, 0.83, 1.0),
    "arm": (0.92, 0.92, 0.90, 1.0),
    "wrist": (0.35, 0.35, 0.37, 1.0),
    "gripper": (0.25, 0.25, 0.27, 1.0),
    "finger": (0.10, 0.10, 0.10, 1.0),
}


def _fmt(values: tuple[float, ...] | list[float]) -> str:
    return " ".join(f"{v:.9g}" for v in values)


def _box_inertia(mass_kg: float, size: tuple[float, float, float]) -> np.ndarray:
    x, y, z = size
    return mass_kg / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])


def _cylinder_inertia(mass_kg: float, radius_m: float, length_m: float) -> np.ndarray:
    side = mass_kg * (3 * radius_m**2 + length_m**2) / 12.0
    return np.diag([side, side, 0.5 * mass_kg * radius_m**2])


def _shape_center_and_inertia(
    shape: Box | Cylinder, mass_kg: float
) -> tuple[tuple[float, float, float], np.ndarray]:
    if isinstance(shape, Box):
        return shape.center, _box_inertia(mass_kg, shape.size)
    inertia = _cylinder_inertia(mass_kg, shape.radius_m, shape.length_m)
    order = {"x": [2, 0, 1], "y": [0, 2, 1], "z": [0, 1, 2]}[shape.axis]
    return shape.center, np.diag(np.diag(inertia)[order])


def _composite_inertia(
    boxes: tuple[Box, ...], total_mass_kg: float
) -> tuple[tuple[float, float, float], np.ndarray]:
    """Centre of mass and inertia about it of solid boxes sharing one density."""
    volumes = np.array([np.prod(b.size) for b in boxes])
    masses = total_mass_kg * volumes / volumes.sum()
    centers = np.array([b.center for b in boxes])
    com = (masses[:, None] * centers).sum(axis=0) / total_mass_kg
    inertia = np.zeros((3, 3))
    for box, mass, center in zip(boxes, masses, centers, strict=True):
        d = center - com
        shift = mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))  # parallel-axis theorem
        inertia += _box_inertia(float(mass), box.size) + shift
    return (float(com[0]), float(com[1]), float(com[2])), inertia


def _add_inertial(
    link: ET.Element, mass_kg: float, com: tuple[float, float, float], inertia: np.ndarray
) -> None:
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "origin", xyz=_fmt(com), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=f"{mass_kg:.9g}")
    ET.SubElement(
        inertial,
        "inertia",
        ixx=f"{inertia[0, 0]:.6e}",
        ixy=f"{inertia[0, 1]:.6e}",
        ixz=f"{inertia[0, 2]:.6e}",
        iyy=f"{inertia[1, 1]:.6e}",
        iyz=f"{inertia[1, 2]:.6e}",
        izz=f"{inertia[2, 2]:.6e}",
    )


def _add_shape(link: ET.Element, shape: Box | Cylinder, color: str) -> None:
    """Adds the same primitive as visual and collision geometry."""
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    if isinstance(shape, Box):
        geometry_tag, attrs = "box", {"size": _fmt(shape.size)}
    else:
        geometry_tag = "cylinder"
        attrs = {"radius": f"{shape.radius_m:.9g}", "length": f"{shape.length_m:.9g}"}
        # A URDF cylinder runs along z; turn it onto the link axis it follows.
        rpy = {"x": (0.0, math.pi / 2, 0.0), "y": (math.pi / 2, 0.0, 0.0), "z": rpy}[shape.axis]
    for kind in ("visual", "collision"):
        element = ET.SubElement(link, kind)
        ET.SubElement(element, "origin", xyz=_fmt(shape.center), rpy=_fmt(rpy))
        geometry = ET.SubElement(element, "geometry")
        ET.SubElement(geometry, geometry_tag, attrs)
        if kind == "visual":
            material = ET.SubElement(element, "material", name=color)
            ET.SubElement(material, "color", rgba=_fmt(_COLORS[color]))


def _add_joint(
    robot: ET.Element,
    name: str,
    kind: str,
    parent: str,
    child: str,
    xyz: tuple[float, float, float],
    rpy: tuple[float, float, float],
    *,
    axis: tuple[float, float, float] | None = None,
    limit: dict[str, float] | None = None,
    damping: float | None = None,
) -> None:
    joint = ET.SubElement(robot, "joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    ET.SubElement(joint, "origin", xyz=_fmt(xyz), rpy=_fmt(rpy))
    if axis is not None:
        ET.SubElement(joint, "axis", xyz=_fmt(axis))
    if limit is not None:
        ET.SubElement(joint, "limit", {k: f"{v:.9g}" for k, v in limit.items()})
    if damping is not None:
        ET.SubElement(joint, "dynamics", damping=f"{damping:.9g}", friction="0")


def _add_arm(robot: ET.Element, side: str) -> None:
    parent = "yumi_body"
    for index, spec in enumerate(specs.ARM_JOINTS, start=1):
        child = specs.arm_link_name(index, side)
        link = ET.SubElement(robot, "link", name=child)
        color = "arm" if index <= 5 else "wrist"
        com, inertia = _shape_center_and_inertia(spec.link_box, spec.link_mass_kg)
        _add_inertial(link, spec.link_mass_kg, com, inertia)
        _add_shape(link, spec.link_box, color)
        xyz = specs.ARM_MOUNT_XYZ[side] if index == 1 else spec.origin_xyz
        rpy = specs.ARM_MOUNT_RPY[side] if index == 1 else spec.origin_rpy
        _add_joint(
            robot,
            specs.arm_joint_name(spec.abb_axis, side),
            "revolute",
            parent,
            child,
            xyz,
            rpy,
            axis=(0.0, 0.0, 1.0),
            limit={
                "lower": spec.lower_rad,
                "upper": spec.upper_rad,
                "effort": spec.max_effort_nm,
                "velocity": spec.max_velocity_rad_s,
            },
            damping=0.5,  # as in the ROS model (facts §1.2)
        )
        parent = child
    _add_gripper(robot, side, parent)


def _add_gripper(robot: ET.Element, side: str, flange_parent: str) -> None:
    base = f"gripper_{side}_base"
    link = ET.SubElement(robot, "link", name=base)
    com, inertia = _shape_center_and_inertia(specs.GRIPPER_BODY, specs.GRIPPER_MASS_KG)
    _add_inertial(link, specs.GRIPPER_MASS_KG, com, inertia)
    _add_shape(link, specs.GRIPPER_BODY, "gripper")
    _add_joint(robot, f"gripper_{side}_flange", "fixed", flange_parent, base,
               specs.FLANGE_XYZ, specs.FLANGE_RPY)
    # Two independent prismatic fingers (PyBullet has no mimic joints); the simulator drives both.
    for finger, y_sign, yaw in (("r", -1.0, 0.0), ("l", 1.0, math.pi)):
        name = f"gripper_{side}_finger_{finger}"
        link = ET.SubElement(robot, "link", name=name)
        com, inertia = _shape_center_and_inertia(specs.FINGER_BOX, specs.FINGER_MASS_KG)
        _add_inertial(link, specs.FINGER_MASS_KG, com, inertia)
        _add_shape(link, specs.FINGER_BOX, "finger")
        joint = f"gripper_{side}_joint" + ("" if finger == "r" else "_m")
        _add_joint(
            robot,
            joint,
            "prismatic",
            base,
            name,
            (0.0, y_sign * specs.FINGER_JOINT_Y_M, specs.FINGER_JOINT_Z_M),
            (0.0, 0.0, yaw),
            axis=(-1.0, 0.0, 0.0),
            limit={
                "lower": 0.0,
                "upper": specs.FINGER_TRAVEL_M,
                "effort": specs.FINGER_MAX_FORCE_N,
                "velocity": specs.FINGER_MAX_SPEED_M_S,
            },
            damping=1.0,  # as in the ROS model (facts §2.2)
        )
    # TCP: a frame-only link with a tiny explicit inertial (PyBullet would give it 1 kg, §6.6).
    tcp = ET.SubElement(robot, "link", name=f"gripper_{side}_tcp")
    _add_inertial(tcp, 1e-4, (0.0, 0.0, 0.0), np.eye(3) * 1e-9)
    _add_joint(robot, f"gripper_{side}_tcp_joint", "fixed", base, f"gripper_{side}_tcp",
               (0.0, 0.0, specs.TCP_Z_M), (0.0, 0.0, 0.0))


def build_urdf() -> str:
    """The URDF text of the YuMi, body frame at the root."""
    robot = ET.Element("robot", name="yumi")
    robot.append(ET.Comment(" Generated by robots/yumi/generate.py from robots/yumi/specs.py; "
                            "do not edit by hand. "))
    body = ET.SubElement(robot, "link", name="yumi_body")
    com, inertia = _composite_inertia(specs.BODY_BOXES, specs.body_mass_kg())
    _add_inertial(body, specs.body_mass_kg(), com, inertia)
    for box in specs.BODY_BOXES:
        _add_shape(body, box, "body")
    for side in specs.ARM_SIDES:
        _add_arm(robot, side)
    ET.indent(robot, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def _adjacent_pairs() -> set[tuple[str, str]]:
    """Links joined by a joint, and the wrist group seen as one body.

    The wrist group is links 5-7, the gripper and its fingers: joint 5's range keeps the real
    gripper clear of the forearm, so an overlap of their primitives is an artefact (it shows at
    ABB's own calibration pose).
    """
    pairs: set[tuple[str, str]] = set()
    for side in specs.ARM_SIDES:
        chain = ["yumi_body"] + [specs.arm_link_name(i, side) for i in range(1, 8)]
        pairs.update(itertools.pairwise(chain))
        hand = [specs.arm_link_name(i, side) for i in (5, 6, 7)]
        hand += [f"gripper_{side}_base", f"gripper_{side}_finger_r", f"gripper_{side}_finger_l"]
        pairs.update(itertools.combinations(hand, 2))
    return {(min(a, b), max(a, b)) for a, b in pairs}


def always_colliding_pairs(
    urdf_text: str, samples: int = 2000, seed: int = 0
) -> set[tuple[str, str]]:
    """Link pairs whose primitives overlap in >= 99 % of random in-limit configurations."""
    import tempfile

    import pinocchio as pin

    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as handle:
        handle.write(urdf_text)
    model = pin.buildModelFromUrdf(handle.name)
    geom = pin.buildGeomFromUrdf(model, handle.name, pin.GeometryType.COLLISION)
    Path(handle.name).unlink()
    geom.addAllCollisionPairs()
    data, geom_data = model.createData(), pin.GeometryData(geom)
    rng = np.random.default_rng(seed)
    counts = np.zeros(len(geom.collisionPairs))
    for _ in range(samples):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        pin.computeCollisions(model, data, geom, geom_data, q, False)
        counts += [r.isCollision() for r in geom_data.collisionResults]
    result = set()
    for index, pair in enumerate(geom.collisionPairs):
        if counts[index] >= 0.99 * samples:
            a = model.frames[geom.geometryObjects[pair.first].parentFrame].name
            b = model.frames[geom.geometryObjects[pair.second].parentFrame].name
            if a != b:
                result.add((min(a, b), max(a, b)))
    return result


def build_srdf(urdf_text: str) -> str:
    """The SRDF: arm groups, the home state, and the collision pairs never worth checking."""
    robot = ET.Element("robot", name="yumi")
    robot.append(ET.Comment(" Generated by robots/yumi/generate.py; do not edit by hand. "))
    for side in specs.ARM_SIDES:
        group = ET.SubElement(robot, "group", name=f"arm_{side}")
        ET.SubElement(group, "chain", base_link="yumi_body", tip_link=f"gripper_{side}_tcp")
    state = ET.SubElement(robot, "group_state", name="home", group="all")
    for side in specs.ARM_SIDES:
        degrees = dict(zip((1, 2, 3, 4, 5, 6, 7), specs.HOME_ABB_ORDER_DEG[side], strict=True))
        for spec in specs.ARM_JOINTS:
            ET.SubElement(state, "joint", name=specs.arm_joint_name(spec.abb_axis, side),
                          value=f"{math.radians(degrees[spec.abb_axis]):.9g}")
        for joint in (f"gripper_{side}_joint", f"gripper_{side}_joint_m"):
            ET.SubElement(state, "joint", name=joint, value="0")
    reasons = {p: "Adjacent" for p in _adjacent_pairs()}
    for pair in always_colliding_pairs(urdf_text):
        reasons.setdefault(pair, "Default")
    for (a, b), reason in sorted(reasons.items()):
        ET.SubElement(robot, "disable_collisions", link1=a, link2=b, reason=reason)
    ET.indent(robot, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def main() -> None:
    """Writes both files next to this module."""
    urdf = build_urdf()
    URDF_PATH.write_text(urdf)
    SRDF_PATH.write_text(build_srdf(urdf))
    print(f"wrote {URDF_PATH} and {SRDF_PATH}")


if __name__ == "__main__":
    main()
