"""The reverse curriculum moves the start states backwards as the later starts succeed."""

import numpy as np
import pytest

from dualarm.training.curriculum import ReverseCurriculum


def episodes(start_class: int, successes: int, failures: int):
    """Finished episodes whose earlier arm started at ``start_class``."""
    n = successes + failures
    starts = np.full((n, 2), 2)
    starts[:, 0] = start_class
    return starts, np.arange(n) < successes


def test_the_frontier_moves_back_as_later_starts_succeed_and_forward_when_they_fail():
    c = ReverseCurriculum((0.2, 0.2, 0.6), threshold=0.5, window=20)
    assert c.frontier() == 2 and np.allclose(c.probs(), [0.2, 0.2, 0.6])
    c.record(*episodes(2, 0, 11))
    c.record(*episodes(2, 9, 0))                         # held starts: 45 %, not yet
    assert c.frontier() == 2
    c.record(*episodes(2, 3, 0))                         # last 20: 12 successes, 8 failures
    assert c.success_rates()[2] == pytest.approx(0.6)
    assert c.frontier() == 1 and np.allclose(c.probs(), [0.2, 0.6, 0.2])
    c.record(*episodes(1, 10, 5))                        # starts at the box: 67 %
    assert c.frontier() == 0 and np.allclose(c.probs(), [0.6, 0.2, 0.2])
    c.record(*episodes(2, 0, 20))                        # the carry is forgotten
    assert c.frontier() == 2
    assert np.isclose(c.probs().sum(), 1.0)


def test_a_class_with_too_few_episodes_does_not_count_as_learned():
    c = ReverseCurriculum((0.2, 0.2, 0.6), threshold=0.5, window=20)
    c.record(*episodes(2, 9, 0))                         # 9 < half a window
    assert c.success_rates()[2] is None and c.frontier() == 2


def test_an_episode_counts_for_its_earlier_arm_and_the_state_round_trips():
    c = ReverseCurriculum((0.1, 0.1, 0.8), threshold=0.9, window=4)
    c.record(np.array([[2, 0], [1, 2], [2, 2], [2, 2]]), np.array([False, True, True, True]))
    assert [len(r) for r in c.recent] == [1, 1, 2]
    copy = ReverseCurriculum((0.1, 0.1, 0.8), threshold=0.9, window=4)
    copy.load_state_dict(c.state_dict())
    assert copy.success_rates() == c.success_rates() == [None, None, 1.0]
    assert copy.frontier() == 1 and np.allclose(copy.probs(), [0.1, 0.8, 0.1])
