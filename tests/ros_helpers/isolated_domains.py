"""ROS domains for the nodes tests create in the pytest process: one per test, kept (with its
context and DDS participant) to the end of the session.

Fast DDS 2.14, our middleware, now and then never returns from deleting a DDS participant:
`rmw_destroy_node` of a context's last node spins in `DomainParticipant::set_listener` while one of
its event threads waits on a writer's mutex. It spins holding the GIL, so pytest-timeout cannot
fire either: a CI run hung 85 minutes in one test. Reproduced with nothing but a loop that creates
and destroys a node in a fresh context (a hang within 100 s, two runs in three; never in 7,500
loops that kept one node of the context alive). Node processes live with it through their teardown
deadline (`tiling_ros.spinning.teardown_deadline`); the test session avoids it instead: a participant
goes with the last node of its context, so each context here keeps an anchor node, tests destroy
only their own nodes and never shut a context down, and the session ends without tearing the
middleware down (`tests/conftest.py`).

Each test gets a domain of its own rather than sharing one long-lived participant: with one, an
assembly node a later test started never received an auction announcement published after the
test's publisher had matched it. (The drivers' tests share one probe node in the session's domain,
`tests/drivers/ros_probe.py`, and wait for what the nodes publish, not for matching.)
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.signals import SignalHandlerOptions

from tiling_sim.ros_domain import claim_domain_id

_held: list[Any] = []  # domain locks and anchor nodes, never released


@dataclass(frozen=True)
class IsolatedDomain:
    """A ROS domain of one test's own and an initialised context in it (do not shut it down)."""

    domain_id: int
    context: Context

    def environ(self) -> dict[str, str]:
        """The environment for a process the test starts in this domain."""
        return dict(os.environ, ROS_DOMAIN_ID=str(self.domain_id))


def fresh_domain() -> IsolatedDomain:
    """Claim a free domain for the rest of the session and a context in it."""
    domain_id, lock = claim_domain_id()
    context = Context()
    rclpy.init(context=context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    _held.extend([lock, rclpy.create_node("test_session_anchor", context=context)])
    return IsolatedDomain(domain_id, context)
