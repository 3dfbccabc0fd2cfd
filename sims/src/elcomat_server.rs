//! A simulated Moeller-Wedel ELCOMAT on the far end of a serial line.
//!
//! [`serve`] speaks the protocol of [`survey_drivers::elcomat`] (see its
//! module documentation for the wire format and for what was looked up versus
//! chosen) over any `AsyncRead + AsyncWrite` stream: the master side of a pty
//! pair ([`pty_pair`]), an in-memory duplex, a socket. Every measurement comes
//! from a [`SimAutocollimator`], so the readings follow its physics and its
//! clock (use a [`VirtualClock`](survey_drivers::VirtualClock): a reading then
//! costs no real time).
//!
//! | command | reply |
//! |---|---|
//! | `a` | `4 003 <X> <Y>` from [`SimAutocollimator::read`], or `4 000` when it has no reflection |
//! | `r` | `2 103 <X-X0> <Y-Y0>` relative to [`ElcomatOptions::relative_zero_arcsec`], or `2 100` |
//! | anything else | nothing (logged at debug level) |
//!
//! Commands may end in CR LF, LF or CR. Replies end in CR LF, values with two
//! decimals. The no-reflection replies (`4 000`, `2 100`) are this
//! simulator's convention (validity digit 0), not a documented one.
//!
//! # Fault injection ([`ElcomatFaults`])
//!
//! Requests (valid `a`/`r` commands) are counted from 1. Per request, in this
//! order:
//!
//! - `close_on`: the port is closed after the command is read, without a
//!   reply (the driver sees a disconnection);
//! - `truncate_and_close_on`: the first half of the reply line is sent with no
//!   line end, then the port is closed;
//! - `drop_reply_on` or probability `drop_probability`: the measurement is
//!   taken but no reply is sent (the driver times out);
//! - `garble_on` or probability `garble_probability`: a garbled line (non-ASCII
//!   bytes in the status field) is sent instead of the reply.
//!
//! The random draws come from the fault stream of `seed`, two per request
//! whatever happens, so a run is reproducible and the noise of the readings
//! does not depend on the faults.

use crate::autocollimator::{CODE_NO_REFLECTION, SimAutocollimator};
use crate::{FAULT_STREAM, seeded_rng};
use rand::Rng;
use std::sync::Mutex;
use survey_drivers::elcomat::{Command, CommandDecoder, Reply, encode_reply};
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::Autocollimator;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// Faults to inject; none by default. Scheduled faults name requests counted
/// from 1.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElcomatFaults {
    /// Seed of the random faults.
    pub seed: u64,
    /// Probability that a reply is dropped.
    pub drop_probability: f64,
    /// Probability that a reply is replaced by a garbled line.
    pub garble_probability: f64,
    /// Drop the reply to these requests.
    pub drop_reply_on: Vec<usize>,
    /// Send a garbled line instead of the reply to these requests.
    pub garble_on: Vec<usize>,
    /// Send half of the reply to this request, then close the port.
    pub truncate_and_close_on: Option<usize>,
    /// Close the port on this request, before replying.
    pub close_on: Option<usize>,
}

/// Settings of [`serve_with`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElcomatOptions {
    /// The zero that `r` readings are relative to, arcsec `(X0, Y0)` (the real
    /// instrument stores one; default `(0, 0)`).
    pub relative_zero_arcsec: (f64, f64),
    /// Faults to inject.
    pub faults: ElcomatFaults,
}

/// Why [`serve`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServeEnd {
    /// End of file from the peer.
    PeerClosed,
    /// A read or write failed (a pty master reads EIO once the other side is
    /// closed).
    LinkError(std::io::ErrorKind),
    /// An injected fault closed the port.
    ClosedByFault,
}

/// What [`serve`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServeReport {
    /// Valid commands received.
    pub requests: usize,
    /// Replies sent in full (valid, no-reflection or garbled).
    pub replies: usize,
    /// Why it returned.
    pub end: ServeEnd,
}

/// Serve `instrument` over `stream` with `faults` and a relative zero of
/// `(0, 0)`, until the peer closes or a fault closes the port. The stream is
/// dropped (the port closed) on return.
pub async fn serve<S>(stream: S, instrument: SimAutocollimator, faults: ElcomatFaults) -> ServeReport
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    serve_with(stream, instrument, ElcomatOptions { faults, ..ElcomatOptions::default() }).await
}

