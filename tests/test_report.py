"""`dualarm report`: curve statistics on curves with known answers, and the report end to end."""

import csv
import math

import numpy as np
import pytest
from scipy import stats

from dualarm.cli.main import main
from dualarm.errors import InputError
from dualarm.curves import (condition_ratios, convergence, episodes_to_target,
                                         max_average, mean_ci, median_ratio_ci, ratio,
                                         trailing_mean)
from dualarm.experiments.report import _median_ratio_text, write_report
from dualarm.experiments.summary import PAPER, PAPER_QUOTED_RATIOS, build_report, paper_ratio
from dualarm.training.config import TrainConfig

# ----------------------------------------------------------------------------- metrics


def test_trailing_mean_averages_the_last_window_and_flags_full_windows():
    x = np.random.default_rng(0).normal(size=250)
    ma, full = trailing_mean(x, 40)
    np.testing.assert_allclose(ma[39:], np.convolve(x, np.ones(40) / 40, mode="valid"))
    assert ma[0] == x[0] and ma[9] == pytest.approx(x[:10].mean())
    assert ma[99] == pytest.approx(x[60:100].mean())
    assert not full[:39].any() and full[39:].all()
    assert not trailing_mean(x[:10], 40)[1].any()


def test_episodes_to_target_of_a_step_in_success():
    # failures up to episode 500, successes after: the last-100 rate is (e - 500) / 100,
    # first >= 0.85 at e = 585
    success = np.r_[np.zeros(500), np.ones(500)]
    assert episodes_to_target(success, 0.85, 100) == 585
    assert episodes_to_target(success, 0.86, 100) == 586
    assert episodes_to_target(success, 0.85, 50) == 543          # 42.5 successes -> 43


def test_episodes_to_target_needs_a_full_window():
    always = np.ones(300)
    assert trailing_mean(always, 100)[0][0] == 1.0                # a partial window says 1.0 ...
    assert episodes_to_target(always, 0.85, 100) == 100           # ... but only full ones count
    assert episodes_to_target(always[:99], 0.85, 100) is None     # never a full window
    assert math.isnan(max_average(always[:99], 100))
    # a lucky start then a 0.8 success rate: never reaches 0.85
    lucky = np.r_[np.ones(20), np.tile([1, 1, 1, 1, 0], 200)]
    assert episodes_to_target(lucky, 0.85, 100) is None
    assert max_average(lucky, 100) == pytest.approx(0.84)         # 20 + 64 of the first 100


def test_convergence_of_a_step_is_known_exactly():
    # 0 up to episode 1000, 10 from 1001: the 50-episode average ramps from 0 to 10 over
    # episodes 1001-1050 (value 10 (e - 1000) / 50); band 10 +- 0.5 (5% of the range, no
    # noise); first inside at 10 (e - 1000) / 50 >= 9.5, e >= 1047.5 -> 1048
    x = np.r_[np.zeros(1000), np.full(2000, 10.0)]
    c = convergence(x, window=50)
    assert c.converged and c.episode == 1048
    assert c.level == pytest.approx(10.0) and c.tolerance == pytest.approx(0.5)
    assert c.drift == pytest.approx(0.0, abs=1e-9)
    # a flat curve has nothing to converge to: it is converged as soon as a window is full
    assert convergence(np.full(500, 3.0), window=50).episode == 50


def _noise_free_exponential_convergence(R, tau, w, n):
    """First episode of the moving average of R (1 - exp(-t / tau)) within 5% of its range
    of the final value R (closed form of the trailing mean of an exponential)."""
    e = np.arange(w, n + 1, dtype=float)
    k = (np.exp(w / tau) - 1) / (np.exp(1 / tau) - 1)             # sum_{j<w} exp(j / tau)
    ma = R - R / w * np.exp(-e / tau) * k
    tol = 0.05 * (ma.max() - ma.min())
    return int(e[np.flatnonzero(R - ma <= tol)[0]])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_convergence_of_a_noisy_exponential_approach(seed):
    R, tau, w, n, sigma = 100.0, 400.0, 100, 6000, 2.0
    t = np.arange(1, n + 1)
    x = R * (1 - np.exp(-t / tau)) + np.random.default_rng(seed).normal(0, sigma, n)
    expected = _noise_free_exponential_convergence(R, tau, w, n)
    assert 1250 < expected < 1350                                  # about tau ln(25.5)
    c = convergence(x, window=w)
    assert c.converged
    assert abs(c.episode - expected) <= 40                         # noise of the average: 0.2
    assert c.level == pytest.approx(R, abs=0.2)


