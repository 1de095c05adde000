#!/usr/bin/env python3
"""Digi's own XBee library (PyPI `digi-xbee`) as a peer for xbee-api's interop test.

Started once by xbee-api/tests/interop.rs; speaks a line protocol on stdin/stdout, one response
line per request line:

    BUILD <ap> <desc>    Digi builds the frame from the fields -> "OK <hex of the wire bytes>"
    PARSE <ap> <hex>     Digi parses the wire bytes            -> "OK <desc>"
    CLASS <ap> <hex>     the class build_frame() returns       -> "OK <class name>"
    VERSION                                                    -> "OK <digi-xbee version> <path>"
    QUIT

<ap> is 1 (API mode, no escaping) or 2 (escaped API mode). Errors answer "ERR <message>".

<desc> is the canonical text of one frame, the same on both sides: a type name, then key=HEX
fields in a fixed order, all hex upper case, numbers zero-padded to their width (u8: 2, u16: 4,
u64: 16 digits), byte strings as 2 digits per byte (empty: nothing after '='):

    TX64 id= dest= opt= data=            RX64 src= rssi= opt= data=
    TX16 id= dest= opt= data=            RX16 src= rssi= opt= data=
    AT   id= cmd= param=                 RX64IO src= rssi= opt= data=
    ATQ  id= cmd= param=                 RX16IO src= rssi= opt= data=
    RAT  id= dest64= dest16= opt= cmd= param=
    ATR  id= cmd= status= data=          TXS id= status=     MS status=
    RATR id= src64= src16= cmd= status= data=

For RX64IO/RX16IO, PARSE appends Digi's reading of the (first) I/O sample: io_dmask= (digital
mask), io_amask= (analog mask as the channel-indicator bits 9-14), io_dio= (lines reported HIGH,
as a bit mask) and io_adc= (six 4-digit values, "----" for a channel without a value).

RSSI is the raw byte, which Digi exposes as a positive magnitude (40 means -40 dBm), exactly like
xbee-api's Rssi::raw().

Wire bytes in AP=2: digi.xbee.packets.factory.build_frame() expects *unescaped* bytes (Digi's
serial reader, digi.xbee.serial.XBeeSerialPort.wait_for_frame, unescapes with
XBeeAPIPacket.unescape_data before calling it), so PARSE does the same.
"""

import sys
import traceback

from digi.xbee.models.address import XBee16BitAddress, XBee64BitAddress
from digi.xbee.models.mode import OperatingMode
from digi.xbee.models.status import ModemStatus, TransmitStatus
from digi.xbee.packets.base import UnknownXBeePacket, XBeeAPIPacket
from digi.xbee.packets.common import (
    ATCommPacket,
    ATCommQueuePacket,
    ATCommResponsePacket,
    ModemStatusPacket,
    RemoteATCommandPacket,
    RemoteATCommandResponsePacket,
)
from digi.xbee.packets.factory import build_frame
from digi.xbee.packets.raw import (
    RX16IOPacket,
    RX16Packet,
    RX64IOPacket,
    RX64Packet,
    TX16Packet,
    TX64Packet,
    TXStatusPacket,
)
from digi.xbee.io import IOLine, IOValue

MODES = {"1": OperatingMode.API_MODE, "2": OperatingMode.ESCAPED_API_MODE}


def h(b):
    return bytes(b or b"").hex().upper()


def u(width, v):
    return "%0*X" % (width, v)


def parse_desc(desc):
    parts = desc.split(" ")
    fields = {}
    for p in parts[1:]:
        k, v = p.split("=", 1)
        fields[k] = bytearray.fromhex(v)
    return parts[0], fields


def num(b):
    return int.from_bytes(b, "big")


def cmd_str(b):
    # Digi takes the command as a string (or bytes); the test only sends ASCII commands.
    return bytes(b).decode("ascii")


