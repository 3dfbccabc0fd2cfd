#!/usr/bin/env python3
"""A Modbus TCP server built with pymodbus (not by this project) that serves
the default register map of survey_positioner_drivers::modbus, minimally.

Used by the interoperability test of the Rust driver (sim-servers/src/modbus_server/
interop.rs). The register layout is written here independently of the Rust
code, from the table in positioner-drivers/src/modbus/mod.rs:

  input registers   0-1  actual position, i32 counts (100000 per degree), high word first
                    2    status bits (0 moving, 1 in position, 2 fault, 3 lower limit,
                         4 upper limit, 5 correction enabled)
                    3    fault code
                    4    table checksum (not computed here)
  holding registers 0-1  commanded position, 2-3 velocity (counts/s), 4 command,
                    10-11 table header, 100-221 table window (stored only)

The test pre-writes the input registers from the command line. The server binds
127.0.0.1 port 0 and prints one JSON line {"port": N}. It serves until its
stdin is closed, then prints one JSON line {"holding": [registers 0..299]}
and exits, so the test can check what the driver wrote.

Usage: modbus_server.py --actual-deg D --status S --fault-code F
"""

import argparse
import asyncio
import json
import struct
import sys

from pymodbus.datastore import (
    ModbusDeviceContext,
    ModbusSequentialDataBlock,
    ModbusServerContext,
)
from pymodbus import ModbusDeviceIdentification
from pymodbus.server import ModbusTcpServer

COUNTS_PER_DEGREE = 100000
HOLDING_SIZE = 300
INPUT_SIZE = 5
FC_READ_HOLDING = 3
FC_READ_INPUT = 4


def i32_words(value):
    """Two registers of a signed 32-bit value, high word first."""
    high, low = struct.unpack(">HH", struct.pack(">i", value))
    return [high, low]


async def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--actual-deg", type=float, required=True)
    parser.add_argument("--status", type=int, required=True)
    parser.add_argument("--fault-code", type=int, default=0)
    args = parser.parse_args()

    # ModbusDeviceContext adds 1 to every protocol address before it reaches
    # the block, so a block starting at 1 puts protocol address a at index a.
    device = ModbusDeviceContext(
        hr=ModbusSequentialDataBlock(1, [0] * HOLDING_SIZE),
        ir=ModbusSequentialDataBlock(1, [0] * INPUT_SIZE),
    )
    context = ModbusServerContext(devices=device, single=True)
    counts = round(args.actual_deg * COUNTS_PER_DEGREE)
    device.setValues(FC_READ_INPUT, 0, i32_words(counts) + [args.status, args.fault_code])

    # What it says it is when asked (Read Device Identification, 0x2B/0x0E).
    identity = ModbusDeviceIdentification(info_name={
        "VendorName": "pymodbus interop",
        "ProductCode": "PM-1",
        "MajorMinorRevision": "3.11",
        "ProductName": "interop server",
    })
    server = ModbusTcpServer(context, identity=identity, address=("127.0.0.1", 0))
    await server.serve_forever(background=True)
    port = server.transport.sockets[0].getsockname()[1]
    print(json.dumps({"port": port}), flush=True)

    # Serve until the test closes our stdin.
    await asyncio.get_running_loop().run_in_executor(None, sys.stdin.read)
    holding = device.getValues(FC_READ_HOLDING, 0, count=HOLDING_SIZE)
    print(json.dumps({"holding": holding}), flush=True)
    await server.shutdown()


if __name__ == "__main__":
    asyncio.run(main())