def test_noise_widens_the_band_of_a_flat_noisy_curve():
    rng = np.random.default_rng(3)
    x = np.r_[np.zeros(300), np.full(2700, 20.0)] + rng.normal(0, 100, 3000)
    c = convergence(x, window=100)
    tail = 300
    assert c.tolerance == pytest.approx(3 * np.std(x[-tail:], ddof=1) / 10)
    ma, full = trailing_mean(x, 100)
    assert c.tolerance > 0.05 * np.ptp(ma[full])                   # the noise term sets it
    assert c.converged and c.episode < 1500


def test_curves_that_do_not_converge():
    # still rising at the end
    ramp = np.arange(2000, dtype=float)
    c = convergence(ramp, window=100)
    assert not c.converged and c.episode is None
    assert c.drift == pytest.approx(199.0)                          # slope 1 over a 200-episode tail
    # a slow drift that stays inside the band over the tail is caught by the slope test:
    # flat, then a rise of 1.5 band half-widths across the last 10%
    x = np.r_[np.zeros(1000), np.full(8000, 100.0), 100 + np.linspace(0, 7.5, 1000)]
    c = convergence(x, window=100)
    assert not c.converged and "drifting" in c.reason
    # a jump in the last 5% leaves the band
    late = np.r_[np.zeros(1900), np.full(100, 50.0)]
    assert not convergence(late, window=100).converged
    # too short for a tail of full windows
    short = convergence(np.ones(105), window=100)
    assert not short.converged and "too short" in short.reason


def test_mean_ci_is_the_student_t_interval():
    v = np.random.default_rng(4).normal(10, 3, 5)
    mean, half = mean_ci(v)
    lo, hi = stats.t.interval(0.95, df=4, loc=v.mean(), scale=stats.sem(v))
    assert mean == pytest.approx(v.mean())
    assert mean - half == pytest.approx(lo) and mean + half == pytest.approx(hi)
    assert mean_ci(v, 0.9)[1] == pytest.approx(stats.t.ppf(0.95, 4) * stats.sem(v))
    curves = np.random.default_rng(5).normal(size=(3, 7))
    m, h = mean_ci(curves, axis=0)
    assert m.shape == h.shape == (7,)
    np.testing.assert_allclose(h, stats.t.ppf(0.975, 2) * stats.sem(curves, axis=0))
    one_mean, one_half = mean_ci([4.0])
    assert one_mean == 4.0 and math.isnan(one_half)
    assert all(math.isnan(x) for x in mean_ci([]))
    assert np.isnan(mean_ci(curves[:1], axis=0)[1]).all()


def test_ratios_are_never_made_up():
    r = condition_ratios({"multi": 4000.0, "single": 5600.0})      # no "none" runs
    assert r[("multi", "single")] == pytest.approx(4000 / 5600)
    assert r[("multi", "none")] is None and r[("single", "none")] is None
    assert condition_ratios({"multi": 1.0, "single": math.nan, "none": None}) == {
        ("multi", "none"): None, ("single", "none"): None, ("multi", "single"): None,
        ("demos", "none"): None, ("demos", "multi"): None}
    assert ratio(3.0, 0.0) is None and ratio(3.0, 4.0) == 0.75


