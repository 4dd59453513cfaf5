"""Motion-capture suit formats (BVH, Xsens MVNX): files written by the formats' specifications
from known joint paths give those joint angles back, whatever the file's world frame, the
segments' axis conventions and the trunk's motion; bad files get one line naming the file."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dualarm.errors import InputError
from dualarm.kinematics import HUMAN_BASE_ROTATION
from dualarm.mocap.bvh import read_bvh
from dualarm.mocap.io import read_recording
from dualarm.mocap.joint_angles import arm_angles, calibration_pose_rotation
from dualarm.mocap.mapping import map_recording
from dualarm.mocap.mvnx import read_mvnx
from dualarm.mocap.recording import ARMS, SENSORS
from dualarm.mocap.synthetic import segment_orientations

RATE = 60.0
# v_G = C_W v_bvh for a Y-up BVH world whose character faces +Z (its left is +X).
C_W = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def pose_angles(pose: str) -> np.ndarray:
    """(14,) joint angles of the calibration pose (all zero for the N-pose)."""
    B = HUMAN_BASE_ROTATION
    out = []
    for arm in ARMS:
        R0 = calibration_pose_rotation(arm, "npose")
        A = B.T @ calibration_pose_rotation(arm, pose) @ R0.T @ B
        q, _ = arm_angles(np.broadcast_to(A, (3, 1, 3, 3)).copy())
        out.append(q[0])
    return np.concatenate(out)


def joint_path(pose: str, seconds: float = 4.0, hold: float = 1.2) -> tuple[np.ndarray, np.ndarray]:
    """time (T,) s and joint angles (T, 14) rad: the pose held for ``hold`` s, then a smooth
    motion of every joint away from it and back."""
    t = np.arange(0.0, seconds, 1.0 / RATE)
    s = np.clip((t - hold) / (seconds - hold), 0.0, 1.0)
    bump = np.sin(np.pi * s) ** 2
    wiggle = np.sin(2 * np.pi * s) * bump
    right = np.stack([-0.3 * bump, 0.7 * bump, 0.25 * wiggle, 1.2 * bump, 0.6 * wiggle, 0.4 * bump,
                      0.3 * wiggle], axis=1)
    mirror = np.array([-1, 1, -1, 1, -1, 1, -1.0])
    return t, pose_angles(pose) + np.concatenate([0.8 * right * mirror, right], axis=1)


def trunk_motion(t: np.ndarray) -> np.ndarray:
    """(T, 3, 3) a leaning, turning trunk in the body frame G (still in the first second)."""
    s = np.clip(t - 1.2, 0.0, None)
    rotvec = np.stack([0.15 * np.sin(s), 0.25 * np.sin(0.7 * s), 0.6 * np.sin(0.5 * s)], axis=1)
    return Rotation.from_rotvec(rotvec).as_matrix()


def segments_in_body(q: np.ndarray) -> dict[str, np.ndarray]:
    """sensor -> (T, 3, 3) its segment in G (the model's zero-pose frames R^0 at q = 0)."""
    return {s: r.as_matrix() for s, r in segment_orientations(q).items()}


# --------------------------------------------------------------------------- BVH by the specification

BVH_ARM = {"Shoulder": (5.0, 15.0, 0.0), "Arm": (12.0, 0.0, 0.0), "ForeArm": (28.0, 0.0, 0.0),
           "Hand": (25.0, 0.0, 0.0)}


def write_bvh(path, t: np.ndarray, q: np.ndarray, *, prefix: str = "", order: str = "ZXY",
              names: dict[str, str] | None = None) -> None:
    """A BVH file (Y up, facing +Z, rest pose a T-pose) whose arms follow ``q`` with a moving
    trunk and clavicles: local rotations by the specification, intrinsic Euler in
    ``order``, degrees."""
    names = names or {}
    P = {arm: calibration_pose_rotation(arm, "tpose") for arm in ARMS}
    trunk = trunk_motion(t)
    seg = segments_in_body(q)
    world = {"Hips": np.broadcast_to(np.eye(3), trunk.shape), "Spine": C_W.T @ trunk @ C_W}
    world["Chest"] = world["Spine"]
    clav = Rotation.from_rotvec(np.outer(np.sin(t), [0.1, 0.2, 0.05])).as_matrix()
    for arm in ARMS:
        side = arm.capitalize()
        world[f"{side}Shoulder"] = world["Chest"] @ clav
        for part, sensor in (("Arm", "upper_arm"), ("ForeArm", "forearm"), ("Hand", "hand")):
            R = trunk @ seg[f"{arm}_{sensor}"] @ P[arm].T  # rotation since the rest pose, in G
            world[f"{side}{part}"] = C_W.T @ R @ C_W
    parent = {"Hips": None, "Spine": "Hips", "Chest": "Spine"}
    offsets = {"Hips": (0.0, 90.0, 0.0), "Spine": (0.0, 10.0, 0.0), "Chest": (0.0, 20.0, 0.0)}
    for arm, sign in (("Left", 1.0), ("Right", -1.0)):
        chain = ["Chest"] + [arm + p for p in BVH_ARM]
        for child, par in zip(chain[1:], chain[:-1]):
            parent[child] = par
            x, y, z = BVH_ARM[child[len(arm):]]
            offsets[child] = (sign * x, y, z)
    order_joints = ["Hips", "Spine", "Chest"] + [a + p for a in ("Left", "Right") for p in BVH_ARM]
    label = {j: prefix + names.get(j, j) for j in order_joints}
    channels = " ".join(f"{a}rotation" for a in order)
    lines = ["HIERARCHY"]

    def emit(joint, depth):
        pad = "  " * depth
        kind = "ROOT" if parent[joint] is None else "JOINT"
        lines.extend([f"{pad}{kind} {label[joint]}", pad + "{", f"{pad}  OFFSET {' '.join(map(str, offsets[joint]))}"])
        if parent[joint] is None:
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {channels}")
        else:
            lines.append(f"{pad}  CHANNELS 3 {channels}")
        children = [j for j in order_joints if parent[j] == joint]
        for c in children:
            emit(c, depth + 1)
        if not children:
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET 10 0 0", pad + "  }"])
        lines.append(pad + "}")

    emit("Hips", 0)
    lines += ["MOTION", f"Frames: {len(t)}", f"Frame Time: {1.0 / RATE!r}"]
    euler = {}
    for j in order_joints:
        local = world[j] if parent[j] is None else np.swapaxes(world[parent[j]], -1, -2) @ world[j]
        euler[j] = Rotation.from_matrix(local).as_euler(order, degrees=True)
    for k in range(len(t)):
        row = [0.0, 90.0, 0.0]
        for j in order_joints:
            row.extend(euler[j][k])
        lines.append(" ".join(f"{v:.9f}" for v in row))
    path.write_text("\n".join(lines) + "\n")


