"""Every setting of the visual inspection, with its default, description and validation.

One flat set: the node declares each field as a ROS parameter (same name, same description), the
offline `classify` command reads the same names from a `--params` file (the node's YAML format,
`/**: ros__parameters:`), and `config/vi_node.yaml` holds the defaults below (a test keeps the two
equal). Lengths in m, angles in rad, times in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from enum import StrEnum
from pathlib import Path
from typing import Any

import yaml

from tiling_ros.parameters import setting
from vi_node.evidence import EvidenceSettings
from vi_node.expected_returns import ReturnSettings
from vi_node.misplacement import MisplacementSettings
from vi_node.robot_mask import RobotMaskSettings


class InspectionMode(StrEnum):
    """How scans are classified; the values are those of the `mode` parameter."""

    DEFAULT = "default"  # pixel evidence, fusion, misplacement
    PAPER = "paper"  # the paper's section 2.2.3 rules


MODES = tuple(mode.value for mode in InspectionMode)
EVIDENCE = EvidenceSettings()
RETURNS = ReturnSettings()
ROBOTS = RobotMaskSettings()
MISPLACEMENT = MisplacementSettings()


class SettingsError(ValueError):
    """A setting with a bad value; the message names it."""


POSITIVE = (  # settings that must be > 0
    "pose_tolerance",
    "pose_near_enough",
    "robot_pose_tolerance",
    "in_hand_memory",
    "floor_stride",
    "icp_max_iterations",
    "alignment_hypotheses",
    "alignment_candidates",
    "seen_through_weight",
    "support_distance",
    "coarse_shift_range",
    "coarse_yaw_range",
    "max_pose_correction",
    "max_yaw_correction",
    "depth_sigmas",
    "misplacement_shift",
    "misplacement_yaw",
    "max_incidence",
    "icp_max_points",
    "misplacement_points",
    "sure_incidence",
    "blank_incidence",
)
NON_NEGATIVE = (  # ... >= 0
    "floor_clearance",
    "box_margin",
    "min_support",
    "min_alignment_points",
    "min_fit_points",
    "depth_margin",
    "min_observed_pixels",
    "robot_position_error",
    "robot_yaw_error",
    "robot_surface_gap",
    "robot_face_reach",
    "tall_margin",
)
FRACTIONS = (  # ... in [0, 1]
    "ratio_threshold",
    "min_alignment_inliers",
    "hidden_by_robots",
    "min_agreement",
    "ambiguity",
    "min_observed_fraction",
    "present_fraction",
    "present_share",
    "present_view_share",
    "missing_fraction",
)

@dataclass(frozen=True)
class InspectionSettings:
    mode: str = setting(
        "default",
        "classification: 'default' (pixel evidence, fusion, misplacement) or 'paper' (section 2.2.3 rules)",
    )
    structure_file: str = setting(
        "", "structure file used until /structure arrives (empty: wait for /structure)"
    )
    expected_tiles: str = setting(
        "all", "S_a until placement reports arrive: 'all' or comma-separated tile ids"
    )
    camera_xyz: list[float] = setting([0.08, 0.0, 0.55], "camera_link position in base_link (m)")  # noqa: RUF009 - a field() with a default_factory
    camera_rpy: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.0, 0.45, 0.0], "camera_link roll, pitch, yaw in base_link (rad, REP 103)"
    )
    intrinsics: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [580.0, 580.0, 319.5, 239.5], "depth camera fx, fy, cx, cy (px) at intrinsics_size"
    )
    intrinsics_size: list[int] = setting(  # noqa: RUF009 - a field() with a default_factory
        [640, 480], "image width, height (px) the intrinsics are given for; other resolutions are scaled"
    )
    min_range: float = setting(RETURNS.min_range, "nearest depth the camera measures (m)")
    max_range: float = setting(RETURNS.max_range, "farthest depth the camera measures (m)")
    projector_offset: float = setting(
        RETURNS.projector_offset, "default: IR projector along the depth camera's x axis (m, + right)"
    )
    sure_incidence: float = setting(
        RETURNS.sure_incidence, "default: the camera surely returns from faces seen less obliquely (rad) ..."
    )
    blank_incidence: float = setting(
        RETURNS.blank_incidence, "default: ... and surely not from faces seen more obliquely (rad)"
    )
    sensor_reliability: str = setting(
        "auto",
        "clouds and overhead poses read 'reliable', 'best_effort' or 'auto' "
        "(reliable when every publisher offers it)",
    )
    pose_tolerance: float = setting(0.1, "largest time between a scan and the overhead pose used for it (s)")
    pose_near_enough: float = setting(
        0.02, "an overhead pose this near the scan's time is used at once, without waiting for a nearer one (s)"
    )
    other_robots: str = setting(
        "", "default: robots whose overhead_pose to follow, comma-separated (empty: every one that appears)"
    )
    robot_pose_tolerance: float = setting(
        0.5, "default: largest time between a scan and another robot's overhead pose used for it; a scan waits "
        "up to this long (wall clock) for the poses of its moment (s)"
    )
    in_hand_memory: float = setting(
        15.0, "a tile a robot was placing this recently before a scan (/robot_status) may lie there unreported: "
        "expected, not judged (s)"
    )
    floor_stride: int = setting(6, "floor fit uses every n-th row and column of the cloud")
    floor_clearance: float = setting(0.01, "points lower than this above the floor are floor (m)")
    box_margin: float = setting(0.03, "candidates lie within this of S_a's bounding box (m)")
    coarse_search: bool = setting(
        True, "search x, y, yaw before ICP (the overhead errors are too large for ICP alone)"
    )
    coarse_yaw_range: float = setting(0.21, "coarse search +- this about the overhead yaw (rad)")
    coarse_shift_range: float = setting(0.10, "coarse search +- this in x and y (m)")
    icp_max_iterations: int = setting(10, "ICP iterations at most (the paper: 10)")
    alignment_hypotheses: int = setting(
        3, "default: best x/y/yaw hypotheses of the coarse search refined before the best fit is kept ..."
    )
    alignment_candidates: int = setting(
        16, "default: x/y/yaw hypotheses of the coarse search ranked by how well the depth image bears them out"
    )
    seen_through_weight: float = setting(
        1.0, "default: a pixel measured behind S_a's surface costs a pose this many agreeing pixels"
    )
    ambiguity: float = setting(
        0.95, "default: ... unless another fit, 3 cm or 2 deg away, puts this share as many points on S_a or "
        "explains the depth image nearly as well"
    )
    min_fit_points: int = setting(
        25, "default: the best fit must put this many of its (at most icp_max_points) points on S_a"
    )
    min_alignment_points: int = setting(60, "a scan with fewer aligned candidates is not classified")
    min_alignment_inliers: float = setting(0.6, "fraction of candidates that must lie on S_a after ICP")
    hidden_by_robots: float = setting(
        0.9, "default: a scan that fails to align while the other robots stand in front of this share of S_a "
        "says S_a is not in view"
    )
    min_agreement: float = setting(0.35, "a scan agreeing with less of what S_a predicts is not classified")
    max_pose_correction: float = setting(
        0.09, "largest believable correction of the overhead camera position (m): 5 cm + lever arms"
    )
    max_yaw_correction: float = setting(0.35, "largest believable correction of the overhead yaw (rad)")
    min_support: int = setting(100, "paper: support below this many points counts as 0")
    ratio_threshold: float = setting(0.7, "paper: missing when min(p/v, v/p) <= this")
    support_distance: float = setting(
        0.015, "paper: a candidate supports the tile it projects onto within this (m)"
    )
    icp_max_points: int = setting(
        1500, "default: ICP on at most this many candidates (paper mode: all of them)"
    )
    depth_sigmas: float = setting(
        EVIDENCE.depth_sigmas, "default: measured and virtual depth agree within this many noise sigmas ..."
    )
    depth_margin: float = setting(
        EVIDENCE.depth_margin, "default: ... plus this (m, model and pose error), more on oblique faces"
    )
    max_incidence: float = setting(
        EVIDENCE.max_incidence, "default: pixels seeing a face more obliquely are not judged (rad)"
    )
    min_observed_pixels: int = setting(
        EVIDENCE.min_observed_pixels, "default: a tile needs this many decisive pixels ..."
    )
    min_observed_fraction: float = setting(
        EVIDENCE.min_observed_fraction, "default: ... and this share of the pixels it should fill"
    )
    present_fraction: float = setting(
        EVIDENCE.present_fraction, "default: present when this share of the decisive pixels agree ..."
    )
    present_share: float = setting(
        EVIDENCE.present_share, "default: ... and they are this share of all pixels that saw its place"
    )
    present_view_share: float = setting(
        EVIDENCE.present_view_share, "default: ... and this share of all its pixels the view would judge were no "
        "robot in the way"
    )
    missing_fraction: float = setting(
        EVIDENCE.missing_fraction, "default: missing when this share of the decisive pixels are against it"
    )
    robot_size: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        list(ROBOTS.size), "default: other robots' box, x and y along the base and height (m)"
    )
    robot_position_error: float = setting(
        ROBOTS.position_error, "default: overhead localization error of the other robots (m) ..."
    )
    robot_yaw_error: float = setting(ROBOTS.yaw_error, "default: ... and of their heading (rad)")
    robot_surface_gap: float = setting(
        0.02, "default: points inside a robot's box but this close to S_a's surfaces (m) are kept ..."
    )
    robot_face_reach: float = setting(
        0.03, "default: ... and judged, unless a point of the robot (off S_a's surfaces) lies this close (m)"
    )
    tall_margin: float = setting(
        ROBOTS.tall_margin, "default: points this far above the structure's top belong to something else (m)"
    )
    fuse_scans: bool = setting(
        True, "publish states fused over the scans of the same S_a (default mode: evidence)"
    )
    misplacement_shift: float = setting(
        MISPLACEMENT.shift, "default: flag a tile whose points say it moved this far (m) ..."
    )
    misplacement_yaw: float = setting(MISPLACEMENT.turn, "default: ... or turned this much (rad)")
    misplacement_points: int = setting(8000, "default: judge placement on at most this many candidates")

    @property
    def inspection_mode(self) -> InspectionMode:
        """The `mode` parameter as an InspectionMode (raises ValueError on an unknown one)."""
        return InspectionMode(self.mode)

    @property
    def paper_rules(self) -> bool:
        """Whether scans are classified and fused by the paper's rules (paper mode)."""
        return self.inspection_mode is InspectionMode.PAPER

    def evidence(self) -> EvidenceSettings:
        """The settings of the per-pixel evidence (`evidence`, `expected_returns`)."""
        return EvidenceSettings(
            depth_sigmas=self.depth_sigmas,
            depth_margin=self.depth_margin,
            max_incidence=self.max_incidence,
            min_observed_pixels=self.min_observed_pixels,
            min_observed_fraction=self.min_observed_fraction,
            present_fraction=self.present_fraction,
            present_share=self.present_share,
            present_view_share=self.present_view_share,
            missing_fraction=self.missing_fraction,
            returns=ReturnSettings(
                min_range=self.min_range,
                max_range=self.max_range,
                sure_incidence=self.sure_incidence,
                blank_incidence=self.blank_incidence,
                projector_offset=self.projector_offset,
            ),
        )

    def misplacement(self) -> MisplacementSettings:
        return replace(MISPLACEMENT, shift=self.misplacement_shift, turn=self.misplacement_yaw)

    def robot_mask(self) -> RobotMaskSettings:
        return replace(
            ROBOTS,
            size=tuple(self.robot_size),  # type: ignore[arg-type]
            position_error=self.robot_position_error,
            yaw_error=self.robot_yaw_error,
            tall_margin=self.tall_margin,
        )

    @staticmethod
    def description(name: str) -> str:
        return next(f.metadata["description"] for f in fields(InspectionSettings) if f.name == name)

    @staticmethod
    def names() -> list[str]:
        return [f.name for f in fields(InspectionSettings)]

    def with_values(self, values: dict[str, Any], source: str = "settings") -> InspectionSettings:
        """A copy with `values` applied and checked (raises SettingsError naming the bad one)."""
        known = {f.name: f for f in fields(InspectionSettings)}
        changes: dict[str, Any] = {}
        for name, value in values.items():
            if name not in known:
                raise SettingsError(f"{source}: unknown parameter '{name}'")
            default = getattr(self, name)
            changes[name] = _coerce(name, value, default, source)
        settings = replace(self, **changes)
        settings.validate(source)
        return settings

    def validate(self, source: str = "settings") -> None:
        def bad(name: str, why: str) -> SettingsError:
            return SettingsError(f"{source}: parameter '{name}' {why} (got {getattr(self, name)!r})")

        if self.mode not in MODES:
            raise bad("mode", f"must be one of {', '.join(MODES)}")
        if self.sensor_reliability not in ("auto", "reliable", "best_effort"):
            raise bad("sensor_reliability", "must be auto, reliable or best_effort")
        for name, length in (("camera_xyz", 3), ("camera_rpy", 3), ("intrinsics", 4), ("intrinsics_size", 2)):
            value = getattr(self, name)
            if len(value) != length or not all(math.isfinite(float(v)) for v in value):
                raise bad(name, f"must be {length} finite numbers")
        if min(self.intrinsics[:2]) <= 0 or min(self.intrinsics_size) <= 0:
            raise bad("intrinsics", "focal lengths and image size must be positive")
        if not 0 < self.min_range < self.max_range:
            raise bad("max_range", "must exceed min_range > 0")
        if not self.sure_incidence <= self.blank_incidence < math.pi / 2:
            raise bad("blank_incidence", "must lie between sure_incidence and pi/2")
        if len(self.robot_size) != 3 or not all(v > 0 for v in self.robot_size):
            raise bad("robot_size", "must be 3 positive numbers")
        if self.expected_tiles.strip().lower() != "all":
            try:
                parse_tile_ids(self.expected_tiles)
            except ValueError as error:
                raise bad("expected_tiles", str(error)) from None
        for name in POSITIVE:
            if not getattr(self, name) > 0:
                raise bad(name, "must be positive")
        for name in NON_NEGATIVE:
            if not getattr(self, name) >= 0:
                raise bad(name, "must not be negative")
        for name in FRACTIONS:
            if not 0 <= getattr(self, name) <= 1:
                raise bad(name, "must be between 0 and 1")


