#!/usr/bin/env python3
"""A pymodbus Modbus TCP client (not written by this project) that drives the
simulated positioner controller of survey_sim_servers::modbus_server through the
default register map, written here independently of the Rust code from the
table in positioner-drivers/src/modbus/mod.rs.

Used by sim-servers/src/modbus_server/interop.rs: the test starts the simulator on
127.0.0.1:<port> and runs this script, which

  1. writes the velocity (counts/s) and the target (i32 counts, 100000 per
     degree, high word first) and the move command (1),
  2. reads the status right after the command (the axis should be moving),
  3. polls the status until the in-position bit is set,
  4. reads the actual position,
  5. provokes two exceptions: a move beyond the travel (exception 3) and a
     read of an unmapped register (exception 2),
  6. reads the device identification (0x2B / MEI 0x0E): the regular objects
     by stream access, object 4 alone, and an unknown object alone (exception 2),

and prints one JSON line with what it saw.

Usage: modbus_client.py <port> <target_deg> <velocity_deg_s> <bad_target_deg>

<port> is a TCP port on 127.0.0.1, or rtu:<serial device> for Modbus RTU
(19200 8N1) on a serial line (the test gives a pty).
"""

import json
import struct
import sys

from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient

COUNTS_PER_DEGREE = 100000
UNIT = 1
IN_POSITION = 1 << 1
MOVE = 1
MAX_POLLS = 2000


def i32_words(value):
    high, low = struct.unpack(">HH", struct.pack(">i", value))
    return [high, low]


def words_i32(words):
    return struct.unpack(">i", struct.pack(">HH", words[0], words[1]))[0]


def check(response, what):
    if response.isError():
        raise SystemExit(f"{what} failed: {response}")
    return response


def main():
    where = sys.argv[1]
    target = float(sys.argv[2])
    velocity = float(sys.argv[3])
    bad_target = float(sys.argv[4])
    if where.startswith("rtu:"):
        client = ModbusSerialClient(where[4:], framer=FramerType.RTU, baudrate=19200, timeout=3, retries=0)
    else:
        client = ModbusTcpClient("127.0.0.1", port=int(where), timeout=3, retries=0)
    if not client.connect():
        raise SystemExit(f"cannot connect to {where}")
    try:
        check(client.write_registers(2, i32_words(round(velocity * COUNTS_PER_DEGREE)), device_id=UNIT), "velocity")
        check(client.write_registers(0, i32_words(round(target * COUNTS_PER_DEGREE)), device_id=UNIT), "target")
        check(client.write_register(4, MOVE, device_id=UNIT), "move")
        first = check(client.read_input_registers(0, count=4, device_id=UNIT), "first read").registers
        polls = 0
        status = first[2]
        while not status & IN_POSITION and polls < MAX_POLLS:
            status = check(client.read_input_registers(2, count=1, device_id=UNIT), "status").registers[0]
            polls += 1
        final = check(client.read_input_registers(0, count=4, device_id=UNIT), "final read").registers
        check(client.write_registers(0, i32_words(round(bad_target * COUNTS_PER_DEGREE)), device_id=UNIT), "bad target")
        refused = client.write_register(4, MOVE, device_id=UNIT)
        unmapped = client.read_holding_registers(1000, count=1, device_id=UNIT)
        # Read Device Identification (0x2B/0x0E), regular objects by stream access.
        identity = check(client.read_device_information(read_code=2, object_id=0, device_id=UNIT), "identification")
        one = check(client.read_device_information(read_code=4, object_id=4, device_id=UNIT), "one object")
        unknown = client.read_device_information(read_code=4, object_id=0x33, device_id=UNIT)
    finally:
        client.close()
    print(json.dumps({
        "first_status": first[2],
        "polls": polls,
        "final_status": final[2],
        "fault_code": final[3],
        "actual_counts": words_i32(final[0:2]),
        "actual_deg": words_i32(final[0:2]) / COUNTS_PER_DEGREE,
        "bad_move_is_error": refused.isError(),
        "bad_move_exception": getattr(refused, "exception_code", 0),
        "unmapped_is_error": unmapped.isError(),
        "unmapped_exception": getattr(unmapped, "exception_code", 0),
        "identity_objects": sorted(identity.information.keys()),
        "identity_simulated": b"(simulated)" in identity.information.get(4, b""),
        "identity_vendor_sims": identity.information.get(0) == b"survey-sims",
        "one_object": sorted(one.information.keys()),
        "unknown_object_exception": getattr(unknown, "exception_code", 0),
    }), flush=True)


if __name__ == "__main__":
    main()