def human_angles(path, pose: str, **kw) -> np.ndarray:
    rec = read_recording(path, **kw)
    return map_recording(rec, calib_seconds=1.0, calib_pose=pose).joints.q


def test_bvh_gives_back_the_joint_paths_from_a_t_pose_start(tmp_path):
    t, q = joint_path("tpose")
    path = tmp_path / "take.bvh"
    write_bvh(path, t, q)
    np.testing.assert_allclose(human_angles(path, "tpose"), q, atol=1e-3)


@pytest.mark.parametrize("order", ["ZYX", "XYZ"])
def test_bvh_channel_order_and_name_prefix_do_not_matter(tmp_path, order):
    t, q = joint_path("tpose")
    path = tmp_path / "mixamo.bvh"
    write_bvh(path, t, q, prefix="mixamorig:", order=order)
    np.testing.assert_allclose(human_angles(path, "tpose"), q, atol=1e-3)


def test_bvh_calibrated_in_an_n_pose(tmp_path):
    # The same file format, the person starting with the arms hanging: --calib-pose npose.
    t, q = joint_path("npose")
    path = tmp_path / "take.bvh"
    write_bvh(path, t, q)
    np.testing.assert_allclose(human_angles(path, "npose"), q, atol=1e-3)
    wrong = human_angles(path, "tpose")  # the wrong pose reads a different posture
    assert np.abs(wrong - q).max() > 0.5


def test_bvh_with_unusual_names_needs_a_sensor_map(tmp_path):
    t, q = joint_path("tpose")
    path = tmp_path / "odd.bvh"
    odd = {"LeftArm": "L_UpArm", "RightArm": "R_UpArm"}
    write_bvh(path, t, q, names=odd)
    with pytest.raises(InputError, match=r"odd\.bvh.*no segment for sensor left_upper_arm.*--sensor-map"):
        read_bvh(path)
    got = human_angles(path, "tpose", sensor_map={"L_UpArm": "left_upper_arm", "R_UpArm": "right_upper_arm"})
    np.testing.assert_allclose(got, q, atol=1e-3)


def test_bvh_joint_named_skeleton(tmp_path):
    # Skeletons that name the joint at the bone's root (LeftShoulder = upper arm, LeftCollar =
    # clavicle) are read without a map.
    t, q = joint_path("tpose")
    path = tmp_path / "joints.bvh"
    names = {}
    for side in ("Left", "Right"):
        names.update({f"{side}Shoulder": f"{side}Collar", f"{side}Arm": f"{side}Shoulder",
                      f"{side}ForeArm": f"{side}Elbow", f"{side}Hand": f"{side}Wrist"})
    write_bvh(path, t, q, names=names)
    np.testing.assert_allclose(human_angles(path, "tpose"), q, atol=1e-3)


