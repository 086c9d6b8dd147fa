"""The helpers every study shares: the Pareto front and the timer."""

import numpy as np
import pytest

from finray.benchmarks.pareto import pareto_front
from finray.benchmarks.timing import Stopwatch, time_calls


def test_pareto_front_keeps_the_non_dominated_points():
    assert np.flatnonzero(pareto_front([1, 2, 3, 4], [5, 6, 1, 0.5])).tolist() == [0, 2, 3]
    cost = np.array([1.0, 2.0, 3.0, 2.0, 4.0])
    err = np.array([5.0, 3.0, 1.0, 4.0, 1.0])
    # (2, 4) is beaten by (2, 3); (4, 1) by (3, 1)
    np.testing.assert_array_equal(pareto_front(cost, err), [True, True, True, False, False])


def test_pareto_front_ties_and_missing_values():
    np.testing.assert_array_equal(pareto_front([1.0, 1.0], [2.0, 2.0]), [True, True])  # ties kept
    # a NaN point is not on the front and does not hide the others
    np.testing.assert_array_equal(
        pareto_front([1.0, np.nan, 2.0], [2.0, 0.1, 1.0]), [True, False, True]
    )
    np.testing.assert_array_equal(pareto_front([0.5, 1.0], [np.inf, 1.0]), [False, True])
    assert pareto_front([], []).shape == (0,)


def test_time_calls_calls_each_input_once_per_repeat_after_the_warmup():
    calls = []
    t = time_calls(calls.append, n_calls=3, repeats=2, warmup=2)
    assert calls == [0, 0, 0, 1, 2, 0, 1, 2]
    assert t.n_calls == 6
    assert min(t.wall_s, t.cpu_s, t.mean_wall_s, t.mean_cpu_s) >= 0
    with pytest.raises(KeyError):
        time_calls(calls.append, cpu="gpu")


def test_stopwatch_freezes_at_the_end_of_its_block():
    with Stopwatch(cpu="thread") as t:
        sum(range(10_000))
    frozen = (t.wall_s, t.cpu_s)
    sum(range(10_000))
    assert (t.wall_s, t.cpu_s) == frozen and min(frozen) >= 0
    running = Stopwatch()
    assert running.wall_s <= running.wall_s  # it runs on outside a block
