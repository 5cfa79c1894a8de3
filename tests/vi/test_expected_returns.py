"""Where the camera would return with a tile there and with it gone, ray traced through S_a."""

from __future__ import annotations

import math

import numpy as np
from vi_helpers import structure

from tiling_sim.kinect import camera_pose
from vi_node.camera_model import PinholeCamera
from vi_node.expected_returns import ReturnSettings, expect_returns
from vi_node.raycast import FLOOR, VirtualScene

CAMERA = PinholeCamera(580.0, 580.0, 319.5, 239.5, 640, 480)


def low_view(bearing_deg: float, distance: float) -> np.ndarray:
    """A camera 0.28 m high, 0.2 rad down, looking at the paper structure's centre."""
    bearing = math.radians(bearing_deg)
    x, y = distance * math.cos(bearing), distance * math.sin(bearing)
    return camera_pose(x, y, bearing + math.pi, (0.0, 0.0, 0.28), (0.0, 0.2, 0.0))


def test_behind_a_top_tile_lies_its_support_or_the_floor_and_grazing_surfaces_return_nothing() -> None:
    paper = structure()
    scene = VirtualScene(list(paper.tiles.values()))
    pose = low_view(-90.0, 1.0)
    rows, cols = CAMERA.box_roi(pose, *paper.bounds)
    virtual = scene.look_behind(scene.cast(CAMERA, pose, rows, cols, 0.5, 4.5), CAMERA, pose)
    assert virtual.behind is not None
    expected = expect_returns(virtual, scene, CAMERA, pose, ReturnSettings())
    index = {int(t): k for k, t in enumerate(scene.tile_ids)}
    triangle = virtual.tile == index[13]  # on long rectangle 11, on the top layer
    assert triangle.sum() > 50
    # with the triangle gone the camera sees its support, the floor, or nothing: never itself
    behind = set(np.unique(virtual.behind.tile[triangle]).tolist())
    assert index[13] not in behind and behind <= {index[11], index[4], index[9], FLOOR, -2}
    assert np.all(virtual.behind.depth[triangle] > virtual.depth[triangle])
    # its upright faces return surely; the tops behind it, seen this low, are grazing: blank
    assert expected.present_returns[triangle].mean() > 0.3
    assert expected.absent_blank[triangle & expected.present_returns].mean() > 0.3
    # off the tiles, taking "that pixel's tile" away changes nothing
    floor = virtual.tile == FLOOR
    assert np.array_equal(expected.absent_returns[floor], expected.present_returns[floor])


def test_the_projector_shadow_of_a_tile_is_a_sure_blank() -> None:
    """Seen from the side, the projector (7.5 cm right of the camera) cannot light the floor just
    left of a tall block; with the block gone it could."""
    gate = structure("gate_9")
    scene = VirtualScene(list(gate.tiles.values()))
    pose = camera_pose(0.0, -0.9, math.pi / 2, (0.0, 0.0, 0.55), (0.0, 0.45, 0.0))
    rows, cols = CAMERA.box_roi(pose, *gate.bounds)
    virtual = scene.look_behind(scene.cast(CAMERA, pose, rows, cols, 0.5, 4.5), CAMERA, pose)
    lit = expect_returns(virtual, scene, CAMERA, pose, ReturnSettings(projector_offset=0.075))
    unlit = expect_returns(virtual, scene, CAMERA, pose, ReturnSettings(projector_offset=0.0))
    floor = virtual.tile == FLOOR
    shadow = floor & lit.present_blank & unlit.present_returns
    assert shadow.sum() > 20  # floor pixels in some block's shadow
    # a shadow lies left of what casts it (smaller columns), as the projector sits to the right
    casting = np.argwhere(shadow)
    for row, col in casting[:: max(1, len(casting) // 10)]:
        assert np.any(virtual.tile[row, col:] >= 0)
