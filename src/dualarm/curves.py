"""Learning-curve statistics of the comparison report: trailing moving averages, episodes to a
success target, convergence of a curve, Student-t confidence intervals and ratios.

Pure functions over NumPy arrays. A training curve is a 1-D array with one value per training
episode, in episode order: element ``i`` is episode ``i + 1`` (episodes are 1-based, as in a
run's ``metrics.csv``). Every episode number these functions return is 1-based.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from dualarm.task import TARGET_SUCCESS

#: The ratios between conditions that the paper quotes (numerator, denominator).
RATIO_PAIRS: tuple[tuple[str, str], ...] = (("multi", "none"), ("single", "none"), ("multi", "single"),
                                           ("demos", "none"), ("demos", "multi"))


def _curve(x, name: str = "x") -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array (one value per episode), got shape {x.shape}")
    return x


def _check_window(window: int) -> int:
    if int(window) != window or window < 1:
        raise ValueError(f"window must be a whole number of episodes >= 1, got {window!r}")
    return int(window)


def trailing_mean(x, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Trailing moving average of a per-episode curve, and where its window is full.

    ``ma[i]`` is the mean of ``x[max(0, i - window + 1) : i + 1]``: the last ``window``
    episodes up to and including episode ``i + 1``, fewer at the start of the run (the
    training plots' ``moving_average`` is this one).

    Args:
        x: (n,) one value per episode, in episode order (any unit).
        window: episodes averaged, >= 1.

    Returns:
        ma: (n,) float, the moving average, same unit as x.
        full: (n,) bool, True where the average spans a full ``window`` episodes, i.e. from
            episode ``window`` on (all False when n < window).
    """
    x = _curve(x)
    window = _check_window(window)
    n = len(x)
    c = np.concatenate([[0.0], np.cumsum(x)])
    end = np.arange(1, n + 1)
    start = np.maximum(end - window, 0)
    ma = (c[end] - c[start]) / (end - start)
    return ma, end >= window


def episodes_to_target(success, target: float = TARGET_SUCCESS, window: int = 100) -> int | None:
    """First episode at which the success rate over the last ``window`` episodes is >= target.

    Only full windows count: the earliest possible answer is episode ``window`` (a lucky first
    success does not make a success rate of 1).

    Args:
        success: (n,) per-episode success, 0 or 1 (or any rate in [0, 1]).
        target: success rate to reach, in (0, 1].
        window: episodes in the trailing window, >= 1.

    Returns:
        The 1-based episode, or None if the full-window success rate never reaches ``target``
        (including runs shorter than ``window``).
    """
    ma, full = trailing_mean(success, window)
    hit = np.flatnonzero(full & (ma >= target))
    return int(hit[0]) + 1 if hit.size else None


def max_average(x, window: int = 100) -> float:
    """Largest full-window trailing mean of ``x`` (n,); NaN if the run is shorter than window."""
    ma, full = trailing_mean(x, window)
    return float(ma[full].max()) if full.any() else math.nan


@dataclass(frozen=True)
class Convergence:
    """Where a training curve converges (see ``convergence``).

    Attributes:
        episode: 1-based first episode from which the moving average stays inside the band
            around its final level until the end of the run; None if not converged.
        level: the final level, mean of the moving average over the tail (unit of the curve).
        tolerance: half-width of the band around ``level`` (unit of the curve).
        drift: change of the least-squares line through the moving average across the tail
            (unit of the curve; NaN if the run is too short).
        reason: why the curve is not converged ("" when it is).
    """

    episode: int | None
    level: float
    tolerance: float
    drift: float
    reason: str = ""

    @property
    def converged(self) -> bool:
        return self.episode is not None