/// [`serve`] with all the settings.
pub async fn serve_with<S>(mut stream: S, mut instrument: SimAutocollimator, options: ElcomatOptions) -> ServeReport
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let faults = &options.faults;
    let mut rng = seeded_rng(faults.seed, FAULT_STREAM);
    let mut decoder = CommandDecoder::new();
    let mut buf = [0u8; 256];
    let mut report = ServeReport { requests: 0, replies: 0, end: ServeEnd::PeerClosed };
    loop {
        while let Some(item) = decoder.next_command() {
            let cmd = match item {
                Ok(cmd) => cmd,
                Err(e) => {
                    tracing::debug!(error = %e, "sim ELCOMAT ignores a line");
                    continue;
                }
            };
            report.requests += 1;
            let n = report.requests;
            if faults.close_on == Some(n) {
                tracing::debug!(request = n, "sim ELCOMAT closes the port (injected)");
                report.end = ServeEnd::ClosedByFault;
                return report;
            }
            let Some(reply) = measure(&mut instrument, cmd, options.relative_zero_arcsec).await else {
                continue;
            };
            let mut line = encode_reply(&reply);
            let (u_drop, u_garble): (f64, f64) = (rng.random(), rng.random());
            if faults.truncate_and_close_on == Some(n) {
                line.truncate((line.len() - 2) / 2);
                tracing::debug!(request = n, sent = %String::from_utf8_lossy(&line), "sim ELCOMAT sends half a line and closes (injected)");
                let _ = stream.write_all(&line).await;
                let _ = stream.flush().await;
                report.end = ServeEnd::ClosedByFault;
                return report;
            }
            if faults.drop_reply_on.contains(&n) || u_drop < faults.drop_probability {
                tracing::debug!(request = n, "sim ELCOMAT drops its reply (injected)");
                continue;
            }
            if faults.garble_on.contains(&n) || u_garble < faults.garble_probability {
                tracing::debug!(request = n, "sim ELCOMAT garbles its reply (injected)");
                line = vec![reply.kind.type_digit() as u8, b' ', b'0', 0xFF, b'3', b' ', b'#', b'?', b'\r', b'\n'];
            }
            if let Err(e) = write_line(&mut stream, &line).await {
                report.end = ServeEnd::LinkError(e.kind());
                return report;
            }
            report.replies += 1;
        }
        match stream.read(&mut buf).await {
            Ok(0) => {
                report.end = ServeEnd::PeerClosed;
                return report;
            }
            Ok(k) => decoder.push(&buf[..k]),
            Err(e) => {
                tracing::debug!(error = %e, "sim ELCOMAT link closed");
                report.end = ServeEnd::LinkError(e.kind());
                return report;
            }
        }
    }
}

async fn write_line<S: AsyncWrite + Unpin>(stream: &mut S, line: &[u8]) -> std::io::Result<()> {
    stream.write_all(line).await?;
    stream.flush().await
}

/// One measurement for `cmd`: the reply, or `None` when the simulated
/// instrument failed in a way the protocol has no reply for.
async fn measure(instrument: &mut SimAutocollimator, cmd: Command, zero: (f64, f64)) -> Option<Reply> {
    match instrument.read().await {
        Ok(r) => Some(match cmd {
            Command::Absolute => Reply::absolute(r.x_arcsec, r.y_arcsec),
            Command::Relative => Reply::relative(r.x_arcsec - zero.0, r.y_arcsec - zero.1),
        }),
        Err(e) if e.kind == ErrorKind::Device && e.code == Some(CODE_NO_REFLECTION) => {
            Some(Reply::no_reflection(cmd.reply_kind()))
        }
        Err(e) => {
            tracing::warn!(error = %e, "sim ELCOMAT: the simulated instrument failed; no reply");
            None
        }
    }
}

/// Serialises pty-pair creation: `pair()` is not thread-safe.
static PTY_PAIR_LOCK: Mutex<()> = Mutex::new(());

