//! `survey resume --config FILE`: an interrupted survey goes on with new
//! transport addresses (a re-plugged adapter's new device path, a new port
//! or host), and nothing else may differ from the configuration it was
//! started with.
//!
//! The two configurations are compared as the survey stores them (every key
//! with its default filled in), key by key. A difference is accepted only in
//! a transport address: `positioner.address` (scpi-tcp, modbus-tcp),
//! `positioner.port` (scpi-serial, modbus-rtu, canopen over slcan),
//! `positioner.interface` (canopen over SocketCAN), `tracker.address`,
//! `autocollimator.port`, and only with the same driver. Any other (a baud
//! rate, a node id, a register map, the plan, the asset) is refused, naming
//! the first key that differs.
//!
//! A device path (a serial port) is checked before it is ever opened, from
//! its metadata and sysfs alone (no `open`, which on a serial line may
//! toggle DTR and reset what is behind it): it must be a character device
//! whose class is `tty` in `/sys/dev/char/MAJOR:MINOR/subsystem` (a serial
//! port: ttyS, ttyUSB, ttyACM, ...) with a device behind it
//! (`/sys/dev/char/MAJOR:MINOR/device`: a UART, a USB-serial adapter, an
//! ACM modem), or a pseudo-terminal's slave (majors 136 to 143, what
//! `survey sim` serves a serial instrument on). A regular file, a folder, a
//! block device, a pipe, a virtual terminal (a console `/dev/tty0`, the
//! multiplexer `/dev/ptmx`), another kind of character device (a disk,
//! `/dev/null`, a sound card) is refused. What this cannot tell: whether the
//! serial port is the same adapter as before (no udev here; two adapters of
//! one kind look alike).

use super::SurveyConfig;
use serde_json::Value;
use std::os::unix::fs::FileTypeExt as _;
use std::os::unix::fs::MetadataExt as _;
use std::path::Path;

/// The keys that hold a transport address: what `resume --config` may change.
pub const ADDRESS_KEYS: [&str; 5] =
    ["positioner.address", "positioner.port", "positioner.interface", "tracker.address", "autocollimator.port"];

/// One address changed: the key, the stored value and the new one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AddressChange {
    pub key: String,
    pub from: String,
    pub to: String,
}

impl std::fmt::Display for AddressChange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {} -> {}", self.key, self.from, self.to)
    }
}

fn shown(v: Option<&Value>) -> String {
    match v {
        None | Some(Value::Null) => "(none)".into(),
        Some(Value::String(s)) => s.clone(),
        Some(other) => other.to_string(),
    }
}

/// Every key (dotted) where `a` and `b` differ, in order.
fn differences(prefix: &str, a: Option<&Value>, b: Option<&Value>, out: &mut Vec<(String, String, String)>) {
    match (a, b) {
        (Some(Value::Object(x)), Some(Value::Object(y))) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                differences(&key, x.get(k), y.get(k), out);
            }
        }
        (a, b) if a == b => {}
        (a, b) => out.push((prefix.to_string(), shown(a), shown(b))),
    }
}

/// The address changes from the configuration a survey was started with
/// (`stored`) to `new`, or the first other difference, in words naming its
/// key.
pub fn address_changes(stored: &SurveyConfig, new: &SurveyConfig) -> Result<Vec<AddressChange>, String> {
    let (a, b) = (
        serde_json::to_value(stored).map_err(|e| e.to_string())?,
        serde_json::to_value(new).map_err(|e| e.to_string())?,
    );
    let mut found = Vec::new();
    differences("", Some(&a), Some(&b), &mut found);
    let mut changes = Vec::new();
    for (key, from, to) in found {
        if !ADDRESS_KEYS.contains(&key.as_str()) {
            return Err(format!(
                "`{key}` is {to} here and was {from} when the survey started: resume takes new transport addresses \
                 only ({}); anything else is a new survey (`survey run`)",
                ADDRESS_KEYS.join(", ")
            ));
        }
        changes.push(AddressChange { key, from, to });
    }
    Ok(changes)
}

/// The serial device paths of a configuration, with their keys.
pub fn device_paths(config: &SurveyConfig) -> Vec<(&'static str, String)> {
    let v = serde_json::to_value(config).unwrap_or_default();
    let mut out = Vec::new();
    for key in ["positioner.port", "autocollimator.port"] {
        let (section, field) = key.split_once('.').expect("dotted");
        if let Some(Value::String(p)) = v.get(section).and_then(|s| s.get(field)) {
            out.push((key, p.clone()));
        }
    }
    out
}

