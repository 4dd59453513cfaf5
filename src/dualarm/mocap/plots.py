"""Figures of joint-angle trajectories, residuals and stick figures (paper Figs. 2 and 4).

Headless by design: every function builds a :class:`matplotlib.figure.Figure`
directly (no ``pyplot`` global state), so it works under the Agg backend, in tests
and in worker processes. Angles are radians in code and degrees on the axes; times
are seconds; lengths metres. Every figure is written as a PNG at ``DPI`` dots per
inch, atomically: to a temporary file in the target directory with the same suffix,
then a rename (:mod:`dualarm.atomic`), so a reader never sees a half-written file.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import matplotlib.ticker
from matplotlib.figure import Figure
import mpl_toolkits.mplot3d  # noqa: F401  (registers the '3d' projection)
import numpy as np

from dualarm.atomic import atomic_open
from dualarm.kinematics import (ARMS, BAXTER_JOINT_NAMES, DEFAULT_HUMAN_LENGTHS, JOINT_NAMES,
                                ArmModel, baxter_arm, human_arm)
from dualarm.mocap.joint_angles import RESIDUAL_COLUMNS

__all__ = ["DPI", "ARM_COLOURS", "save_figure", "stick_points", "plot_joint_angles",
           "plot_stick_figures", "plot_residuals"]

#: Resolution of every saved figure (dots per inch).
DPI = 120
#: Line colour of each arm.
ARM_COLOURS = {"left": "tab:blue", "right": "tab:red"}
_BODY_COLOUR = "0.45"


# --------------------------------------------------------------------------- saving

def save_figure(fig: Figure, path: str | os.PathLike) -> Path:
    """Write ``fig`` to ``path`` atomically (temp file in the same directory, then replace).

    The format follows the suffix of ``path`` (PNG for ``.png``); the parent
    directory is created if missing.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_open(path) as out:
        fig.savefig(out, dpi=DPI, format=fmt)
    return path


# --------------------------------------------------------------------------- checks

def _as_time(time, n: int) -> np.ndarray:
    t = np.asarray(time, dtype=float)
    if t.shape != (n,):
        raise ValueError(f"time must have shape ({n},), got {t.shape}")
    return t


def _as_columns(name: str, x, width: int) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{name} must have shape (T, {width}), got {a.shape}")
    return a


# --------------------------------------------------------------------------- joint angles

