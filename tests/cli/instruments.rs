//! `survey check --config` and `survey run --config`, from outside: against
//! simulators speaking the real protocols, and against addresses where
//! nothing answers.

use super::Bench;
use serde_json::Value;
use std::sync::Arc;
use survey_drivers::{Clock, VirtualClock};
use survey_sim_servers::elcomat_server::{pty_pair, serve};
use survey_sim_servers::scpi_server::serve_tcp;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::faults::Faults;
use survey_sims::{Preset, SimBench};
use tokio_serial::SerialPort as _;

/// A configuration for an SCPI positioner at `address` and an ELCOMAT on `port`.
fn config(address: &str, port: &str) -> String {
    format!(
        "[survey]\npoints = 24\nruns = 2\nbidirectional = true\nreference = \"autocollimator\"\n\
         [positioner]\ndriver = \"scpi-tcp\"\naddress = \"{address}\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"{port}\"\nbaud = 115200\n\
         [polygon]\nfaces = 24\n\
         [timing]\ncall_timeout_s = 0.5\nmeasure_timeout_s = 1.0\n"
    )
}

#[test]
fn check_says_which_instrument_is_unreachable() {
    let bench = Bench::new();
    // Port 1 on loopback refuses connections; the serial port does not exist.
    bench.write("c.toml", config("127.0.0.1:1", "/nonexistent/ttyX"));
    let out = bench.survey(&["check", "--config", "c.toml", "--json"]);
    assert_eq!(out.code, 1, "{out}");
    let doc: Value = serde_json::from_str(&out.stdout).expect("one JSON document");
    assert_eq!(doc["ok"], false);
    let lines = doc["instruments"].as_array().unwrap();
    assert_eq!(lines.len(), 2);
    for l in lines {
        assert_eq!(l["ok"], false, "{l}");
        assert_eq!(l["verdict"], "address unreachable", "{l}");
    }
    assert!(out.stderr.contains("2 of 2 instruments failed the check"), "{out}");
    assert!(!bench.exists("survey.db"), "check stores nothing");
}

#[test]
fn check_says_when_the_device_speaks_another_protocol() {
    // A TCP server that answers every line with binary garbage.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    std::thread::spawn(move || {
        use std::io::{Read, Write};
        if let Ok((mut s, _)) = listener.accept() {
            let mut buf = [0u8; 256];
            while let Ok(n) = s.read(&mut buf) {
                if n == 0 || s.write_all(&[0xff, 0xfe, 0x00, b'\n']).is_err() {
                    break;
                }
            }
        }
    });
    let bench = Bench::new();
    bench.write("c.toml", config(&address, "/nonexistent/ttyX"));
    let out = bench.survey(&["check", "--config", "c.toml"]);
    assert_eq!(out.code, 1, "{out}");
    let positioner = out.stdout.lines().find(|l| l.starts_with("positioner")).expect("a positioner line");
    assert!(positioner.contains("wrong protocol"), "{out}");
}

#[test]
fn check_passes_against_simulators_speaking_the_protocols() {
    survey_store::runtime::block_on_bounded(2, async {
        let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
        let preset = Preset::by_name("fig8").unwrap();
        let sims = SimBench::builder(&preset, 3, clock).autocollimator(AutocollimatorConfig::seeded(24, 4)).build();
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let address = listener.local_addr().unwrap().to_string();
        let server = tokio::spawn(serve_tcp(listener, sims.positioner, Faults::new()));
        let (master, slave) = pty_pair().unwrap();
        let port = slave.name().expect("the pty has a path");
        let bench = Bench::new();
        bench.write("c.toml", config(&address, &port));
        // Keep our slave open until the survey binary has opened the port, so the
        // master does not read EIO; the binary's open is not exclusive of ours.
        let elcomat = tokio::spawn(serve(master, sims.autocollimator));
        let out = tokio::task::spawn_blocking(move || {
            let out = bench.survey(&["check", "--config", "c.toml", "--json"]);
            drop(slave);
            out
        })
        .await
        .unwrap();
        server.abort();
        elcomat.abort();
        assert_eq!(out.code, 0, "{out}");
        let doc: Value = serde_json::from_str(&out.stdout).unwrap();
        assert_eq!(doc["ok"], true, "{out}");
        let lines = doc["instruments"].as_array().unwrap();
        assert_eq!(lines[0]["instrument"], "positioner");
        assert!(lines[0]["detail"].as_str().unwrap().contains("readout 0 deg"), "{out}");
        // What the controller says it is (*IDN?), as it says it.
        let idn = "identifies itself as \"survey-sims,MI-4190-style positioner controller (simulated),0,1.0\"";
        assert!(lines[0]["detail"].as_str().unwrap().ends_with(idn), "{out}");
        assert_eq!(lines[1]["verdict"], "ok");
    })
    .expect("a runtime");
}

