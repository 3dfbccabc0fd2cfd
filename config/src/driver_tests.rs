//! Every driver's section: its settings read, a misspelt key refused, the engine's deadline beyond the driver's own.

use super::*;

#[test]
fn every_driver_reads_its_settings_and_refuses_a_misspelt_one() {
    let tracker = "[tracker]\ndriver = \"emscon\"\naddress = \"10.0.0.5:700\"\nmeasurement_time_ms = 500\n";
    let cfg = SurveyConfig::parse(
        &format!("[positioner]\ndriver = \"canopen\"\ninterface = \"can0\"\nnode_id = 5\n{tracker}"),
        "c.toml",
    )
    .unwrap();
    let PositionerConfig::Canopen { drive, .. } = &cfg.positioner else { panic!() };
    assert_eq!(cfg.positioner.can_link(), Some(Ok(CanLink::SocketCan("can0".into()))));
    assert_eq!(drive.node_id, 5);
    let slcan = SurveyConfig::parse(
        &format!(
            "[positioner]\ndriver = \"canopen\"\ntransport = \"slcan\"\nport = \"/dev/ttyACM0\"\nnode_id = 5\n{tracker}"
        ),
        "c.toml",
    )
    .unwrap();
    let link = CanLink::Slcan { port: "/dev/ttyACM0".into(), bitrate: DEFAULT_CAN_BITRATE };
    assert_eq!(slcan.positioner.can_link(), Some(Ok(link)));
    for (bad, why) in [
        ("transport = \"slcan\"\n", "c.toml:1: positioner.port: missing: transport = \"slcan\" needs"),
        (
            "transport = \"slcan\"\nport = \"/dev/x\"\nbitrate = 12345\n",
            "c.toml:5: positioner.bitrate: 12345 has no SLCAN command",
        ),
        ("", "c.toml:1: positioner.interface: missing: a CANopen drive on SocketCAN needs it"),
        ("interface = \"can0\"\nport = \"/dev/x\"\n", "c.toml:4: positioner.port: is for transport = \"slcan\""),
    ] {
        let e = SurveyConfig::parse(&format!("[positioner]\ndriver = \"canopen\"\n{bad}{tracker}"), "c.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(why), "{bad}: {e}");
    }
    let Some(TrackerConfig::Emscon { settings, .. }) = &cfg.tracker else { panic!() };
    assert_eq!(settings.measurement_time_ms, 500);
    for (bad, says) in [
        (format!("[positioner]\ndriver = \"canopen\"\ninterface = \"can0\"\nnode = 5\n{tracker}"), "4: positioner.node: no such key"),
        (format!("[positioner]\ndriver = \"modbus-tcp\"\naddress = \"h:502\"\n[positioner.map]\nunit = 2\n{tracker}"), "5: positioner.map.unit: no such key"),
        ("[positioner]\ndriver = \"modbus-tcp\"\naddress = \"h:502\"\n[tracker]\ndriver = \"emscon\"\naddress = \"h:700\"\nmeasurement_time = 1\n".to_string(), "7: tracker.measurement_time: no such key"),
        // Serde let these through silently: a misspelt deadline of the tracker, a key in the encoding.
        (format!("[positioner]\ndriver = \"canopen\"\ninterface = \"can0\"\n{tracker}[tracker.timeouts]\nrequest = 1\n"), "9: tracker.timeouts.request: no such key in [tracker.timeouts]; did you mean request_ms?"),
        (format!("[positioner]\ndriver = \"modbus-tcp\"\naddress = \"h:502\"\nmap = {{ position_encoding = {{ kind = \"float32\", x = 1 }} }}\n{tracker}"), "4: positioner.map.position_encoding.x: no such key"),
    ] {
        let e = SurveyConfig::parse(&bad, "c.toml").unwrap_err().to_string();
        assert!(e.starts_with(&format!("c.toml:{says}")), "{bad}\n-> {e}");
    }
}

/// The engine's deadline of a call must be longer than the positioner
/// driver's own and the drain of late replies after it: refused when
/// read, naming both keys.
#[test]
fn the_engine_deadline_is_longer_than_the_drivers_own() {
    let tracker = "[tracker]\ndriver = \"emscon\"\naddress = \"h:700\"\n";
    let rtu = "[positioner]\ndriver = \"modbus-rtu\"\nport = \"/dev/ttyUSB0\"\n";
    let can = "[positioner]\ndriver = \"canopen\"\ninterface = \"can0\"\n";
    let tcp = "[positioner]\ndriver = \"modbus-tcp\"\naddress = \"h:502\"\n";
    for (positioner, timing, says) in [
        (
            rtu,
            "call_timeout_s = 1.4\n",
            "positioner.timeouts.request_ms (not given: 1000 ms) and the 500 ms it then drains",
        ),
        (can, "call_timeout_s = 0.75\n", "positioner.sdo_timeout_ms (not given: 500 ms) and the 250 ms it then drains"),
        (tcp, "call_timeout_s = 1.0\n", "positioner.timeouts.request_ms (not given: 1000 ms):"),
    ] {
        let e =
            SurveyConfig::parse(&format!("{positioner}{tracker}[timing]\n{timing}"), "c.toml").unwrap_err().to_string();
        assert!(e.starts_with("c.toml:8: timing.call_timeout_s: ") && e.contains(says), "{positioner}: {e}");
    }
    // The defaults (2 s for a call) are longer than every driver's own.
    for positioner in [rtu, can, tcp] {
        SurveyConfig::parse(&format!("{positioner}{tracker}"), "c.toml").unwrap();
    }
    let fast = format!("{rtu}timeouts = {{ request_ms = 100 }}\n{tracker}[timing]\ncall_timeout_s = 0.2\n");
    SurveyConfig::parse(&fast, "c.toml").unwrap();
}