def _joint_ylim(curve_deg: np.ndarray, lo_deg: float | None, hi_deg: float | None) -> tuple[float, float]:
    """Data range, widened to show a limit when it is near the data (within one span)."""
    finite = curve_deg[np.isfinite(curve_deg)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (-1.0, 1.0)
    span = max(hi - lo, 10.0)
    for lim in (lo_deg, hi_deg):
        if lim is not None and lo - span <= lim <= hi + span:
            lo, hi = min(lo, lim), max(hi, lim)
    pad = 0.08 * max(hi - lo, 10.0)
    return lo - pad, hi + pad


def plot_joint_angles(time, q, path: str | os.PathLike, *, title: str | None = None,
                      limits=None, residual=None, limits_label: str = "Baxter range") -> Path:
    """Joint angles of both arms over time, one panel per joint.

    Two columns (left arm, right arm), seven rows q1..q7 (also labelled with
    Baxter's names s0, s1, e0, e1, w0, w1, w2), curves in degrees against time in s.

    Args:
        time: (T,) seconds.
        q: (T, 14) rad, left q1..q7 then right q1..q7.
        path: output PNG file.
        title: figure title.
        limits: (7, 2) [lower, upper] rad (e.g. ``BAXTER_JOINT_LIMITS``), the same
            for both arms; the allowed band is shaded lightly and its edges dashed.
            The y range is widened to show a limit only when it is near the data.
        limits_label: legend entry of the shaded band.
        residual: (T, 4) rad, columns ``RESIDUAL_COLUMNS`` (left elbow, left wrist,
            right elbow, right wrist); adds an eighth row with each arm's residuals.
    Returns:
        The written path.
    """
    q = _as_columns("q", q, 14)
    t = _as_time(time, len(q))
    lim = None if limits is None else np.asarray(limits, dtype=float)
    if lim is not None and lim.shape != (7, 2):
        raise ValueError(f"limits must have shape (7, 2), got {lim.shape}")
    res = None if residual is None else _as_columns("residual", residual, 4)
    if res is not None and len(res) != len(q):
        raise ValueError(f"residual has {len(res)} rows, q has {len(q)}")

    n_rows = 7 + (res is not None)
    fig = Figure(figsize=(11.0, 1.45 * n_rows + 0.9), layout="constrained")
    axes = fig.subplots(n_rows, 2, sharex=True, squeeze=False)
    q_deg = np.rad2deg(q)
    for c, arm in enumerate(ARMS):
        colour = ARM_COLOURS[arm]
        axes[0, c].set_title(f"{arm} arm", fontsize=11, color=colour, fontweight="bold")
        for j in range(7):
            ax = axes[j, c]
            curve = q_deg[:, 7 * c + j]
            lo_deg = hi_deg = None
            if lim is not None:
                lo_deg, hi_deg = np.rad2deg(lim[j])
                ax.axhspan(lo_deg, hi_deg, color="tab:green", alpha=0.10, lw=0,
                           label=limits_label if j == 0 else None)
                for v in (lo_deg, hi_deg):
                    ax.axhline(v, color="tab:green", lw=0.8, ls="--", alpha=0.7)
            ax.plot(t, curve, color=colour, lw=1.3)
            ax.set_ylim(*_joint_ylim(curve, lo_deg, hi_deg))
            ax.set_ylabel(f"{JOINT_NAMES[j]} ({BAXTER_JOINT_NAMES[j]})\n[deg]", fontsize=9)
            ax.grid(True, lw=0.4, alpha=0.5)
            ax.tick_params(labelsize=8)
        if lim is not None:
            axes[0, c].legend(loc="upper right", fontsize=7, frameon=False)
        if res is not None:
            ax = axes[7, c]
            r = np.rad2deg(res[:, 2 * c:2 * c + 2])
            ax.plot(t, r[:, 0], color=colour, lw=1.3, label="elbow")
            ax.plot(t, r[:, 1], color=colour, lw=1.1, ls="--", label="wrist")
            ax.set_ylabel("residual\n[deg]", fontsize=9)
            ax.set_ylim(bottom=0.0, top=max(1.0, 1.1 * float(np.nanmax(r, initial=0.0))))
            ax.legend(loc="upper right", fontsize=7, ncol=2, frameon=False)
            ax.grid(True, lw=0.4, alpha=0.5)
            ax.tick_params(labelsize=8)
        axes[-1, c].set_xlabel("time [s]")
        if len(t) > 1:
            axes[-1, c].set_xlim(t[0], t[-1])
    if title:
        fig.suptitle(title, fontsize=12)
    return save_figure(fig, path)


# --------------------------------------------------------------------------- stick figures

def stick_points(model: ArmModel, q) -> np.ndarray:
    """The stick figure of one arm: origins of D-H frames 0 (base) .. 7 (hand) in the world.

    Args:
        model: the arm, e.g. ``human_arm('left')`` or ``baxter_arm('right')``.
        q: (7,) joint angles, rad (or (..., 7) for a batch).
    Returns:
        (8, 3) positions in m (or (..., 8, 3)); row 0 is the base (shoulder or
        arm mount), row 7 the end point (palm centre or gripper mount).
    """
    return model.joint_positions(np.asarray(q, dtype=float))


def _human_body(arms: dict[str, ArmModel]) -> tuple[list[np.ndarray], np.ndarray]:
    """Torso polylines (m) and the head centre of the human model."""
    sl, sr = arms["left"].base[:3, 3], arms["right"].base[:3, 3]
    mid = (sl + sr) / 2
    hip_drop = np.array([0.0, 0.0, -0.50])
    hl = mid + hip_drop + 0.65 * (sl - mid)
    hr = mid + hip_drop + 0.65 * (sr - mid)
    head = mid + np.array([0.0, 0.0, 0.22])
    lines = [np.array([sl, sr]), np.array([mid, (hl + hr) / 2]), np.array([hl, hr]),
             np.array([mid, head - np.array([0.0, 0.0, 0.08])])]
    return lines, head


def _baxter_body(arms: dict[str, ArmModel]) -> tuple[list[np.ndarray], np.ndarray]:
    """Torso outline (m) and the head (display) centre of the Baxter model."""
    ml, mr = arms["left"].base[:3, 3], arms["right"].base[:3, 3]
    mid = (ml + mr) / 2
    x, w, top, bottom = 0.0, 0.16, mid[2], mid[2] - 0.55
    box = np.array([[x, w, top], [x, w, bottom], [x, -w, bottom], [x, -w, top], [x, w, top]])
    head = np.array([0.06, 0.0, 0.93 + 0.686])  # URDF head pan joint above the torso origin
    lines = [np.array([ml, mr]), box, np.array([mid, head - np.array([0.0, 0.0, 0.06])])]
    return lines, head


def _scene(arms: dict[str, ArmModel], body, qi: np.ndarray):
    """Arm polylines per side and body lines for one instant."""
    pts = {arm: stick_points(arms[arm], qi[7 * c:7 * c + 7]) for c, arm in enumerate(ARMS)}
    lines, head = body(arms)
    return pts, lines, head


def _bounds(scenes) -> tuple[np.ndarray, np.ndarray]:
    allp = []
    for pts, lines, head in scenes:
        allp.extend(pts.values())
        allp.extend(lines)
        allp.append(head[None])
    allp = np.concatenate(allp)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    centre, half = (lo + hi) / 2, np.maximum((hi - lo) / 2, 0.15) + 0.06
    return centre - half, centre + half


def _draw(ax, scene, lo, hi, title: str, view: tuple[float, float]) -> None:
    pts, lines, head = scene
    for ln in lines:
        ax.plot(*ln.T, color=_BODY_COLOUR, lw=2.0)
    ax.scatter(*head, s=160, color=_BODY_COLOUR, depthshade=False)
    for arm, p in pts.items():
        colour = ARM_COLOURS[arm]
        ax.plot(*p.T, color=colour, lw=2.6, label=f"{arm} arm")
        ax.scatter(*p[:-1].T, s=18, color=colour, depthshade=False)
        ax.scatter(*p[-1], s=70, marker="*", color="k", edgecolor=colour, depthshade=False, zorder=5)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(hi - lo))
    ax.view_init(elev=view[0], azim=view[1])
    ax.set_xlabel("x [m]", fontsize=8, labelpad=-2)
    ax.set_ylabel("y [m]", fontsize=8, labelpad=-2)
    ax.set_zlabel("z [m]", fontsize=8, labelpad=-2)
    ax.tick_params(labelsize=7, pad=0)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(matplotlib.ticker.MultipleLocator(0.25))
    ax.set_title(title, fontsize=10)


