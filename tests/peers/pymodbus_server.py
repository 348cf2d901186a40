#!/usr/bin/python3
"""A Modbus server nobody here wrote: pymodbus (Debian python3-pymodbus) serving 10000 of each table, as
libmodbus_server.c does, on loopback. The conformance runner's peer (conformance/README.md).

    pymodbus_server.py tcp|udp|rtu-tcp|ascii-tcp PORT [--holding-registers-at-50000 |
                       --register ADDRESS=VALUE ... | --lower-case-replies]

--holding-registers-at-50000 moves the holding registers away from 0 to one at 50000: a device whose probe
read cannot be a holding register at the start of its map. --register sets a holding register's value
before serving (repeatable): a datastore that holds what a device's map says elsewhere (a Walchem
alternative map's object field) and not there. --lower-case-replies (ascii-tcp) writes every reply's hex
digits in lower case, which SL §2.5.2.1 does not allow: pymodbus's ASCII framer upper-cases what it sends,
and this undoes that, a device's lapse for the rule that must catch it.
"""
import logging
import sys

from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
from pymodbus.server import StartTcpServer, StartUdpServer
from pymodbus.transaction import ModbusAsciiFramer, ModbusRtuFramer, ModbusSocketFramer


def main():
    scheme, port = sys.argv[1], int(sys.argv[2])
    logging.basicConfig(level=logging.CRITICAL)
    block = lambda: ModbusSequentialDataBlock(0, [0] * 10000)  # noqa: E731
    options = sys.argv[3:]
    far = "--holding-registers-at-50000" in options
    holding = ModbusSequentialDataBlock(50000, [0]) if far else block()
    for option, value in zip(options, options[1:]):
        if option == "--register":
            address, word = value.split("=")
            holding.setValues(int(address, 0), [int(word, 0)])
    store = ModbusSlaveContext(di=block(), co=block(), hr=holding, ir=block(), zero_mode=True)
    context = ModbusServerContext(slaves=store, single=True)
    address = ("127.0.0.1", port)
    if "--lower-case-replies" in options:
        upper_case_packet = ModbusAsciiFramer.buildPacket
        ModbusAsciiFramer.buildPacket = lambda self, message: upper_case_packet(self, message).lower()
    if scheme == "udp":
        StartUdpServer(context=context, address=address)
    elif scheme == "rtu-tcp":
        StartTcpServer(context=context, address=address, framer=ModbusRtuFramer)
    elif scheme == "ascii-tcp":
        StartTcpServer(context=context, address=address, framer=ModbusAsciiFramer)
    else:
        StartTcpServer(context=context, address=address, framer=ModbusSocketFramer)


if __name__ == "__main__":
    main()