def convergence(x, window: int = 100, tail_fraction: float = 0.1, rel_tol: float = 0.05,
                noise_k: float = 3.0) -> Convergence:
    """Episode at which a per-episode training curve (e.g. the return) has converged.

    Definition. Let ``m`` be the trailing ``window``-episode moving average of ``x``, taken
    where its window is full (episodes ``window .. n``), and let the tail be the last
    ``T = max(2, ceil(tail_fraction * n))`` episodes of the run.

    * Final level ``L``: the mean of ``m`` over the tail.
    * Band: ``L +- tol`` with ``tol = max(rel_tol * (max m - min m),
      noise_k * std(x over the tail) / sqrt(window))``: a fraction of how far the curve moved
      during the run, widened, when the episodes are noisy, to ``noise_k`` standard errors of
      a ``window``-episode mean, so that the noise of a flat curve does not count as movement
      (and never below 1e-9 of the curve's magnitude, the rounding error of the sums).
    * The curve is converged when (a) ``m`` stays inside the band over the whole tail and
      (b) it no longer drifts: the least-squares line through ``m`` over the tail changes by at
      most ``tol`` across the tail.
    * The convergence episode is then the first episode from which ``m`` stays inside the
      band until the end of the run (at least ``window``; at most the first episode of the
      tail, by (a)).

    A curve still rising (or falling) at the end fails (b) or (a); a run too short to hold a
    tail of full windows (``n - window + 1 < T``) is not converged either.

    Args:
        x: (n,) one value per training episode, in episode order.
        window: moving-average window, episodes, >= 1.
        tail_fraction: fraction of the run that defines the final level, in (0, 1).
        rel_tol: band half-width as a fraction of the range of the moving average, >= 0.
        noise_k: band half-width floor in standard errors of a window mean, >= 0.

    Returns:
        A ``Convergence``; its ``episode`` is None when the curve has not converged.
    """
    x = _curve(x)
    window = _check_window(window)
    if not 0 < tail_fraction < 1:
        raise ValueError(f"tail_fraction must be in (0, 1), got {tail_fraction}")
    if rel_tol < 0 or noise_k < 0:
        raise ValueError(f"rel_tol and noise_k must be >= 0, got {rel_tol}, {noise_k}")
    n = len(x)
    tail = max(2, math.ceil(tail_fraction * n))
    if n - window + 1 < tail:
        return Convergence(None, math.nan, math.nan, math.nan,
                           f"run too short: {n} episodes hold no tail of {tail} full "
                           f"{window}-episode windows")
    ma, _ = trailing_mean(x, window)
    m = ma[window - 1:]
    m_tail = m[-tail:]
    level = float(m_tail.mean())
    noise = float(np.std(x[-tail:], ddof=1)) / math.sqrt(window)
    rounding = 1e-9 * max(float(np.abs(m).max()), 1.0)        # float error of the sums
    tol = max(rel_tol * float(m.max() - m.min()), noise_k * noise, rounding)
    slope = np.polyfit(np.arange(tail, dtype=float), m_tail, 1)[0]
    drift = float(slope * (tail - 1))
    outside = np.abs(m - level) > tol
    if outside[-tail:].any():
        return Convergence(None, level, tol, drift,
                           f"the moving average leaves the band {level:.4g} +- {tol:.3g} in the "
                           f"last {tail} episodes")
    if abs(drift) > tol:
        return Convergence(None, level, tol, drift,
                           f"still drifting: {drift:+.3g} over the last {tail} episodes "
                           f"(band +- {tol:.3g})")
    out = np.flatnonzero(outside)
    first = int(out[-1]) + 1 if out.size else 0          # index in m of the first in-band point
    return Convergence(window + first, level, tol, drift)


