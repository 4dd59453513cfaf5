"""Assemble the Baxter reach-grasp-align scene with ``mujoco.MjSpec`` from robosuite's assets.

The robot and gripper models (MJCF with visual meshes and primitive collision
geometry) come from the installed ``robosuite`` package, read as files: robosuite's
Python code is never imported, so none of its dependencies load. The scene adds a
table, two boxes on free joints, two target spheres (mocap bodies) and cameras.

World frame: x forward from the robot, y to the robot's left, z up, metres. The
torso origin stands ``TORSO_HEIGHT`` above the floor, as in ``kinematics.baxter_arm``.
"""

from __future__ import annotations

import functools
import importlib.util
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from dualarm.errors import DualarmError
from dualarm.kinematics import ARMS, BAXTER_JOINT_LIMITS, BAXTER_JOINT_NAMES
from dualarm.typed_fields import check_field_types

#: Height of Baxter's torso origin above the floor (m);.
TORSO_HEIGHT = 0.93

#: Joint-position servo per Baxter joint s0..w2 (joint mode): stiffness (N m/rad), damping
#: (N m s/rad, set by hand for well-damped tracking of 0.1 rad steps) and torque limit
#: (N m, robosuite's motor ranges).
SERVO_KP = np.array([800.0, 1000.0, 600.0, 500.0, 150.0, 150.0, 60.0])
SERVO_KV = np.array([60.0, 80.0, 40.0, 35.0, 8.0, 8.0, 3.0])
SERVO_TORQUE_LIMIT = np.array([50.0, 100.0, 50.0, 50.0, 15.0, 15.0, 15.0])

CONTROL_MODES = ("cartesian", "joint")

#: Natural rest posture per arm (rad; robosuite's Baxter initial pose), rows left, right.
REST_POSTURE = np.array([
    [-0.403, -0.636, -0.114, 1.432, -0.735, 1.205, 0.269],
    [0.403, -0.636, 0.114, 1.432, 0.735, 1.205, -0.269],
])

#: Grip-site orientation (w, x, y, z) that points the gripper down with the fingers closing
#: along world y: a half turn about (1, -1, 0), so site x = -y, site y = -x, site z = -z in
#: the world. Of the two yaws that close along y, this one keeps both wrists near the rest
#: posture (w2 about +-0.3 rad instead of against its limit).
GRIP_DOWN_QUAT = [0.0, 0.7071067811865476, -0.7071067811865476, 0.0]

#: Cartesian mode: joint springs towards REST_POSTURE (N m/rad) and joint damping (N m s/rad).
#: Weak against the weld, they only settle what the weld leaves free (the elbow swivel).
POSTURE_STIFFNESS = np.array([3.0, 3.0, 3.0, 3.0, 1.0, 1.0, 1.0])
POSTURE_DAMPING = np.array([8.0, 8.0, 6.0, 6.0, 2.0, 2.0, 1.0])
#: Weld constraint (time constant s, damping ratio): how fast the gripper follows its target.
WELD_SOLREF = (0.02, 1.0)

#: Colours of Fig. 5: black box and red target for the left arm, yellow box and blue target for the right.
BOX_RGBA = {"left": (0.05, 0.05, 0.05, 1.0), "right": (0.95, 0.8, 0.05, 1.0)}
TARGET_RGBA = {"left": (0.9, 0.1, 0.1, 0.55), "right": (0.1, 0.25, 0.95, 0.55)}


@dataclass(frozen=True)
class SceneConfig:
    """Geometry of the scene (m, kg); physics options.

    Attributes:
        table_center: (x, y) of the table top centre.
        table_half_size: (x, y) half extents of the table top.
        table_height: height of the table top above the floor.
        box_half_size: half edge of each cubic box.
        box_mass: mass of each box.
        box_friction: sliding friction of the boxes (the fingers' own is 0, as in robosuite,
            so the box's value governs the grip).
        target_radius: radius of the target spheres (visual only).
        timestep: physics step (s).
    """

    table_center: tuple[float, float] = (0.72, 0.0)
    table_half_size: tuple[float, float] = (0.3, 0.6)
    table_height: float = 0.75
    box_half_size: float = 0.025
    box_mass: float = 0.1
    box_friction: float = 1.0
    target_radius: float = 0.03
    timestep: float = 0.002

    def __post_init__(self):
        check_field_types(self)


def robosuite_assets() -> Path:
    """Folder ``robosuite/models/assets`` of the installed robosuite package.

    Raises:
        DualarmError: robosuite is not installed (``pip install robosuite``).
    """
    override = os.environ.get("DUALARM_ROBOSUITE_ASSETS")
    if override:
        root = Path(override)
    else:
        spec = importlib.util.find_spec("robosuite")  # locates without importing its code
        if spec is None or not spec.submodule_search_locations:
            raise DualarmError("the Baxter model comes from robosuite's assets: "
                               "pip install 'robosuite>=1.5,<1.6'")
        root = Path(next(iter(spec.submodule_search_locations))) / "models" / "assets"
    robot = root / "robots" / "baxter" / "robot.xml"
    if not robot.is_file():
        raise DualarmError(f"{robot}: Baxter model not found in the robosuite assets")
    return root


