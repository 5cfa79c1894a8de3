"""The accuracy and benchmark scripts and the bag replayer run as users run them."""

from __future__ import annotations

import re
from pathlib import Path

from vi_helpers import SCANS, ros2_run


def test_accuracy_script_prints_the_paper_style_tables(tmp_path: Path) -> None:
    png = tmp_path / "accuracy.png"
    result = ros2_run(
        "tiling_sim",
        "vi_accuracy",
        "--scenes",
        "2",
        "--views",
        "2",
        "--misplaced-scenes",
        "1",
        "--structures",
        "paper_14",
        "--conditions",
        "paper,robot_near",
        "--png",
        str(png),
    )
    assert result.returncode == 0, result.stderr
    out = result.stdout
    for title in (
        "mode default, single view",
        "mode default, fused over up to 2 views",
        "mode paper, single view",
        "mode paper, fused over up to 2 views",
        "misplaced tiles (default mode, single views)",
    ):
        assert title in out
    for condition in ("paper", "robot_near"):
        assert f"== condition {condition}:" in out
    assert len(re.findall(r"  all\s+\d+\s+\d+ \(", out)) == 8  # 4 tables per condition
    assert "paper (Worcester et al.)      22" in out
    assert re.search(r"alignment: \d+/\d+ scans aligned", out)
    assert re.search(r"present tiles flagged MISPLACED: +\d+", out)
    assert "6/6 scenes" in result.stderr  # progress over both conditions
    assert png.stat().st_size > 10_000


def test_accuracy_script_refuses_unknown_modes() -> None:
    result = ros2_run("tiling_sim", "vi_accuracy", "--modes", "magic")
    assert result.returncode == 2 and "unknown mode" in result.stderr and "Traceback" not in result.stderr


def test_benchmark_script_times_every_stage_next_to_plain_open3d() -> None:
    result = ros2_run("tiling_sim", "vi_benchmark", "--scans", "2", "--repeat", "1")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    for stage in ("floor", "candidates", "coarse", "icp", "raycast", "classify"):
        assert f" {stage} " in out
    assert re.search(r"plain Open3D\s+total\s+\d+\.\d", out)
    assert re.search(r"plain Open3D / paper: \d+\.\d\dx", out)
    assert re.search(r"plain Open3D / default: \d+\.\d\dx", out)
    assert " evidence " in out and " misplacement " in out


def test_replayer_refuses_what_it_cannot_play(tmp_path: Path) -> None:
    missing = ros2_run("tiling_sim", "replay_bag", "--bag", str(tmp_path / "nothing"))
    assert missing.returncode == 1 and "not a rosbag2 folder" in missing.stderr
    negative = ros2_run("tiling_sim", "replay_bag", "--bag", str(SCANS / "paper_qvga"), "--rate", "-1")
    assert negative.returncode == 2 and negative.stderr.count("\n") == 1