def _coerce(name: str, value: Any, default: Any, source: str) -> Any:
    try:
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise TypeError
            return value
        if isinstance(default, int):
            if isinstance(value, bool) or int(value) != value:
                raise TypeError
            return int(value)
        if isinstance(default, float):
            if isinstance(value, bool):
                raise TypeError
            number = float(value)
            if not math.isfinite(number):
                raise TypeError
            return number
        if isinstance(default, str):
            if not isinstance(value, str):
                raise TypeError
            return value
        if isinstance(default, list):
            kind = int if default and isinstance(default[0], int) else float
            if isinstance(value, str | bytes) or any(isinstance(v, bool) for v in value):
                raise TypeError
            return [kind(v) for v in value]
    except (TypeError, ValueError):
        pass
    raise SettingsError(
        f"{source}: parameter '{name}' has the wrong type (got {value!r}, expected like {default!r})"
    )


def parse_tile_ids(text: str) -> list[int]:
    """'3,5, 7' -> [3, 5, 7]; raises ValueError with a reason."""
    ids = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        if not part.isdigit() or int(part) <= 0:
            raise ValueError(f"'{part}' is not a positive tile id")
        ids.append(int(part))
    if not ids:
        raise ValueError("no tile ids given")
    return ids


def load_settings(path: str | Path, base: InspectionSettings | None = None) -> InspectionSettings:
    """Settings from a ROS parameter file (`/**:` or `vi_node:` -> `ros__parameters:`).

    Raises SettingsError with one line naming the file and the problem.
    """
    source = str(path)
    try:
        document = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as error:
        raise SettingsError(f"{source}: cannot read: {error.strerror or error}") from None
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        raise SettingsError(f"{source}: not valid YAML: {str(error).splitlines()[0]}") from None
    if not isinstance(document, dict):
        raise SettingsError(f"{source}: expected a mapping of node names to 'ros__parameters'")
    values: dict[str, Any] = {}
    for node, entry in document.items():
        if node not in ("/**", "vi_node", "/vi_node", "/vi/vi_node", "**"):
            continue
        if not isinstance(entry, dict) or not isinstance(entry.get("ros__parameters"), dict):
            raise SettingsError(f"{source}: '{node}' needs a 'ros__parameters' mapping")
        values.update(entry["ros__parameters"])
    return (base or InspectionSettings()).with_values(values, source)
