"""RunOrders on its own (millctl/controller/overtake.py): which RUNNING a STOP that overtook an order explains."""

from __future__ import annotations

from millctl.controller.overtake import RunOrders
from millctl.protocol import NodeState

BOUND_S = 0.5
"""A bound like ``interlock.command_confirm_s`` (an exact binary fraction, so that the bound is exact)."""


def test_nothing_is_explained_before_any_order() -> None:
    orders = RunOrders(BOUND_S)
    assert not orders.explains_running(0.0)
    orders.stop_sent(1.0)
    assert not orders.explains_running(1.0)


def test_an_order_without_a_stop_after_it_explains_nothing() -> None:
    orders = RunOrders(BOUND_S)
    orders.setpoints_sent(1.0, moving=True, node=NodeState.ARMED)
    assert not orders.explains_running(1.25)
    orders.stop_sent(0.5)  # a STOP before the order
    orders.setpoints_sent(1.0, moving=True, node=NodeState.ARMED)
    assert not orders.explains_running(1.25)


def test_a_stop_issued_with_the_order_or_after_it_explains_running_until_the_bound_inclusive() -> None:
    orders = RunOrders(BOUND_S)
    orders.setpoints_sent(1.0, moving=True, node=NodeState.ARMED)
    orders.stop_sent(1.0)  # in the same tick as the order
    assert orders.explains_running(1.25)
    assert orders.explains_running(1.0 + BOUND_S)  # at the bound
    assert not orders.explains_running(1.0 + BOUND_S + 1e-6)


def test_only_a_moving_setpoint_to_an_armed_node_is_an_order_and_any_other_report_ends_it() -> None:
    orders = RunOrders(BOUND_S)
    orders.setpoints_sent(1.0, moving=False, node=NodeState.ARMED)
    orders.setpoints_sent(1.0, moving=True, node=NodeState.RUNNING)
    orders.stop_sent(1.1)
    assert not orders.explains_running(1.2)
    orders.setpoints_sent(2.0, moving=True, node=NodeState.ARMED)
    orders.stop_sent(2.1)
    orders.reported(NodeState.ARMED)
    assert orders.explains_running(2.2)
    orders.reported(NodeState.RUNNING)  # answered: explained once
    assert not orders.explains_running(2.3)
