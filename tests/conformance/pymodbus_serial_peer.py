#!/usr/bin/python3
"""pymodbus (Debian python3-pymodbus) as a serial slave nobody here wrote, for the conformance runner's
serial-line tests (serial_line_test.cpp): 10000 zeros in each table, zero-based, on a serial device (one
end of a socat pseudo-terminal pair), at 19200 baud.

    pymodbus_serial_peer.py rtu|ascii DEVICE [--damage-normal-fc3=bad-crc|wrong-unit]

Its context is single=True, as pymodbus's examples set it: every unit id is served as its own, so the slave
answers requests for other units (SL §2.1 wants only the addressed slave to answer). Its ASCII framer stops
answering for good after a request with a bad LRC, and its RTU framer keeps half a request until more bytes
complete it: the departures the serial tests name.

--damage-normal-fc3 (rtu) damages every normal reply to FC3, and only those (exceptions and the other
functions stay whole): its CRC flipped, or its unit id one more than the request's under a CRC that holds.
A device the runner certified as passing: the generic profile's probing found no usable read of the holding
registers and every rule needing them was skipped.
"""
import logging
import struct
import sys

from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
from pymodbus.server import StartSerialServer
from pymodbus.transaction import ModbusAsciiFramer, ModbusRtuFramer
from pymodbus.utilities import computeCRC


def main():
    framing, device = sys.argv[1], sys.argv[2]
    logging.basicConfig(level=logging.CRITICAL)
    block = lambda: ModbusSequentialDataBlock(0, [0] * 10000)  # noqa: E731
    store = ModbusSlaveContext(di=block(), co=block(), hr=block(), ir=block(), zero_mode=True)
    context = ModbusServerContext(slaves=store, single=True)
    framer = ModbusAsciiFramer if framing == "ascii" else ModbusRtuFramer
    for option in sys.argv[3:]:
        if option.startswith("--damage-normal-fc3="):
            damage = option.split("=", 1)[1]
            whole = ModbusRtuFramer.buildPacket

            def damaged(self, message, whole=whole, damage=damage):
                packet = bytearray(whole(self, message))
                if message.function_code != 3:  # an exception carries 0x83
                    return bytes(packet)
                if damage == "bad-crc":
                    packet[-1] ^= 0xFF
                else:
                    packet[0] = (packet[0] + 1) & 0xFF
                    packet[-2:] = struct.pack(">H", computeCRC(bytes(packet[:-2])))
                return bytes(packet)

            ModbusRtuFramer.buildPacket = damaged
    StartSerialServer(context=context, framer=framer, port=device, baudrate=19200)


if __name__ == "__main__":
    main()
