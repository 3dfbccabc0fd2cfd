//! The one place where a link fault rebuilds a connection, for every driver.
//!
//! A wire driver that meets a link fault (timeout, disconnect, garbled frame)
//! reports it and is then considered dead: its stream may hold half a frame or
//! a late reply. [`Reconnecting`] owns a [`Connect`]or and the current driver;
//! after a link fault it drops the driver, and the next call connects afresh.
//! The engine's retry loop decides whether to call again; this wrapper only
//! makes sure the call after a link fault starts on a clean connection.

use crate::error::{DriverError, Result};
use crate::traits::{
    AcReading, AcState, Autocollimator, CapturedReadout, Positioner, PositionerStatus, SmrMeasurement, StreamedPoint,
    Tracker, TrackerState,
};
use async_trait::async_trait;
use std::fmt;
use std::future::Future;
use std::pin::Pin;
use std::time::Duration;
use survey_processing::table::CorrectionTable;

/// Opens a connection to one instrument.
#[async_trait]
pub trait Connect<D: ?Sized>: Send + Sync {
    /// Open the connection and bring the instrument to a usable state.
    async fn connect(&self) -> Result<Box<D>>;
    /// What is connected to, for logs and errors (`modbus-tcp 10.0.0.5:502`).
    fn describe(&self) -> String;
}

/// How many times a connection's set-up is tried before its fault is
/// reported ([`Reconnecting::connect`]).
pub const SETUP_TRIES: u32 = 8;

/// A driver that reconnects after a link fault.
pub struct Reconnecting<D: ?Sized> {
    connector: Box<dyn Connect<D>>,
    current: Option<Box<D>>,
    name: String,
    connects: u32,
}

impl<D: ?Sized> fmt::Debug for Reconnecting<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Reconnecting")
            .field("name", &self.name)
            .field("connected", &self.current.is_some())
            .field("connects", &self.connects)
            .finish()
    }
}

type CallFuture<'a, T> = Pin<Box<dyn Future<Output = Result<T>> + Send + 'a>>;

impl<D: ?Sized + Send> Reconnecting<D> {
    /// Wrap a connector; nothing is opened until the first call (or [`Self::connect`]).
    pub fn new(connector: Box<dyn Connect<D>>) -> Self {
        let name = connector.describe();
        Self { connector, current: None, name, connects: 0 }
    }

    /// Open the connection now (to fail early, before a survey starts). A
    /// set-up the instrument refused (a device fault in reply to an
    /// initialising request: an SDO abort, an emScon mode refused) is tried
    /// again, up to [`SETUP_TRIES`] times in all, each refusal logged; a link
    /// fault (refused, dropped, garbled) is reported at once, for the engine
    /// to count and retry.
    pub async fn connect(&mut self) -> Result<()> {
        if self.current.is_none() {
            let mut tries = 1;
            let driver = loop {
                match self.connector.connect().await {
                    Ok(d) => break d,
                    Err(e) if tries < SETUP_TRIES && e.kind == crate::error::ErrorKind::Device => {
                        tracing::warn!(instrument = %self.name, error = %e, tries, "the set-up was refused: trying again");
                        tries += 1;
                    }
                    Err(e) => return Err(self.connect_error(e)),
                }
            };
            self.connects += 1;
            if self.connects > 1 {
                tracing::info!(instrument = %self.name, connects = self.connects, "reconnected");
            }
            self.current = Some(driver);
        }
        Ok(())
    }

    fn connect_error(&self, e: DriverError) -> DriverError {
        // The connector's kind stands: a refused socket is a link fault, an
        // instrument that answers with a fault while initialising is a device fault.
        DriverError {
            kind: e.kind,
            instrument: self.name.clone(),
            code: e.code,
            message: format!("cannot connect: {}", e.message),
        }
    }

    /// How many times a connection has been opened.
    pub fn connects(&self) -> u32 {
        self.connects
    }

    /// Whether a connection is open now.
    pub fn is_connected(&self) -> bool {
        self.current.is_some()
    }