def mean_ci(values, confidence: float = 0.95, axis: int | None = None):
    """Mean and half-width of the Student-t confidence interval of the mean.

    ``half = t_{(1 + confidence) / 2, n - 1} * s / sqrt(n)`` with ``s`` the sample standard
    deviation (ddof = 1) of the n values (e.g. one per seed). The interval is
    ``mean +- half``. With one value the half-width is NaN (no interval from one seed); with
    none, the mean is NaN too. NaN values are not skipped: filter them first.

    Args:
        values: array of values (any unit); reduced over ``axis`` (all of it when None).
        confidence: coverage of the interval, in (0, 1).
        axis: the axis holding the samples (e.g. 0 for a (seeds, episodes) array).

    Returns:
        (mean, half): floats when ``axis`` is None, else arrays with ``axis`` removed; same
        unit as ``values``.
    """
    from scipy import stats

    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    v = np.asarray(values, dtype=float)
    n = v.size if axis is None else v.shape[axis]
    shape = () if axis is None else tuple(np.delete(np.array(v.shape), axis))
    if n == 0:
        mean = np.full(shape, math.nan)
    else:
        mean = v.mean(axis=axis)
    if n < 2:
        half = np.full(shape, math.nan)
    else:
        half = stats.t.ppf(0.5 + confidence / 2, n - 1) * v.std(axis=axis, ddof=1) / math.sqrt(n)
    if axis is None:
        return float(mean), float(half)
    return np.asarray(mean), np.asarray(half)


def ratio(numerator: float | None, denominator: float | None) -> float | None:
    """``numerator / denominator``, or None when either is missing or not finite, or the
    denominator is 0 (a ratio is never made up)."""
    if numerator is None or denominator is None:
        return None
    if not (math.isfinite(numerator) and math.isfinite(denominator)) or denominator == 0:
        return None
    return numerator / denominator


def median_ratio_ci(numerator, denominator, confidence: float = 0.95, draws: int = 10000,
                    seed: int = 0) -> tuple[float, float, float] | None:
    """Ratio of the medians of two conditions' per-seed values, with a seed-bootstrap interval.

    A seed that never reached the criterion (NaN) counts as beyond the run (+inf), so a
    condition that fails in some seeds is not flattered by leaving them out: its median is
    infinite when half or more of its seeds failed. The interval resamples the seeds of
    each condition with replacement (``draws`` times, a fixed ``seed``: the same numbers on
    every run of the report) and takes the percentiles of the ratio of the medians.

    Args:
        numerator, denominator: (seeds,) values (episodes, s), NaN where not reached.
        confidence: coverage of the interval, in (0, 1).

    Returns:
        (ratio, low, high), each possibly inf (numerator median beyond the run) or 0
        (denominator beyond it); None when a condition has no seeds or both medians are
        beyond the run.
    """
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    a = np.asarray(numerator, dtype=float)
    b = np.asarray(denominator, dtype=float)
    if a.size == 0 or b.size == 0:
        return None
    a, b = (np.where(np.isnan(x), np.inf, x) for x in (a, b))

    def quotient(ma, mb):
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(np.isinf(ma) & np.isinf(mb), np.nan, ma / mb)

    point = float(quotient(np.median(a), np.median(b)))
    if math.isnan(point):
        return None
    rng = np.random.default_rng(seed)
    ma = np.median(a[rng.integers(0, a.size, (draws, a.size))], axis=1)
    mb = np.median(b[rng.integers(0, b.size, (draws, b.size))], axis=1)
    q = quotient(ma, mb)
    q = q[~np.isnan(q)]             # draws where both medians are beyond the run say nothing
    tail = (1 - confidence) / 2 * 100
    low, high = np.percentile(q, [tail, 100 - tail], method="lower") if q.size else (math.nan,) * 2
    return point, float(low), float(high)


def condition_ratios(means: Mapping[str, float | None],
                     pairs: Iterable[tuple[str, str]] = RATIO_PAIRS) -> dict[tuple[str, str], float | None]:
    """Ratios between per-condition means, e.g. episodes to convergence multi / none.

    Args:
        means: condition -> mean over seeds (None or NaN where no seed reached the criterion;
            a condition may be absent).
        pairs: (numerator, denominator) conditions.

    Returns:
        (numerator, denominator) -> ratio, None where either mean is missing.
    """
    return {(a, b): ratio(means.get(a), means.get(b)) for a, b in pairs}
