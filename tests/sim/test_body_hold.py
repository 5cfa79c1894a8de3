"""BodyHold: the world's clock waits at the end of a body's phase until the body says what it does next."""

from tiling_sim.body_hold import BodyHold


def test_the_earliest_phase_end_of_any_busy_body_is_the_ceiling() -> None:
    hold = BodyHold(limit=5.0)
    assert hold.ceiling() is None
    hold.busy_until("robot1", 30.0)
    hold.busy_until("robot2", 12.0)
    assert hold.ceiling() == 12.0
    hold.busy_until("robot2", 40.0)  # robot2 started its next phase
    assert hold.ceiling() == 30.0
    hold.idle("robot1")  # robot1's placement is over
    assert hold.ceiling() == 40.0
    hold.idle("robot2")
    assert hold.ceiling() is None


def test_a_hold_lapses_after_its_wall_time_limit_counted_from_when_it_was_reached() -> None:
    hold = BodyHold(limit=5.0)
    hold.busy_until("robot1", 30.0)
    assert hold.lapsed(now=20.0, wall=100.0) == []  # not reached yet: nothing is held
    assert hold.lapsed(now=30.0, wall=101.0) == []  # reached: the hold starts now
    assert hold.lapsed(now=30.0, wall=106.0) == []
    assert hold.lapsed(now=30.0, wall=106.5) == ["robot1"]
    assert hold.ceiling() is None  # the clock runs on without robot1
    hold.busy_until("robot1", 50.0)  # until its next news
    assert hold.ceiling() == 50.0


def test_at_the_start_every_robot_may_begin_its_first_goal_within_its_patience() -> None:
    hold = BodyHold(limit=5.0)
    hold.starting(["robot1", "robot2"], at=0.0, patience=1.0)
    assert hold.ceiling() == 0.0
    assert hold.lapsed(now=0.0, wall=10.0) == []
    hold.busy_until("robot1", 0.0)  # robot1's first goal starts (STARTING): held on its own terms
    assert hold.lapsed(now=0.0, wall=11.2) == []  # robot2 had nothing to begin: no fault, no warning
    assert hold.ceiling() == 0.0  # robot1 still holds until it declares its first phase
    hold.busy_until("robot1", 4.0)
    assert hold.ceiling() == 4.0


def test_the_robots_still_deciding_at_a_time_are_those_the_clock_waits_for_there() -> None:
    hold = BodyHold(limit=5.0)
    hold.busy_until("robot1", 157.05)
    hold.busy_until("robot2", 160.0)
    assert hold.deciding(157.05) == ["robot1"]
    hold.busy_until("robot1", 162.0)  # it said what it does next
    assert hold.deciding(157.05) == []
    hold.idle("robot2")
    assert hold.deciding(160.0) == []


def test_the_clock_stays_where_a_goal_ended_for_the_others_reactions_even_once_that_robot_goes_on() -> None:
    hold = BodyHold(limit=5.0)
    hold.busy_until("robot2", 157.05)  # its goal ended: it waits for its next
    hold.reacting(157.05, window=0.5)
    hold.busy_until("robot2", 170.0)  # its next goal began at once
    assert hold.ceiling() == 157.05  # robot1, which waited for the tile robot2 placed, may begin at 157.05 too
    assert hold.lapsed(now=157.05, wall=10.0) == []
    assert hold.lapsed(now=157.05, wall=10.6) == []  # no fault: nobody failed to answer
    assert hold.ceiling() == 170.0
    hold.reacting(200.0, window=0.0)  # no window: nothing held
    assert hold.ceiling() == 170.0