    /// Run one call on the current connection (opening it if needed); drop the
    /// connection when the call meets a link fault.
    pub async fn call<T>(&mut self, f: impl for<'a> FnOnce(&'a mut D) -> CallFuture<'a, T> + Send) -> Result<T> {
        self.connect().await?;
        let driver = self.current.as_mut().expect("connected above");
        let result = f(driver).await;
        if let Err(e) = &result
            && e.kind.is_link()
        {
            tracing::warn!(instrument = %self.name, error = %e, "link fault: the connection will be rebuilt");
            self.current = None;
        }
        result
    }
}

#[async_trait]
impl Positioner for Reconnecting<dyn Positioner> {
    fn name(&self) -> &str {
        &self.name
    }
    async fn move_to(&mut self, target_deg: f64) -> Result<()> {
        self.call(|d| d.move_to(target_deg)).await
    }
    async fn readout(&mut self) -> Result<f64> {
        self.call(|d| d.readout()).await
    }
    async fn status(&mut self) -> Result<PositionerStatus> {
        self.call(|d| d.status()).await
    }
    async fn stop(&mut self) -> Result<()> {
        self.call(|d| d.stop()).await
    }
    async fn set_velocity(&mut self, deg_per_s: f64) -> Result<()> {
        self.call(|d| d.set_velocity(deg_per_s)).await
    }
    async fn clear_fault(&mut self) -> Result<()> {
        self.call(|d| d.clear_fault()).await
    }
    async fn load_correction_table(&mut self, table: &CorrectionTable) -> Result<()> {
        let table = table.clone();
        self.call(move |d| Box::pin(async move { d.load_correction_table(&table).await })).await
    }
    async fn enable_correction(&mut self, enabled: bool) -> Result<()> {
        self.call(|d| d.enable_correction(enabled)).await
    }
    async fn correction_state(&mut self) -> Result<Option<bool>> {
        self.call(|d| d.correction_state()).await
    }
    async fn identification(&mut self) -> Result<Option<String>> {
        self.call(|d| d.identification()).await
    }
    /// The connected driver's (false before the first connection).
    fn can_capture(&self) -> bool {
        self.current.as_ref().is_some_and(|d| d.can_capture())
    }
    async fn start_capture(&mut self, period: Duration) -> Result<()> {
        self.call(|d| d.start_capture(period)).await
    }
    async fn read_capture(&mut self) -> Result<Vec<CapturedReadout>> {
        self.call(|d| d.read_capture()).await
    }
    async fn stop_capture(&mut self) -> Result<()> {
        self.call(|d| d.stop_capture()).await
    }
}

#[async_trait]
impl Tracker for Reconnecting<dyn Tracker> {
    fn name(&self) -> &str {
        &self.name
    }
    async fn measure(&mut self) -> Result<SmrMeasurement> {
        self.call(|d| d.measure()).await
    }
    async fn identification(&mut self) -> Result<Option<String>> {
        self.call(|d| d.identification()).await
    }
    async fn status(&mut self) -> Result<TrackerState> {
        self.call(|d| d.status()).await
    }
    async fn reacquire(&mut self) -> Result<()> {
        self.call(|d| d.reacquire()).await
    }
    /// The connected driver's (false before the first connection).
    fn can_point(&self) -> bool {
        self.current.as_ref().is_some_and(|d| d.can_point())
    }
    async fn point_at(&mut self, xyz_mm: [f64; 3]) -> Result<()> {
        self.call(|d| d.point_at(xyz_mm)).await
    }
    /// The connected driver's (false before the first connection).
    fn can_stream(&self) -> bool {
        self.current.as_ref().is_some_and(|d| d.can_stream())
    }
    async fn start_stream(&mut self, period: Duration) -> Result<()> {
        self.call(|d| d.start_stream(period)).await
    }
    async fn read_stream(&mut self) -> Result<Vec<StreamedPoint>> {
        self.call(|d| d.read_stream()).await
    }
    async fn stop_stream(&mut self) -> Result<()> {
        self.call(|d| d.stop_stream()).await
    }
}

