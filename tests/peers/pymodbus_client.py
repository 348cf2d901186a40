#!/usr/bin/python3
"""A Modbus client nobody here wrote: pymodbus (Debian python3-pymodbus) against slaves, one line of
results per slave, for tests/slave/pymodbus_client_test.cpp.

    pymodbus_client.py tcp|udp|rtu-tcp|ascii-tcp|rtu|ascii < TARGETS

Each line of standard input names one slave: TARGET UNIT ADDRESS VALUE BAD_VALUE. TARGET is HOST:PORT, or
the serial device (38400 baud, 8N1) for rtu and ascii. The client writes VALUE to holding register ADDRESS
and reads it back, writes BAD_VALUE (expected to be refused), reads again, and asks for FC17. One line out
per line in:
    write=ok|exception:N|error  read=V|...  bad=...  after=V  fc17=...
One interpreter serves every slave of a transport: starting Python and importing pymodbus costs more than
the exchanges themselves.
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


def client_for(transport, target):
    if transport in FRAMERS:
        return ModbusSerialClient(framer=FRAMERS[transport], port=target, baudrate=38400, parity="N",
                                  timeout=1)
    host, port = target.rsplit(":", 1)
    if transport == "udp":
        return ModbusUdpClient(host, port=int(port), timeout=1)
    # rtu-tcp and ascii-tcp: serial framing over a TCP connection, as a serial gateway carries it.
    framer = FRAMERS.get(transport.removesuffix("-tcp"))
    kwargs = {"framer": framer} if framer else {}
    return ModbusTcpClient(host, port=int(port), timeout=1, **kwargs)


def session(transport, target, unit, address, value, bad):
    client = client_for(transport, target)
    if not client.connect():
        return "connect=failed"
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
    return " ".join(out)


def main():
    transport = sys.argv[1]
    logging.basicConfig(level=logging.CRITICAL)
    for line in sys.stdin:
        fields = line.split()
        if len(fields) != 5:
            continue
        target = fields[0]
        unit, address, value, bad = (int(f) for f in fields[1:])
        print(session(transport, target, unit, address, value, bad), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