/// What kind of serial line the device at `path` is, found without opening
/// it (see the module's documentation), or why it is not one.
pub fn serial_line(path: &Path) -> Result<String, String> {
    let meta = std::fs::metadata(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let kind = meta.file_type();
    if !kind.is_char_device() {
        let what = if meta.is_dir() {
            "a folder"
        } else if meta.is_file() {
            "a regular file"
        } else if kind.is_block_device() {
            "a block device (a disk)"
        } else if kind.is_fifo() {
            "a named pipe"
        } else {
            "not a device"
        };
        return Err(format!("{} is {what}, not a serial port", path.display()));
    }
    let rdev = meta.rdev();
    let (major, minor) = (((rdev >> 8) & 0xfff) | ((rdev >> 32) & !0xfff), (rdev & 0xff) | ((rdev >> 12) & !0xff));
    let class = std::fs::read_link(format!("/sys/dev/char/{major}:{minor}/subsystem"))
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()));
    // A pseudo-terminal's slave (what `survey sim` serves on); a tty with a
    // device behind it (a UART, a USB adapter, an ACM modem). A virtual tty
    // (a console `/dev/tty0`, the multiplexer `/dev/ptmx`) has none.
    let hardware = Path::new(&format!("/sys/dev/char/{major}:{minor}/device")).exists();
    match class.as_deref() {
        _ if (136..=143).contains(&major) => Ok(format!("a pseudo-terminal (character device {major}:{minor})")),
        Some("tty") if hardware => Ok(format!("a serial port (character device {major}:{minor}, class tty)")),
        Some("tty") => Err(format!(
            "{} is a virtual terminal ({major}:{minor}: a console or the pseudo-terminal multiplexer), not a serial \
             port",
            path.display()
        )),
        Some(other) => Err(format!(
            "{} is a character device of class {other} ({major}:{minor}), not a serial port",
            path.display()
        )),
        None => Err(format!("{} is a character device ({major}:{minor}) that is not a serial port", path.display())),
    }
}

/// Whether `token` (a word of a sentence) is a local path: it begins with
/// `/` and names something under it (`/dev/ttyUSB0`, `/tmp/x/positioner`).
fn is_local_path(token: &str) -> bool {
    token.starts_with('/') && !token.trim_matches(|c: char| c == '/' || c == '.').is_empty()
}

/// Splits `text` into words and what is between them, and maps each word
/// that is a local path through `f` (`None`: dropped with the space before it).
fn map_paths(text: &str, mut f: impl FnMut(Option<&str>) -> Option<&'static str>) -> String {
    let mut out = String::with_capacity(text.len());
    let mut previous: Option<&str> = None;
    let mut rest = text;
    while !rest.is_empty() {
        let start = rest.find(|c: char| !is_break(c)).unwrap_or(rest.len());
        let (gap, after) = rest.split_at(start);
        let end = after.find(is_break).unwrap_or(after.len());
        let (word, tail) = after.split_at(end);
        // A sentence's colon or full stop after a path is the sentence's.
        let path = word.trim_end_matches([':', '.']);
        match is_local_path(path).then(|| f(previous)) {
            Some(None) => out.extend([gap.trim_end_matches(' '), &word[path.len()..]]),
            Some(Some(said)) => out.extend([gap, said, &word[path.len()..]]),
            None => out.extend([gap, word]),
        }
        if !word.is_empty() {
            previous = Some(word);
        }
        rest = tail;
    }
    out
}

/// What ends a word: white space, quotes, brackets and the punctuation after one.
fn is_break(c: char) -> bool {
    c.is_whitespace() || "\"'()[]{}<>,;=`".contains(c)
}

/// `text` with every local path (a device's, a file's: a serial adapter's
/// `/dev/serial/by-id/...` carries its serial number) said as
/// `(a local path)`: what the lab's pages and `/api/` show of an event.
/// A URL's path (`postgres://host/db`) is not one.
pub fn without_local_paths(text: &str) -> String {
    map_paths(text, |_| Some("(a local path)"))
}

