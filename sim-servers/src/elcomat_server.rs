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
//! # Faults
//!
//! Link faults are the [`relay`](crate::relay)'s in front of the instrument
//! ([`garbled`]: the ELCOMAT way to garble a reply, non-ASCII bytes in the
//! status field). Its device fault is the simulated autocollimator's own: no
//! reflection (a blocked view, [`SimAutocollimator`]).

use crate::serve::{self, Answer, Codec, Service};
use async_trait::async_trait;
use std::sync::Mutex;
use survey_drivers::elcomat::{Command, CommandDecoder, DecodeError, Reply, encode_reply};
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::Autocollimator;
use survey_sims::autocollimator::{CODE_NO_REFLECTION, SimAutocollimator};
use survey_sims::faults::{Fault, Garble};
use tokio::io::{AsyncRead, AsyncWrite};

pub use crate::serve::ServeEnd;

/// Settings of [`serve_with`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElcomatOptions {
    /// The zero that `r` readings are relative to, arcsec `(X0, Y0)` (the real
    /// instrument stores one; default `(0, 0)`).
    pub relative_zero_arcsec: (f64, f64),
}

/// What [`serve`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServeReport {
    /// Valid commands received.
    pub requests: usize,
    /// Replies sent (valid or no-reflection).
    pub replies: usize,
    /// Why it returned.
    pub end: ServeEnd,
}

/// The ELCOMAT way to garble a reply, for the relay in front of it: a line
/// with non-ASCII bytes in the status field.
pub fn garbled() -> Fault {
    Fault::Garble(Garble::edit("ELCOMAT status field garbled", |line: &[u8]| {
        let digit = *line.first()?;
        Some(vec![digit, b' ', b'0', 0xFF, b'3', b' ', b'#', b'?', b'\r', b'\n'])
    }))
}

/// Serve `instrument` over `stream` with a relative zero of `(0, 0)`, until
/// the peer closes or the link fails. The stream is dropped (the port
/// closed) on return.
pub async fn serve<S>(stream: S, instrument: SimAutocollimator) -> ServeReport
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    serve_with(stream, instrument, ElcomatOptions::default()).await
}

/// [`serve`] with all the settings.
pub async fn serve_with<S>(stream: S, instrument: SimAutocollimator, options: ElcomatOptions) -> ServeReport
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let mut elcomat = Elcomat { instrument, zero: options.relative_zero_arcsec, requests: 0, replies: 0 };
    let end = serve::serve_stream(stream, CommandDecoder::new(), &mut elcomat).await;
    ServeReport { requests: elcomat.requests, replies: elcomat.replies, end }
}

/// The instrument: commands in, reply lines out.
struct Elcomat {
    instrument: SimAutocollimator,
    zero: (f64, f64),
    requests: usize,
    replies: usize,
}

impl Codec for CommandDecoder {
    type Item = Result<Command, DecodeError>;
    fn push(&mut self, bytes: &[u8]) {
        CommandDecoder::push(self, bytes);
    }
    fn next_item(&mut self) -> Option<Self::Item> {
        self.next_command()
    }
}

#[async_trait]
impl Service for Elcomat {
    type Request = Result<Command, DecodeError>;
    type Reply = Vec<u8>;

    async fn call(&mut self, command: Self::Request) -> Answer<Vec<u8>> {
        let command = match command {
            Ok(c) => c,
            Err(e) => {
                tracing::debug!(error = %e, "sim ELCOMAT ignores a line");
                return Answer::Nothing;
            }
        };
        self.requests += 1;
        match measure(&mut self.instrument, command, self.zero).await {
            Some(reply) => {
                self.replies += 1;
                Answer::Send(encode_reply(&reply))
            }
            None => Answer::Nothing,
        }
    }
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
    use crate::relay::{Ended, Framing, Relay, pty_relay};
    use std::sync::Arc;
    use std::time::Duration;
    use survey_drivers::VirtualClock;
    use survey_drivers::elcomat::{ElcomatDriver, STATUS_ABSOLUTE_NO_REFLECTION, STATUS_RELATIVE_NO_REFLECTION};
    use survey_drivers::traits::{AcReading, AcState};
    use survey_sims::autocollimator::AutocollimatorConfig;
    use survey_sims::faults::{FaultRates, Faults};
    use survey_sims::turntable::Turntable;
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
        /// The relay's link faults.
        faults: Faults,
        relay: JoinHandle<Ended>,
    }

    /// The simulator on a pty master, a relay between it and the driver's
    /// line (its link faults: armed, and at `rates`).
    fn rig_with(seed: u64, options: ElcomatOptions, rates: FaultRates) -> Rig {
        let clock = VirtualClock::new();
        let table = Turntable::new(0.0);
        let cfg = AutocollimatorConfig::seeded(24, seed);
        let ac = SimAutocollimator::new(cfg.clone(), Arc::new(clock), table.clone());
        let faults = Faults::new();
        let relay = Relay { rates, seed, ..Relay::armed(faults.clone(), Framing::Lines) };
        let (slave, master, relay) = pty_relay(relay);
        let server = tokio::spawn(serve_with(master, ac, options));
        let driver = ElcomatDriver::new(slave).with_timeout(TIMEOUT).with_name("elcomat-test");
        Rig { table, cfg, driver, server, faults, relay }
    }

    fn rig(seed: u64, options: ElcomatOptions) -> Rig {
        rig_with(seed, options, FaultRates::default())
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
        let mut rig = rig(3, ElcomatOptions { relative_zero_arcsec: zero });
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
        let mut rig = rig(2, ElcomatOptions::default());
        rig.faults.arm(Fault::Drop);
        let want = place(&rig, 6, 55.0);
        let t0 = std::time::Instant::now();
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
        assert!(t0.elapsed() >= TIMEOUT);
        assert_near(rig.driver.read().await.unwrap(), want);
    }

    #[tokio::test]
    async fn a_garbled_line_is_garbled_and_the_next_request_works() {
        let mut rig = rig(4, ElcomatOptions::default());
        rig.faults.arm(Fault::Pass);
        rig.faults.arm(garbled());
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
        let mut rig = rig(5, ElcomatOptions::default());
        rig.faults.arm(Fault::Pass);
        rig.faults.arm(Fault::Disconnect);
        let want = place(&rig, 0, 20.0);
        assert_near(rig.driver.read().await.unwrap(), want);
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        assert_eq!(rig.relay.await.unwrap(), Ended::Disconnect, "the relay cut the line");
    }

    #[tokio::test]
    async fn closing_mid_exchange_is_disconnected_not_a_timeout() {
        let mut rig = rig(6, ElcomatOptions::default());
        rig.faults.arm(Fault::Disconnect);
        place(&rig, 1, 0.0);
        let e = rig.driver.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        assert!(e.is_link());
    }

    #[tokio::test]
    async fn random_faults_are_link_faults_and_never_wrong_readings() {
        let rates = FaultRates { timeout: 0.1, garbled: 0.15, ..FaultRates::default() };
        let mut rig = rig_with(8, ElcomatOptions::default(), rates);
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
        tokio::spawn(serve(master, ac));
        assert_eq!(survey_drivers::traits::Autocollimator::name(&driver), format!("elcomat {path}"));
        table.place(cfg.nominal_deg(3) + 100.0 / 3600.0);
        let r = driver.read().await.unwrap();
        assert_near(r, (100.0 - cfg.certificate_arcsec[3], cfg.pyramidal_arcsec[3]));
    }
}
