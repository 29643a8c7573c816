"""CAN bus errors between processes: an error-passive and a bus-off error frame reach the service's controller.

The service and the node as processes on the transport under test (udp_multicast
inside ``tests/hil/in_netns``; socketcan in the VM); the adversary puts error
frames in SocketCAN's layout (linux/can/error.h) on the bus, as a controller's
driver delivers them on a real ``can0`` (docs/protocol.md#bus-errors).
"""

from __future__ import annotations

import pytest

from millctl.protocol.bus_health import CAN_ERR_BUSOFF, CAN_ERR_CNT, CAN_ERR_CRTL
from tests.hil.adversary import Adversary, raw_frame
from tests.hil.scenario_support import Mill, Probe, wait_for
from tests.hil.test_adversary import assert_stops_inside, mill  # noqa: F401 (the fixture)

pytestmark = pytest.mark.hil


def test_error_passive_is_shown_and_bus_off_trips_the_service_with_its_reason(
    mill: tuple[Mill, Probe, Adversary],  # noqa: F811 (the fixture)
) -> None:
    m, probe, adversary = mill
    passive = raw_frame(CAN_ERR_CRTL | CAN_ERR_CNT, bytes((0, 0x20, 0, 0, 0, 0, 136, 2)), is_error_frame=True)
    adversary.send(passive)
    health = wait_for(lambda: (h := m.status()["bus_health"])["condition"] == "error-passive" and h,
                      m.timeout(3.0), "bus_health error-passive in the service's status")
    assert (health["tx_error_counter"], health["rx_error_counter"], health["error_passive_count"]) == (136, 2, 1)
    assert m.status()["state"] == "RUNNING", "error-passive is shown, it does not trip"
    t_off = adversary.send(raw_frame(CAN_ERR_BUSOFF, bytes(8), is_error_frame=True))
    tripped = m.wait_state("TRIPPED", 3.0)
    assert tripped["trip_cause"].startswith(f"CAN bus-off on {m.config.bus.interface}:"), tripped["trip_cause"]
    assert tripped["bus_health"]["bus_off_count"] == 1
    assert_stops_inside(m, probe, t_off)