/// An instrument as stored in a survey (`modbus-rtu /dev/ttyUSB0 slave 1`)
/// as the pages, the certificate and the DCC name it: by its driver and
/// transport (`modbus-rtu (serial port) slave 1`, `canopen slcan node 3`,
/// `scpi-serial`), never by a local path. A network address stays.
pub fn instrument_words(described: &str) -> String {
    map_paths(described, |before| match before {
        Some(w) if w == "slcan" || w.ends_with("-serial") => None,
        _ => Some("(serial port)"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SERIAL: &str = "[positioner]\ndriver = \"scpi-serial\"\nport = \"/dev/ttyUSB0\"\n\n[tracker]\ndriver = \
                          \"emscon\"\naddress = \"10.0.0.5:700\"\n";

    fn config(text: &str) -> SurveyConfig {
        SurveyConfig::parse(text, "c.toml").unwrap()
    }

    #[test]
    fn only_transport_addresses_may_change_and_any_other_key_is_named() {
        let stored = config(SERIAL);
        assert_eq!(address_changes(&stored, &stored).unwrap(), []);
        let moved = config(&SERIAL.replace("/dev/ttyUSB0", "/dev/ttyUSB1").replace("10.0.0.5", "10.0.0.6"));
        let changes = address_changes(&stored, &moved).unwrap();
        assert_eq!(changes.len(), 2);
        assert_eq!(changes[0].to_string(), "positioner.port: /dev/ttyUSB0 -> /dev/ttyUSB1");
        assert_eq!(changes[1].to_string(), "tracker.address: 10.0.0.5:700 -> 10.0.0.6:700");
        let baud = config(&SERIAL.replace("port = \"/dev/ttyUSB0\"", "port = \"/dev/ttyUSB1\"\nbaud = 19200"));
        let e = address_changes(&stored, &baud).unwrap_err();
        assert!(e.starts_with("`positioner.baud` is 19200 here and was 9600"), "{e}");
        let driver = config(&SERIAL.replace("scpi-serial", "modbus-rtu"));
        assert!(address_changes(&stored, &driver).unwrap_err().contains("`positioner."), "another driver");
        assert_eq!(device_paths(&stored), [("positioner.port", "/dev/ttyUSB0".to_string())]);
    }

    #[test]
    fn a_device_path_is_a_serial_line_or_refused_without_opening_it() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f");
        std::fs::write(&file, "x").unwrap();
        assert!(serial_line(&file).unwrap_err().contains("a regular file"));
        assert!(serial_line(dir.path()).unwrap_err().contains("a folder"));
        assert!(serial_line(Path::new("/dev/null")).unwrap_err().contains("not a serial port"));
        assert!(serial_line(&dir.path().join("none")).is_err());
        // The terminal multiplexer and a console are ttys with no device behind them.
        for virtual_tty in ["/dev/ptmx", "/dev/tty0"] {
            if Path::new(virtual_tty).exists() {
                assert!(serial_line(Path::new(virtual_tty)).is_err(), "{virtual_tty}");
            }
        }
        // A pseudo-terminal's slave is what `survey sim` serves on.
        let pts = std::fs::read_dir("/dev/pts").into_iter().flatten().flatten().map(|e| e.path());
        if let Some(slave) = pts.into_iter().find(|p| p.file_name().is_some_and(|n| n != "ptmx")) {
            assert!(serial_line(&slave).unwrap().contains("pseudo-terminal"), "{}", slave.display());
        }
    }

    #[test]
    fn local_paths_are_not_shown_on_the_pages() {
        assert_eq!(instrument_words("modbus-rtu /dev/ttyUSB0 slave 1"), "modbus-rtu (serial port) slave 1");
        assert_eq!(instrument_words("scpi-serial /dev/serial/by-id/usb-FTDI_A12345-if00"), "scpi-serial");
        assert_eq!(instrument_words("canopen slcan /tmp/survey-sim-x/positioner node 3"), "canopen slcan node 3");
        assert_eq!(instrument_words("elcomat /tmp/s/autocollimator"), "elcomat (serial port)");
        assert_eq!(instrument_words("modbus-tcp 192.168.1.40:502"), "modbus-tcp 192.168.1.40:502");
        assert_eq!(
            without_local_paths("positioner.port: /dev/ttyUSB0 -> /dev/ttyUSB1; cannot open (/tmp/a/b): gone"),
            "positioner.port: (a local path) -> (a local path); cannot open ((a local path)): gone"
        );
        assert_eq!(without_local_paths("\"/dev/ttyACM0\", 3 / 4 deg/s"), "\"(a local path)\", 3 / 4 deg/s");
        assert_eq!(without_local_paths("postgres://lab.example/survey"), "postgres://lab.example/survey");
        assert_eq!(without_local_paths("full at /tmp/x/survey.db: stop."), "full at (a local path): stop.");
    }
}