#[test]
fn a_bad_configuration_is_bad_input_naming_the_file_and_line() {
    let bench = Bench::new();
    bench.write("c.toml", "[positioner]\ndriver = \"scpi-tcp\"\nadress = \"10.0.0.1:4000\"\n");
    let out = bench.survey(&["run", "--config", "c.toml"]);
    assert_eq!(out.code, 2, "{out}");
    assert!(out.stderr.contains("c.toml:3: positioner.adress: no such key") && out.stderr.contains("address"), "{out}");
    assert!(!bench.exists("survey.db"), "nothing stored");
    let out = bench.survey(&["check", "--config", "missing.toml"]);
    assert_eq!(out.code, 2, "{out}");
    assert!(out.stderr.contains("missing.toml"), "{out}");
    // Simulation flags make no sense with real instruments.
    bench.write("ok.toml", config("127.0.0.1:1", "/nonexistent/ttyX"));
    let out = bench.survey(&["run", "--config", "ok.toml", "--preset", "fig4"]);
    assert_eq!(out.code, 2, "{out}");
}

#[test]
fn a_survey_of_unreachable_instruments_fails_at_run_time_and_can_be_resumed_later() {
    let bench = Bench::new();
    bench.write(
        "c.toml",
        config("127.0.0.1:1", "/nonexistent/ttyX")
            .replace("[timing]\n", "[timing]\nmax_retries = 1\nretry_backoff_s = 0.01\n"),
    );
    let out = bench.survey(&["run", "--config", "c.toml"]);
    assert_eq!(out.code, 1, "{out}");
    assert!(out.stderr.contains("cannot connect") && out.stderr.contains("survey resume --survey 1"), "{out}");
    // The survey is kept as interrupted, with its configuration, for `resume`.
    let out = bench.survey(&["resume"]);
    assert_eq!(out.code, 1, "{out}");
    assert!(out.stderr.contains("resumed at step 0"), "{out}");
}

#[test]
fn a_tiny_or_huge_timing_value_is_bad_input_naming_its_key_never_a_panic() {
    let bench = Bench::new();
    for (value, key) in [
        ("velocity_deg_s = 1e-300", "timing.velocity_deg_s: 1e-300"),
        ("accel_deg_s2 = 1e-300", "timing.accel_deg_s2: 1e-300"),
        ("scan_velocity_deg_s = 1e-300", "timing.scan_velocity_deg_s: 1e-300"),
        ("calibration_velocity_deg_s = 1e-300", "timing.calibration_velocity_deg_s: 1e-300"),
    ] {
        let text = config("127.0.0.1:1", "/nonexistent/ttyX").replace("[timing]\n", &format!("[timing]\n{value}\n"));
        bench.write("c.toml", text);
        for command in ["run", "check"] {
            let out = bench.survey(&[command, "--config", "c.toml"]);
            assert_eq!(out.code, 2, "{value}: {out}");
            assert!(out.stderr.contains("c.toml") && out.stderr.contains(key), "{out}");
            assert!(!out.stderr.contains("panicked"), "{out}");
        }
        assert!(!bench.exists("survey.db"), "nothing stored");
    }
}

/// Issue 51, item 3: a serial port that is there but is not a serial line
/// (`/dev/null`, a regular file, a folder, a console) is refused by `run`
/// and `check` at its line and key, before anything is stored or opened.
#[test]
fn a_device_path_that_is_not_a_serial_line_is_refused_by_run_and_check() {
    let bench = Bench::new();
    bench.write("plain.txt", "not a tty");
    let port_line = config("127.0.0.1:1", "X").lines().position(|l| l.starts_with("port =")).unwrap() + 1;
    let mut devices = vec![("/dev/null", "not a serial port"), ("plain.txt", "a regular file"), (".", "a folder")];
    if std::path::Path::new("/dev/tty0").exists() {
        devices.push(("/dev/tty0", "not a serial port"));
    }
    for (port, what) in devices {
        bench.write("c.toml", config("127.0.0.1:1", port));
        for command in ["run", "check"] {
            bench.survey(&[command, "--config", "c.toml"]).bad_input(&[
                &format!("c.toml:{port_line}: autocollimator.port: "),
                what,
                "nothing was opened",
            ]);
        }
        assert!(!bench.exists("survey.db"), "nothing stored");
    }
}

