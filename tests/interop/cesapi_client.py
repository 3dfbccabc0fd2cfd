#!/usr/bin/env python3
"""An independent emScon client (PyPI `CESAPI==1.1.3`, "Leica AT4xx laser
tracker control modules", code no one here wrote) against the emScon server
`survey sim` serves: the set-up a client sends, a stationary measurement of
the SMR the tracker is locked on, then the positioning commands a survey of
several SMRs uses (`ES_C_GoPosition` beside the SMR, `ES_C_FindReflector`,
a measurement there), and a search where there is no reflector.

    python3 cesapi_client.py HOST PORT

Prints one JSON line: {"status", "first": [x, y, z], "found": [x, y, z],
"nowhere": "<cesapi's exception text>", "commands": [...]}.

cesapi's quirks, which the simulator must live with: its signatures are
alphabetical (`GoPosition(bUseADM, dVal1, dVal2, dVal3)`), it reads every
answer at its full size (even a failed one) and raises on any non-zero
status, it sleeps 0.2 s after each packet it receives.
"""
import json
import math
import sys

import CESAPI.command
import CESAPI.connection
import CESAPI.packet as P


def main():
    host, port = sys.argv[1], int(sys.argv[2])
    conn = CESAPI.connection.Connection()
    stream = conn.connect(host=host, port=port)
    sent = []
    write = stream.write

    def logged(packet):
        sent.append(packet.packetInfo.command)
        return write(packet)

    stream.write = logged
    cmd = CESAPI.command.CommandSync(conn)
    out = {}
    try:
        status = cmd.GetSystemStatus()
        out["serial"] = status.lTrackerSerialNumber
        if status.trackerProcessorStatus != P.ES_TPS_Initialized:
            cmd.Initialize()
        units = P.SystemUnitsDataT()
        units.lenUnitType = P.ES_LU_Millimeter
        units.angUnitType = P.ES_AU_Degree
        units.tempUnitType = P.ES_TU_Celsius
        units.pressUnitType = P.ES_PU_Mbar
        units.humUnitType = P.ES_HU_RH
        cmd.SetUnits(units)
        cmd.SetCoordinateSystemType(P.ES_CS_RHR)
        cmd.SetMeasurementMode(P.ES_MM_Stationary)
        params = P.StationaryModeDataT()
        params.lMeasTime = 1000
        params.bUseADM = 0
        cmd.SetStationaryModeParams(params)
        m = cmd.StartMeasurement()
        first = [m.dVal1, m.dVal2, m.dVal3]
        out["first"] = first
        out["air"] = [m.dTemperature, m.dPressure, m.dHumidity]
        # Point a few millimetres beside the SMR, search there, measure.
        x, y, z = first[0] + 4.0, first[1] - 3.0, first[2] + 2.0
        cmd.GoPosition(0, x, y, z)
        cmd.FindReflector(math.sqrt(x * x + y * y + z * z))
        m = cmd.StartMeasurement()
        out["found"] = [m.dVal1, m.dVal2, m.dVal3]
        # Where there is no reflector: the search fails with a result status.
        cmd.GoPosition(0, 100.0, 200.0, 300.0)
        try:
            cmd.FindReflector(math.sqrt(100.0**2 + 200.0**2 + 300.0**2))
            out["nowhere"] = None
        except Exception as e:  # CommandSync raises "Command 63 failed with status S"
            out["nowhere"] = str(e)
        out["status"] = "ok"
    except Exception as e:
        out["status"] = f"failed: {e}"
    finally:
        conn.disconnect()
    out["commands"] = sent
    print(json.dumps(out))
    return 0 if out["status"] == "ok" else 1


if __name__ == "__main__":
    sys.exit(main())