def build(ap, desc):
    kind, f = parse_desc(desc)
    op = MODES[ap]
    if kind == "TX64":
        p = TX64Packet(num(f["id"]), XBee64BitAddress(f["dest"]), num(f["opt"]), f["data"], op_mode=op)
    elif kind == "TX16":
        p = TX16Packet(num(f["id"]), XBee16BitAddress(f["dest"]), num(f["opt"]), f["data"], op_mode=op)
    elif kind == "AT":
        p = ATCommPacket(num(f["id"]), cmd_str(f["cmd"]), f["param"], op_mode=op)
    elif kind == "ATQ":
        p = ATCommQueuePacket(num(f["id"]), cmd_str(f["cmd"]), f["param"], op_mode=op)
    elif kind == "RAT":
        p = RemoteATCommandPacket(
            num(f["id"]), XBee64BitAddress(f["dest64"]), XBee16BitAddress(f["dest16"]),
            num(f["opt"]), cmd_str(f["cmd"]), f["param"], op_mode=op)
    elif kind == "RX64":
        p = RX64Packet(XBee64BitAddress(f["src"]), num(f["rssi"]), num(f["opt"]), f["data"], op_mode=op)
    elif kind == "RX16":
        p = RX16Packet(XBee16BitAddress(f["src"]), num(f["rssi"]), num(f["opt"]), f["data"], op_mode=op)
    elif kind == "RX64IO":
        p = RX64IOPacket(XBee64BitAddress(f["src"]), num(f["rssi"]), num(f["opt"]), f["data"], op_mode=op)
    elif kind == "RX16IO":
        p = RX16IOPacket(XBee16BitAddress(f["src"]), num(f["rssi"]), num(f["opt"]), f["data"], op_mode=op)
    elif kind == "ATR":
        p = ATCommResponsePacket(num(f["id"]), cmd_str(f["cmd"]), num(f["status"]), f["data"], op_mode=op)
    elif kind == "TXS":
        p = TXStatusPacket(num(f["id"]), TransmitStatus.get(num(f["status"])), op_mode=op)
    elif kind == "MS":
        p = ModemStatusPacket(ModemStatus.get(num(f["status"])), op_mode=op)
    elif kind == "RATR":
        p = RemoteATCommandResponsePacket(
            num(f["id"]), XBee64BitAddress(f["src64"]), XBee16BitAddress(f["src16"]),
            cmd_str(f["cmd"]), num(f["status"]), f["data"], op_mode=op)
    else:
        raise ValueError("unknown frame kind " + kind)
    return h(p.output(escaped=(ap == "2")))


def io_fields(sample):
    if sample is None:
        return " io=none"
    dio = 0
    for line, value in sample.digital_values.items():
        if value == IOValue.HIGH:
            dio |= 1 << line.index
    adc = []
    for ch in range(6):
        v = sample.get_analog_value(IOLine.get(ch))
        adc.append("----" if v is None else u(4, v))
    return " io_dmask=%s io_amask=%s io_dio=%s io_adc=%s" % (
        u(4, sample.digital_mask), u(4, sample.analog_mask), u(4, dio), "".join(adc))