#[test]
fn a_connection_error_names_the_instrument_and_the_cause_once() {
    let bench = Bench::new();
    bench.write(
        "c.toml",
        config("127.0.0.1:1", "/nonexistent/ttyX")
            .replace("[timing]\n", "[timing]\nmax_retries = 1\nretry_backoff_s = 0.01\n"),
    );
    let out = bench.survey(&["run", "--config", "c.toml"]);
    assert_eq!(out.code, 1, "{out}");
    let line = out.stderr.lines().find_map(|l| l.strip_prefix("error: ")).expect("an error line").to_string();
    // Each layer adds what it knows: the instrument, the kind of fault, what
    // was being done, the system's reason; none of it twice.
    assert_eq!(line.matches("127.0.0.1:1").count(), 1, "{line}");
    assert_eq!(line.matches("refused").count(), 1, "{line}");
    assert_eq!(line.matches("cannot connect").count() + line.matches("connect failed").count(), 1, "{line}");
}

/// `[polygon] turns`: the operator turns the polygon between runs; turns
/// that cannot close it are refused before anything is connected or
/// stored, naming the file; `--polygon-turns` is the simulated bench's.
#[test]
fn polygon_turns_in_a_configuration_are_checked_before_anything_is_stored() {
    let bench = Bench::new();
    let with = |turns: &str| {
        config("127.0.0.1:1", "/nonexistent/ttyX").replace("faces = 24\n", &format!("faces = 24\nturns = {turns}\n"))
    };
    for (turns, said) in [
        ("[0, 12]", "c.toml: [polygon] turns 0,12: the turns between them share a divisor with the 24 faces"),
        ("[0]", "c.toml: [polygon] turns needs two turns or more"),
        ("[0, 1, 2]", "c.toml: [polygon] turns names 3 turns but the survey has 2 runs"),
        ("[0, 30]", "c.toml: [polygon] turns: 30 faces is past the polygon's 24"),
        ("[0, -1]", "polygon.turns[1]: -1 is out of range"),
        ("[0, 1.5]", "polygon.turns[1]: 1.5 is not a whole number"),
    ] {
        bench.write("c.toml", with(turns));
        let out = bench.survey(&["run", "--config", "c.toml"]);
        assert_eq!(out.code, 2, "{turns}: {out}");
        assert!(out.stderr.contains(said), "{turns}: {out}");
    }
    bench.write("c.toml", config("127.0.0.1:1", "/nonexistent/ttyX"));
    let out = bench.survey(&["run", "--config", "c.toml", "--polygon-turns", "0,1"]);
    assert_eq!(out.code, 2, "{out}");
    assert!(out.stderr.contains("[polygon] turns"), "{out}");
    assert!(!bench.exists("survey.db"), "nothing stored");
}

/// Issue 51, item 3: `survey resume --config FILE` takes new transport
/// addresses for an interrupted survey, refuses any other difference naming
/// the key (exit 2), and records the change in the survey's events; a device
/// path that is there but is not a serial line is refused before anything
/// opens it.
#[test]
fn resume_takes_new_addresses_refuses_other_changes_and_checks_a_device_before_opening_it() {
    let bench = Bench::new();
    let base = |address: &str, port: &str| {
        config(address, port).replace("[timing]\n", "[timing]\nmax_retries = 1\nretry_backoff_s = 0.01\n")
    };
    bench.write("c.toml", base("127.0.0.1:1", "/nonexistent/ttyX"));
    assert_eq!(bench.survey(&["run", "--config", "c.toml"]).code, 1);
    let stored = || std::fs::read(bench.path("survey.db")).unwrap();
    let before = stored();
    for (name, text, key) in [
        ("baud.toml", base("127.0.0.1:1", "/nonexistent/ttyX").replace("115200", "9600"), "`autocollimator.baud`"),
        (
            "points.toml",
            base("127.0.0.1:1", "/nonexistent/ttyX").replace("points = 24", "points = 12"),
            "`survey.points`",
        ),
        (
            "axis.toml",
            base("127.0.0.1:1", "/nonexistent/ttyX")
                .replace("driver = \"scpi-tcp\"\n", "driver = \"scpi-tcp\"\naxis = 2\n"),
            "`positioner.axis`",
        ),
    ] {
        bench.write(name, text);
        bench.survey(&["resume", "--config", name]).bad_input(&[name, key, "transport addresses only"]);
    }
    // A path that is there but not a serial line: named, never opened.
    bench.write("plain.txt", "not a tty");
    for (port, what) in [("plain.txt", "is a regular file, not a serial port"), ("/dev/null", "not a serial port")] {
        bench.write("device.toml", base("127.0.0.1:1", port));
        bench.survey(&["resume", "--config", "device.toml"]).bad_input(&[
            "autocollimator.port",
            what,
            "nothing was opened",
        ]);
    }
    assert!(stored() == before, "nothing stored by a refused resume");
    // New addresses: taken, said, kept in the events and for the next resume.
    bench.write("moved.toml", base("127.0.0.1:2", "/nonexistent/ttyY"));
    let out = bench.survey(&["resume", "--config", "moved.toml"]);
    assert_eq!(out.code, 1, "{out}");
    let change =
        "autocollimator.port: /nonexistent/ttyX -> /nonexistent/ttyY; positioner.address: 127.0.0.1:1 -> 127.0.0.1:2";
    assert!(out.stderr.contains(change), "{out}");
    let events: Vec<String> = {
        let conn = rusqlite::Connection::open(bench.path("survey.db")).unwrap();
        let mut q = conn.prepare("SELECT message FROM events WHERE message LIKE 'resumed on new addresses%'").unwrap();
        q.query_map([], |r| r.get(0)).unwrap().map(Result::unwrap).collect()
    };
    assert_eq!(events.len(), 1, "{events:?}");
    assert!(events[0].contains(change), "{events:?}");
    let out = bench.survey(&["resume"]);
    assert_eq!(out.code, 1, "{out}");
    assert!(out.stderr.contains("127.0.0.1:2") && !out.stderr.contains("127.0.0.1:1 "), "{out}");
}

