"""The team file (config/team.yaml): what the launch files and the experiment both start."""

from __future__ import annotations

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
