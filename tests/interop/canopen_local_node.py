"""A python-canopen LocalNode (an SDO server no one here wrote) on the CAN
bus behind a simulated SLCAN adapter, through python-can's `slcan` interface
on PORT, for our SDO client to read and write.

    python3 canopen_local_node.py PORT NODE_ID

Objects: 0x2000 UNSIGNED32 rw (0x12345678), 0x2001 VISIBLE_STRING rw (a
45-byte text: segmented), 0x2002 UNSIGNED16 ro (0xBEEF). Prints `ready`, then
serves until its standard input closes; then prints the final values as JSON.
"""
import json
import sys

import canopen
from canopen.objectdictionary import ObjectDictionary, ODVariable
from canopen.objectdictionary import datatypes as dt

TEXT = "survey: a segmented SDO transfer, 45 bytes.."


def variable(index, data_type, access, default):
    v = ODVariable(f"0x{index:04X}", index, 0)
    v.data_type = data_type
    v.access_type = access
    v.default = default
    return v


def main():
    port, node_id = sys.argv[1], int(sys.argv[2])
    od = ObjectDictionary()
    od.add_object(variable(0x2000, dt.UNSIGNED32, "rw", 0x12345678))
    od.add_object(variable(0x2001, dt.VISIBLE_STRING, "rw", TEXT))
    od.add_object(variable(0x2002, dt.UNSIGNED16, "ro", 0xBEEF))
    network = canopen.Network()
    network.connect(interface="slcan", channel=port, bitrate=500000, sleep_after_open=0)
    try:
        node = network.create_node(node_id, od)
        print("ready", flush=True)
        sys.stdin.read()
        print(json.dumps({"0x2000": node.sdo[0x2000].raw, "0x2001": node.sdo[0x2001].raw}), flush=True)
    finally:
        network.disconnect()


if __name__ == "__main__":
    main()
