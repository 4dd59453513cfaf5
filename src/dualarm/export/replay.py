"""Replay a time-parameterised trajectory in the simulator: do the boxes still reach their
targets when the arms follow the smoothed motion with their position servos?"""

from __future__ import annotations

import numpy as np

from dualarm.envs.baxter import BaxterReachGraspAlign
from dualarm.envs.config import TaskConfig
from dualarm.export.retime import Retimed


def replay(retimed: Retimed, task: TaskConfig, seed: int, settle_s: float = 0.5,
           camera: str | None = None, frame_every_s: float = 0.25) -> tuple[bool, list[np.ndarray]]:
    """Follow ``retimed`` from the episode reset by ``seed`` (boxes and targets placed as the
    recorded episode had them), the joint position servos and fingers commanded at every
    physics step, then hold the last point for ``settle_s``.

    Returns:
        (success: both boxes held at their targets at the end, frames rendered every
        ``frame_every_s`` of simulated time from ``camera`` if given).
    """
    env = BaxterReachGraspAlign(task.with_(control="joint", condition="none",
                                           terminate_on_success=False))
    try:
        env.reset(seed=seed)
        dt = env.model.opt.timestep
        times = np.arange(0.0, retimed.duration + settle_s + dt / 2, dt)
        samples = retimed.at(times)
        frames, next_frame = [], 0.0
        for k, t in enumerate(times):
            env.servo_to(0, samples.joints[k].reshape(2, 7), samples.grip[k], dt)
            if camera and t >= next_frame - 1e-9:
                frames.append(env.render(camera))
                next_frame += frame_every_s
        return env.task_state(0)["success"], frames
    finally:
        env.close()
