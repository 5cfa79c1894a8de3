"""planner_node: plans the assembly (paper section 2.1) and replans it for the robots left.

Publishes, latched (transient_local, reliable, depth 1, so that late joiners get them):
  /structure  tiling_assembly_msgs/Structure     the structure S_d being built
  /plan       tiling_assembly_msgs/AssemblyPlan  revision 0 at start, +1 on every replan
and /diagnostics. Serves /replan (tiling_assembly_msgs/srv/Replan): the tiles already placed and
the robots still available in, a plan for the rest out (and republished on /plan). An impossible
request (unknown robot, no robot left, placed ids not in the structure) gets success=false with a
one-line message; the current plan stays.

Parameters (defaults in config/planner_node.yaml): structure_file, num_robots or robot_names,
method, improve_time_limit, help_neighbours, and the time model pick_time, place_time, travel_speed,
cache_standoff, cache_crowding and type_place_time.<tile type>. A bad value or structure file: one line
on stderr, exit code 2.
"""

from __future__ import annotations

import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from planner_node.parameters import NODE_NAME, ParameterError, PlannerParameters, parameters_from_values
from planner_node.plan_messages import plan_to_msg
from planner_node.planner import Plan, PlanningError, plan_assembly, replan_assembly
from tiling_assembly.messages import structure_to_msg
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import AssemblyPlan, Structure
from tiling_assembly_msgs.srv import Replan
from tiling_ros.parameters import declare_parameter, declare_values, setting_description, setting_names
from tiling_ros.qos import LATCHED
from tiling_ros.spinning import run_node

_DEFAULTS = PlannerParameters()
# declared from the settings as they are; robot_names has no default (unset: num_robots counts) and
# type_place_time is one parameter per tile type of the structure (`type_place_time.<type>`)
_PLAIN = [name for name in setting_names(PlannerParameters) if name not in ("robot_names", "type_place_time")]


class PlannerNode(Node):
    """Thin adapter: parameters and a structure file in, `plan_assembly`, messages out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        parameters = self._declare_parameters()
        self.structure = load_structure(parameters.structure_file)
        self.parameters = self._declare_type_place_times(parameters)
        self.time_model = self.parameters.time_model()
        self.known_robots = self.parameters.robots()
        self.structure_publisher = self.create_publisher(Structure, "/structure", LATCHED)
        self.plan_publisher = self.create_publisher(AssemblyPlan, "/plan", LATCHED)
        self.diagnostics_publisher = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.revision = 0
        self.plan = plan_assembly(
            self.structure, self.known_robots, self.time_model, **self.parameters.planning_options(),
            robot_starts=self.parameters.robot_starts(),
        )
        structure_msg = structure_to_msg(self.structure)
        structure_msg.header.stamp = self.get_clock().now().to_msg()
        self.structure_publisher.publish(structure_msg)
        self._publish_plan(self.plan)
        self.create_service(Replan, "/replan", self._on_replan)

    def _declare_parameters(self) -> PlannerParameters:
        values = declare_values(self, _DEFAULTS, names=_PLAIN)
        declare_parameter(
            self, "robot_names", Parameter.Type.STRING_ARRAY, setting_description(PlannerParameters, "robot_names")
        )
        try:
            values["robot_names"] = list(self.get_parameter("robot_names").value)
        except ParameterUninitializedException:
            pass
        parameters, _ = parameters_from_values(values)
        if not parameters.structure_file:
            raise ParameterError("parameter structure_file is required (a structure YAML file)")
        return parameters

    def _declare_type_place_times(self, parameters: PlannerParameters) -> PlannerParameters:
        """One parameter type_place_time.<type> per tile type of the structure."""
        values = {name: getattr(parameters, name) for name in _PLAIN}
        values["robot_names"] = list(parameters.robot_names)
        for type_name in self.structure.tile_types:
            name = f"type_place_time.{type_name}"
            description = f"Place time of a '{type_name}' tile (s)"
            values[name] = declare_parameter(self, name, parameters.place_time, description)
        return parameters_from_values(values)[0]

    def _publish_plan(self, plan: Plan) -> None:
        msg = plan_to_msg(plan, self.revision, self.structure.frame_id)
        msg.header.stamp = self.get_clock().now().to_msg()
        self.plan_publisher.publish(msg)
        self.get_logger().info(
            f"published plan revision {self.revision} ({plan.method.value}): "
            f"{sum(len(t.tile_ids) for t in plan.tasks)} tiles for {len(plan.tasks)} robots, "
            f"makespan {plan.makespan:.1f} s, lower bound {plan.lower_bound:.1f} s"
        )
        self._diagnose(
            DiagnosticStatus.OK,
            f"plan revision {self.revision}",
            {
                "revision": str(self.revision),
                "method": plan.method.value,
                "robots": ",".join(t.robot_name for t in plan.tasks),
                "makespan": f"{plan.makespan:.3f}",
                "lower_bound": f"{plan.lower_bound:.3f}",
            },
        )

    def _diagnose(self, level: bytes, message: str, values: dict[str, str]) -> None:
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        array.status = [
            DiagnosticStatus(
                level=level,
                name=f"{NODE_NAME}: plan",
                message=message,
                hardware_id=self.structure.name,
                values=[KeyValue(key=k, value=v) for k, v in values.items()],
            )
        ]
        self.diagnostics_publisher.publish(array)

    def _on_replan(self, request: Replan.Request, response: Replan.Response) -> Replan.Response:
        robots = list(request.available_robots) or [t.robot_name for t in self.plan.tasks]
        try:
            unknown = [r for r in robots if r not in self.known_robots]
            if unknown:
                raise PlanningError(
                    f"unknown robot {unknown[0]!r} (known: {', '.join(self.known_robots)})"
                )
            if not robots:
                raise PlanningError("no robots left to plan for")
            plan = replan_assembly(
                self.structure,
                [int(t) for t in request.placed_tile_ids],
                list(dict.fromkeys(robots)),
                self.time_model,
                **self.parameters.planning_options(),
            )
        except PlanningError as error:
            return self._refuse(response, str(error))
        except Exception as error:
            return self._refuse(response, f"internal error while replanning: {error}")
        self.revision += 1
        self.plan = plan
        self._publish_plan(plan)
        response.success = True
        response.message = ""
        response.plan = plan_to_msg(plan, self.revision, self.structure.frame_id)
        response.plan.header.stamp = self.get_clock().now().to_msg()
        return response

    def _refuse(self, response: Replan.Response, reason: str) -> Replan.Response:
        self.get_logger().warning(f"replan refused: {reason}")
        self._diagnose(DiagnosticStatus.WARN, f"replan refused: {reason}", {"revision": str(self.revision)})
        response.success = False
        response.message = reason
        return response


def main(args: list[str] | None = None) -> int:
    return run_node(PlannerNode, (StructureError, ParameterError, PlanningError, ParameterException), args=args)


if __name__ == "__main__":
    sys.exit(main())
