"""The compile notice: shown once while the kernels compile, never when they are cached."""

from __future__ import annotations

import io
import logging

import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.sim import compile_notice as N


@pytest.fixture
def fresh_notice(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(N, "_announced", False)


def test_the_kernels_of_this_process_are_ready() -> None:
    # ./dev warms the cache before the tests: the check must see it (no false alarm)
    assert N.kernels_ready()
    assert K.is_cached(K.simulate_kernel)


def test_a_plain_function_is_not_cached() -> None:
    assert not K.is_cached(len)


def test_nothing_is_shown_when_the_kernels_are_cached(fresh_notice, caplog) -> None:
    out = io.StringIO()
    with caplog.at_level(logging.INFO, logger="drivetrain_ctrl"), N.compile_progress(out):
        N.announce_compile()
    assert out.getvalue() == "" and caplog.records == []


def test_the_library_logs_once_per_process(fresh_notice, monkeypatch, caplog) -> None:
    monkeypatch.setattr(N, "kernels_ready", lambda: False)
    with caplog.at_level(logging.WARNING, logger="drivetrain_ctrl"):
        N.announce_compile()
        N.announce_compile()
    msgs = [r.getMessage() for r in caplog.records]
    assert len(msgs) == 1 and "compiling the simulator kernels" in msgs[0], msgs
    assert f"about {N.EXPECTED_COMPILE_S:.0f} s" in msgs[0]


def test_the_cli_notice_shows_expected_and_taken_time(fresh_notice, monkeypatch, caplog) -> None:
    monkeypatch.setattr(N, "kernels_ready", lambda: False)
    out = io.StringIO()  # not a terminal: a start line and a done line
    with caplog.at_level(logging.WARNING, logger="drivetrain_ctrl"), N.compile_progress(out):
        N.announce_compile()  # inside the notice, the library stays quiet
    lines = out.getvalue().splitlines()
    assert len(lines) == 2, lines
    assert "compiling the simulator kernels" in lines[0] and "two cores" in lines[0]
    assert lines[1].startswith("[drivetrain-ctrl] compiled in ")
    assert caplog.records == []


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_on_a_terminal_the_elapsed_time_ticks_in_place(fresh_notice, monkeypatch) -> None:
    import time

    monkeypatch.setattr(N, "kernels_ready", lambda: False)
    out = _Tty()
    with N.compile_progress(out, interval=0.01):
        time.sleep(0.1)
    text = out.getvalue()
    assert text.count("\r") >= 3 and text.rstrip().endswith("s") and "compiled in" in text
    assert text.count("\n") == 1  # one line, updated in place
