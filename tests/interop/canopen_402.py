"""python-canopen's CiA 402 client (BaseNode402) against `survey sim`'s
simulated drive behind its simulated SLCAN adapter, through python-can's
`slcan` interface on the pty `survey sim` links at PORT.

    python3 canopen_402.py PORT NODE_ID TARGET_DEG COUNTS_PER_DEG

Prints one JSON line: the states and modes it saw, the position reached.
Exit status 0 when the drive was enabled, switched to profile position,
moved and read back; 1 otherwise (with the reason on stderr).
"""
import json
import sys
import time

import canopen
from canopen.objectdictionary import ObjectDictionary, ODVariable
from canopen.objectdictionary import datatypes as dt


def variable(index, name, data_type, access):
    v = ODVariable(name, index, 0)
    v.data_type = data_type
    v.access_type = access
    return v


def dictionary():
    """The CiA 402 objects BaseNode402 uses, with their standard types."""
    od = ObjectDictionary()
    for index, name, data_type, access in [
        (0x6040, "Controlword", dt.UNSIGNED16, "rw"),
        (0x6041, "Statusword", dt.UNSIGNED16, "ro"),
        (0x6060, "Modes of operation", dt.INTEGER8, "rw"),
        (0x6061, "Modes of operation display", dt.INTEGER8, "ro"),
        (0x6064, "Position actual value", dt.INTEGER32, "ro"),
        (0x607A, "Target position", dt.INTEGER32, "rw"),
        (0x6081, "Profile velocity", dt.UNSIGNED32, "rw"),
        (0x6502, "Supported drive modes", dt.UNSIGNED32, "ro"),
    ]:
        od.add_object(variable(index, name, data_type, access))
    return od


def main():
    port, node_id, target_deg, counts_per_deg = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    network = canopen.Network()
    network.connect(interface="slcan", channel=port, bitrate=500000, sleep_after_open=0)
    try:
        node = canopen.BaseNode402(node_id, dictionary())
        network.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 1.0
        node.nmt.state = "OPERATIONAL"
        node.setup_402_state_machine(read_pdos=False)
        seen = {"start_state": node.state}
        node.op_mode = "PROFILED POSITION"
        seen["op_mode"] = node.op_mode
        node.state = "OPERATION ENABLED"
        seen["state"] = node.state
        target = round(target_deg * counts_per_deg)
        node.sdo[0x607A].raw = target
        node.controlword = 0x1F  # enable operation + new set-point (bit 4)
        deadline = time.monotonic() + 20.0
        while not node.statusword & (1 << 12):  # set-point acknowledge
            if time.monotonic() > deadline:
                raise RuntimeError("no set-point acknowledge")
        node.controlword = 0x0F
        while not node.statusword & (1 << 10):  # target reached
            if time.monotonic() > deadline:
                raise RuntimeError("target not reached in 20 s")
            time.sleep(0.01)
        seen["position_counts"] = node.sdo[0x6064].raw
        seen["target_counts"] = target
        seen["statusword"] = node.statusword
        print(json.dumps(seen), flush=True)
    finally:
        network.disconnect()


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # the reason, for the Rust test's message
        print(f"{type(e).__name__}: {e}", file=sys.stderr)
        sys.exit(1)
