"""A CiA 402 drive with the standard objects only, as a python-canopen
LocalNode (an SDO server no one here wrote) on the CAN bus behind a simulated
SLCAN adapter, through python-can's `slcan` interface on PORT.

    python3 canopen_standard_drive.py PORT NODE_ID

Objects: CiA 301 0x1000, 0x1001, 0x1008; CiA 402 0x603F, 0x6040, 0x6041,
0x6060, 0x6061, 0x6064, 0x607A, 0x6081, 0x60FD, 0x6502. Nothing in the
manufacturer-specific range 0x2000-0x5FFF: reading one is answered with abort
0x06020000, as a real drive answers. A write callback runs the CiA 402 state
machine (shutdown, switch on, enable operation, disable voltage, quick stop;
each transition at once), shows 0x6060 in 0x6061, and on the rising edge of
controlword bit 4 in operation enabled puts the axis on 0x607A at once (target
reached, set-point acknowledge until bit 4 falls). Prints `ready`, serves
until its standard input closes, then prints the objects written as JSON.
"""
import json
import struct
import sys

import canopen
from canopen.objectdictionary import ObjectDictionary, ODVariable
from canopen.objectdictionary import datatypes as dt

# Statusword patterns (bit 4 voltage enabled, bit 9 remote).
SWITCH_ON_DISABLED = 0x0250
READY_TO_SWITCH_ON = 0x0231
SWITCHED_ON = 0x0233
OPERATION_ENABLED = 0x0237
TARGET_REACHED = 1 << 10
SET_POINT_ACK = 1 << 12


def variable(index, data_type, access, default):
    v = ODVariable(f"0x{index:04X}", index, 0)
    v.data_type = data_type
    v.access_type = access
    v.default = default
    return v


class Drive:
    def __init__(self, node):
        self.node = node
        self.state = SWITCH_ON_DISABLED
        self.controlword = 0
        self.ack = False
        self.reached = True
        self.written = []

    def get(self, index, fmt):
        return struct.unpack(fmt, self.node.get_data(index, 0))[0]

    def set(self, index, fmt, value):
        self.node.set_data(index, 0, struct.pack(fmt, value))

    def publish(self):
        word = self.state
        if self.state == OPERATION_ENABLED and self.reached:
            word |= TARGET_REACHED
        if self.ack:
            word |= SET_POINT_ACK
        self.set(0x6041, "<H", word)

    def on_write(self, index, subindex, od, data):
        if index in (0x6041, 0x6061, 0x6064):
            return  # our own updates
        self.written.append(f"0x{index:04X}")
        if index == 0x6060:
            self.set(0x6061, "<b", struct.unpack("<b", bytes(data))[0])
        elif index == 0x6040:
            self.controlword_written(struct.unpack("<H", bytes(data))[0])

    def controlword_written(self, cw):
        old, self.controlword = self.controlword, cw
        state = self.state
        if cw & 0x87 == 0x06:
            state = READY_TO_SWITCH_ON
        elif cw & 0x8F == 0x07 and self.state in (READY_TO_SWITCH_ON, OPERATION_ENABLED):
            state = SWITCHED_ON
        elif cw & 0x8F == 0x0F and self.state in (READY_TO_SWITCH_ON, SWITCHED_ON, OPERATION_ENABLED):
            state = OPERATION_ENABLED
        elif cw & 0x82 == 0x00 or cw & 0x86 == 0x02:
            state = SWITCH_ON_DISABLED
        self.state = state
        rising = cw & 0x10 and not old & 0x10
        if rising and self.state == OPERATION_ENABLED and not cw & 0x100:
            self.set(0x6064, "<i", self.get(0x607A, "<i"))
            self.reached = True
            self.ack = True
        if not cw & 0x10:
            self.ack = False
        self.publish()


def main():
    port, node_id = sys.argv[1], int(sys.argv[2])
    od = ObjectDictionary()
    od.add_object(variable(0x1000, dt.UNSIGNED32, "ro", 0x00020192))
    od.add_object(variable(0x1001, dt.UNSIGNED8, "ro", 0))
    od.add_object(variable(0x1008, dt.VISIBLE_STRING, "const", "python-canopen standard CiA 402 drive"))
    od.add_object(variable(0x603F, dt.UNSIGNED16, "ro", 0))
    od.add_object(variable(0x6040, dt.UNSIGNED16, "rw", 0))
    od.add_object(variable(0x6041, dt.UNSIGNED16, "ro", SWITCH_ON_DISABLED))
    od.add_object(variable(0x6060, dt.INTEGER8, "rw", 0))
    od.add_object(variable(0x6061, dt.INTEGER8, "ro", 0))
    od.add_object(variable(0x6064, dt.INTEGER32, "ro", 0))
    od.add_object(variable(0x607A, dt.INTEGER32, "rw", 0))
    od.add_object(variable(0x6081, dt.UNSIGNED32, "rw", 100000))
    od.add_object(variable(0x60FD, dt.UNSIGNED32, "ro", 0))
    od.add_object(variable(0x6502, dt.UNSIGNED32, "ro", 1))
    network = canopen.Network()
    network.connect(interface="slcan", channel=port, bitrate=500000, sleep_after_open=0)
    try:
        node = network.create_node(node_id, od)
        drive = Drive(node)
        node.add_write_callback(drive.on_write)
        print("ready", flush=True)
        sys.stdin.read()
        print(json.dumps({"written": sorted(set(drive.written))}), flush=True)
    finally:
        network.disconnect()


if __name__ == "__main__":
    main()
