"""sim_robot: one simulated assembly robot's body, on board the robot (run in its namespace, /robotK).

Serves the robot's `place_tile` action as the real M3 robot does: drives to the parts cache of the
tile's type, finds and picks the tile, drives to the structure, places the tile and backs off, with
the phases and durations of `robot_motion.placement_phases` (`config/tiling_sim.yaml`), sleeping
on simulated time (`/clock`). The physics is the world's (`sim_world`): at the start of each phase
the body tells the world where its base will stand when the phase ends (`/sim/motion`), and it asks
the world before it sets out, when the picking ends (did the tile slip?) and when the placing ends
(is the tile now in place, or which support is absent?) over `/sim/place`. It serves `remove_tile`
as well (a repair: drive to the tile, lift it off, carry it to the drop-off), asking the world when
it sets out and when the lifting ends (is the tile there, with nothing resting on it?). Before each
drive to a stop it asks the world for room there (`standing_room`): where another robot stands, it
stops beside the cache or round the tile, or waits until the other has gone. It serves `navigate_to`
too: its robot driving home with nothing left to place (a straight drive at the motion model's
speed; where another robot stands there, it stops beside it).

One goal at a time, of any of the three actions (the robot has one arm): a second is refused. A goal the world
does not answer fails (FAILED_HARDWARE).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any

from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.task import Future
from rclpy.timer import Timer

from tiling_assembly.polygons import convex_hull_2d
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.action import NavigateTo, PlaceTile, RemoveTile
from tiling_assembly_msgs.msg import SimMotion
from tiling_assembly_msgs.srv import SimPlace
from tiling_ros.parameters import declare_settings
from tiling_ros.qos import SIM_MOTION
from tiling_ros.spinning import run_node
from tiling_ros.stamps import stamp_from_seconds, stamp_to_seconds
from tiling_sim import sim_interface as sim
from tiling_sim.robot_motion import (
    Phase,
    Point2,
    Polygon,
    approach_point,
    drive_phase,
    placement_phases,
    removal_phases,
)
from tiling_sim.sim_settings import RobotBodySettings
from tiling_sim.standing_room import alternative_spot

Result = PlaceTile.Result
Removal = RemoveTile.Result
ASK_AGAIN_PAUSE = 0.02  # s of wall time before asking the world for room again (see standing_room)


class SimRobot(Node):
    def __init__(self) -> None:
        super().__init__("sim_robot")
        self.settings: RobotBodySettings = declare_settings(
            self, RobotBodySettings, dynamic_typing=True, build=RobotBodySettings.from_values
        )
        self.name = self.get_namespace().strip("/")
        if self.name not in self.settings.team:
            raise ValueError(f"sim_robot runs in the namespace of one of {self.settings.team} "
                             f"(-r __ns:=/robot1), not '{self.get_namespace()}'")
        structure = load_structure(self.settings.structure_file)
        self.motion = self.settings.motion()
        # where a base may not stand: on any tile of the structure, placed or not
        self.footprints = [convex_hull_2d(tile.vertices[:, :2]) for tile in structure.tiles.values()]
        self.position: Point2 = self.settings.robot_starts(structure)[self.name]
        self.busy = False
        self.idle_timer: Timer | None = None  # ends the hold for the team's next decision
        self.time = sim.SimTime(self)
        self.world = sim.WorldClient(self, SimPlace, sim.PLACE)
        self.motion_pub = self.create_publisher(SimMotion, sim.MOTION, SIM_MOTION)
        # served from the start, so that the team's clients and this server have long discovered
        # each other when the first goal comes (a goal response sent before is lost for good)
        self.server = ActionServer(
            self, PlaceTile, "place_tile", execute_callback=self.execute, goal_callback=self.accept,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
        )
        self.removal_server = ActionServer(
            self, RemoveTile, "remove_tile", execute_callback=self.execute_removal, goal_callback=self.accept,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
        )
        self.navigation_server = ActionServer(
            self, NavigateTo, "navigate_to", execute_callback=self.execute_navigation, goal_callback=self.accept,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
        )
        self.get_logger().info(f"serving {self.resolve_topic_name('place_tile')} from "
                               f"({self.position[0]:+.2f}, {self.position[1]:+.2f})")

    def accept(self, _goal: PlaceTile.Goal | RemoveTile.Goal | NavigateTo.Goal) -> GoalResponse:
        if self.busy:
            self.get_logger().warn(f"{self.name} is busy: refusing a second goal (one arm, one goal at a time)")
            return GoalResponse.REJECT
        self.busy = True  # from acceptance: a goal of the other action arriving now is refused
        return GoalResponse.ACCEPT

    async def execute(self, handle: Any) -> Result:
        return await self.run_goal(handle, self.place, Result)

    async def execute_removal(self, handle: Any) -> Removal:
        return await self.run_goal(handle, self.remove, Removal)

    async def execute_navigation(self, handle: Any) -> NavigateTo.Result:
        """Drive to the goal's x, y (yaw is not modelled: the base's heading costs no time here)."""
        self.busy = True
        self.end_decision_window()
        try:
            target = handle.request.target.pose.position
            goal = (target.x, target.y)
            # the world's time, not this body's latest tick (see `place`)
            answer = await self.ask(SimPlace.Request.GOING_TO, x=goal[0], y=goal[1])
            at, stop = stamp_to_seconds(answer.stamp), goal
            if answer.outcome != SimPlace.Response.OK:
                stop, at = await self.make_room(goal, goal, self.position, at)
            feedback = NavigateTo.Feedback(current_pose=self.pose_msg(at),
                                           distance_remaining=float(math.dist(self.position, stop)))
            handle.publish_feedback(feedback)
            phase = drive_phase(self.motion, self.position, stop)
            self.declare(at + phase.duration, busy=True, position=phase.end)
            at = await self.time.until(at + phase.duration)
            self.position = phase.end
            result = NavigateTo.Result(success=True, final_pose=self.pose_msg(at))
            handle.succeed()
        except WorldSilentError as error:
            self.get_logger().error(str(error))
            result = NavigateTo.Result(success=False, message=str(error))
            handle.abort()
        finally:
            self.busy = False
        self.hold_for_next_goal()
        return result

    async def run_goal(self, handle: Any, mission: Any, result_type: type[Result] | type[Removal]) -> Any:
        self.busy = True
        self.end_decision_window()
        try:
            result, start, end = await mission(handle)
        except WorldSilentError as error:
            self.get_logger().error(str(error))
            result, start, end = _finish(handle.abort, result_type.FAILED_HARDWARE, str(error), result_type), 0.0, 0.0
        finally:
            self.busy = False
        self.hold_for_next_goal()  # not when shut down mid-goal: the publisher is gone
        result.duration = end - start
        return result

    async def place(self, handle: Any) -> tuple[Result, float, float]:
        """One placement, phase by phase: the result (with the goal's end status set), the simulated
        times it started and ended.

        Each phase starts at the tick the last one ended at, not when the world's answer about it
        came back, and the world's clock waits there until this body declares its next phase (busy)
        or its end (idle): the round trips to the world and a body that runs late cost no simulated
        time, as when it was one process (`body_hold`).
        """
        goal: PlaceTile.Goal = handle.request
        answer = await self.ask(SimPlace.Request.STARTING, goal.tile_id)
        # the world's time, not this body's latest tick (which lags on a loaded host); the world's
        # clock waits there until the first phase is declared
        start = at = stamp_to_seconds(answer.stamp)
        if answer.outcome == SimPlace.Response.ALREADY_PRESENT:
            return _finish(handle.succeed, Result.ALREADY_PRESENT, answer.reason), start, at
        if answer.outcome != SimPlace.Response.OK:
            return _finish(handle.abort, Result.FAILED_PRECONDITION, answer.reason), start, at
        tile_xy, cache = (goal.pose.pose.position.x, goal.pose.pose.position.y), (goal.cache.x, goal.cache.y)
        cache_stop, at = await self.make_room(approach_point(self.motion, cache, self.position), cache,
                                              self.position, at)
        phases = placement_phases(self.motion, self.position, cache, tile_xy, self.footprints, cache_stop)
        for k in range(len(phases)):
            if phases[k].phase == PlaceTile.Feedback.DRIVING_TO_STRUCTURE:
                target, at = await self.make_room(phases[k].end, tile_xy, cache, at, self.footprints)
                phases = placement_phases(self.motion, self.position, cache, tile_xy, self.footprints, cache_stop,
                                          target)
            phase = phases[k]
            at = await self.run_phase(handle, PlaceTile.Feedback, phase, at)
            if handle.is_cancel_requested:
                return _finish(handle.canceled, Result.CANCELED, "canceled"), start, at
            if phase.phase == PlaceTile.Feedback.PICKING:
                answer = await self.ask(SimPlace.Request.PICKED, goal.tile_id)
                if answer.outcome == SimPlace.Response.DROPPED:
                    return _finish(handle.abort, Result.FAILED_GRASP, answer.reason), start, at
            if phase.phase == PlaceTile.Feedback.PLACING:
                answer = await self.ask(SimPlace.Request.PLACING, goal.tile_id)
                if answer.outcome == SimPlace.Response.ALREADY_PRESENT:
                    return _finish(handle.succeed, Result.ALREADY_PRESENT, answer.reason), start, at
                if answer.outcome == SimPlace.Response.BLOCKED:
                    result = _finish(handle.abort, Result.FAILED_BLOCKED, answer.reason)
                    result.wrong_tiles = list(answer.wrong_tiles)
                    return result, start, at
                if answer.outcome != SimPlace.Response.OK:
                    result = _finish(handle.abort, Result.FAILED_PRECONDITION, answer.reason)
                    result.missing_supports = list(answer.absent_supports)
                    return result, start, at
        result = _finish(handle.succeed, Result.SUCCEEDED, "")
        result.placed_pose = goal.pose
        return result, start, at

    async def remove(self, handle: Any) -> tuple[Removal, float, float]:
        """One removal, phase by phase, timed and held like a placement (see `place`)."""
        goal: RemoveTile.Goal = handle.request
        answer = await self.ask(SimPlace.Request.REMOVING, goal.tile_id)
        start = at = stamp_to_seconds(answer.stamp)
        refused = self.removal_refused(handle, answer)
        if refused is not None:
            return refused, start, at
        tile_xy, drop_off = (goal.pose.pose.position.x, goal.pose.pose.position.y), (goal.drop_off.x, goal.drop_off.y)
        phases = removal_phases(self.motion, self.position, tile_xy, drop_off, self.footprints)
        target, at = await self.make_room(phases[0].end, tile_xy, drop_off, at, self.footprints)
        phases = removal_phases(self.motion, self.position, tile_xy, drop_off, self.footprints, target)
        for k in range(len(phases)):
            if phases[k].phase == RemoveTile.Feedback.DRIVING_TO_DROP_OFF:
                drop_stop, at = await self.make_room(approach_point(self.motion, drop_off, self.position), drop_off,
                                                     tile_xy, at)
                phases = removal_phases(self.motion, self.position, tile_xy, drop_off, self.footprints, target,
                                        drop_stop)
            phase = phases[k]
            at = await self.run_phase(handle, RemoveTile.Feedback, phase, at)
            if handle.is_cancel_requested:
                return _finish(handle.canceled, Removal.CANCELED, "canceled", Removal), start, at
            if phase.phase == RemoveTile.Feedback.LIFTING:
                refused = self.removal_refused(handle, await self.ask(SimPlace.Request.LIFTED, goal.tile_id))
                if refused is not None:
                    return refused, start, at
        result = _finish(handle.succeed, Removal.SUCCEEDED, "", Removal)
        result.found_pose = goal.pose
        return result, start, at

    @staticmethod
    def removal_refused(handle: Any, answer: SimPlace.Response) -> Removal | None:
        """The result of a removal the world's `answer` ends; None when it may go on."""
        if answer.outcome == SimPlace.Response.OK:
            return None
        if answer.outcome == SimPlace.Response.NOT_THERE:
            return _finish(handle.succeed, Removal.ALREADY_ABSENT, answer.reason, Removal)
        if answer.outcome == SimPlace.Response.TILE_ON_TOP:
            result = _finish(handle.abort, Removal.FAILED_TILE_ON_TOP, answer.reason, Removal)
            result.resting_on_it = list(answer.resting_on_it)
            return result
        return _finish(handle.abort, Removal.FAILED_NOT_FOUND, answer.reason, Removal)

    async def make_room(
        self, preferred: Point2, around: Point2, towards: Point2, at: float, obstacles: Sequence[Polygon] = (),
    ) -> tuple[Point2, float]:
        """Where to drive next, and the time (s) the drive may start: `preferred`, else another stop
        within reach round `around` (a cache, a tile), else `preferred` once the robot standing there
        has gone (asking every `room_wait_step` s, the world's clock held meanwhile), or after
        `room_patience` s anyway (`standing_room`)."""
        s = self.settings
        waited = 0.0
        searched: list[Point2] | None = None  # the other robots' spots the last search was for
        while True:
            answer = await self.ask(SimPlace.Request.GOING_TO, x=preferred[0], y=preferred[1],
                                    insist=waited >= s.room_patience)
            if answer.outcome == SimPlace.Response.OK:
                return preferred, at
            others = [(p.x, p.y) for p in answer.robots]
            spot = None
            if others != searched:  # nobody moved: no new stop to find
                spot = alternative_spot(self.motion, around, towards, preferred, others, s.robot_clearance, obstacles)
                searched = others
            if spot is not None:
                answer = await self.ask(SimPlace.Request.GOING_TO, x=spot[0], y=spot[1])
                if answer.outcome == SimPlace.Response.OK:
                    return spot, at
            self.declare(at + s.room_wait_step, busy=True)
            at = await self.time.until(at + s.room_wait_step)
            waited += s.room_wait_step

    async def run_phase(self, handle: Any, feedback_type: Any, phase: Phase, at: float) -> float:
        """Announce `phase` to the goal's client and the world, and sleep through it; the time it ends."""
        handle.publish_feedback(feedback_type(phase=phase.phase, phase_progress=0.0, robot_pose=self.pose_msg(at)))
        self.declare(at + phase.duration, busy=True, position=phase.end)
        at = await self.time.until(at + phase.duration)
        self.position = phase.end
        return at

    def hold_for_next_goal(self) -> None:
        """Keep the world's clock at this goal's end for `decision_window` s of wall time, then idle:
        the team's decision about this robot's next goal costs no simulated time (a robot decides in
        milliseconds; on a loaded host a second of wall time would cost 20 s simulated)."""
        self.declare(self.time.now, busy=True)
        self.idle_timer = self.create_timer(self.settings.decision_window, self.end_decision_window,
                                            clock=Clock(clock_type=ClockType.STEADY_TIME))

    def end_decision_window(self) -> None:
        if self.idle_timer is None:
            return
        self.destroy_timer(self.idle_timer)
        self.idle_timer = None
        if not self.busy:
            self.declare(self.time.now, busy=False)

    def declare(self, arrive_at: float, busy: bool, position: tuple[float, float] | None = None) -> None:
        """Tell the world where the base stands from `arrive_at` (s) on; `busy`: the world's clock waits
        there until this body says what it does next (`body_hold`)."""
        x, y = position or self.position
        self.motion_pub.publish(SimMotion(robot=self.name, arrive_at=arrive_at, x=x, y=y, yaw=0.0, busy=busy))

    async def ask(self, step: int, tile_id: int = 0, **where: Any) -> SimPlace.Response:
        """The world's answer to one step of a placement (FAILED_HARDWARE's reason when none comes).
        Asked for room while a robot before this one in the team may still ask at the same time, it
        asks again a moment of wall time later (the world's clock waits meanwhile)."""
        while True:
            answer = await self.world.call(SimPlace.Request(robot=self.name, tile_id=tile_id, step=step, **where))
            if answer is None:
                raise WorldSilentError(f"the simulated world did not answer on {sim.PLACE} within "
                                       f"{sim.WORLD_PATIENCE:g} s")
            if answer.outcome != SimPlace.Response.ASK_AGAIN:
                return answer
            await self.wall_pause(ASK_AGAIN_PAUSE)

    async def wall_pause(self, seconds: float) -> None:
        done = Future()
        timer = self.create_timer(seconds, lambda: done.done() or done.set_result(None),
                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
        try:
            await done
        finally:
            self.destroy_timer(timer)

    def pose_msg(self, at: float) -> PoseStamped:
        """Where the base is at `at` (s): the body knows its own pose exactly (the overhead cameras'
        view, with its errors, is the world's)."""
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = stamp_from_seconds(at)
        pose.pose.position.x, pose.pose.position.y = self.position
        pose.pose.orientation.w = 1.0
        return pose


class WorldSilentError(RuntimeError):
    """The simulated world did not answer a step of a placement."""


def _finish(end: Any, code: int, message: str, result_type: type[Result] | type[Removal] = Result) -> Any:
    """End the goal (`handle.succeed`, `abort` or `canceled`) with a result of `code`."""
    end()
    return result_type(error_code=code, message=message)


def main(args: list[str] | None = None) -> int:
    return run_node(SimRobot, (ValueError, StructureError), args=args, error_prefix="sim_robot")


if __name__ == "__main__":
    sys.exit(main())
