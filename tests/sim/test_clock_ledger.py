"""ClockLedger: the wall time of a run charged to what held the world's clock."""

from __future__ import annotations

from tiling_sim.clock_ledger import ClockLedger, Holder
from tiling_sim.scan_hold import ScanHold


def test_a_report_says_how_fast_time_ran_and_who_held_it_most() -> None:
    ledger = ClockLedger(period=10.0)
    ledger.charge(4.0, 4.0, [], simulated=0.0)  # ran 4 s of wall time
    ledger.charge(7.0, 3.0, [Holder("scan", "vi2")], simulated=80.0)
    ledger.charge(9.0, 2.0, [Holder("step", "robot3"), Holder("step", "robot5")], simulated=80.0)
    ledger.charge(10.0, 1.0, [Holder("reaction")], simulated=80.0)
    assert ledger.due(10.0)
    line = ledger.report(10.0, simulated=80.0)
    assert line.startswith("simulated time ran 80.0 s in the last 10 s of wall time (8.00x): 40% running")
    assert "30% held for VI scans being judged (vi2 30%)" in line
    assert "20% held for robots' next steps (robot3 10%, robot5 10%)" in line
    assert "10% held for the team's reaction to a goal's end" in line
    assert "next frames" not in line  # nothing held it that way


def test_a_report_starts_the_next_one_afresh() -> None:
    ledger = ClockLedger(period=5.0)
    assert not ledger.due(100.0)  # nothing charged yet
    ledger.charge(5.0, 5.0, [Holder("frame", "vi1")], simulated=10.0)
    ledger.report(5.0, simulated=10.0)
    assert not ledger.due(9.0)
    ledger.charge(10.0, 5.0, [], simulated=10.0)
    assert ledger.due(10.0)
    assert ledger.report(10.0, simulated=110.0).endswith("(20.00x): 100% running")


def test_the_scan_hold_names_the_vi_robots_that_hold_the_clock() -> None:
    hold = ScanHold(limit=30.0)
    hold.starting(["vi1", "vi2"], wall=0.0, patience=2.0)
    assert hold.stopping(1.0) == ["vi1", "vi2"]  # before their first viewpoints
    hold.moved("vi1", until=12.0)
    hold.moved("vi2", until=30.0)
    assert hold.stopping(1.5) == []
    assert hold.at_ceiling(11.0) == []
    assert hold.at_ceiling(12.0) == ["vi1"]  # vi1's arrival, until its frame there is taken
    hold.hold(int(12.0e9), wall=3.0, robot="vi1", stop=True, period=1.0)
    assert hold.stopping(3.5) == ["vi1"]  # its frame is being judged
    assert hold.judged(int(12.0e9), "vi1", wall=4.0)
    assert hold.stopping(4.5) == []
    assert hold.at_ceiling(13.0) == ["vi1"]  # the frame a period on waits for the next snapshot
    assert hold.at_ceiling(12.5) == []
