"""A node's parameters from one frozen settings dataclass: its fields' defaults and descriptions.

Every node keeps its defaults in one place, a frozen dataclass whose fields are made with
`setting(default, description)`, and declares every field as a ROS parameter of the same name with
that description (`declare_settings`). The parameter files in config/ document the same names
(tests/test_parameter_files.py keeps them and the dataclasses in step).

Typing: by default a parameter takes the type of its default and ROS refuses a value of another
type; `dynamic_typing=True` accepts any type and leaves the checking to the settings class (its own
`from_values` or `with_values`). Defining settings (`setting`) needs no ROS: a ROS-free module
(the planner's file reader, the simulator's settings) may hold them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from rclpy.node import Node

SettingsT = TypeVar("SettingsT")

DESCRIPTION = "description"  # the metadata key of a field's description


def setting(default: Any, description: str) -> Any:
    """A settings dataclass field: its default (a list or dict is copied for every instance) and description."""
    if isinstance(default, list | dict):
        kind, items = type(default), default.copy()
        return dataclasses.field(default_factory=lambda: kind(items), metadata={DESCRIPTION: description})
    return dataclasses.field(default=default, metadata={DESCRIPTION: description})


def setting_names(settings_class: type) -> list[str]:
    """The names of a settings dataclass's parameters, in declaration order."""
    return [f.name for f in dataclasses.fields(settings_class)]


def setting_description(settings_class: type, name: str) -> str:
    """The description of one field of a settings dataclass."""
    for f in dataclasses.fields(settings_class):
        if f.name == name:
            return str(f.metadata[DESCRIPTION])
    raise KeyError(f"{settings_class.__name__} has no setting '{name}'")


def declare_parameter(node: Node, name: str, default: Any, description: str, *,
                      dynamic_typing: bool = False) -> Any:
    """Declare one parameter with its description and return its value (for parameters whose
    names depend on other parameters, such as one per tile type)."""
    from rcl_interfaces.msg import ParameterDescriptor

    descriptor = ParameterDescriptor(description=description, dynamic_typing=dynamic_typing)
    return node.declare_parameter(name, default, descriptor).value


def declare_values(node: Node, defaults: Any, *, names: Iterable[str] | None = None,
                   dynamic_typing: bool = False) -> dict[str, Any]:
    """Declare the fields of a settings instance (all, or those in `names`, in field order) as
    parameters with its values as defaults and its descriptions; their values by name."""
    wanted = None if names is None else set(names)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(defaults):
        if wanted is not None and f.name not in wanted:
            continue
        values[f.name] = declare_parameter(node, f.name, getattr(defaults, f.name), str(f.metadata[DESCRIPTION]),
                                           dynamic_typing=dynamic_typing)
    return values


def declare_settings(node: Node, settings_class: type[SettingsT], *, defaults: SettingsT | None = None,
                     dynamic_typing: bool = False,
                     build: Callable[[Mapping[str, Any]], SettingsT] | None = None) -> SettingsT:
    """Declare every field of `settings_class` as a parameter of `node` and return the settings.

    `defaults` replaces the class's own defaults (a default that depends on another parameter);
    `build` makes the settings from the values by name (a class that checks them); without it the
    values replace the defaults' as they are.
    """
    base = defaults if defaults is not None else settings_class()
    values = declare_values(node, base, dynamic_typing=dynamic_typing)
    if build is not None:
        return build(values)
    return dataclasses.replace(base, **values)