def _strip_visual_meshes(spec: mujoco.MjSpec) -> None:
    """Delete mesh geoms that never collide, and then the unused meshes (faster compile)."""
    for geom in list(spec.geoms):
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH and geom.contype == 0 and geom.conaffinity == 0:
            spec.delete(geom)
    used = {g.meshname for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH}
    for mesh in list(spec.meshes):
        if mesh.name not in used:
            spec.delete(mesh)


def _set_first(element, attribute: str, value: float) -> None:
    """Set a scalar joint property that MuJoCo 4 turned into a vector (first entry = the old scalar)."""
    current = getattr(element, attribute)
    if np.ndim(current) == 0:
        setattr(element, attribute, value)
    else:
        vector = np.zeros(len(current))
        vector[0] = value
        setattr(element, attribute, vector)


def _baxter_spec(assets: Path, visual: bool, control: str) -> mujoco.MjSpec:
    """Baxter with both Rethink electric grippers and gravity compensation.

    ``control="joint"``: a position servo per arm joint. ``control="cartesian"``: no arm
    servos; each gripper is welded to a mocap body (``{arm}_hand_target``) and each
    joint has a weak spring to the rest posture, which decides the elbow swivel.
    """
    robot = mujoco.MjSpec.from_file(str(assets / "robots" / "baxter" / "robot.xml"))
    # The torso's collision mesh (the only mesh that collides) becomes a box: the arms
    # never reach it in this task and primitives keep the physics fast.
    torso_mesh = robot.geom("base_link_col")
    torso = robot.body("torso")
    robot.delete(torso_mesh)
    torso.add_geom(name="torso_col", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.12, 0.15, 0.3],
                   pos=[-0.05, 0, 0.25], rgba=[0.5, 0.1, 0.1, 1], group=3)
    for actuator in list(robot.actuators):  # robosuite's torque motors -> joint servos
        robot.delete(actuator)
    for a, arm in enumerate(ARMS):
        for k, joint in enumerate(BAXTER_JOINT_NAMES):
            if control == "cartesian":
                spring = robot.joint(f"{arm}_{joint}")
                _set_first(spring, "stiffness", POSTURE_STIFFNESS[k])
                _set_first(spring, "damping", POSTURE_DAMPING[k])
                spring.springref = REST_POSTURE[a, k]
                continue
            act = robot.add_actuator(name=f"{arm}_{joint}_servo", target=f"{arm}_{joint}",
                                     trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_position(kp=SERVO_KP[k], kv=SERVO_KV[k])
            act.ctrllimited = True
            act.ctrlrange = BAXTER_JOINT_LIMITS[k]
            act.forcelimited = True
            act.forcerange = [-SERVO_TORQUE_LIMIT[k], SERVO_TORQUE_LIMIT[k]]
        gripper = mujoco.MjSpec.from_file(str(assets / "grippers" / "rethink_gripper.xml"))
        for sensor in list(gripper.sensors):
            gripper.delete(sensor)
        for geom in gripper.geoms:
            # Only the finger pads touch the boxes: the other finger boxes overlap them and
            # would double the contacts (and the solver's work) without changing the grasp.
            if geom.name.endswith(("finger_g0", "finger_g1", "fingertip_g0")):
                geom.contype = 0
                geom.conaffinity = 0
        hand = robot.body(f"{arm}_hand")
        frame = hand.add_frame()
        frame.attach_body(gripper.body("gripper_base"), f"{arm}_gripper_", "")
        for finger in ("r", "l"):  # robosuite's finger ctrlranges are swapped: use the joint ranges
            act = robot.actuator(f"{arm}_gripper_gripper_{finger}_finger_joint")
            act.ctrlrange = robot.joint(f"{arm}_gripper_{finger}_finger_joint").range
        if control == "cartesian":
            target = robot.worldbody.add_body(name=f"{arm}_hand_target", mocap=True,
                                              pos=[0.6, 0.25 if arm == "left" else -0.25, 0.95],
                                              quat=GRIP_DOWN_QUAT)
            target.add_site(name=f"{arm}_hand_target_site", size=[0.008, 0, 0],
                            rgba=[0.1, 0.9, 0.1, 0.4], group=2)
            weld = robot.add_equality(type=mujoco.mjtEq.mjEQ_WELD, name=f"{arm}_hand_weld",
                                      name1=f"{arm}_hand_target", name2=f"{arm}_gripper_eef",
                                      objtype=mujoco.mjtObj.mjOBJ_BODY)
            data = np.zeros(len(weld.data))   # anchor, relpos, relquat, torquescale
            data[6] = 1.0                     # identity relative pose: eef frame = target frame
            data[10] = 1.0
            weld.data = data
            weld.solref = list(WELD_SOLREF)
    for geom in robot.geoms:   # robosuite's translucent head-collision spheres: keep, but unseen
        if geom.name.startswith("collision_head_link"):
            geom.rgba = [0.8, 0.3, 0.3, 0.0]
    if not visual:
        _strip_visual_meshes(robot)
    for body in robot.bodies:
        body.gravcomp = 1.0  # the arm servos then track without a gravity sag
    return robot


def build_spec(config: SceneConfig = SceneConfig(), visual: bool = True,
               control: str = "cartesian") -> mujoco.MjSpec:
    """The whole scene as an editable ``MjSpec``.

    Args:
        config: table, box and physics values.
        control: "cartesian" (mocap-welded grippers) or "joint" (joint servos).
        visual: keep the robot's visual meshes: needed for rendering, about 2 s more to
            compile and 10% slower steps (they join the broad phase) though they never
            collide. The environment steps a model without them and renders a twin with them.
    """
    assets = robosuite_assets()
    # The robot's spec is the root: the scene is added around it (attaching it to an
    # empty spec would need a name prefix on every joint and actuator).
    if control not in CONTROL_MODES:
        raise ValueError(f"control must be one of {CONTROL_MODES}, got {control!r}")
    spec = _baxter_spec(assets, visual, control)
    spec.body("base").pos = [0.0, 0.0, TORSO_HEIGHT]  # the torso sits at the base origin
    spec.modelname = "baxter_reach_grasp_align"
    spec.compiler.degree = False
    spec.option.timestep = config.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    spec.visual.quality.shadowsize = 2048
    spec.stat.center = [0.5, 0.0, 0.9]
    spec.stat.extent = 1.5

    world = spec.worldbody
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.55, 0.65, 0.8],
                     rgb2=[0.1, 0.12, 0.16], width=256, height=256)
    spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.82, 0.84, 0.86],
                     rgb2=[0.72, 0.74, 0.76], width=512, height=512)
    spec.add_material(name="floor", textures=["", "grid"], texrepeat=[6, 6], reflectance=0.1)
    world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[3, 3, 0.05],
                   material="floor")
    world.add_light(name="key", pos=[1.2, 0.0, 2.6], dir=[-0.3, 0.0, -1.0],
                    castshadow=True, diffuse=[0.7, 0.7, 0.7])
    world.add_light(name="fill", pos=[0.5, -1.5, 2.0], dir=[0.0, 1.0, -1.0], castshadow=False,
                    diffuse=[0.35, 0.35, 0.35])

    # Table: one box, top at table_height.
    tx, ty = config.table_center
    hx, hy = config.table_half_size
    top = config.table_height
    table = world.add_body(name="table", pos=[tx, ty, top / 2])
    table.add_geom(name="table_top", type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx, hy, top / 2],
                   rgba=[0.62, 0.47, 0.33, 1.0], friction=[1.0, 0.005, 0.0001])

    # Pedestal under the torso (visual only).
    world.add_geom(name="pedestal", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.16, 0.42],
                   pos=[-0.05, 0, 0.42], rgba=[0.2, 0.2, 0.22, 1], contype=0, conaffinity=0)

    s = config.box_half_size
    for arm in ARMS:
        box = world.add_body(name=f"{arm}_box", pos=[0.6, 0.2 if arm == "left" else -0.2, top + s])
        box.add_freejoint(name=f"{arm}_box_joint")
        box.add_geom(name=f"{arm}_box_geom", type=mujoco.mjtGeom.mjGEOM_BOX, size=[s, s, s],
                     mass=config.box_mass, rgba=list(BOX_RGBA[arm]), condim=3,
                     friction=[config.box_friction, 0.01, 0.0002])
        box.add_site(name=f"{arm}_box_site", size=[0.004, 0, 0], rgba=[1, 1, 1, 0.0])
        target = world.add_body(name=f"{arm}_target", mocap=True, pos=[0.7, 0.1 if arm == "left" else -0.1, 1.0])
        target.add_geom(name=f"{arm}_target_geom", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                        size=[config.target_radius, 0, 0], rgba=list(TARGET_RGBA[arm]),
                        contype=0, conaffinity=0)

    # Cameras: front view as in Fig. 5 (from in front of and above the table, looking back at
    # the robot), and a top view.
    world.add_camera(name="front", pos=[1.7, 0.0, 1.55], xyaxes=[0, 1, 0, -0.479, 0, 0.878], fovy=50)
    world.add_camera(name="side", pos=[1.3, -1.2, 1.5],
                     xyaxes=[0.8637, 0.5039, 0, -0.1854, 0.3178, 0.9297], fovy=45)
    return spec


@functools.lru_cache(maxsize=4)
def compiled_model(config: SceneConfig = SceneConfig(), visual: bool = True,
                   control: str = "cartesian") -> mujoco.MjModel:
    """The compiled scene, built once per process and configuration (MjModel is read-only in use)."""
    return build_spec(config, visual, control).compile()
