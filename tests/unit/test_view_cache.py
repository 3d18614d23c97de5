"""The cache of what is computed from views of a longer time array (gcs_core.problem.view_cache)."""

from __future__ import annotations

import numpy as np

from gcs_core.problem.view_cache import ViewCache


def test_a_view_is_answered_once_and_an_array_of_its_own_each_time():
    t = np.arange(100.0)
    cache, calls = ViewCache(8), []

    def compute():
        calls.append(1)
        return len(calls)

    assert cache.get(t[10:20], "a", compute) == 1
    assert cache.get(t[10:20], "a", compute) == 1  # the same place in the same array
    assert cache.get(t[10:20], "b", compute) == 2  # another tag
    assert cache.get(t[11:20], "a", compute) == 3  # another place
    assert cache.get(t[10:20].copy(), "a", compute) == 4  # not a view: never kept
    assert cache.get(t[10:20].copy(), "a", compute) == 5
    assert cache.get(t[10:30:2], "a", compute) == 6  # a strided view: not kept
    assert cache.get(t[10:30:2], "a", compute) == 7


def test_an_entry_does_not_answer_for_another_array():
    cache = ViewCache(8)
    t = np.arange(50.0)
    assert cache.get(t[:5], "", lambda: "first") == "first"
    u = t.copy()  # same values, another array
    assert cache.get(u[:5], "", lambda: "second") == "second"


def test_bounded():
    t = np.arange(100.0)
    cache = ViewCache(3)
    for i in range(10):
        cache.get(t[i : i + 5], "", lambda: 0)
    assert len(cache._entries) <= 3
