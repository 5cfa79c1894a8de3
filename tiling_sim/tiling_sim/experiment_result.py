"""What an experiment was asked to do (`ExperimentConfig`, from `experiment`'s command line) and
what it gave (`ExperimentResult`): the data the runner (`experiment`) fills and the report
(`report`) reads, apart from both so that neither imports the other."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel
from tiling_sim.network_plan import NetworkSettings
from tiling_sim.sim_settings import VI_ROBOT
from tiling_sim.trial_record import TrialRecord


@dataclass
class ExperimentConfig:
    """What `experiment` runs; its defaults are the command line's."""

    structure_file: Path = Path("config/structures/paper_14.yaml")
    robots: int = 2
    trials: int = 14
    removals: int = 22
    misplacements: int = 0  # placements landing shifted or turned, over all trials
    wrong_tiles: int = 0  # placements of a tile of the wrong type, over all trials
    seed: int = 1
    real_time_factor: float = 20.0
    report_dir: Path = Path("reports/paper_14")
    config_dir: Path = Path("config")
    baseline: bool = True
    drop_probability: float = 0.0
    kill_robot: str = ""  # robot to kill mid-run (tests and demonstrations)
    kill_after_placements: int = 3
    silent_robot: str = ""  # robot that never bids (tests)
    robots_find_missing: bool = True  # False: only inspection finds missing tiles (the paper)
    wall_limit: float = 0.0  # s per trial; 0: derived from the structure
    quiet: bool = False
    inspection: bool = True  # run the VI robots' nodes (inspection and exploration)
    vi_robots: int = 1  # scanning robots
    record_scans: bool = False  # every VI robot's Kinect frames to a rosbag2 in the trial's logs
    network: NetworkSettings = field(default_factory=NetworkSettings)  # one host, or a host per computer

    @property
    def robot_names(self) -> list[str]:
        return [f"robot{k + 1}" for k in range(self.robots)]

    @property
    def vi_robot_names(self) -> list[str]:
        """/vi for one VI robot (as always), /vi1, /vi2, ... for several."""
        return [VI_ROBOT] if self.vi_robots == 1 else [f"{VI_ROBOT}{k + 1}" for k in range(self.vi_robots)]



@dataclass
class ExperimentResult:
    config: ExperimentConfig
    structure: Structure
    records: list[TrialRecord] = field(default_factory=list)
    link_counters: dict[str, dict[str, int]] = field(default_factory=dict)  # robot -> its link's counters
    robot_starts: dict[str, tuple[float, float]] = field(default_factory=dict)  # where each robot stood at the start
    interrupted: bool = False  # stopped by Ctrl-C or SIGTERM: `records` holds the trials finished before

    def fault_trials(self) -> list[TrialRecord]:
        return [r for r in self.records if r.trial > 0]

    def time_model(self) -> TimeModel:
        """The planner's default time model for this team on this structure (crowding at the caches)."""
        return TimeModel().for_team(self.structure, self.config.robots)
