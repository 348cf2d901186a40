#!/usr/bin/python3
"""A Modbus client nobody here wrote: pymodbus (Debian python3-pymodbus) against a slave, one line of
results per step, for tests/slave/pymodbus_client_test.cpp.

    pymodbus_client.py tcp|udp|rtu-tcp|ascii-tcp|rtu|ascii TARGET UNIT ADDRESS VALUE BAD_VALUE

TARGET is HOST:PORT, or the serial device (38400 baud, 8N1) for rtu and ascii. Writes VALUE to holding register ADDRESS and reads it
back, writes BAD_VALUE (expected to be refused), reads again, and asks for FC17. Prints:
    write=ok|exception:N|error  read=V|...  bad=...  after=V  fc17=...
"""
import logging
import sys

from pymodbus.client import ModbusSerialClient, ModbusTcpClient, ModbusUdpClient
from pymodbus.other_message import ReportSlaveIdRequest
from pymodbus.pdu import ExceptionResponse
from pymodbus.transaction import ModbusAsciiFramer, ModbusRtuFramer

FRAMERS = {"rtu": ModbusRtuFramer, "ascii": ModbusAsciiFramer}


def outcome(response):
    if isinstance(response, ExceptionResponse):
        return "exception:%d" % response.exception_code
    if response is None or response.isError():
        return "error"
    return "ok"


def main():
    transport, target, unit, address, value, bad = sys.argv[1:7]
    unit, address, value, bad = int(unit), int(address), int(value), int(bad)
    logging.basicConfig(level=logging.CRITICAL)
    if transport in FRAMERS:
        client = ModbusSerialClient(framer=FRAMERS[transport], port=target, baudrate=38400, parity="N",
                                    timeout=1)
    elif transport == "udp":
        host, port = target.rsplit(":", 1)
        client = ModbusUdpClient(host, port=int(port), timeout=1)
    else:
        # rtu-tcp and ascii-tcp: serial framing over a TCP connection, as a serial gateway carries it.
        host, port = target.rsplit(":", 1)
        framer = FRAMERS.get(transport.removesuffix("-tcp"))
        kwargs = {"framer": framer} if framer else {}
        client = ModbusTcpClient(host, port=int(port), timeout=1, **kwargs)
    if not client.connect():
        print("connect=failed")
        return 1
    out = []
    w = client.write_register(address, value, slave=unit)
    out.append("write=" + outcome(w))
    r = client.read_holding_registers(address, 1, slave=unit)
    out.append("read=" + (str(r.registers[0]) if outcome(r) == "ok" else outcome(r)))
    b = client.write_register(address, bad, slave=unit)
    out.append("bad=" + outcome(b))
    r = client.read_holding_registers(address, 1, slave=unit)
    out.append("after=" + (str(r.registers[0]) if outcome(r) == "ok" else outcome(r)))
    s = client.execute(ReportSlaveIdRequest(unit=unit))
    out.append("fc17=" + outcome(s))
    client.close()
    print(" ".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
