"""What each python-can interface needs besides python-can: the sentence a failed open says about installing it.

Every interface the ``[bus]`` section accepts (``can.interfaces.VALID_INTERFACES``)
either opens with python-can alone (:data:`SELF_CONTAINED`) or has an entry in
:data:`NEEDS`: the vendor library, Python package or device it loads, and where
it comes from. :func:`~millctl.protocol.factory.open_bus` appends that sentence
to every failure to open the bus, so a missing library is exit 3 with what to
install, never a driver's own ``NameError`` (python-can's kvaser module calls
``canGetNumberOfChannels`` even when CANlib did not load).
"""

from __future__ import annotations

SELF_CONTAINED = frozenset({"virtual", "udp_multicast", "millctl_udp_multicast"})
"""Interfaces that need nothing but python-can (and an IP stack): no library, no adapter."""

_SERIAL = (
    "pyserial (pip install 'millctl[adapters]') and the adapter's serial device at bus.channel "
    "(e.g. /dev/ttyACM0; ls /dev/serial/by-id/)"
)

NEEDS: dict[str, str] = {
    "socketcan": "a Linux SocketCAN network device named by bus.channel: the adapter's kernel driver "
    "(modprobe can_raw and the adapter's module, e.g. peak_usb, gs_usb, kvaser_usb) and the link up "
    "(ip link set can0 up type can bitrate 500000)",
    "pcan": "PEAK's PCAN-Basic library (libpcanbasic.so from peak-system.com, with the PCAN driver or the "
    "kernel's peak_usb; PCANBasic.dll on Windows) and a PCAN adapter plugged in",
    "kvaser": "Kvaser's CANlib (libcanlib.so: the linuxcan driver from kvaser.com/downloads; canlib32.dll on "
    "Windows) and a Kvaser adapter plugged in",
    "vector": "Vector's XL Driver Library (vxlapi64.dll, Windows only, from vector.com) and the channel "
    "assigned to the application in Vector Hardware Config",
    "ixxat": "HMS IXXAT's VCI driver (vcinpl2.dll on Windows; the IXXAT ECI on Linux) and an IXXAT adapter",
    "nican": "National Instruments' NI-CAN driver (nican.dll, 32-bit Python on Windows only)",
    "nixnet": "National Instruments' NI-XNET driver and the nixnet package (pip install nixnet; Windows only)",
    "iscan": "Thorsis' isCAN driver (iscandrv.dll / libiscandrv.so from thorsis.com)",
    "neovi": "Intrepid Control Systems' python-ics package (pip install python-ics filelock) and a neoVI device",
    "usb2can": "8devices' USB2CAN driver (usb2can.dll) and pywin32 (pip install pywin32; Windows only)",
    "systec": "SYS TEC's USB-CANmodul driver (usbcan64.dll; Windows only)",
    "canalystii": "the canalystii package (pip install canalystii) and a CANalyst-II adapter on USB",
    "cantact": "the cantact package (pip install cantact) and a CANtact adapter on USB",
    "gs_usb": "pyusb and gs_usb (pip install 'millctl[adapters]'), libusb-1.0, and a gs_usb adapter "
    "(candleLight, CANable) on USB with access to it (a udev rule)",
    "slcan": _SERIAL,
    "serial": _SERIAL,
    "robotell": _SERIAL,
    "seeedstudio": _SERIAL,
    "neousys": "Neousys' WDT_DIO library (WDT_DIO.dll; Windows only) on a Neousys computer",
    "etas": "ETAS' BOA/ECI libraries (Windows only, from etas.com) and an ETAS interface",
    "socketcand": "a socketcand daemon reachable at bus.options host and port (apt install socketcand on the "
    "machine with the CAN adapter)",
}
"""Per interface: what it needs besides python-can, as one sentence a user can act on."""


def install_hint(interface: str) -> str:
    """The sentence naming what ``interface`` needs installed or attached ("" for a self-contained one)."""
    if interface in SELF_CONTAINED:
        return ""
    needs = NEEDS.get(interface)
    if needs is None:  # a plug-in interface (a can.interface entry point) that this table does not know
        return (f"interface {interface} comes from a python-can plug-in: install that plug-in's package and "
                "whatever library and adapter its documentation names")
    return f"interface {interface} needs {needs}"


__all__ = ["NEEDS", "SELF_CONTAINED", "install_hint"]