#[async_trait]
impl Autocollimator for Reconnecting<dyn Autocollimator> {
    fn name(&self) -> &str {
        &self.name
    }
    async fn read(&mut self) -> Result<AcReading> {
        self.call(|d| d.read()).await
    }
    async fn identification(&mut self) -> Result<Option<String>> {
        self.call(|d| d.identification()).await
    }
    async fn status(&mut self) -> Result<AcState> {
        self.call(|d| d.status()).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ErrorKind;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// An autocollimator whose connection fails on chosen calls.
    #[derive(Debug)]
    struct Flaky {
        calls: Arc<AtomicU32>,
        fail_on: u32,
        kind: ErrorKind,
    }

    #[async_trait]
    impl Autocollimator for Flaky {
        fn name(&self) -> &str {
            "flaky"
        }
        async fn read(&mut self) -> Result<AcReading> {
            let n = self.calls.fetch_add(1, Ordering::SeqCst) + 1;
            if n == self.fail_on {
                return Err(DriverError::new(self.kind, "flaky", "injected"));
            }
            Ok(AcReading { x_arcsec: n as f64, y_arcsec: 0.0 })
        }
        async fn status(&mut self) -> Result<AcState> {
            Ok(AcState::InRange)
        }
    }

    struct FlakyConnector {
        calls: Arc<AtomicU32>,
        connects: Arc<AtomicU32>,
        fail_on: u32,
        kind: ErrorKind,
        refuse: bool,
    }

    #[async_trait]
    impl Connect<dyn Autocollimator> for FlakyConnector {
        async fn connect(&self) -> Result<Box<dyn Autocollimator>> {
            self.connects.fetch_add(1, Ordering::SeqCst);
            if self.refuse {
                return Err(DriverError::new(ErrorKind::Disconnected, "flaky", "connection refused"));
            }
            Ok(Box::new(Flaky { calls: self.calls.clone(), fail_on: self.fail_on, kind: self.kind }))
        }
        fn describe(&self) -> String {
            "flaky at test".into()
        }
    }

    fn wrapped(fail_on: u32, kind: ErrorKind, refuse: bool) -> (Reconnecting<dyn Autocollimator>, Arc<AtomicU32>) {
        let connects = Arc::new(AtomicU32::new(0));
        let c =
            FlakyConnector { calls: Arc::new(AtomicU32::new(0)), connects: connects.clone(), fail_on, kind, refuse };
        (Reconnecting::new(Box::new(c)), connects)
    }

    #[tokio::test]
    async fn a_link_fault_drops_the_connection_and_the_next_call_reconnects() {
        let (mut ac, connects) = wrapped(2, ErrorKind::Timeout, false);
        assert_eq!(ac.read().await.unwrap().x_arcsec, 1.0);
        assert_eq!(connects.load(Ordering::SeqCst), 1);
        let e = ac.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout);
        assert!(!ac.is_connected());
        assert_eq!(ac.read().await.unwrap().x_arcsec, 3.0);
        assert_eq!(connects.load(Ordering::SeqCst), 2);
        assert_eq!(ac.connects(), 2);
        assert_eq!(ac.name(), "flaky at test");
    }

    #[tokio::test]
    async fn a_device_fault_keeps_the_connection() {
        let (mut ac, connects) = wrapped(1, ErrorKind::Device, false);
        assert_eq!(ac.read().await.unwrap_err().kind, ErrorKind::Device);
        assert!(ac.is_connected());
        ac.read().await.unwrap();
        assert_eq!(connects.load(Ordering::SeqCst), 1);
    }

    #[tokio::test]
    async fn a_refused_connection_is_a_link_fault_naming_the_instrument() {
        let (mut ac, connects) = wrapped(0, ErrorKind::Device, true);
        let e = ac.read().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected);
        assert!(e.to_string().contains("flaky at test") && e.message.contains("cannot connect"), "{e}");
        assert!(ac.read().await.is_err());
        assert_eq!(connects.load(Ordering::SeqCst), 2, "every call tries to connect again");
    }
}
