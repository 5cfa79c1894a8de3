"""Parameters: config/vi_node.yaml holds the defaults, and bad values are refused in one line."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from vi_helpers import REPO

from vi_node.inspection_settings import InspectionSettings, SettingsError, load_settings


def test_config_file_holds_exactly_the_defaults() -> None:
    document = yaml.safe_load((REPO / "config" / "vi_node.yaml").read_text())
    values = document["/**"]["ros__parameters"]
    defaults = InspectionSettings()
    assert sorted(values) == sorted(InspectionSettings.names())
    for name, value in values.items():
        expected = getattr(defaults, name)
        if isinstance(expected, float):
            assert value == pytest.approx(expected), name
        else:
            assert value == expected, name
    assert load_settings(REPO / "config" / "vi_node.yaml") == defaults


@pytest.mark.parametrize(
    "values, message",
    [
        ({"mode": "clever"}, "parameter 'mode' must be one of"),
        ({"camera_xyz": [1.0, 2.0]}, "parameter 'camera_xyz' must be 3 finite numbers"),
        ({"intrinsics": [0.0, 580.0, 319.5, 239.5]}, "focal lengths"),
        ({"min_support": -1}, "parameter 'min_support' must not be negative"),
        ({"ratio_threshold": 1.5}, "between 0 and 1"),
        ({"expected_tiles": "1,x"}, "'x' is not a positive tile id"),
        ({"icp_max_iterations": 2.5}, "wrong type"),
        ({"coarse_search": "yes"}, "wrong type"),
        ({"no_such": 1}, "unknown parameter 'no_such'"),
    ],
)
def test_bad_values_are_named(values: dict, message: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(SettingsError, match=message):
        InspectionSettings().with_values(values)


def test_integers_are_accepted_for_floats() -> None:
    assert InspectionSettings().with_values({"max_range": 4}).max_range == 4.0


def test_parameter_files_in_the_node_format(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("/**:\n  ros__parameters:\n    min_support: 50\n    camera_rpy: [0.0, 0.5, 0.0]\n")
    settings = load_settings(path)
    assert settings.min_support == 50 and settings.camera_rpy == [0.0, 0.5, 0.0]
    path.write_text("/**:\n  ros__parameters: [1, 2]\n")
    with pytest.raises(SettingsError, match="needs a 'ros__parameters' mapping"):
        load_settings(path)
    path.write_text("{{{")
    with pytest.raises(SettingsError, match="not valid YAML"):
        load_settings(path)
    with pytest.raises(SettingsError, match="cannot read"):
        load_settings(tmp_path / "missing.yaml")
