"""Import Open3D without the web stack of its plotly viewer.

`import open3d` always imports `open3d.visualization.draw_plotly`, which imports plotly and dash
(with flask, werkzeug and more: ~160 MB the project never uses). The workspace installs Open3D
without them; this module puts a stand-in for that one viewer module in place first, whose
functions raise a clear error if anyone calls them, and then imports Open3D. Where plotly and
dash are installed, Open3D is imported untouched.
"""

from __future__ import annotations

import importlib.util
import sys
import types
from typing import Any, NoReturn

from tiling_assembly.interrupts import postponed_signals

_VIEWER = "open3d.visualization.draw_plotly"


def _viewer_unavailable(*_args: Any, **_kwargs: Any) -> NoReturn:
    raise RuntimeError(
        "Open3D's plotly viewer needs plotly and dash, which this workspace does not install"
    )


def import_open3d() -> types.ModuleType:
    """The `open3d` module, importable without plotly and dash."""
    if "open3d" in sys.modules:
        return sys.modules["open3d"]
    if _VIEWER not in sys.modules and not all(
        importlib.util.find_spec(name) for name in ("plotly", "dash")
    ):
        viewer = types.ModuleType(_VIEWER, "Open3D's plotly viewer (not installed)")
        for name in ("get_plotly_fig", "draw_plotly", "draw_plotly_server"):
            setattr(viewer, name, _viewer_unavailable)
        sys.modules[_VIEWER] = viewer
    with postponed_signals():  # interrupted, Open3D's import makes the process exit 1 at its end
        import open3d

    return open3d