def test_a_ratio_whose_denominator_never_got_there_says_so():
    # demos reached the target in every seed, none in no seed: the ratio is 0, which the
    # table must not print as a measured "0.00"
    m = median_ratio_ci([480, 560, 400], [math.nan] * 3)
    assert _median_ratio_text(m, "none") == "0 (none beyond the run) (0 to 0)"
    assert _median_ratio_text((1.32, 0.87, math.inf), "none") == "1.32 (0.87 to beyond the run)"
    assert _median_ratio_text((0.44, 0.0, 0.48), "none") == "0.44 (0 to 0.48)"
    assert _median_ratio_text(None, "none") == "n/a"


def test_median_ratios_count_failed_seeds_as_beyond_the_run():
    # identical seeds: the interval collapses onto the ratio of the medians
    assert median_ratio_ci([1000, 1000, 1000], [2000, 2000]) == (0.5, 0.5, 0.5)
    # one failed seed of three leaves the median finite; the interval's top is unbounded,
    # since a resampling can draw the failure twice
    r, lo, hi = median_ratio_ci([5000, 7000, math.nan], [6000, 6000, 6000])
    assert r == pytest.approx(7000 / 6000) and lo == pytest.approx(5000 / 6000) and math.isinf(hi)
    # two of three failed: the median itself is beyond the run; dropping them (the ratio of
    # the means over the seeds that reached) would have said 0.83
    r, lo, hi = median_ratio_ci([5000, math.nan, math.nan], [6000, 6000, 6000])
    assert math.isinf(r) and lo == pytest.approx(5000 / 6000) and math.isinf(hi)
    # the denominator failing makes the numerator infinitely faster: 0
    assert median_ratio_ci([5000] * 3, [math.nan] * 3)[:2] == (0.0, 0.0)
    # both beyond the run, or no seeds: no ratio
    assert median_ratio_ci([math.nan] * 2, [math.nan] * 3) is None
    assert median_ratio_ci([], [1.0]) is None
    # the same numbers on every call (a fixed bootstrap seed), and they depend on the data
    a, b = [4000, 5200, 6100, 7000, 9000], [5000, 6400, 7700, 8800, 9900]
    assert median_ratio_ci(a, b) == median_ratio_ci(a, b)
    r, lo, hi = median_ratio_ci(a, b)
    assert r == pytest.approx(6100 / 7700) and lo < r < hi < 2
    with pytest.raises(ValueError, match="confidence"):
        median_ratio_ci(a, b, confidence=1.5)


def test_the_paper_ratios_agree_with_its_values():
    for (quantity, pair), quoted in PAPER_QUOTED_RATIOS.items():
        derived = PAPER[quantity][pair[0]] / PAPER[quantity][pair[1]]
        assert abs(derived - quoted) <= 0.006, (quantity, pair)
    assert paper_ratio("convergence_episode", ("single", "none")) == (0.80, True)
    value, quoted = paper_ratio("episodes_to_target", ("single", "none"))
    assert not quoted and value == pytest.approx(5810 / 7685)


# ----------------------------------------------------------------------------- end to end

N, WINDOW = 600, 50
BASE = {"none": 300, "single": 200, "multi": 100}                 # last failing episode, seed 0
RATE = {"none": 10.0, "single": 12.0, "multi": 12.0}              # wall seconds per episode
FINAL_EVAL = {"none": 0.80, "single": 0.86, "multi": 0.92}


def write_run(root, condition, seed, success, returns, wall, eval_rows=(), planned=None,
              name=None, **config):
    d = root / (name or f"runs/{condition}-seed{seed}")
    d.mkdir(parents=True)
    TrainConfig.paper().with_(condition=condition, seed=seed, episodes=planned or len(success), **config).save(
        d / "config.yaml")
    with open(d / "metrics.csv", "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["episode", "env_steps", "wall_time_s", "steps", "return_left", "return_total",
                    "success"])
        for i, (s, r, t) in enumerate(zip(success, returns, wall)):
            w.writerow([i + 1, 50 * (i + 1), f"{t:.3f}", 50, f"{r / 2:.6f}", f"{r:.6f}", int(s)])
    with open(d / "eval.csv", "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["episode", "env_steps", "wall_time_s", "success_rate", "return_mean",
                    "steps_mean"])
        for ep, rate in eval_rows:
            w.writerow([ep, 50 * ep, ep, rate, 0.0, 50])
    return d


