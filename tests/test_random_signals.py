"""Every node executable stops cleanly at SIGINT or SIGTERM sent to its process alone, at a random
moment: while it imports and starts, while it waits (for a port, for /plan, for goals), in the middle
of its work (an inspection, a drive). That is what `ros2 launch` does at Ctrl-C; tools/signal_trials.py
reproduces it without launch (see its docstring; run it for a longer campaign).

A modest share of that campaign: two trials per scenario (one SIGINT, one SIGTERM), half of them
within the scenario's start-up, a quarter with the signal sent twice (Ctrl-C pressed twice, or
launch's SIGTERM while the node still stops), three at once. The seed changes per run and is in
the report, so a failure can be run again with `tools/signal_trials.py --seed N --trials 2
--max-delay 6 --startup-share 0.5 --twice-share 0.25 --only NAME`.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _load_harness():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("signal_trials", REPO / "tools" / "signal_trials.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["signal_trials"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


trials = _load_harness()


def test_every_node_executable_stops_cleanly_when_signalled_at_random_moments(tmp_path: Path) -> None:
    settings = trials.TrialSettings(trials=2, max_delay=6.0, startup_share=0.5, parallel=3, twice_share=0.25,
                                    seed=time.time_ns() % 1_000_000, log_dir=tmp_path)
    chosen = [s for s in trials.scenarios() if s.name != "experiment"]  # the team runner: the campaign's
    results = trials.run_campaign(settings, chosen, progress=lambda line: None)
    report = f"seed {settings.seed}\n{trials.table(results)}"
    print(report)
    assert {r.plan.scenario.name for r in results} == {s.name for s in chosen}
    assert not [r for r in results if r.outcome == "failed"], report


def test_a_signal_before_python_runs_our_code_is_told_apart_from_a_failure(tmp_path: Path) -> None:
    """The harness's "too early": only a failure whose process had no SIGTERM handler of its own yet
    (the interpreter and the script setuptools generates start in ~50-300 ms, before any code of
    ours can catch a signal). A signal sent at once lands there."""
    settings = trials.TrialSettings(trials=2, max_delay=0.0, parallel=2, seed=1, log_dir=tmp_path,
                                    only=("create_base (no device)",))
    chosen = trials.selected(trials.scenarios(), settings.only)
    results = trials.run_campaign(settings, chosen, progress=lambda line: None)
    assert [r.outcome for r in results] == ["too early", "too early"], trials.table(results)