/// A connected pty pair `(master, slave)` as async serial streams, created
/// under a process-wide lock (pty-pair creation is not thread-safe). The
/// slave is in raw mode and has a `/dev/pts/N` name. Must be called within a
/// tokio runtime.
pub fn pty_pair() -> std::io::Result<(tokio_serial::SerialStream, tokio_serial::SerialStream)> {
    let _guard = PTY_PAIR_LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    tokio_serial::SerialStream::pair().map_err(std::io::Error::from)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::autocollimator::AutocollimatorConfig;
    use crate::turntable::Turntable;
    use std::sync::Arc;
    use std::time::Duration;
    use survey_drivers::VirtualClock;
    use survey_drivers::elcomat::{ElcomatDriver, STATUS_ABSOLUTE_NO_REFLECTION, STATUS_RELATIVE_NO_REFLECTION};
    use survey_drivers::traits::{AcReading, AcState};
    use tokio::task::JoinHandle;
    use tokio_serial::{SerialPort, SerialStream};

    /// Driver timeout in these tests: short, so a dropped reply costs little.
    const TIMEOUT: Duration = Duration::from_millis(200);
    /// Noise is 0.1 arcsec: 5 sigma, plus the 0.005 of printing two decimals.
    const TOL: f64 = 0.5 + 0.005;

    struct Rig {
        table: Turntable,
        cfg: AutocollimatorConfig,
        driver: ElcomatDriver<SerialStream>,
        server: JoinHandle<ServeReport>,
    }

    /// The simulator on the pty master, the driver on the slave.
    fn rig(seed: u64, options: ElcomatOptions) -> Rig {
        let clock = VirtualClock::new();
        let table = Turntable::new(0.0);
        let cfg = AutocollimatorConfig::seeded(24, seed);
        let ac = SimAutocollimator::new(cfg.clone(), Arc::new(clock), table.clone());
        let (master, slave) = pty_pair().expect("pty pair");
        let server = tokio::spawn(serve_with(master, ac, options));
        let driver = ElcomatDriver::new(slave).with_timeout(TIMEOUT).with_name("elcomat-test");
        Rig { table, cfg, driver, server }
    }

    fn faults(f: ElcomatFaults) -> ElcomatOptions {
        ElcomatOptions { faults: f, ..ElcomatOptions::default() }
    }

    /// Place the table `off_arcsec` from face `k`; the expected (X, Y) by the
    /// SimAutocollimator convention `X = 3600 (theta - phi_k) - c_k`, `Y = pyramidal_k`.
    fn place(rig: &Rig, k: usize, off_arcsec: f64) -> (f64, f64) {
        rig.table.place(rig.cfg.nominal_deg(k) + off_arcsec / 3600.0);
        (off_arcsec - rig.cfg.certificate_arcsec[k], rig.cfg.pyramidal_arcsec[k])
    }

    fn assert_near(r: AcReading, (x, y): (f64, f64)) {
        assert!((r.x_arcsec - x).abs() < TOL && (r.y_arcsec - y).abs() < TOL, "{r:?} vs expected ({x}, {y})");
    }

    #[tokio::test]
    async fn absolute_readings_follow_the_physics() {
        let mut rig = rig(7, ElcomatOptions::default());
        for (k, off) in [(0, 0.0), (1, -700.0), (5, 123.4), (12, 950.0), (23, -999.0)] {
            let want = place(&rig, k, off);
            assert_near(rig.driver.read().await.unwrap(), want);
        }
        drop(rig.driver);
        let report = rig.server.await.unwrap();
        assert_eq!((report.requests, report.replies), (5, 5));
    }

    #[tokio::test]
    async fn relative_readings_are_taken_from_the_stored_zero() {
        let zero = (150.0, -40.0);
        let mut rig = rig(3, ElcomatOptions { relative_zero_arcsec: zero, ..ElcomatOptions::default() });
        let (x, y) = place(&rig, 4, 300.0);
        let rel = rig.driver.read_relative().await.unwrap();
        assert_near(rel, (x - zero.0, y - zero.1));
        let abs = rig.driver.read_absolute().await.unwrap();
        assert_near(abs, (x, y));
    }

    #[tokio::test]
    async fn status_and_out_of_range_follow_the_turntable() {
        let mut rig = rig(1, ElcomatOptions::default());
        place(&rig, 2, 10.0);
        assert_eq!(rig.driver.status().await.unwrap(), AcState::InRange);
        // Half-way between two faces of the 24-face polygon: no reflection.
        rig.table.place(2.5 * 15.0);
        assert_eq!(rig.driver.status().await.unwrap(), AcState::NoReflection);
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(i64::from(STATUS_ABSOLUTE_NO_REFLECTION))), "{e}");
        assert!(e.message.contains("no reflection"), "{e}");
        let e = rig.driver.read_relative().await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(i64::from(STATUS_RELATIVE_NO_REFLECTION))), "{e}");
        // Just inside the 1000 arcsec range again.
        let want = place(&rig, 3, -990.0);
        assert_eq!(rig.driver.status().await.unwrap(), AcState::InRange);
        assert_near(rig.driver.read().await.unwrap(), want);
    }

    #[tokio::test]
    async fn a_dropped_reply_times_out_and_the_next_request_works() {
        let mut rig = rig(2, faults(ElcomatFaults { drop_reply_on: vec![1], ..ElcomatFaults::default() }));
        let want = place(&rig, 6, 55.0);
        let t0 = std::time::Instant::now();
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
        assert!(t0.elapsed() >= TIMEOUT);
        assert_near(rig.driver.read().await.unwrap(), want);
    }

    #[tokio::test]
    async fn a_garbled_line_is_garbled_and_the_next_request_works() {
        let mut rig = rig(4, faults(ElcomatFaults { garble_on: vec![2], ..ElcomatFaults::default() }));
        let want = place(&rig, 9, -12.0);
        assert_near(rig.driver.read().await.unwrap(), want);
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
        assert_near(rig.driver.read().await.unwrap(), want);
        assert_near(rig.driver.read_relative().await.unwrap(), want);
    }

    /// A truncated line followed by a closed port is `Disconnected` (never
    /// `Garbled`): whether or not the half line reached the driver before the
    /// hangup, end of file with a partial line is a disconnection.
    #[tokio::test]
    async fn a_truncated_line_then_close_is_disconnected() {
        let mut rig = rig(5, faults(ElcomatFaults { truncate_and_close_on: Some(2), ..ElcomatFaults::default() }));
        let want = place(&rig, 0, 20.0);
        assert_near(rig.driver.read().await.unwrap(), want);
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        assert_eq!(rig.server.await.unwrap().end, ServeEnd::ClosedByFault);
    }

    #[tokio::test]
    async fn closing_mid_exchange_is_disconnected_not_a_timeout() {
        let mut rig = rig(6, faults(ElcomatFaults { close_on: Some(1), ..ElcomatFaults::default() }));
        place(&rig, 1, 0.0);
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        assert!(e.is_link());
    }

    #[tokio::test]
    async fn random_faults_are_link_faults_and_never_wrong_readings() {
        let options = faults(ElcomatFaults {
            seed: 11,
            drop_probability: 0.1,
            garble_probability: 0.15,
            ..ElcomatFaults::default()
        });
        let mut rig = rig(8, options);
        let (mut ok, mut failed) = (0, 0);
        for i in 0..30 {
            let want = place(&rig, i % 24, (i as f64 * 37.0) % 900.0 - 450.0);
            match rig.driver.read().await {
                Ok(r) => {
                    assert_near(r, want);
                    ok += 1;
                }
                Err(e) => {
                    assert!(matches!(e.kind, ErrorKind::Timeout | ErrorKind::Garbled), "{e}");
                    failed += 1;
                }
            }
        }
        assert!(ok >= 15 && failed >= 1, "ok {ok}, failed {failed}");
    }

    #[tokio::test]
    async fn open_serial_by_path() {
        let clock = VirtualClock::new();
        let table = Turntable::new(0.0);
        let cfg = AutocollimatorConfig::seeded(24, 9);
        let ac = SimAutocollimator::new(cfg.clone(), Arc::new(clock), table.clone());
        let (master, slave) = pty_pair().unwrap();
        let path = slave.name().expect("the slave pty has a path");
        // The pair's slave holds the port's exclusive lock: close it, open the
        // path, and only then start serving (the master reads EIO while no
        // slave is open).
        drop(slave);
        let mut driver = ElcomatDriver::open_serial(&path, 115_200).unwrap().with_timeout(TIMEOUT);
        tokio::spawn(serve(master, ac, ElcomatFaults::default()));
        assert_eq!(survey_drivers::traits::Autocollimator::name(&driver), format!("elcomat {path}"));
        table.place(cfg.nominal_deg(3) + 100.0 / 3600.0);
        let r = driver.read().await.unwrap();
        assert_near(r, (100.0 - cfg.certificate_arcsec[3], cfg.pyramidal_arcsec[3]));
    }
}