def plot_stick_figures(q_human, q_robot, instants: Sequence[int], path: str | os.PathLike, *,
                       time=None, lengths: tuple[float, float, float] | None = None,
                       view: tuple[float, float] = (28.0, 35.0)) -> Path:
    """Human and Baxter postures side by side at chosen instants (the paper's Figs. 2 and 4).

    One row per instant, two 3-D panels: left the human model (both arms of
    ``human_arm(side, lengths)``, shoulders, torso, hips, head), right the Baxter
    model (both arms of ``baxter_arm(side)`` from their mounts, torso outline and
    head). Arms are drawn from :func:`stick_points` (frames 0..7): joints as dots,
    the hand as a star; left arm blue, right arm red. Each model keeps the same
    axis box in every row, with equal scale on x, y and z (the person faces +x,
    z is up, y to the left).

    Args:
        q_human: (T, 14) human joint angles, rad.
        q_robot: (T, 14) Baxter joint angles, rad (e.g. ``to_baxter(q_human).q``).
        instants: sample indices into the rows of both arrays.
        path: output PNG file.
        time: (T,) seconds, for the panel titles (sample indices if None).
        lengths: human (l1, l2, l3) in m; ``DEFAULT_HUMAN_LENGTHS`` if None.
        view: (elevation, azimuth) of the camera, degrees.
    Returns:
        The written path.
    """
    qh = _as_columns("q_human", q_human, 14)
    qr = _as_columns("q_robot", q_robot, 14)
    if len(qh) != len(qr):
        raise ValueError(f"q_human has {len(qh)} rows, q_robot has {len(qr)}")
    idx = [int(i) for i in instants]
    if not idx:
        raise ValueError("need at least one instant")
    for i in idx:
        if not -len(qh) <= i < len(qh):
            raise ValueError(f"instant {i} outside 0..{len(qh) - 1}")
    t = None if time is None else _as_time(time, len(qh))
    lengths = DEFAULT_HUMAN_LENGTHS if lengths is None else tuple(lengths)
    humans = {arm: human_arm(arm, lengths) for arm in ARMS}
    robots = {arm: baxter_arm(arm) for arm in ARMS}

    h_scenes = [_scene(humans, _human_body, qh[i]) for i in idx]
    r_scenes = [_scene(robots, _baxter_body, qr[i]) for i in idx]
    h_lo, h_hi = _bounds(h_scenes)
    r_lo, r_hi = _bounds(r_scenes)

    n = len(idx)
    fig = Figure(figsize=(11.0, 4.8 * n), layout="constrained")
    fig.get_layout_engine().set(h_pad=0.12, w_pad=0.05, hspace=0.04, wspace=0.0)
    grid = fig.add_gridspec(n, 2, width_ratios=(0.8, 1.2))
    for row, i in enumerate(idx):
        when = f"t = {t[i]:.2f} s" if t is not None else f"sample {i % len(qh)}"
        ax_h = fig.add_subplot(grid[row, 0], projection="3d")
        ax_r = fig.add_subplot(grid[row, 1], projection="3d")
        _draw(ax_h, h_scenes[row], h_lo, h_hi, f"human, {when}", view)
        _draw(ax_r, r_scenes[row], r_lo, r_hi, f"Baxter, {when}", view)
        if row == 0:
            ax_h.legend(loc="upper left", fontsize=8, frameon=False)
    return save_figure(fig, path)


