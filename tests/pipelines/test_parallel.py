"""The seeds' work split over forked processes (:func:`dancekit.pipelines.parallel.fork_map`): results in part order,
a child's exception raised in the parent, a child that dies named, one process where fork is off."""

from __future__ import annotations

import os
import sys

import pytest

from dancekit.pipelines.parallel import can_fork, fork_map, usable_cores

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork_map forks on Linux only")


def pid_and_square(part):
    return os.getpid(), [x * x for x in part]


def test_each_part_in_its_own_process_results_in_order():
    out = fork_map(pid_and_square, [[1, 2], [3], [4, 5, 6]])
    assert [r[1] for r in out] == [[1, 4], [9], [16, 25, 36]]
    pids = [r[0] for r in out]
    assert pids[0] == os.getpid() and len(set(pids)) == 3  # the first part here, the others in two children


def fail_in_child(part):
    if part == "child":
        raise ValueError("bad part 'child'")
    return part


def test_a_childs_exception_is_raised_here():
    with pytest.raises(ValueError, match="bad part 'child'"):
        fork_map(fail_in_child, ["here", "child"])


def die_in_child(part):
    if part == "child":
        os._exit(3)
    return part


def test_a_child_that_dies_without_a_result_is_an_error():
    with pytest.raises(RuntimeError, match="without a result"):
        fork_map(die_in_child, ["here", "child"])


def test_without_fork_every_part_runs_here(monkeypatch):
    monkeypatch.setenv("DANCEKIT_NO_FORK", "1")
    assert not can_fork()
    out = fork_map(pid_and_square, [[1], [2]])
    assert [r[0] for r in out] == [os.getpid()] * 2 and [r[1] for r in out] == [[1], [4]]
    assert usable_cores() >= 1
