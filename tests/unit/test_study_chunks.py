"""The default chunk size of a study run (:class:`drivetrain_ctrl.studies.runner._ChunkSizer`)."""

from __future__ import annotations

import math

import pytest

from drivetrain_ctrl.studies import runner
from drivetrain_ctrl.studies.runner import _chunked, _ChunkSizer


def test_a_fixed_size_is_kept_and_the_last_chunk_is_the_rest() -> None:
    s = _ChunkSizer(3, 10, 2)
    chunks = list(_chunked(iter(range(10)), s.size))
    assert [len(c) for c in chunks] == [3, 3, 3, 1]
    assert [x for c in chunks for x in c] == list(range(10))


def test_first_chunks_are_small_until_a_cost_is_known() -> None:
    s = _ChunkSizer(None, 10_000, 2)
    assert [s.size() for _ in range(8)] == [runner.FIRST_CHUNK] * 8


def test_chunks_aim_at_the_target_time(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [100.0]
    monkeypatch.setattr(runner.time, "perf_counter", lambda: now[0])
    s = _ChunkSizer(None, 100_000, 2)
    for _ in range(4):
        s.size()
    # 40 runs done by 2 workers in 0.4 s: 20 ms of one worker per run
    now[0] += 0.4
    s.finished(40)
    assert s.size() == round(runner.CHUNK_TARGET_S / 0.02)
    # very cheap runs: capped at MAX_CHUNK
    now[0] += 0.0
    s.finished(100_000)
    assert s.size() == runner.MAX_CHUNK


def test_the_tail_is_shared_out_between_the_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [0.0]
    monkeypatch.setattr(runner.time, "perf_counter", lambda: now[0])
    s = _ChunkSizer(None, 100, 2)
    s.size()  # 4 taken: 96 remain
    now[0] = 1.0
    s.finished(4)  # 0.5 s per run: 4 per chunk by time
    assert s.size() == 4
    now[0] = 1.001
    s.finished(1000)  # now cheap: the time target allows many, the tail cap 92 / 4
    assert s.size() == math.ceil(92 / 4)


def test_every_item_is_chunked_once_whatever_the_sizes(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [0.0]
    monkeypatch.setattr(runner.time, "perf_counter", lambda: now[0])
    s = _ChunkSizer(None, 1000, 3)
    out: list[int] = []
    for ch in _chunked(iter(range(1000)), s.size):
        out += ch
        now[0] += 0.01
        s.finished(len(ch))
    assert out == list(range(1000))
