"""SimClock: simulated time at the chosen pace of the wall clock."""

from __future__ import annotations

import pytest

from tiling_sim.sim_clock import Pace, SimClock


def test_time_stands_still_until_started() -> None:
    clock = SimClock(factor=20.0)
    assert not clock.running
    assert clock.advance(5.0) == 0.0
    clock.start(10.0)
    assert clock.running
    assert clock.advance(10.5) == pytest.approx(10.0)


def test_each_pace_charges_the_wall_time_since_the_last_call() -> None:
    clock = SimClock(factor=20.0)
    clock.start(0.0)
    clock.advance(1.0)  # fast: 20 s
    clock.advance(1.2, Pace.STOPPED)  # a scan rendered: no simulated time
    clock.advance(1.35, Pace.REAL)  # its inspection: 150 ms, as on the robot's computer
    assert clock.now == pytest.approx(20.15)


def test_a_wall_clock_going_backwards_costs_nothing() -> None:
    clock = SimClock(factor=20.0)
    clock.start(5.0)
    assert clock.advance(4.0) == 0.0
    assert clock.advance(4.5) == pytest.approx(10.0)


def test_a_ceiling_stops_the_clock_there_and_never_turns_it_back() -> None:
    clock = SimClock(factor=20.0)
    clock.start(0.0)
    assert clock.advance(1.0, ceiling=12.5) == pytest.approx(12.5)  # 20 s due, held at 12.5
    assert clock.advance(2.0, ceiling=12.5) == pytest.approx(12.5)
    assert clock.advance(3.0, ceiling=5.0) == pytest.approx(12.5)  # a promise heard late: no going back
    assert clock.advance(3.1) == pytest.approx(14.5)  # released: fast from the moment it was released
