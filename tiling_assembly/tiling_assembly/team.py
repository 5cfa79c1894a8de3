"""How the team starts (config/team.yaml): the one description the launch files and the experiment
runner both read.

A role is one computer of the team: the base station (planner and auction node, once), an
assembly robot (once per robot, in /robot1, /robot2, ...) and the scanning robot (/vi). Each role
lists its nodes, which run alike on real robots and in simulation, the hardware_drivers launch
file that drives its body, and what stands in for that body in simulation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import yaml

ROLES = ("base_station", "assembly_robot", "vi_robot")
NEEDS = ("structure_file", "robot_names")  # launch arguments a node may need


class TeamFileError(ValueError):
    """A team file that cannot be used; the message is one line naming the file and the problem."""


@dataclass(frozen=True)
class TeamNode:
    package: str
    executable: str
    parameters: tuple[str, ...] = ()  # parameter files of config/, in order
    needs: tuple[str, ...] = ()  # of NEEDS


@dataclass(frozen=True)
class TeamRole:
    name: str
    namespace: str  # "" (root), a name, or "{robot}" for each assembly robot's own
    nodes: tuple[TeamNode, ...]
    hardware: str = ""  # launch file of hardware_drivers driving the body
    simulated_by: tuple[TeamNode, ...] = ()

    def namespace_of(self, robot: str = "") -> str:
        """The role's namespace, with '/' (or '' for the root namespace)."""
        name = self.namespace.replace("{robot}", robot)
        return f"/{name}" if name else ""


def load_team(path: Path) -> dict[str, TeamRole]:
    """Every role of the team file at `path`."""
    try:
        document = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as error:
        raise TeamFileError(f"{path}: cannot read the team file ({error})".replace("\n", " ")) from None
    if not isinstance(document, dict) or set(document) != set(ROLES):
        raise TeamFileError(f"{path}: a team file has exactly the roles {', '.join(ROLES)}")
    return {name: _role(path, name, document[name]) for name in ROLES}


def _role(path: Path, name: str, entry: object) -> TeamRole:
    if not isinstance(entry, dict) or not isinstance(entry.get("nodes"), list) or not entry["nodes"]:
        raise TeamFileError(f"{path}: role {name} needs a list of nodes")
    return TeamRole(
        name=name,
        namespace=str(entry.get("namespace", "")),
        nodes=tuple(_node(path, name, n) for n in entry["nodes"]),
        hardware=str(entry.get("hardware", "")),
        simulated_by=tuple(_node(path, name, n) for n in entry.get("simulated_by", [])),
    )


def _node(path: Path, role: str, entry: object) -> TeamNode:
    if not isinstance(entry, dict) or not entry.get("package") or not entry.get("executable"):
        raise TeamFileError(f"{path}: every node of role {role} needs a package and an executable")
    needs = tuple(str(n) for n in entry.get("needs", []))
    unknown = [n for n in needs if n not in NEEDS]
    if unknown:
        raise TeamFileError(f"{path}: role {role} needs unknown launch arguments {unknown} (known: {NEEDS})")
    return TeamNode(
        package=str(entry["package"]),
        executable=str(entry["executable"]),
        parameters=tuple(str(p) for p in entry.get("parameters", [])),
        needs=needs,
    )
