//! Where `survey sim` serves a configuration written for the real bench, and
//! the configuration it writes to run against.
//!
//! A bench's configuration names its instruments' real addresses: a TCP
//! address on the lab's network, a serial device under `/dev`, a SocketCAN
//! interface. The simulators stand in for them on this machine:
//!
//! - a TCP address that is not on loopback is served on `127.0.0.1` at a
//!   free port (a loopback address is served as configured);
//! - a serial port under `/dev/` is a pseudo-terminal linked in the sim's own
//!   folder (`<folder>/positioner`, `<folder>/autocollimator`); any other path
//!   is served as configured;
//! - a CANopen drive on a SocketCAN interface this machine does not have is
//!   served behind a simulated USB-CAN adapter (SLCAN) on a pseudo-terminal in
//!   that folder.
//!
//! The folder is a temporary one (`survey-sim-*` in the system's temporary
//! folder), removed when `survey sim` stops. It also holds the configuration
//! to run against: the given one with every instrument's address replaced by
//! where it is served (a TCP port 0 by the port taken), everything else as it
//! was. Our own design.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use survey_store::error::bad_input;

/// The sim's folder and what it changed of the configuration.
#[derive(Debug)]
pub struct StandIns {
    dir: tempfile::TempDir,
    /// `(section, key, value)`: the value served (`None`: the key removed).
    rewrites: Vec<(&'static str, &'static str, Option<toml::Value>)>,
    /// What was moved, for the operator: `positioner: 192.168.1.40:502 -> 127.0.0.1:40123`.
    pub moved: Vec<String>,
}

impl StandIns {
    pub fn new() -> anyhow::Result<Self> {
        let dir = tempfile::Builder::new()
            .prefix("survey-sim-")
            .tempdir()
            .map_err(|e| survey_store::error::path_error(e, "survey sim: cannot make its temporary folder".into()))?;
        Ok(Self { dir, rewrites: Vec::new(), moved: Vec::new() })
    }

    /// The sim's folder.
    pub fn dir(&self) -> &Path {
        self.dir.path()
    }

    /// The address to listen on for `configured` (`host:port`): itself on
    /// loopback (`localhost` is 127.0.0.1), else a free loopback port (a host
    /// name is never looked up: it is the lab's).
    pub fn tcp(&self, what: &str, configured: &str) -> anyhow::Result<SocketAddr> {
        let any = SocketAddr::from(([127, 0, 0, 1], 0));
        if let Ok(addr) = configured.parse::<SocketAddr>() {
            return Ok(if addr.ip().is_loopback() { addr } else { any });
        }
        match configured.rsplit_once(':').map(|(h, p)| (h, p.parse::<u16>())) {
            Some(("localhost", Ok(port))) => Ok(SocketAddr::from(([127, 0, 0, 1], port))),
            Some((host, Ok(_))) if !host.is_empty() => Ok(any),
            _ => Err(bad_input(format!("{what}: '{configured}' is not a host:port address"))),
        }
    }

    /// The path to link a serial instrument's pseudo-terminal at for
    /// `configured`: in the sim's folder for a device under `/dev/`, else itself.
    pub fn serial(&self, what: &str, configured: &str) -> String {
        if configured.starts_with("/dev/") { self.dir().join(what).display().to_string() } else { configured.into() }
    }

    /// `section.key` is served at `served` (configured as `configured`).
    pub fn served(&mut self, section: &'static str, key: &'static str, configured: &str, served: &str) {
        if configured != served {
            self.moved.push(format!("{section}: {configured} -> {served}"));
        }
        self.rewrites.push((section, key, Some(toml::Value::String(served.into()))));
    }

    /// The instruments run `scale` times faster than the hardware: the
    /// configuration to run against says so (`[timing] time_scale`), so a
    /// survey reports its instrument time on the instruments' clock (and
    /// refuses what needs real time, a continuous scan). Nothing is written
    /// at 1.
    pub fn time_scale(&mut self, scale: f64) {
        if scale != 1.0 {
            self.rewrites.push(("timing", "time_scale", Some(toml::Value::Float(scale))));
        }
    }

    /// The configuration to run against says its instruments are simulated
    /// (`[rehearsal] simulator`), and the survey records it: a rehearsal,
    /// never a calibration.
    pub fn rehearsal(&mut self, simulator: String) {
        self.rewrites.push(("rehearsal", "simulator", Some(toml::Value::String(simulator))));
    }

    /// `section.key` is left out of the configuration to run against.
    pub fn removed(&mut self, section: &'static str, key: &'static str) {
        self.rewrites.push((section, key, None));
    }

    /// The simulated bench's machine frame (a model file's
    /// `[machine_frame]`): the configuration to run against states it, as
    /// `survey run --model` stores it with the survey, in place of any the
    /// configuration gave (that is the real bench's).
    pub fn machine_frame(&mut self, f: &survey_processing::frame::MachineFrame, configured: bool) {
        let three = |v: [f64; 3]| Some(toml::Value::Array(v.map(toml::Value::Float).to_vec()));
        self.rewrites.push(("machine_frame", "origin_mm", three(f.origin_mm)));
        self.rewrites.push(("machine_frame", "rotation_deg", three(f.rotation_deg)));
        self.rewrites.push(("machine_frame", "origin_u_mm", f.origin_u_mm.map(toml::Value::Float)));
        self.rewrites.push(("machine_frame", "rotation_u_deg", f.rotation_u_deg.map(toml::Value::Float)));
        self.moved.push(format!(
            "machine_frame: the model file's (the simulated bench's){}",
            if configured { ", in place of the configuration's" } else { "" }
        ));
    }

