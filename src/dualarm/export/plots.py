"""The check a person makes before sending a trajectory to hardware: per joint, position,
velocity and acceleration against their limits (degrees on the axes, radians in code)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from dualarm.export.retime import Retimed
from dualarm.export.trajectory import POSITION_LIMITS
from dualarm.kinematics import BAXTER_JOINT_NAMES
from dualarm.mocap.plots import save_figure
from dualarm.task import ARMS, JOINTS_PER_ARM

_ARM_COLOURS = {"left": "tab:blue", "right": "tab:orange"}


def plot_retimed(retimed: Retimed, path: str | Path, rate_hz: float = 200.0) -> Path:
    """A 3 x 7 grid (position, velocity, acceleration x s0..w2), both arms in each panel,
    limits dashed, the waypoints as dots on the positions; written atomically as PNG."""
    s = retimed.sample(rate_hz)
    lim = retimed.limits
    rows = (("position [deg]", s.joints, None), ("velocity [deg/s]", s.velocity, lim.velocity),
            ("acceleration [deg/s²]", s.acceleration, lim.acceleration))
    fig = Figure(figsize=(20, 8.5), layout="constrained")
    axes = fig.subplots(3, 7, sharex=True)
    for r, (label, values, limit) in enumerate(rows):
        for j, joint in enumerate(BAXTER_JOINT_NAMES):
            ax = axes[r, j]
            for a, arm in enumerate(ARMS):
                col = JOINTS_PER_ARM * a + j
                ax.plot(s.time, np.degrees(values[:, col]), color=_ARM_COLOURS[arm], lw=1.2,
                        label=arm if (r, j) == (0, 0) else None)
                if r == 0:
                    ax.plot(retimed.waypoint_time, np.degrees(retimed.source.joints[:, col]), ".",
                            color=_ARM_COLOURS[arm], ms=3)
            low, high = POSITION_LIMITS[j] if limit is None else (-limit[j], limit[j])
            for y in (low, high):
                ax.axhline(np.degrees(y), color="k", ls="--", lw=0.8)
            if r == 0:
                ax.set_title(joint)
            if j == 0:
                ax.set_ylabel(label)
            if r == 2:
                ax.set_xlabel("time [s]")
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="best")
    fig.suptitle(f"time-parameterised trajectory: {retimed.duration:.2f} s (waypoints: "
                 f"{retimed.source.duration:.2f} s); dashed: Baxter's limits")
    return save_figure(fig, path)