def describe(p):
    if isinstance(p, TX64Packet):
        return "TX64 id=%s dest=%s opt=%s data=%s" % (
            u(2, p.frame_id), h(p.x64bit_dest_addr.address), u(2, p.transmit_options), h(p.rf_data))
    if isinstance(p, TX16Packet):
        return "TX16 id=%s dest=%s opt=%s data=%s" % (
            u(2, p.frame_id), h(p.x16bit_dest_addr.address), u(2, p.transmit_options), h(p.rf_data))
    if isinstance(p, ATCommQueuePacket):
        return "ATQ id=%s cmd=%s param=%s" % (
            u(2, p.frame_id), h(p.command.encode("ascii")), h(p.parameter))
    if isinstance(p, ATCommPacket):
        return "AT id=%s cmd=%s param=%s" % (
            u(2, p.frame_id), h(p.command.encode("ascii")), h(p.parameter))
    if isinstance(p, RemoteATCommandPacket):
        return "RAT id=%s dest64=%s dest16=%s opt=%s cmd=%s param=%s" % (
            u(2, p.frame_id), h(p.x64bit_dest_addr.address), h(p.x16bit_dest_addr.address),
            u(2, p.transmit_options), h(p.command.encode("ascii")), h(p.parameter))
    if isinstance(p, RX64IOPacket):
        return "RX64IO src=%s rssi=%s opt=%s data=%s" % (
            h(p.x64bit_source_addr.address), u(2, p.rssi), u(2, p.receive_options),
            h(p.rf_data)) + io_fields(p.io_sample)
    if isinstance(p, RX16IOPacket):
        return "RX16IO src=%s rssi=%s opt=%s data=%s" % (
            h(p.x16bit_source_addr.address), u(2, p.rssi), u(2, p.receive_options),
            h(p.rf_data)) + io_fields(p.io_sample)
    if isinstance(p, RX64Packet):
        return "RX64 src=%s rssi=%s opt=%s data=%s" % (
            h(p.x64bit_source_addr.address), u(2, p.rssi), u(2, p.receive_options), h(p.rf_data))
    if isinstance(p, RX16Packet):
        return "RX16 src=%s rssi=%s opt=%s data=%s" % (
            h(p.x16bit_source_addr.address), u(2, p.rssi), u(2, p.receive_options), h(p.rf_data))
    if isinstance(p, ATCommResponsePacket):
        return "ATR id=%s cmd=%s status=%s data=%s" % (
            u(2, p.frame_id), h(p.command.encode("ascii")), u(2, p.real_status), h(p.command_value))
    if isinstance(p, TXStatusPacket):
        return "TXS id=%s status=%s" % (u(2, p.frame_id), u(2, p.transmit_status.code))
    if isinstance(p, ModemStatusPacket):
        return "MS status=%s" % u(2, p.modem_status.code)
    if isinstance(p, RemoteATCommandResponsePacket):
        return "RATR id=%s src64=%s src16=%s cmd=%s status=%s data=%s" % (
            u(2, p.frame_id), h(p.x64bit_source_addr.address), h(p.x16bit_source_addr.address),
            h(p.command.encode("ascii")), u(2, p.real_status), h(p.command_value))
    raise ValueError("Digi built an unexpected packet class " + type(p).__name__)


def parse(ap, hexwire):
    raw = bytearray.fromhex(hexwire)
    if ap == "2":
        # As digi.xbee.serial.XBeeSerialPort.wait_for_frame does before build_frame().
        raw = XBeeAPIPacket.unescape_data(raw)
    p = build_frame(raw, MODES[ap])
    if isinstance(p, UnknownXBeePacket) and len(raw) > 3 and raw[3] in (0x00, 0x01):
        # digi-xbee 1.5.0's build_frame() has no case for TX64 (0x00) and TX16 (0x01): it returns
        # an UnknownXBeePacket for them. Parse them with the classes' own create_packet() instead.
        p = (TX64Packet if raw[3] == 0x00 else TX16Packet).create_packet(raw, MODES[ap])
    return describe(p)


def factory_class(ap, hexwire):
    raw = bytearray.fromhex(hexwire)
    if ap == "2":
        raw = XBeeAPIPacket.unescape_data(raw)
    return type(build_frame(raw, MODES[ap])).__name__


def main():
    import digi.xbee
    from importlib.metadata import version

    for line in sys.stdin:
        line = line.strip()
        if not line:
            continue
        try:
            verb, _, rest = line.partition(" ")
            if verb == "QUIT":
                break
            if verb == "VERSION":
                out = version("digi-xbee") + " " + digi.xbee.__file__
            elif verb == "BUILD":
                ap, _, desc = rest.partition(" ")
                out = build(ap, desc)
            elif verb == "CLASS":
                ap, _, hexwire = rest.partition(" ")
                out = factory_class(ap, hexwire)
            elif verb == "PARSE":
                ap, _, hexwire = rest.partition(" ")
                out = parse(ap, hexwire)
            else:
                raise ValueError("unknown request " + verb)
            sys.stdout.write("OK " + out + "\n")
        except Exception as e:  # report, keep serving
            msg = "%s: %s | %s" % (type(e).__name__, e, traceback.format_exc().replace("\n", " / "))
            sys.stdout.write("ERR " + msg + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