/// On resume, the instruments at the survey's addresses must be the ones it
/// began on: a positioner that identifies itself otherwise (here the
/// survey's record says it began on another controller; `survey sim`'s says
/// it is simulated) is refused, exit 2, with nothing stored, the new address
/// included; the same controller is taken.
#[test]
fn resume_refuses_an_instrument_that_identifies_itself_as_another() {
    let b = Bench::new();
    let config = |positioner: &str, tracker: &str| {
        format!(
            "[survey]\npoints = 4\nruns = 2\nreference = \"tracker\"\n\
             [positioner]\ndriver = \"modbus-tcp\"\naddress = \"{positioner}\"\n\
             [tracker]\ndriver = \"emscon\"\naddress = \"{tracker}\"\n\
             [timing]\ndwell_s = 0.01\nlocate_points = 4\nmax_retries = 1\nretry_backoff_s = 0.01\ntime_scale = 500\n"
        )
    };
    // Begun where nothing answers: stored, not complete, nothing identified.
    b.write("gone.toml", config("127.0.0.1:1", "127.0.0.1:2"));
    assert_eq!(b.survey(&["run", "--config", "gone.toml"]).code, 1);
    let conn = rusqlite::Connection::open(b.path("survey.db")).unwrap();
    let began = |positioner: &str| {
        let ids = serde_json::json!({"positioner": positioner, "reference": null}).to_string();
        conn.execute(
            "UPDATE surveys SET instruments_json = json_set(instruments_json, '$.identified', json(?1))",
            [ids],
        )
        .unwrap();
    };
    // As if it had begun on another controller.
    began("ACME,AZ-200,1042,2.1");
    b.write("sim.toml", config("127.0.0.1:0", "127.0.0.1:0").replace("time_scale = 500\n", ""));
    let (_sim, ready) = super::drift::Sim::serve(&b, &["--config", "sim.toml", "--time-scale", "500"]);
    let at = |k: &str| ready["instruments"][k].as_str().unwrap().to_string();
    b.write("moved.toml", config(&at("positioner"), &at("tracker")));
    let before = std::fs::read(b.path("survey.db")).unwrap();
    b.survey(&["resume", "--config", "moved.toml"]).bad_input(&[
        "the positioner at modbus-tcp",
        "identifies itself as \"vendor survey-sims",
        "began on one that identified itself as \"ACME,AZ-200,1042,2.1\"",
        "nothing was stored",
    ]);
    assert!(std::fs::read(b.path("survey.db")).unwrap() == before, "nothing stored by a refused resume");
    // The same controller (as it says now): taken, and the survey finishes on it.
    let said = b.survey(&["check", "--config", "moved.toml", "--json"]).success().json();
    let line = said["instruments"][0]["detail"].as_str().unwrap().to_string();
    let idn = line.split("identifies itself as \"").nth(1).and_then(|s| s.strip_suffix('"')).expect("its words");
    began(idn);
    let out = b.survey(&["resume", "--config", "moved.toml"]);
    assert_eq!(out.code, 0, "{out}");
    assert!(out.stderr.contains("resumed on new addresses"), "{out}");
}