    /// Write the configuration to run against: `original` (the text of
    /// `source`) with the served addresses, in the sim's folder; its path.
    pub fn write_config(&self, original: &str, source: &Path) -> anyhow::Result<PathBuf> {
        let mut cfg: toml::Table =
            original.parse().map_err(|e| bad_input(format!("{}: not a TOML table: {e}", source.display())))?;
        for (section, key, value) in &self.rewrites {
            let table = cfg
                .entry(*section)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()))
                .as_table_mut()
                .ok_or_else(|| bad_input(format!("{}: [{section}] is not a table", source.display())))?;
            match value {
                Some(v) => table.insert((*key).into(), v.clone()),
                None => table.remove(*key),
            };
        }
        let name = source.file_name().map_or_else(|| "config.toml".into(), |n| n.to_string_lossy().into_owned());
        let path = self.dir().join(name);
        let text = format!(
            "# Written by survey sim from {}: its instruments as served on this machine.\n\
             # Valid while that survey sim runs (it removes this folder when it stops).\n\n{}",
            source.display(),
            toml::to_string(&cfg)?
        );
        std::fs::write(&path, text)
            .map_err(|e| survey_store::error::path_error(e, format!("survey sim: cannot write {}", path.display())))?;
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::StandIns;

    #[test]
    fn a_bench_address_is_served_on_loopback_and_a_device_in_the_sims_folder() {
        let s = StandIns::new().unwrap();
        let tcp = |a: &str| s.tcp("positioner", a).map(|a| a.to_string()).map_err(|e| e.to_string());
        assert_eq!(tcp("192.168.1.40:502").unwrap(), "127.0.0.1:0");
        assert_eq!(tcp("tracker.lab:700").unwrap(), "127.0.0.1:0", "a host name is the lab's: never looked up");
        assert_eq!(tcp("127.0.0.1:5020").unwrap(), "127.0.0.1:5020");
        assert_eq!(tcp("[::1]:7").unwrap(), "[::1]:7");
        assert_eq!(tcp("localhost:5020").unwrap(), "127.0.0.1:5020");
        for bad in ["no-port", ":700", "host:99999"] {
            assert!(tcp(bad).unwrap_err().contains(&format!("'{bad}' is not a host:port address")), "{bad}");
        }
        assert_eq!(s.serial("autocollimator", "/dev/ttyUSB0"), s.dir().join("autocollimator").display().to_string());
        assert_eq!(s.serial("positioner", "/tmp/bench-positioner"), "/tmp/bench-positioner");
    }

    #[test]
    fn the_configuration_written_names_what_is_served_and_keeps_the_rest() {
        let mut s = StandIns::new().unwrap();
        s.served("positioner", "transport", "socketcan", "slcan");
        s.served("positioner", "port", "can0", "/tmp/p");
        s.removed("positioner", "interface");
        s.served("tracker", "address", "10.0.0.5:700", "127.0.0.1:4000");
        assert_eq!(
            s.moved,
            ["positioner: socketcan -> slcan", "positioner: can0 -> /tmp/p", "tracker: 10.0.0.5:700 -> 127.0.0.1:4000"]
        );
        let original = "# mine\n[positioner]\ndriver = \"canopen\"\ninterface = \"can0\"\nnode_id = 5\n\
                        [tracker]\ndriver = \"emscon\"\naddress = \"10.0.0.5:700\"\n";
        let path = s.write_config(original, std::path::Path::new("/x/bench.toml")).unwrap();
        assert_eq!(path, s.dir().join("bench.toml"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("# Written by survey sim from /x/bench.toml"), "{text}");
        let cfg: toml::Table = text.parse().unwrap();
        let p = &cfg["positioner"];
        assert_eq!(
            (p["transport"].as_str(), p["port"].as_str(), p.get("interface")),
            (Some("slcan"), Some("/tmp/p"), None)
        );
        assert_eq!((p["driver"].as_str(), p["node_id"].as_integer()), (Some("canopen"), Some(5)));
        assert_eq!(cfg["tracker"]["address"].as_str(), Some("127.0.0.1:4000"));
        assert!(cfg.get("machine_frame").is_none(), "none stated, none written");
        // A model file's machine frame replaces the configuration's, keys and all.
        let frame = survey_processing::frame::MachineFrame {
            origin_mm: [2500.0, 800.0, -300.0],
            rotation_deg: [0.0, 0.3, 30.0],
            origin_u_mm: Some(0.05),
            rotation_u_deg: None,
        };
        s.machine_frame(&frame, true);
        let original = format!("{original}[machine_frame]\norigin_mm = [0, 0, 0]\nrotation_u_deg = 1\n");
        let text = std::fs::read_to_string(s.write_config(&original, std::path::Path::new("/x/bench.toml")).unwrap());
        let written: toml::Table = text.unwrap().parse().unwrap();
        let parsed = survey_processing::frame::parse_section(
            written["machine_frame"].as_table().unwrap(),
            "machine_frame",
            &|_| None,
        );
        assert_eq!(parsed, Ok(frame));
        assert!(s.moved.last().unwrap().contains("in place of the configuration's"), "{:?}", s.moved);
        let dir = s.dir().to_path_buf();
        drop(s);
        assert!(!dir.exists(), "the folder goes with the sim");
    }
}