def known_run(root, condition, seed, n=N, **kw):
    """Success steps from 0 to 1 after episode k = BASE + 10 seed; the return is 100 x success
    (for none seed 2, plus a rise over the last 100 episodes: never converges)."""
    k = BASE[condition] + 10 * seed
    e = np.arange(1, n + 1)
    success = (e > k).astype(float)
    returns = 100 * success
    if condition == "none" and seed == 2:
        returns = returns + 0.5 * np.maximum(0, e - (n - 100))
    evals = [(ep, min(1.0, ep / n)) for ep in range(100, n, 100)]
    evals.append((n, FINAL_EVAL[condition] + 0.02 * seed))
    return write_run(root, condition, seed, success, returns, RATE[condition] * e, evals, **kw)


@pytest.fixture(scope="module")
def comparison(tmp_path_factory):
    root = tmp_path_factory.mktemp("comparison")
    for c in BASE:
        for seed in range(3):
            known_run(root, c, seed)
    return root


def read_table(path):
    with open(path, newline="") as f:
        return {row["condition"]: row for row in csv.DictReader(f)}


def test_report_end_to_end(comparison, capsys):
    out = comparison / "report"                                    # the default
    assert main(["report", str(comparison), "--window", str(WINDOW)]) == 0
    printed = capsys.readouterr()
    assert str(out / "index.html") in printed.out
    assert "none: only 2 of 3 seeds reached convergence" in printed.err
    half3 = stats.t.ppf(0.975, 2) * 10 / math.sqrt(3)             # seeds k, k + 10, k + 20
    half2 = stats.t.ppf(0.975, 1) * np.std([0, 10], ddof=1) / math.sqrt(2)
    t = read_table(out / "table.csv")
    assert list(t) == ["none", "single", "multi"]
    for c, base in BASE.items():
        row = t[c]
        assert int(row["seeds"]) == 3 and int(row["episodes_compared"]) == N
        # 42.5 successes in the last 50 -> 43 episodes after the step
        assert float(row["episodes_to_target_mean"]) == pytest.approx(base + 10 + 43)
        assert float(row["episodes_to_target_ci95"]) == pytest.approx(half3)
        assert int(row["episodes_to_target_seeds_reached"]) == 3
        assert float(row["max_avg_success_mean"]) == 1.0
        assert float(row["final_eval_success_mean"]) == pytest.approx(FINAL_EVAL[c] + 0.02)
    # return 100 x success: the average reaches 95 (the band) 48 episodes after the step
    for c in ("single", "multi"):
        assert float(t[c]["convergence_episode_mean"]) == pytest.approx(BASE[c] + 10 + 48)
        assert float(t[c]["convergence_time_s_mean"]) == pytest.approx(RATE[c] * (BASE[c] + 58))
        assert float(t[c]["convergence_time_s_ci95"]) == pytest.approx(RATE[c] * half3)
    # none seed 2 still rises at the end: 2 of 3 seeds, mean over seeds 0 and 1
    assert int(t["none"]["convergence_episode_seeds_reached"]) == 2
    assert float(t["none"]["convergence_episode_mean"]) == pytest.approx(300 + 5 + 48)
    assert float(t["none"]["convergence_episode_ci95"]) == pytest.approx(half2)
    # ratios of the means, beside the paper's
    multi, single, none = (float(t[c]["convergence_episode_mean"]) for c in ("multi", "single", "none"))
    assert float(t["multi"]["convergence_episode_ratio_vs_none"]) == pytest.approx(multi / none)
    assert float(t["multi"]["convergence_episode_ratio_vs_single"]) == pytest.approx(multi / single)
    assert float(t["single"]["convergence_episode_ratio_vs_none"]) == pytest.approx(single / none)
    assert float(t["multi"]["paper_convergence_episode_ratio_vs_single"]) == 0.71
    assert float(t["multi"]["episodes_to_target_ratio_vs_none"]) == pytest.approx(153 / 353)
    assert float(t["multi"]["paper_episodes_to_target"]) == 4480
    assert t["none"]["convergence_episode_ratio_vs_none"] == ""   # not a pair the paper quotes
    # medians over every seed with bootstrap intervals. none seed 2 never converged: counted
    # as beyond the run, the none median is seed 1's 358 (seeds 0, 1: 348, 358), and
    # resamplings that draw it twice make none's median infinite (the interval's low end 0)
    assert float(t["multi"]["convergence_episode_median_ratio_vs_none"]) == pytest.approx(158 / 358)
    assert float(t["multi"]["convergence_episode_median_ratio_vs_none_low"]) == 0.0
    # the top: multi at its slowest median (168) over none at its fastest (348), both drawn
    # often enough (7/27 each) to hold the 97.5th percentile
    assert float(t["multi"]["convergence_episode_median_ratio_vs_none_high"]) == pytest.approx(168 / 348)
    assert float(t["multi"]["episodes_to_target_median_ratio_vs_none"]) == pytest.approx(153 / 353)
    # time to the target: the wall time at that episode (RATE seconds per episode)
    assert float(t["multi"]["time_to_target_s_mean"]) == pytest.approx(RATE["multi"] * 153)
    assert t["multi"]["paper_time_to_target_s_ratio_vs_none"] == ""  # the paper gives none
    # figures, table and page
    for png in ("fig6_return.png", "fig7_success.png", "fig8_convergence_time.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f'src="{png}"' in (out / "index.html").read_text()
    page = (out / "index.html").read_text()
    md = (out / "table.md").read_text()
    assert "<table>" in page and "multi-segment C2&amp;C3 (multi)" in page
    assert f"{BASE['multi'] + 53} ± {half3:.0f} (3/3)" in md and f"{BASE['multi'] + 53} ± {half3:.0f} (3/3)" in page
    assert "353 ± " in md and "(2/3 †)" in md                      # none convergence flagged
    assert "none: only 2 of 3 seeds reached convergence" in md
    assert "not converged | runs/none-seed2 | the moving average leaves the band" in md
    assert "median ratio, 95% CI (unreached = beyond the run)" in md and "beyond the run)" in md
    assert md.count("| none | ") == 3                              # one line per run
    assert not list(out.glob(".*.tmp*"))                           # atomic writes left nothing


def test_missing_condition_and_unreached_target(tmp_path):
    e = np.arange(1, N + 1)
    for seed in range(2):
        known_run(tmp_path, "multi", seed)
        success = np.tile([1, 1, 1, 1, 0], N // 5)                 # a success rate of 0.8
        write_run(tmp_path, "single", seed, success, 50 * success, e)
    r = build_report(tmp_path, window=WINDOW)
    assert r.ratios["convergence_episode"][("multi", "none")] is None
    assert r.ratios["convergence_episode"][("multi", "single")] == pytest.approx(
        r.conditions["multi"].convergence_episode.mean / r.conditions["single"].convergence_episode.mean)
    assert r.conditions["single"].episodes_to_target.reached == 0
    assert r.conditions["multi"].episodes_to_target.reached == 2
    assert r.ratios["episodes_to_target"][("multi", "single")] is None
    index = write_report(tmp_path, tmp_path / "rep", window=WINDOW)
    assert index == tmp_path / "rep" / "index.html" and index.exists()
    md = (index.parent / "table.md").read_text()
    assert "not reached (0/2)" in md and "no single seed reached it" in md
    assert "no none runs" in md


def test_runs_of_different_lengths_are_compared_over_the_common_range(tmp_path):
    known_run(tmp_path, "multi", 0)
    known_run(tmp_path, "multi", 1, n=400, planned=N)              # stopped at 400 of 600
    known_run(tmp_path, "single", 0, name="one-seed")               # one level deep also found
    r = build_report(tmp_path, window=WINDOW)
    multi = r.conditions["multi"]
    assert multi.episodes == 400 and multi.ma_return.shape == (2, 400)
    assert multi.truncated and r.conditions["single"].seeds == 1
    # seed 0's final evaluation is the last one within episodes 1-400
    assert multi.final_eval_success.values[0] == pytest.approx(400 / 600)
    assert any("partial run, 400 of 600" in n for n in r.notes)
    assert any("common range, episodes 1-400" in n for n in r.notes)
    assert any("different episode ranges" in n for n in r.notes)
    assert math.isnan(r.conditions["single"].episodes_to_target.ci95)   # one seed: no CI


def test_a_run_being_written_loses_only_its_incomplete_last_row(tmp_path):
    d = known_run(tmp_path, "multi", 0)
    with open(d / "metrics.csv", "a") as f:
        f.write("601,30050,60")                                    # no line end: being written
    r = build_report(tmp_path, window=WINDOW)
    assert r.conditions["multi"].episodes == N
    assert any("incomplete last row" in n for n in r.notes)


def test_bad_input_names_the_file_and_the_column(tmp_path, capsys):
    with pytest.raises(InputError, match="no run directories"):
        build_report(tmp_path)
    assert main(["report", str(tmp_path)]) == 2
    assert "no run directories" in capsys.readouterr().err

    d = known_run(tmp_path, "multi", 0)
    metrics = d / "metrics.csv"
    lines = metrics.read_text().splitlines()
    original = list(lines)
    cells = lines[5].split(",")
    cells[5] = "abc"                                               # return_total of data row 5
    metrics.write_text("\n".join(lines[:5] + [",".join(cells)] + lines[6:]) + "\n")
    with pytest.raises(InputError) as err:
        build_report(tmp_path)
    assert str(metrics) in str(err.value) and "row 5" in str(err.value)
    assert "'return_total'" in str(err.value) and "'abc'" in str(err.value)
    assert main(["report", str(tmp_path)]) == 2
    assert "return_total" in capsys.readouterr().err

    header = lines[0].split(",")
    keep = [i for i, h in enumerate(header) if h != "success"]
    metrics.write_text("\n".join(",".join(line.split(",")[i] for i in keep) for line in lines) + "\n")
    with pytest.raises(InputError, match="missing required column") as err:
        build_report(tmp_path)
    assert err.value.column == "success" and err.value.source == str(metrics)

    lines[10] = lines[10].replace("10,", "12,", 1)                 # episode 10 logged as 12
    metrics.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="episodes must run") as err:
        build_report(tmp_path)
    assert err.value.column == "episode" and err.value.row == 10

    known_run(tmp_path, "single", 0)
    (d.parent / "single-seed0" / "eval.csv").write_text("episode,success_rate\n100,nan\n")
    metrics.write_text("\n".join(original) + "\n")
    with pytest.raises(InputError, match="not a finite number") as err:
        build_report(tmp_path)
    assert err.value.column == "success_rate" and "eval.csv" in err.value.source


def test_cli_rejects_bad_options(tmp_path, capsys):
    for option in (["--window", "0"], ["--target", "1.5"], ["--target", "x"]):
        with pytest.raises(SystemExit) as exc:
            main(["report", str(tmp_path), *option])
        assert exc.value.code == 2


def test_runs_with_later_starts_are_measured_on_their_evaluations(tmp_path):
    """Training episodes that start holding the boxes succeed without the task being learned:
    such runs reach the target at their first evaluation at or above it, not by training
    success, and say so."""
    e = np.arange(1, 401)
    evals = [(100, 0.0), (200, 0.5), (300, 0.9), (400, 0.95)]
    write_run(tmp_path, "none", 0, np.ones(400), 100 * np.ones(400), e, evals,
              starts={"probs": (0.2, 0.2, 0.6)})
    report = build_report(tmp_path, window=50)
    none = report.conditions["none"]
    assert none.episodes_to_target.values.tolist() == [300]          # training success: 50
    assert none.max_avg_success.values.tolist() == [0.95]
    assert any("read from the evaluations" in n for n in report.notes)


def test_runs_that_stop_at_an_evaluation_are_measured_on_their_evaluations(tmp_path):
    """A run from the normal reset only that ends at the evaluation reaching its stop_at
    (configs/reset-starts.yaml) has a training success still far below it when it stops: it
    reached the target at that evaluation, not never. The same run without a stop_at is read
    from training success, as the paper's Fig. 7 is."""
    e = np.arange(1, 301)
    training = (e % 10 == 0).astype(float)                         # 0.1: exploring, from the reset
    evals = [(100, 0.0), (200, 0.5), (300, 0.9)]
    write_run(tmp_path / "stops", "none", 0, training, training, e, evals, planned=600,
              stop_at=0.85)
    stops = build_report(tmp_path / "stops", window=50)
    assert stops.conditions["none"].episodes_to_target.values.tolist() == [300]
    assert stops.conditions["none"].max_avg_success.values.tolist() == [0.9]
    assert any("stop_at" in n and "read from the evaluations" in n for n in stops.notes)
    write_run(tmp_path / "full", "none", 0, training, training, e, evals)
    full = build_report(tmp_path / "full", window=50)
    assert np.isnan(full.conditions["none"].episodes_to_target.values[0])
    assert not any("read from the evaluations" in n for n in full.notes)


def test_the_averaged_actors_evaluations_are_read_on_request(tmp_path, capsys):
    """`--actor average` reads eval.csv's average_success_rate (the averaged actors, evaluated
    beside the run's policy): episodes to target and max success follow that column, and a
    run without it is an error naming the file and the column."""
    e = np.arange(1, 401)
    d = write_run(tmp_path, "none", 0, np.ones(400), 100 * np.ones(400), e,
                  starts={"probs": (0.2, 0.2, 0.6)})
    rows = [(100, 0.0, 0.5), (200, 0.5, 0.9), (300, 0.9, 0.95), (400, 0.6, 0.7)]
    (d / "eval.csv").write_text("episode,success_rate,average_success_rate\n"
                                + "".join(f"{a},{b},{c}\n" for a, b, c in rows))
    own = build_report(tmp_path, window=50).conditions["none"]
    assert own.episodes_to_target.values.tolist() == [300]
    assert own.final_eval_success.values.tolist() == [0.6]
    report = build_report(tmp_path, window=50, actors="average")
    avg = report.conditions["none"]
    assert avg.episodes_to_target.values.tolist() == [200]
    assert avg.max_avg_success.values.tolist() == [0.95]
    assert avg.final_eval_success.values.tolist() == [0.7]
    assert report.actors == "average" and any("averaged actors" in n for n in report.notes)
    assert main(["report", str(tmp_path), "-o", str(tmp_path / "rep"), "--window", "50",
                 "--actor", "average"]) == 0
    assert "averaged actors" in (tmp_path / "rep" / "table.md").read_text()

    (d / "eval.csv").write_text("episode,success_rate\n100,0.5\n")
    with pytest.raises(InputError, match="missing required column") as err:
        build_report(tmp_path, actors="average")
    assert err.value.column == "average_success_rate" and err.value.source == str(d / "eval.csv")
    with pytest.raises(InputError, match="actors must be one of"):
        build_report(tmp_path, actors="target")


# ----------------------------------------------------------------------------- findings
def step_run(root, condition, seed, last_fail, n=N):
    """Training success 0 up to ``last_fail``, 1 after; the return is 100 x success."""
    success = (np.arange(1, n + 1) > last_fail).astype(float)
    return write_run(root, condition, seed, success, 100 * success, np.arange(1, n + 1))


def test_findings_say_guidance_is_faster_only_when_the_seeds_show_it(comparison, tmp_path, capsys):
    from dualarm.experiments.findings import findings

    # three seeds, every multi and single seed ahead of every none seed: faster at 95 %
    r = build_report(comparison, window=WINDOW)
    lines = findings(r)
    reached = [r.conditions[c].episodes_to_target.values for c in ("none", "single", "multi")]
    assert lines[0].startswith("Every condition reached success 0.85")
    assert f"multi median {np.median(reached[2]):,.0f} episodes, 3 of 3 seeds" in lines[0]
    ratio = np.median(reached[2]) / np.median(reached[0])
    multi_none = next(x for x in lines if x.startswith("multi/none"))
    assert multi_none.startswith(f"multi/none {ratio:.2f}: multi needed {1 - ratio:.0%} fewer")
    assert "(paper: 0.58)" in multi_none and "guidance faster at 95 %" in multi_none
    # overlapping seeds: the interval includes 1, and the sentence says so
    mixed = tmp_path / "mixed"
    for seed, (m, n) in enumerate([(100, 150), (300, 250), (200, 350), (400, 200)]):
        step_run(mixed, "multi", seed, m)
        step_run(mixed, "none", seed, n)
    lines = findings(build_report(mixed, window=WINDOW))
    assert [x.split(" ")[0] for x in lines[1:]] == ["multi/none"]       # no single: no line
    assert "which includes 1: no difference measurable" in lines[1]
    # one seed each: a single draw, and how to measure it
    one = tmp_path / "one"
    step_run(one, "multi", 0, 100)
    step_run(one, "none", 0, 300)
    assert main(["report", str(one), "--window", str(WINDOW)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("Every condition reached success 0.85: none at ")
    assert "a single draw rather than a measurement" in out[1] and "--seeds 0,1,2,3,4" in out[2]
    md = (one / "report" / "table.md").read_text()
    assert md.index("## Findings") < md.index("| condition |") and out[1] in md
    assert "<h2>Findings</h2>" in (one / "report" / "index.html").read_text()


def test_findings_name_the_condition_that_did_not_learn(tmp_path):
    from dualarm.experiments.findings import findings

    for seed in range(2):
        step_run(tmp_path, "multi", seed, 100)
        step_run(tmp_path, "single", seed, N)                       # never succeeds
    lines = findings(build_report(tmp_path, window=WINDOW))
    assert lines[0].startswith("Reached success 0.85: multi median")
    assert f"Not reached: single (0 of 2 seeds in {N:,} episodes)" in lines[0]
    assert lines[1] == "multi/single: single did not reach success 0.85 in most seeds (paper: 0.77)."


def test_runs_that_stopped_at_their_target_are_done_not_partial(tmp_path):
    """A run that ended at the evaluation reaching its ``stop_at`` is done: no "partial" note,
    and the other seeds of its condition are read to their own ends, not cut to its length
    (a seed that stopped at 300 must not make a seed that reached it at 500 look censored)."""
    e = np.arange(1, 601)
    stop = {"starts": {"probs": (0.2, 0.2, 0.6)}, "stop_at": 0.85}
    write_run(tmp_path, "multi", 0, np.ones(300), np.ones(300), e[:300],
              [(100, 0.1), (200, 0.5), (300, 0.9)], planned=600, **stop)
    write_run(tmp_path, "multi", 1, np.ones(500), np.ones(500), e[:500],
              [(100, 0.1), (300, 0.5), (500, 0.86)], planned=600, **stop)
    write_run(tmp_path, "multi", 2, np.ones(600), np.ones(600), e,
              [(200, 0.1), (600, 0.7)], planned=600, **stop)        # never reached it
    report = build_report(tmp_path, window=50)
    multi = report.conditions["multi"]
    assert [r.stopped for r in multi.runs] == [True, True, False]
    assert not any("partial run" in n for n in report.notes)
    assert multi.episodes_to_target.values.tolist()[:2] == [300, 500]
    assert np.isnan(multi.episodes_to_target.values[2])
    assert multi.max_avg_success.values.tolist() == [0.9, 0.86, 0.7]
    assert multi.episodes == 300                                   # the curves' common range
    assert any("reached their stop_at" in n and "multi seed 0 at 300" in n for n in report.notes)
    write_run(tmp_path, "none", 0, np.ones(300), np.ones(300), e[:300], [(300, 0.5)],
              planned=600, **stop)                                  # below its stop: partial
    assert any("none-seed0: partial run, 300 of 600" in n for n in build_report(tmp_path).notes)
