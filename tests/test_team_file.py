"""The team file (config/team.yaml): what the launch files and the experiment both start."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from tiling_assembly.team import TeamFileError, load_team

REPO = Path(__file__).resolve().parents[1]


def test_the_team_file_names_installed_executables_and_existing_parameter_files() -> None:
    team = load_team(REPO / "config" / "team.yaml")
    assert team["assembly_robot"].namespace_of("robot2") == "/robot2"
    assert team["vi_robot"].namespace_of() == "/vi" and team["base_station"].namespace_of() == ""
    for role in team.values():
        for node in (*role.nodes, *role.simulated_by):
            lib = REPO / "install" / node.package / "lib" / node.package
            assert (lib / node.executable).exists(), f"{node.package} installs no {node.executable}"
            for name in node.parameters:
                assert (REPO / "config" / name).is_file(), name
        if role.hardware:
            assert (REPO / "hardware_drivers" / "launch" / role.hardware).is_file()


@pytest.mark.parametrize(("text", "problem"), [
    ("base_station: {nodes: []}", "exactly the roles"),
    ("[1, 2]", "exactly the roles"),
    ("base_station: {nodes: [{package: a}]}\nassembly_robot: {nodes: [{package: a, executable: b}]}\n"
     "vi_robot: {nodes: [{package: a, executable: b}]}", "needs a package and an executable"),
    ("base_station: {nodes: [{package: a, executable: b, needs: [speed]}]}\n"
     "assembly_robot: {nodes: [{package: a, executable: b}]}\nvi_robot: {nodes: [{package: a, executable: b}]}",
     "unknown launch arguments"),
    ("base_station: [", "cannot read"),
])
def test_a_bad_team_file_gets_one_line_naming_the_problem(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "team.yaml"
    path.write_text(text)
    with pytest.raises(TeamFileError, match=problem) as error:
        load_team(path)
    assert "\n" not in str(error.value) and str(path) in str(error.value)


LAUNCH_ROLES = {"auction_node/launch/team.launch.py": "base_station",
                "assembly_node/launch/assembly_robot.launch.py": "assembly_robot",
                "vi_node/launch/inspection.launch.py": "vi_robot"}


@pytest.mark.parametrize(("path", "role"), LAUNCH_ROLES.items())
def test_each_launch_file_starts_its_role_of_the_team_file(path: str, role: str) -> None:
    text = (REPO / path).read_text()
    assert f'installed_team()["{role}"]' in text and "role_nodes(" in text
    assert "Node(" not in text, "a node started beside the team file"
    if load_team(REPO / "config" / "team.yaml")[role].hardware:
        assert "role.hardware" in text


def test_the_experiment_starts_every_node_of_the_team_file_as_the_launch_files_do(tmp_path: Path) -> None:
    from tiling_sim.experiment import Experiment, ExperimentConfig, TrialSetup

    config = ExperimentConfig(structure_file=REPO / "config/structures/paper_14.yaml", robots=3,
                              config_dir=REPO / "config")
    commands = Experiment(config).node_commands(TrialSetup(1, 1, 0, False))
    started = set()
    for argv in commands.values():
        namespace = next((a.removeprefix("__ns:=") for a in argv if a.startswith("__ns:=")), "")
        files = tuple(Path(a).name for k, a in itertools.pairwise(argv) if k == "--params-file")
        started.add((namespace, Path(argv[0]).parent.name, Path(argv[0]).name, files))
    team = load_team(REPO / "config" / "team.yaml")
    expected = {("", "tiling_sim", "sim_world", ("tiling_sim.yaml",))}
    for role in team.values():
        robots = config.robot_names if role.name == "assembly_robot" else [""]
        for robot in robots:
            for node in (*role.nodes, *role.simulated_by):
                expected.add((role.namespace_of(robot), node.package, node.executable, node.parameters))
    assert started == expected


def test_a_config_folder_without_a_team_file_uses_the_installed_one(tmp_path: Path) -> None:
    from tiling_sim.experiment import team_file

    assert team_file(tmp_path) == REPO / "install/tiling_assembly/share/tiling_assembly/config/team.yaml"
    (tmp_path / "team.yaml").write_text("")
    assert team_file(tmp_path) == tmp_path / "team.yaml"


def test_recording_scans_asks_each_vi_robots_camera_for_a_bag_in_the_trials_logs(tmp_path: Path) -> None:
    from tiling_sim.experiment import Experiment, ExperimentConfig, TrialSetup, parse_args

    config = parse_args(["--structure", str(REPO / "config/structures/paper_14.yaml"), "--vi-robots", "2",
                         "--record-scans", "--report", str(tmp_path / "report"), "--config", str(REPO / "config")])
    assert isinstance(config, ExperimentConfig) and config.record_scans
    commands = Experiment(config).node_commands(TrialSetup(3, 1, 0, False))
    bags = {name: a.removeprefix("record_scans:=") for name, argv in commands.items() for a in argv
            if a.startswith("record_scans:=")}
    logs = tmp_path / "report" / "logs" / "trial_03"
    assert bags == {"vi1_body": str(logs / "vi1_body_scans"), "vi2_body": str(logs / "vi2_body_scans")}


def test_a_trial_may_be_given_its_own_wall_clock_limit(tmp_path: Path) -> None:
    from tiling_sim.experiment import Experiment, parse_args

    common = ["--structure", str(REPO / "config/structures/paper_14.yaml"), "--report", str(tmp_path),
              "--config", str(REPO / "config")]
    derived = Experiment(parse_args(common)).wall_limit
    assert derived > 0
    assert Experiment(parse_args([*common, "--wall-limit", "5400"])).wall_limit == 5400.0
    with pytest.raises(SystemExit):
        parse_args([*common, "--wall-limit", "-1"])


@pytest.mark.parametrize("robots, expected", [
    (2, [-0.6, -0.9, 0.6, -0.9]),  # config/tiling_sim.yaml's, which fit two robots
    (3, None),  # spread round the structure, as the simulated world spreads them
])
def test_the_planner_is_told_where_the_simulated_robots_start(tmp_path: Path, robots: int, expected: list | None
                                                              ) -> None:
    from tiling_assembly.structure_file import load_structure
    from tiling_sim.experiment import Experiment, TrialSetup, parse_args
    from tiling_sim.sim_settings import RobotBodySettings

    structure = REPO / "config/structures/paper_14.yaml"
    config = parse_args(["--structure", str(structure), "--robots", str(robots), "--report", str(tmp_path),
                         "--config", str(REPO / "config")])
    commands = Experiment(config).node_commands(TrialSetup(1, 1, 0, False))
    (given,) = [a.removeprefix("robot_start_xy:=") for a in commands["planner_node"] if a.startswith("robot_start_xy")]
    xy = [float(v) for v in given.strip("[]").split(",")]
    if expected is None:
        names = [f"robot{k}" for k in range(1, robots + 1)]
        spread = RobotBodySettings(robot_names=names, robot_start_xy=[0.0]).robot_starts(load_structure(structure))
        expected = [v for name in names for v in spread[name]]
    assert xy == pytest.approx(expected, abs=1e-4)
