"""Human recordings replayed in the simulator as the learner's own episodes (robot
demonstrations).

A recording, mapped to Baxter's joints with the calibration and mapping the constraints use
(``dualarm.demos.loading``), is a path of each hand through the person's task. Replayed at its
own scene (``dualarm.demos.scene``), it becomes an episode of the learner's task, in the
learner's action space, with the rewards the environment computes:

1. **Retime.** The task window of the recording (the earliest reach start to the latest align
   end of its labels, about 3-4 s of a person's motion) is sampled at ``steps`` + 1 evenly
   spaced instants: the person's pace scaled to the robot's (an episode is 50 steps of 20 ms).
2. **Hand path.** At each instant, both grip sites by the simulator's forward kinematics of the
   recorded joint angles (``BaxterBatch.grip_sites``), and each hand's gripper event (closed or
   open) from the recording's grip columns.
3. **Follow.** In cartesian control, each step commands each grip site towards the path's next
   point, ``gain`` x the offset in units of the largest step (the scripted expert's rule), and
   the grip closed or open as recorded; after the path, the last point is held to the end of
   the episode.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dualarm.demos.labels import DemoLabels
from dualarm.demos.loading import DemoJoints, MappingOptions, load_demo_dir
from dualarm.demos.scene import Scene, Workspace, demo_scenes
from dualarm.task import SUBTASKS

#: Steps of the retimed task window: the expert needs about 25, a learner's episode is 50;
#: 40 leaves a still hand 5-9 steps to close on its box (the human's grasp phase is a sixth
#: to a fifth of the task).
DEFAULT_STEPS = 40


@dataclass
class Replay:
    """One recording replayed at its scene.

    Attributes:
        name: the demonstration's name.
        success: both boxes at their targets within the episode.
        steps: environment steps taken (to success, or the episode's end).
        retimed_steps: steps the recording's task window was retimed to.
        final_subtasks: (2,) each arm's sub-task at the end (0 reach, 1 grasp, 2 align).
        tracking_error: (2,) m, the largest distance of each grip site from the path's point
            it was sent to, one step after it was sent there.
        obs, act, rew, next_obs, done: the episode as the learner stores it: (S, 2, O),
            (S, 2, 4), (S, 2), (S, 2, O), (S,).
        terms: the environment's reward terms by name, each (S, 2).
        states: the episode's scene and states for ``dualarm.envs.starts.RecordedStates``:
            ``boxes``, ``targets`` (2, 3) m, and after the reset and each step ``qpos``
            (S + 1, 2, 16), ``fingers`` (S + 1, 2, 2), ``subtask`` (S + 1, 2).
    """

    name: str
    success: bool
    steps: int
    retimed_steps: int
    final_subtasks: np.ndarray
    tracking_error: np.ndarray
    obs: np.ndarray = field(repr=False)
    act: np.ndarray = field(repr=False)
    rew: np.ndarray = field(repr=False)
    next_obs: np.ndarray = field(repr=False)
    done: np.ndarray = field(repr=False)
    terms: dict = field(default_factory=dict, repr=False)
    states: dict | None = field(default=None, repr=False)

    @property
    def joints(self) -> np.ndarray:
        """(S + 1, 14) rad, Baxter's joint angles after the reset and after each step, left
        s0..w2 then right (the first 7 of each arm's ``states["qpos"]``)."""
        return self.states["qpos"][:, :, :7].reshape(-1, 14)

    @property
    def why(self) -> str:
        """Where an unsuccessful replay stopped, arm by arm ("" after a success)."""
        if self.success:
            return ""
        names = ("left", "right")
        return ", ".join(f"{names[a]} arm ended in {SUBTASKS[s]}"
                         for a, s in enumerate(self.final_subtasks))


def load_replay_folder(demo_dir, workspace: Workspace, labels_path=None,
                       options: MappingOptions = MappingOptions()
                       ) -> tuple[list[DemoJoints], dict[str, DemoLabels], dict[str, Scene]]:
    """What replaying a demonstration folder needs: its recordings as Baxter joint angles with
    their gripper events, their labels and their scenes (``workspace``: where a scene may
    place things, ``TaskConfig.workspace()``).

    Raises:
        InputError: the folder, its labels or its scene are missing or bad (naming the file).
    """
    demos, labels = load_demo_dir(demo_dir, labels_path, options, with_grip=True)
    scenes = demo_scenes(demo_dir, [d.name for d in demos], workspace)
    return demos, labels, scenes


def task_window(labels: DemoLabels) -> tuple[float, float]:
    """(start, end) s of a demonstration's task: the earliest reach start, the latest align end."""
    w = labels.windows
    return float(w[:, 0, 0].min()), float(w[:, 2, 1].max())


def retime(time: np.ndarray, values: np.ndarray, start: float, end: float, steps: int) -> np.ndarray:
    """``values`` (T, ...) sampled at ``time`` (T,) s, linearly interpolated at ``steps`` + 1
    evenly spaced instants from ``start`` to ``end`` s: (steps + 1, ...)."""
    at = np.linspace(start, end, steps + 1)
    flat = np.asarray(values, dtype=float).reshape(len(time), -1)
    out = np.stack([np.interp(at, time, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    return out.reshape((steps + 1,) + np.shape(values)[1:])


def demonstration_path(env, demo: DemoJoints, labels: DemoLabels,
                       steps: int = DEFAULT_STEPS) -> tuple[np.ndarray, np.ndarray]:
    """A recording's hands as the robot would follow them: its task window retimed to
    ``steps`` steps, then both grip sites by ``env``'s forward kinematics of the recorded joints.

    Returns:
        path: (steps + 1, 2, 3) m, each arm's grip site at each retimed instant (world frame).
        closed: (steps + 1, 2) bool, each hand's gripper closed at that instant.
    """
    if demo.grip is None:
        raise ValueError(f"{demo.source}: replay needs the recording's gripper events "
                         "(left_grip, right_grip columns)")
    limit = env.config.max_episode_steps
    if not 1 <= steps <= limit:
        raise ValueError(f"steps must be in 1..{limit}, got {steps}")
    start, end = task_window(labels)
    q = retime(demo.time, demo.q, start, end, steps)                     # (K + 1, 14)
    closed = retime(demo.time, demo.grip, start, end, steps) > 0.5       # (K + 1, 2)
    return env.grip_sites(q), closed


def replay_demonstration(env, demo: DemoJoints, labels: DemoLabels, scene: Scene,
                         steps: int = DEFAULT_STEPS, gain: float = 1.5) -> Replay:
    """Replay one recording at its scene in ``env`` (a ``BaxterReachGraspAlign`` in cartesian
    control; its condition sets the guide term of the rewards).

    Args:
        demo: the recording as Baxter joint angles, with its grip events (``with_grip``).
        labels: its sub-task times (the task window).
        scene: where its boxes and targets were.
        steps: steps the task window is retimed to (at most the episode's length).
        gain: action per metre of offset, in units of the largest step.
    """
    if env.config.control != "cartesian":
        raise ValueError("replay follows the hand path in cartesian control")
    path, closed = demonstration_path(env, demo, labels, steps)
    return follow_path(env, demo.name, path, closed, scene, gain)


def follow_path(env, name: str, path: np.ndarray, closed: np.ndarray, scene: Scene,
                gain: float = 1.5) -> Replay:
    """One episode of ``env`` (cartesian control) at ``scene`` that sends both grip sites along
    ``path`` (K + 1, 2, 3) m, one point per step, with the grippers ``closed`` (K + 1, 2) as
    given, then holds the last point to the episode's end. The episode is ``name``'s."""
    steps = len(path) - 1
    error = np.zeros(2)

    def act(k: int, obs: np.ndarray) -> np.ndarray:
        point = path[min(k + 1, steps)]
        move = gain * (point - env.grip_pos[0]) / env.config.max_cartesian_step
        command = np.where(closed[min(k + 1, steps)], 1.0, -1.0)
        return np.clip(np.concatenate([move, command[:, None]], axis=1), -1.0, 1.0)

    def after(k: int) -> None:
        if k < steps:
            point = path[min(k + 1, steps)]
            np.maximum(error, np.linalg.norm(env.grip_pos[0] - point, axis=-1), out=error)

    return _episode(env, name, scene, steps, act, error, after)


def _episode(env, name: str, scene: Scene, retimed_steps: int, act, error: np.ndarray,
             after=None) -> Replay:
    """One episode of ``env`` at ``scene`` with the actions ``act(k, obs)`` (2, 4) of step k,
    recorded as the learner stores it; ``after(k)`` runs after each step, and ``error`` (2,)
    is the follower's largest tracking error by the end."""
    limit = env.config.max_episode_steps
    obs, info = env.reset(placement=scene)
    rows = {k: [] for k in ("obs", "act", "rew", "next_obs", "done")}
    terms: dict[str, list] = {}
    states = {"boxes": env.box_start.copy(), "targets": env.targets.copy(),
              "qpos": [], "fingers": [], "subtask": []}

    def keep_state(info):
        qpos, fingers = env.arm_states()
        states["qpos"].append(qpos)
        states["fingers"].append(fingers)
        states["subtask"].append(np.asarray(info["subtask"], dtype=np.int64).copy())

    keep_state(info)
    for k in range(limit):
        action = act(k, obs)
        result = env.step(action)
        keep_state(result.info)
        if after is not None:
            after(k)
        done = bool(result.terminated)
        for key, value in (("obs", obs), ("act", action), ("rew", result.reward),
                           ("next_obs", result.obs), ("done", float(done))):
            rows[key].append(np.asarray(value, dtype=float))
        for term, value in result.info["reward_terms"].items():
            terms.setdefault(term, []).append(np.asarray(value, dtype=float))
        obs = result.obs
        if done or result.truncated:
            break
    return Replay(name, bool(result.info["is_success"]), len(rows["done"]), retimed_steps,
                  np.asarray(result.info["subtask"]).copy(), error,
                  *(np.stack(rows[k]) for k in ("obs", "act", "rew", "next_obs", "done")),
                  {term: np.stack(v) for term, v in terms.items()},
                  {k: np.stack(v) if isinstance(v, list) else v for k, v in states.items()})


#: Joint-control replays command the target plus this much of the joints' lag behind it:
#: the position servos trail a moving target by up to 0.2 rad, enough to miss the grasp
#: (0 of the 10 shipped recordings succeed without it, 8 with it; 2 and 3 do worse, 5 and 4).
SERVO_LAG_GAIN = 1.0


def in_joint_control(env, replay: Replay, scene: Scene, lag_gain: float = SERVO_LAG_GAIN) -> Replay:
    """``replay`` (made in cartesian control) done again in ``env`` (joint control) at the same
    ``scene``: each step moves the joint servos' targets to the joint angles the cartesian
    replay reached after that step, plus ``lag_gain`` times the joints' lag behind them (7 joint
    deltas per arm, in units of ``max_joint_step``), with the same gripper commands, and holds
    the last angles after the replay's end. The result is a demonstration in the joint-control
    learner's own action space."""
    if env.config.control != "joint":
        raise ValueError("in_joint_control replays into a joint-control task")
    targets = replay.joints.reshape(-1, 2, 7)
    last = len(replay.act) - 1

    def act(k: int, obs: np.ndarray) -> np.ndarray:
        target = targets[min(k + 1, last + 1)]
        command = target + lag_gain * (target - env.joint_angles().reshape(2, 7))
        delta = (command - env.joint_command[0]) / env.config.max_joint_step
        grip = replay.act[min(k, last), :, 3:4]
        return np.clip(np.concatenate([delta, grip], axis=1), -1.0, 1.0)

    return _episode(env, replay.name, scene, replay.retimed_steps, act, replay.tracking_error)
