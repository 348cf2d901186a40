#!/usr/bin/python3
"""A Modbus server nobody here wrote: pymodbus (Debian python3-pymodbus) serving 10000 of each table, as
libmodbus_server.c does, on loopback. The conformance runner's peer (conformance/README.md).

    pymodbus_server.py tcp|udp|rtu-tcp PORT
"""
import logging
import sys

from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
from pymodbus.server import StartTcpServer, StartUdpServer
from pymodbus.transaction import ModbusRtuFramer, ModbusSocketFramer


def main():
    scheme, port = sys.argv[1], int(sys.argv[2])
    logging.basicConfig(level=logging.CRITICAL)
    block = lambda: ModbusSequentialDataBlock(0, [0] * 10000)  # noqa: E731
    store = ModbusSlaveContext(di=block(), co=block(), hr=block(), ir=block(), zero_mode=True)
    context = ModbusServerContext(slaves=store, single=True)
    address = ("127.0.0.1", port)
    if scheme == "udp":
        StartUdpServer(context=context, address=address)
    elif scheme == "rtu-tcp":
        StartTcpServer(context=context, address=address, framer=ModbusRtuFramer)
    else:
        StartTcpServer(context=context, address=address, framer=ModbusSocketFramer)


if __name__ == "__main__":
    main()
