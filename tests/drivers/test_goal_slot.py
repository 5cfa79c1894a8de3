"""GoalSlot: one goal at a time, and no wedge when an accepted goal never starts."""

from __future__ import annotations

from hardware_drivers.goal_slot import GoalSlot


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_second_goal_is_refused_while_one_is_accepted_or_running() -> None:
    clock = FakeClock()
    slot = GoalSlot(start_grace=2.0, clock=clock)
    assert slot.reserve()
    assert not slot.reserve()
    assert slot.start()
    clock.now = 100.0
    assert slot.busy and not slot.reserve()
    slot.finish()
    assert not slot.busy and slot.reserve()


def test_an_accepted_goal_that_never_starts_frees_the_slot_after_the_grace() -> None:
    clock = FakeClock()
    slot = GoalSlot(start_grace=2.0, clock=clock)
    assert slot.reserve()  # its goal response is lost: it never starts
    clock.now = 1.9
    assert not slot.reserve()
    clock.now = 2.1
    assert slot.reserve()


def test_a_late_starter_is_refused_while_another_goal_runs() -> None:
    clock = FakeClock()
    slot = GoalSlot(start_grace=2.0, clock=clock)
    assert slot.reserve()
    clock.now = 3.0
    assert slot.reserve() and slot.start()
    assert not slot.start()  # the first goal finally starts: refused, the running one keeps the slot
    slot.finish()
    assert slot.start()