# --------------------------------------------------------------------------- residuals

def _heading_text(estimates) -> str:
    lines = ["hinge fits (deg): child sensor heading offset; flexion-axis angle phi",
             "(elbow: the arm's facing; wrist: the forearm twist); RMS hinge violation",
             "sensor           heading     phi   rms before→after"]
    for e in estimates:
        mark = "" if e.detected else "  (not detected)"
        lines.append(f"{e.sensor:<15} {np.rad2deg(e.offset_rad):+8.1f} {np.rad2deg(getattr(e, 'axis_rad', 0.0)):+7.1f}"
                     f"   {np.rad2deg(e.rms_before_rad):5.1f} → {np.rad2deg(e.rms_after_rad):5.1f}{mark}")
    return "\n".join(lines)


def plot_residuals(time, residual, path: str | os.PathLike, *, heading_estimates=None) -> Path:
    """Residual angles of the elbow and wrist joints of both arms over time.

    Args:
        time: (T,) seconds.
        residual: (T, 4) rad, columns ``RESIDUAL_COLUMNS`` (left elbow, left wrist,
            right elbow, right wrist), plotted in degrees.
        path: output PNG file.
        heading_estimates: optional sequence of objects with fields ``sensor``,
            ``offset_rad``, ``rms_before_rad``, ``rms_after_rad``, ``detected``
            (:class:`dualarm.mocap.heading.HeadingEstimate`), listed in a text box.
    Returns:
        The written path.
    """
    res = _as_columns("residual", residual, 4)
    t = _as_time(time, len(res))
    estimates = list(heading_estimates) if heading_estimates is not None else []
    text_h = 0.16 * (len(estimates) + 2) + 0.25 if estimates else 0.0
    fig = Figure(figsize=(10.0, 4.2 + text_h), layout="constrained")
    if estimates:
        ax, ax_text = fig.subplots(2, 1, height_ratios=(4.0, text_h))
    else:
        ax, ax_text = fig.subplots(1, 1), None
    r = np.rad2deg(res)
    for k, name in enumerate(RESIDUAL_COLUMNS):
        arm, joint = name.split("_")
        ax.plot(t, r[:, k], color=ARM_COLOURS[arm], ls="-" if joint == "elbow" else "--",
                lw=1.3, label=f"{arm} {joint}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("residual [deg]")
    ax.set_title("elbow and wrist residuals (rotation the 2-DOF joints cannot explain)", fontsize=11)
    ax.set_ylim(bottom=0.0, top=max(1.0, 1.1 * float(np.nanmax(r, initial=0.0))))
    if len(t) > 1:
        ax.set_xlim(t[0], t[-1])
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(loc="upper right", fontsize=8, ncol=4, frameon=False)
    if ax_text is not None:
        ax_text.axis("off")
        ax_text.text(0.0, 1.0, _heading_text(estimates), family="monospace", fontsize=8.5,
                     va="top", ha="left", transform=ax_text.transAxes,
                     bbox=dict(boxstyle="round", facecolor="0.96", edgecolor="0.7"))
    return save_figure(fig, path)
