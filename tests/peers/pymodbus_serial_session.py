#!/usr/bin/python3
"""A serial Modbus master nobody here wrote: pymodbus's RTU client (Debian python3-pymodbus) on a serial
device, for tests/analyzer/pymodbus_socat_test.cpp, where socat relays it to the slave and logs the line.

    pymodbus_serial_session.py DEVICE UNIT ADDRESS VALUE COUNT

Writes VALUE to holding register ADDRESS (FC6), reads COUNT holding registers from ADDRESS (FC3) and
eight coils from 0 (FC1), one attempt each. Prints one line:
    write=ok|exception:N|error  regs=V,V,...|...  coils=0,1,...|...
"""
import logging
import sys

from pymodbus.client import ModbusSerialClient
from pymodbus_client import outcome  # the same reading of a reply as the TCP peer's


def main():
    device, unit, address, value, count = sys.argv[1:6]
    unit, address, value, count = int(unit), int(address), int(value), int(count)
    logging.basicConfig(level=logging.CRITICAL)
    client = ModbusSerialClient(port=device, baudrate=38400, parity="N", timeout=1, retries=0)
    if not client.connect():
        print("connect=failed")
        return 1
    out = []
    w = client.write_register(address, value, slave=unit)
    out.append("write=" + outcome(w))
    r = client.read_holding_registers(address, count, slave=unit)
    out.append("regs=" + (",".join(str(v) for v in r.registers) if outcome(r) == "ok" else outcome(r)))
    c = client.read_coils(0, 8, slave=unit)
    out.append("coils=" + (",".join(str(int(b)) for b in c.bits[:8]) if outcome(c) == "ok" else outcome(c)))
    client.close()
    print(" ".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