@pytest.mark.parametrize("mangle, message", [
    (lambda s: s[:s.index("MOTION")], "no MOTION section"),
    (lambda s: s[:s.rindex("\n", 0, len(s) - 1)] + "\n", "cut short"),
    (lambda s: s.replace("Frames: 240", "Frames: 9999"), "cut short"),
    (lambda s: s.replace("HIERARCHY", "HIERARCHIE", 1), "first line must be HIERARCHY"),
    (lambda s: s.replace("MOTION", "}\nMOTION", 1), "braces do not balance"),
    (lambda s: s.replace("Frame Time: ", "Frame Time: -", 1), "Frame Time must be a positive"),
    (lambda s: _last_frame(s, lambda v: v[:-1]), "numbers, the hierarchy"),
    (lambda s: _last_frame(s, lambda v: v[:-1] + ["nan"]), "NaN or infinite"),
    (lambda s: _last_frame(s, lambda v: v[:-1] + ["x1"]), "not a number: 'x1'"),
    (lambda s: s.replace("JOINT RightHand", "JOINT RightPaw"), "no segment for sensor right_hand"),
])
def test_bad_bvh_gets_one_line_naming_the_file(tmp_path, mangle, message):
    t, q = joint_path("tpose")
    good = tmp_path / "good.bvh"
    write_bvh(good, t, q)
    bad = tmp_path / "bad.bvh"
    bad.write_text(mangle(good.read_text()))
    # bvhio waits forever for lines a truncated file lacks: a subprocess with a timeout proves
    # the reader answers.
    code = ("import sys\nfrom dualarm.mocap.bvh import read_bvh\nfrom dualarm.errors import InputError\n"
            "try:\n    read_bvh(sys.argv[1])\nexcept InputError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code, str(bad)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "bad.bvh" in out.stdout and message in out.stdout


def _last_frame(text: str, edit) -> str:
    lines = text.rstrip("\n").split("\n")
    lines[-1] = " ".join(edit(lines[-1].split()))
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- MVNX by the specification

MVNX_SEGMENTS = ["Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head", "RightShoulder", "RightUpperArm",
                 "RightForeArm", "RightHand", "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand"]
_SENSOR_OF = {"LeftUpperArm": "left_upper_arm", "LeftForeArm": "left_forearm", "LeftHand": "left_hand",
              "RightUpperArm": "right_upper_arm", "RightForeArm": "right_forearm", "RightHand": "right_hand"}


def write_mvnx(path, t: np.ndarray, q: np.ndarray, *, heading: float = 0.7, positions: bool = True,
               seed: int = 0) -> None:
    """An MVNX 4 file: Z-up world turned by ``heading`` about the vertical, a moving trunk,
    and every segment with a random axis convention of its own (an unknown, constant mounting),
    except T8 without positions, which has Xsens' axes (x forward, y left, z up)."""
    rng = np.random.default_rng(seed)
    W = Rotation.from_euler("z", heading).as_matrix()
    trunk = trunk_motion(t)
    seg = segments_in_body(q)
    mount = {name: Rotation.random(random_state=rng).as_matrix() for name in MVNX_SEGMENTS}
    if not positions:
        mount["T8"] = np.eye(3)
    orient, where = {}, {}
    for name in MVNX_SEGMENTS:
        body = seg[_SENSOR_OF[name]] if name in _SENSOR_OF else np.broadcast_to(np.eye(3), (len(t), 3, 3))
        lead = W if name == "Pelvis" else W @ trunk
        orient[name] = lead @ body @ mount[name]
    pelvis = np.array([0.0, 0.0, 1.0])
    chest = np.array([0.0, 0.0, 0.45])
    for name in MVNX_SEGMENTS:
        local = {"T8": chest, "LeftUpperArm": chest + [0.02, 0.19, 0.05],
                 "RightUpperArm": chest + [0.02, -0.19, 0.05]}.get(name, np.zeros(3))
        where[name] = (W @ pelvis) + np.einsum("ij,tjk,k->ti", W, trunk, local)
    head = ('<?xml version="1.0" encoding="UTF-8"?>\n<mvnx version="4" xmlns="http://www.xsens.com/mvn/mvnx">\n'
            f'<subject label="p1" frameRate="{RATE:g}" segmentCount="{len(MVNX_SEGMENTS)}">\n<segments>\n')
    body = "".join(f'<segment label="{n}" id="{i + 1}"><points/></segment>\n' for i, n in enumerate(MVNX_SEGMENTS))
    frames = ['</segments>\n<frames segmentCount="15">\n',
              '<frame time="0" index="" tc="" ms="" type="identity"><orientation>'
              + " ".join(["1 0 0 0"] * len(MVNX_SEGMENTS)) + "</orientation></frame>\n"]
    for k, tk in enumerate(t):
        quats = " ".join(" ".join(f"{v:.9f}" for v in Rotation.from_matrix(orient[n][k]).as_quat(scalar_first=True))
                         for n in MVNX_SEGMENTS)
        frame = f'<frame time="{1000 * tk:.3f}" index="{k}" tc="" ms="" type="normal">\n<orientation>{quats}</orientation>\n'
        if positions:
            pos = " ".join(" ".join(f"{v:.6f}" for v in where[n][k]) for n in MVNX_SEGMENTS)
            frame += f"<position>{pos}</position>\n"
        frames.append(frame + "</frame>\n")
    path.write_text(head + body + "".join(frames) + "</frames>\n</subject>\n</mvnx>\n")


@pytest.mark.parametrize("pose", ["npose", "tpose"])
def test_mvnx_gives_back_the_joint_paths(tmp_path, pose):
    t, q = joint_path(pose)
    path = tmp_path / "take.mvnx"
    write_mvnx(path, t, q)
    np.testing.assert_allclose(human_angles(path, pose), q, atol=1e-3)


def test_mvnx_without_positions_takes_xsens_segment_axes(tmp_path):
    # Without <position> the body axes are T8's own, as Xsens defines them.
    t, q = joint_path("npose")
    path = tmp_path / "take.mvnx"
    write_mvnx(path, t, q, positions=False, seed=1)
    assert "<position>" not in path.read_text()
    np.testing.assert_allclose(human_angles(path, "npose"), q, atol=1e-3)


@pytest.mark.parametrize("mangle, message", [
    (lambda s: s.replace("</mvnx>", ""), "not valid XML"),
    (lambda s: s.replace('label="T8"', 'label="Chest"'), "no segment 'T8'"),
    (lambda s: s.replace('label="LeftHand"', 'label="LeftPaw"'), "no segment for sensor left_hand"),
    (lambda s: s.replace('type="normal">\n<orientation>', 'type="normal">\n<orientation>x ', 1),
     "orientation> of frame 1: not a number: 'x'"),
    (lambda s: s.replace('type="normal"', 'type="tpose"'), "no frames of type normal"),
    (lambda s: s.replace("</orientation>\n<position>", " 1</orientation>\n<position>", 1), "61 numbers, 60"),
])
def test_bad_mvnx_gets_one_line_naming_the_file(tmp_path, mangle, message):
    t, q = joint_path("npose")
    good = tmp_path / "good.mvnx"
    write_mvnx(good, t[:90], q[:90])
    bad = tmp_path / "bad.mvnx"
    bad.write_text(mangle(good.read_text()))
    with pytest.raises(InputError, match=message) as e:
        read_mvnx(bad)
    assert "bad.mvnx" in str(e.value) and "\n" not in str(e.value)


# --------------------------------------------------------------------------- end to end


def test_suit_recordings_run_end_to_end_to_constraints(tmp_path):
    """`mocap joints` on a BVH and a demonstration folder of BVH and MVNX recordings through
    `constraints extract` with --calib-pose tpose."""
    from dualarm.cli.main import main

    folder = tmp_path / "demos"
    folder.mkdir()
    t, q = joint_path("tpose", seconds=5.0)
    write_bvh(folder / "a.bvh", t, q)
    write_mvnx(folder / "b.mvnx", t, q)
    rows = ["demo,arm,subtask,start_s,end_s"]
    for demo in ("a", "b"):
        for arm in ARMS:
            rows += [f"{demo},{arm},reach,1.5,2.5", f"{demo},{arm},grasp,2.5,3.0", f"{demo},{arm},align,3.0,4.8"]
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    assert main(["mocap", "joints", str(folder / "a.bvh"), "--calib-pose", "tpose",
                 "-o", str(tmp_path / "a.csv")]) == 0
    table = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 1:], q, atol=1e-3)
    out = tmp_path / "multi.yaml"
    assert main(["constraints", "extract", str(folder), "--calib-pose", "tpose", "-o", str(out)]) == 0
    from dualarm.constraints.constraint_set import ConstraintSet

    multi = ConstraintSet.load(out)
    assert multi.provenance["options"]["calib_pose"] == "tpose"
    assert sorted(d["file"] for d in multi.provenance["demos"]) == ["a.bvh", "b.mvnx"]
