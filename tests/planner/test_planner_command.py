"""The `plan` command as a user runs it (a real process): the JSON contract, the paper's Table 1,
parameter files and bad input."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from conftest import DATA, REPO, STRUCTURES
from planner_checks import plan_problems

from planner_node.assembly_graph import build_graph
from planner_node.makespan_bound import makespan_lower_bound
from planner_node.parameters import PlannerParameters, read_parameter_file
from planner_node.plan_format import type_label
from tiling_assembly.structure_file import load_structure
from tiling_assembly.time_model import TimeModel

PAPER = STRUCTURES / "paper_14.yaml"
LEFT = {6, 9, 4, 11, 13}  # the paper's robot 1 (Table 1), on the -x side
RIGHT = {7, 8, 5, 10, 12, 14}  # the paper's robot 2, on the +x side
CENTRE = {1, 2, 3}  # the long rectangles of the base, under both octagons


def plan(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["ros2", "run", "planner_node", "plan", *args], cwd=REPO, capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize("method", ["paper", "default"])
def test_json_output_follows_the_contract(method: str) -> None:
    result = plan("--structure", str(PAPER), "--robots", "2", "--method", method)
    assert result.returncode == 0, result.stderr
    output = json.loads(result.stdout)
    structure = load_structure(PAPER)
    assert [r["id"] for r in output["robots"]] == [1, 2]
    assert sorted(t for r in output["robots"] for t in r["tiles"]) == sorted(structure.tiles)
    assert {int(k): tuple(v) for k, v in output["supports"].items()} == dict(structure.supports)
    assert output["makespan"] >= output["lower_bound"] > 0
    orders = {f"robot{r['id']}": r["tiles"] for r in output["robots"]}
    assert plan_problems(structure, orders, TimeModel()) == []
    # the paper's left/right split: each robot builds one side, the base's centre is shared
    robot1, robot2 = (set(r["tiles"]) for r in output["robots"])
    assert LEFT <= robot1 and RIGHT <= robot2
    assert robot1 | robot2 == LEFT | RIGHT | CENTRE
    assert 6 <= len(robot1) <= 8 and 6 <= len(robot2) <= 8


def test_table_reads_like_the_papers_table_1() -> None:
    table = plan("--structure", str(PAPER), "--robots", "2", "--method", "paper", "--format", "table")
    assert table.returncode == 0, table.stderr
    lines = table.stdout.splitlines()
    header = next(k for k, line in enumerate(lines) if line.startswith("Robot 1"))
    assert lines[header].split() == ["Robot", "1", "Tile", "ID", "Robot", "2", "Tile", "ID"]
    rows = []
    for line in lines[header + 2 :]:
        if not line.strip():
            break
        rows.append(line)
    as_json = json.loads(plan("--structure", str(PAPER), "--robots", "2", "--method", "paper").stdout)
    structure = load_structure(PAPER)
    for column, robot in enumerate(as_json["robots"]):
        assert len(rows) >= len(robot["tiles"])
        for row, tile in zip(rows, robot["tiles"], strict=False):
            cells = [c for c in row.split("  ") if c.strip()]
            name, tile_id = cells[2 * column].strip(), cells[2 * column + 1].strip()
            assert tile_id == str(tile)
            assert name == type_label(structure.tiles[tile].type_name)
        layers = [structure.layers[t] for t in robot["tiles"]]
        assert layers == sorted(layers)  # the paper's sequences go up layer by layer
    assert "Long Rectangle" in table.stdout and "Trapezoid" in table.stdout
    assert "Makespan" in table.stdout and "lower bound" in table.stdout


def test_parameter_file_sets_the_time_model(tmp_path: Path) -> None:
    slow = json.loads(plan("--structure", str(PAPER), "--robots", "2", "--params",
                           str(REPO / "config" / "planner_node.yaml")).stdout)
    fast_file = tmp_path / "fast.yaml"
    fast_file.write_text("/**:\n  ros__parameters:\n    travel_speed: 0.6\n    type_place_time:\n"
                         "      triangle: 30.0\n    colour: red\n")
    result = plan("--structure", str(PAPER), "--robots", "2", "--params", str(fast_file))
    assert result.returncode == 0, result.stderr
    assert "unknown parameter 'colour'" in result.stderr
    fast = json.loads(result.stdout)
    structure = load_structure(PAPER)
    expected = TimeModel(travel_speed=0.6, type_place_time={"triangle": 30.0}).for_team(structure, 2)
    total = sum(expected.tile_cost(structure, t) for t in structure.tiles)
    bound = makespan_lower_bound(build_graph(structure, expected), 2)
    assert fast["lower_bound"] == pytest.approx(bound.value, abs=1e-3)
    assert bound.work_per_robot == pytest.approx(total / 2)
    assert fast["lower_bound"] < slow["lower_bound"]
    big_file = tmp_path / "big.yaml"  # a bigger base stops further out round paper_14's tiles (nearer the caches)
    big_file.write_text("/**:\n  ros__parameters:\n    base_size: [0.6, 0.6]\n")
    big = json.loads(plan("--structure", str(PAPER), "--robots", "2", "--params", str(big_file)).stdout)
    assert abs(big["lower_bound"] - slow["lower_bound"]) > 1.0
    away_file = tmp_path / "away.yaml"  # both robots 2 m from every cache: the plan takes the drive
    away_file.write_text("/**:\n  ros__parameters:\n    robot_start_xy: [0.0, 3.0, 0.0, 3.0]\n")
    away = json.loads(plan("--structure", str(PAPER), "--robots", "2", "--params", str(away_file)).stdout)
    assert away["makespan"] > slow["makespan"] + 10.0


def test_config_file_holds_the_defaults() -> None:
    parameters, unknown = read_parameter_file(REPO / "config" / "planner_node.yaml")
    assert unknown == []
    assert parameters == PlannerParameters()
    assert parameters.time_model() == TimeModel()


@pytest.mark.parametrize(
    "text, message",
    [
        ("/**:\n  ros__parameters:\n    travel_speed: 0\n", "travel_speed"),
        ("/**:\n  ros__parameters:\n    method: fastest\n", "method"),
        ("/**:\n  ros__parameters:\n    robot_names: [a, b, c]\n", "robot_names"),
        ("/**:\n  ros__parameters:\n    base_size: [0.3]\n", "base_size"),
        ("/**:\n  ros__parameters:\n    base_size: [wide, long]\n", "base_size"),
        ("/**:\n  ros__parameters:\n    robot_start_xy: [0.0, 1.0, 2.0]\n", "robot_start_xy must be x, y pairs"),
        ("/**:\n  ros__parameters:\n    robot_start_xy: [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]\n",
         "3 start positions for 2 robots"),
        ("planner: {}\n", "ros__parameters"),
        ("[1, 2\n", "YAML"),
    ],
)
def test_bad_parameter_files_give_one_line_and_exit_2(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    result = plan("--structure", str(PAPER), "--robots", "2", "--params", str(path))
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0]


def test_invalid_structure_gives_the_structure_error_and_exit_2() -> None:
    bad = DATA / "structures" / "invalid" / "overlapping_tiles.yaml"
    result = plan("--structure", str(bad), "--robots", "2")
    assert result.returncode == 2
    assert result.stdout == ""
    assert result.stderr.strip().splitlines() == [
        f"error: {bad}: overlap [tiles 1, 2]: tiles 1 and 2 overlap by 10.0 mm"
    ]
    missing = plan("--structure", str(REPO / "no_such_file.yaml"), "--robots", "2")
    assert missing.returncode == 2 and "cannot read the file" in missing.stderr


def test_more_robots_than_tiles_leaves_some_robots_idle() -> None:
    result = plan("--structure", str(PAPER), "--robots", "20")
    assert result.returncode == 0, result.stderr
    robots = json.loads(result.stdout)["robots"]
    assert len(robots) == 20
    assert sorted(t for r in robots for t in r["tiles"]) == list(range(1, 15))
