//! The SDO client: expedited and segmented upload and download over any
//! [`CanBus`], each response awaited under its own deadline.
//!
//! - Before each transfer, frames already waiting are dropped (a late
//!   response to an earlier request must not be taken for this one's). After
//!   a timeout the client drains the bus for as long as the node may still
//!   answer ([`SdoTimeouts::late_window`]) before it reports the timeout.
//! - An initiate response or an abort that names another object than the
//!   transfer's (a late response to an earlier transfer) is discarded and
//!   logged, not taken: the client waits on for its own within the deadline.
//! - Frames with other COB-IDs than `0x580 + node` are ignored (other nodes'
//!   traffic, heartbeats, emergencies).
//! - No response within [`SdoTimeouts::response`] -> [`ErrorKind::Timeout`];
//!   the client sends the abort `0x0504_0000` (SDO protocol timed out) so the
//!   node forgets the transfer, as CiA 301 has it.
//! - A response that does not decode, has an unexpected command specifier,
//!   or breaks the toggle sequence or the size -> [`ErrorKind::Garbled`];
//!   the client aborts the transfer
//!   (`0x0504_0001`, `0x0503_0000` or `0x0607_001x`).
//! - An abort from the node -> the code and its standard text, classified by
//!   [`abort_kind`] ([`ErrorKind::Device`] or [`ErrorKind::Usage`]).
//! - A bus failure -> [`ErrorKind::Disconnected`].

use super::frame::{CanBus, CanFrame};
use super::sdo::{
    InitData, Multiplexer, Reassembler, SDO_REQUEST_BASE, SDO_RESPONSE_BASE, SdoRequest, SdoResponse, Segmenter, abort,
    abort_kind, abort_text,
};
use std::time::Duration;
use survey_drivers::error::{DriverError, ErrorKind, Result};
use tokio::time::Instant;

/// Deadlines of the SDO client.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SdoTimeouts {
    /// How long to wait for each response frame. Default 500 ms.
    pub response: Duration,
    /// After a timeout, how long the client drains late frames at least
    /// (see [`SdoTimeouts::late_window`]). Default 20 ms.
    pub resync_grace: Duration,
}

impl SdoTimeouts {
    /// After a response timed out, how long the node may still answer: the
    /// bus is drained for so long (half the response deadline, or the
    /// resync grace when longer) before the timeout is reported. The
    /// client's own bound of one response is the deadline and this.
    pub fn late_window(&self) -> Duration {
        (self.response / 2).max(self.resync_grace)
    }
}

impl Default for SdoTimeouts {
    fn default() -> Self {
        Self { response: Duration::from_millis(500), resync_grace: Duration::from_millis(20) }
    }
}

/// Largest upload accepted, bytes (a node announcing more is refused with
/// the abort "out of memory").
pub const MAX_UPLOAD: usize = 1 << 20;

/// An SDO client for one node.
#[derive(Debug, Clone)]
pub struct SdoClient {
    node_id: u8,
    timeouts: SdoTimeouts,
    name: String,
}

/// How a transfer step failed, before it is turned into a [`DriverError`].
enum Step {
    /// Already a driver error (bus failure).
    Failed(DriverError),
    /// No response in time.
    Timeout,
    /// A response that is not the one expected: abort with this code.
    Garbled { code: u32, why: String },
    /// The node aborted.
    Aborted(u32),
}

impl From<DriverError> for Step {
    fn from(e: DriverError) -> Self {
        Step::Failed(e)
    }
}

impl SdoClient {
    /// A client for node `node_id` (1..=127), errors named `name`.
    pub fn new(node_id: u8, timeouts: SdoTimeouts, name: impl Into<String>) -> Self {
        Self { node_id, timeouts, name: name.into() }
    }

    /// The node served.
    pub fn node_id(&self) -> u8 {
        self.node_id
    }

    /// The deadlines.
    pub fn timeouts(&self) -> SdoTimeouts {
        self.timeouts
    }

    /// Rename (for errors and logs).
    pub fn set_name(&mut self, name: impl Into<String>) {
        self.name = name.into();
    }

    fn request_id(&self) -> u16 {
        SDO_REQUEST_BASE + u16::from(self.node_id)
    }

    fn response_id(&self) -> u16 {
        SDO_RESPONSE_BASE + u16::from(self.node_id)
    }

    /// Read `index:subindex`. An expedited response that does not indicate
    /// its size gives all 4 bytes (see [`Self::upload_exact`]).
    pub async fn upload<B: CanBus + ?Sized>(&mut self, bus: &mut B, index: u16, subindex: u8) -> Result<Vec<u8>> {
        Ok(self.upload_sized(bus, index, subindex).await?.0)
    }

    /// Read `index:subindex`, an object of `len` bytes: an expedited response
    /// without size indication is cut to `len`; any other length is
    /// [`ErrorKind::Garbled`].
    pub async fn upload_exact<B: CanBus + ?Sized>(
        &mut self,
        bus: &mut B,
        index: u16,
        subindex: u8,
        len: usize,
    ) -> Result<Vec<u8>> {
        let (mut data, size_indicated) = self.upload_sized(bus, index, subindex).await?;
        if !size_indicated && len <= data.len() {
            data.truncate(len);
        }
        if data.len() != len {
            let e = DriverError::new(
                ErrorKind::Garbled,
                &self.name,
                format!(
                    "{} came back with {} bytes where {len} were expected",
                    Multiplexer(index, subindex),
                    data.len()
                ),
            );
            tracing::warn!(instrument = %self.name, error = %e, "wrong object size");
            return Err(e);
        }
        Ok(data)
    }

    /// The data and whether its size was known (false only for an expedited
    /// response without size indication).
    async fn upload_sized<B: CanBus + ?Sized>(
        &mut self,
        bus: &mut B,
        index: u16,
        subindex: u8,
    ) -> Result<(Vec<u8>, bool)> {
        let what = format!("SDO upload of {}", Multiplexer(index, subindex));
        self.drain(bus).await?;
        let outcome = self.upload_steps(bus, index, subindex).await;
        self.finish(bus, index, subindex, &what, outcome).await
    }

    /// Write `data` to `index:subindex` (expedited up to 4 bytes, segmented above).
    pub async fn download<B: CanBus + ?Sized>(
        &mut self,
        bus: &mut B,
        index: u16,
        subindex: u8,
        data: &[u8],
    ) -> Result<()> {
        let what = format!("SDO download of {} ({} bytes)", Multiplexer(index, subindex), data.len());
        self.drain(bus).await?;
        let outcome = self.download_steps(bus, index, subindex, data).await;
        self.finish(bus, index, subindex, &what, outcome).await
    }

    /// Send an abort for `index:subindex` with `code` (no response comes).
    pub async fn send_abort<B: CanBus + ?Sized>(
        &mut self,
        bus: &mut B,
        index: u16,
        subindex: u8,
        code: u32,
    ) -> Result<()> {
        self.send(bus, &SdoRequest::Abort { index, subindex, code }).await
    }

    async fn upload_steps<B: CanBus + ?Sized>(
        &mut self,
        bus: &mut B,
        index: u16,
        subindex: u8,
    ) -> Result<(Vec<u8>, bool), Step> {
        self.send(bus, &SdoRequest::InitiateUpload { index, subindex }).await?;
        let size = match self.response(bus, (index, subindex)).await? {
            SdoResponse::InitiateUpload { index: i, subindex: s, data } if (i, s) == (index, subindex) => match data {
                InitData::Expedited { data, size_indicated } => return Ok((data, size_indicated)),
                InitData::Segmented { size } => size,
            },
            other => return Err(unexpected(&other, "an initiate upload response echoing the object", index, subindex)),
        };
        let mut joined = Reassembler::new(size, MAX_UPLOAD)
            .map_err(|e| Step::Garbled { code: e.abort_code(), why: format!("the node announces {e}") })?;
        loop {
            let toggle = joined.toggle();
            self.send(bus, &SdoRequest::UploadSegment { toggle }).await?;
            match self.response(bus, (index, subindex)).await? {
                SdoResponse::UploadSegment { toggle: t, data, last } => {
                    let done = joined.push(t, &data, last).map_err(|e| Step::Garbled {
                        code: e.abort_code(),
                        why: format!("upload segment after {} bytes: {e}", joined.received()),
                    })?;
                    if done {
                        return Ok((joined.into_data(), true));
                    }
                }
                other => return Err(unexpected(&other, "an upload segment", index, subindex)),
            }
        }
    }

    async fn download_steps<B: CanBus + ?Sized>(
        &mut self,
        bus: &mut B,
        index: u16,
        subindex: u8,
        data: &[u8],
    ) -> Result<(), Step> {
        let init = if data.len() <= 4 && !data.is_empty() {
            InitData::Expedited { data: data.to_vec(), size_indicated: true }
        } else {
            let size = u32::try_from(data.len()).map_err(|_| Step::Garbled {
                code: abort::OUT_OF_MEMORY,
                why: format!("{} bytes do not fit an SDO transfer", data.len()),
            })?;
            InitData::Segmented { size: Some(size) }
        };
        let segmented = matches!(init, InitData::Segmented { .. });
        self.send(bus, &SdoRequest::InitiateDownload { index, subindex, data: init }).await?;
        match self.response(bus, (index, subindex)).await? {
            SdoResponse::InitiateDownload { index: i, subindex: s } if (i, s) == (index, subindex) => {}
            other => {
                return Err(unexpected(&other, "an initiate download response echoing the object", index, subindex));
            }
        }
        if !segmented {
            return Ok(());
        }
        let mut segments = Segmenter::new(data.to_vec());
        while let Some(seg) = segments.next_segment() {
            let toggle = seg.toggle;
            self.send(bus, &SdoRequest::DownloadSegment { toggle, data: seg.data, last: seg.last }).await?;
            match self.response(bus, (index, subindex)).await? {
                SdoResponse::DownloadSegment { toggle: t } if t == toggle => {}
                SdoResponse::DownloadSegment { toggle: t } => {
                    return Err(Step::Garbled {
                        code: abort::TOGGLE_BIT,
                        why: format!("download segment response with toggle {t} where {toggle} was sent"),
                    });
                }
                other => return Err(unexpected(&other, "a download segment response", index, subindex)),
            }
        }
        Ok(())
    }

    /// Turn a step failure into the driver error, aborting the transfer on
    /// the bus where the node may still hold it.
    async fn finish<T, B: CanBus + ?Sized>(
        &mut self,
        bus: &mut B,
        index: u16,
        subindex: u8,
        what: &str,
        outcome: Result<T, Step>,
    ) -> Result<T> {
        match outcome {
            Ok(v) => Ok(v),
            Err(Step::Failed(e)) => {
                tracing::warn!(instrument = %self.name, what, error = %e, "SDO transfer failed");
                Err(e)
            }
            Err(Step::Timeout) => {
                let limit = self.timeouts.response;
                tracing::warn!(instrument = %self.name, what, ?limit, "no SDO response; aborting the transfer");
                self.send(bus, &SdoRequest::Abort { index, subindex, code: abort::TIMEOUT }).await?;
                self.drain_late(bus).await?;
                Err(DriverError::timeout(&self.name, what, limit))
            }
            Err(Step::Garbled { code, why }) => {
                tracing::warn!(instrument = %self.name, what, %why, code = format_args!("0x{code:08X}"), "garbled SDO response; aborting the transfer");
                self.send(bus, &SdoRequest::Abort { index, subindex, code }).await?;
                Err(DriverError::new(ErrorKind::Garbled, &self.name, format!("{what}: {why}")))
            }
            Err(Step::Aborted(code)) => {
                let kind = abort_kind(code);
                let text = abort_text(code);
                tracing::debug!(instrument = %self.name, what, code = format_args!("0x{code:08X}"), text, "SDO abort from the node");
                Err(DriverError {
                    kind,
                    instrument: self.name.clone(),
                    code: Some(i64::from(code)),
                    message: format!("SDO abort 0x{code:08X} ({text}) in the {what}"),
                })
            }
        }
    }

    async fn send<B: CanBus + ?Sized>(&self, bus: &mut B, req: &SdoRequest) -> Result<()> {
        let frame = CanFrame::full(self.request_id(), req.encode())
            .map_err(|e| DriverError::usage(&self.name, format!("node id {}: {e}", self.node_id)))?;
        tracing::trace!(instrument = %self.name, %frame, ?req, "SDO request");
        bus.send(frame).await
    }

    /// The next response from our node to the transfer of `mux`, within the
    /// response deadline: an initiate response or an abort naming another
    /// object answers an earlier transfer (it came late) and is discarded.
    async fn response<B: CanBus + ?Sized>(&self, bus: &mut B, mux: (u16, u8)) -> Result<SdoResponse, Step> {
        let deadline = Instant::now() + self.timeouts.response;
        loop {
            let frame = match tokio::time::timeout_at(deadline, bus.recv()).await {
                Err(_) => return Err(Step::Timeout),
                Ok(r) => r?,
            };
            if frame.id() != self.response_id() {
                tracing::trace!(instrument = %self.name, %frame, "ignored a frame of another COB-ID");
                continue;
            }
            tracing::trace!(instrument = %self.name, %frame, "SDO response");
            let decoded = SdoResponse::decode(frame.data());
            if let Ok(
                SdoResponse::InitiateUpload { index, subindex, .. }
                | SdoResponse::InitiateDownload { index, subindex }
                | SdoResponse::Abort { index, subindex, .. },
            ) = &decoded
                && (*index, *subindex) != mux
            {
                tracing::warn!(
                    instrument = %self.name, %frame, transfer = %Multiplexer(mux.0, mux.1),
                    "discarded an SDO response for another object (a late one)"
                );
                continue;
            }
            return match decoded {
                Ok(SdoResponse::Abort { code, .. }) => Err(Step::Aborted(code)),
                Ok(r) => Ok(r),
                Err(e) => Err(Step::Garbled { code: abort::COMMAND_SPECIFIER, why: format!("{e} in {frame}") }),
            };
        }
    }

    /// After a timeout: drop the frames of our node that arrive while it may
    /// still answer ([`SdoTimeouts::late_window`]).
    async fn drain_late<B: CanBus + ?Sized>(&mut self, bus: &mut B) -> Result<()> {
        let window = self.timeouts.late_window();
        let until = Instant::now() + window;
        let mut dropped = 0usize;
        while let Ok(r) = tokio::time::timeout_at(until, bus.recv()).await {
            if r?.id() == self.response_id() {
                dropped += 1;
            }
        }
        tracing::warn!(instrument = %self.name, ?window, dropped, "drained the bus after a timeout");
        Ok(())
    }

    /// Drop frames already waiting.
    async fn drain<B: CanBus + ?Sized>(&mut self, bus: &mut B) -> Result<()> {
        let mut dropped = 0usize;
        while let Some(frame) = bus.try_recv()? {
            if frame.id() == self.response_id() {
                dropped += 1;
            }
        }
        if dropped > 0 {
            tracing::warn!(instrument = %self.name, dropped, "dropped stale SDO responses before a transfer");
        }
        Ok(())
    }
}

/// A response of the wrong kind (or for the wrong object).
fn unexpected(got: &SdoResponse, expected: &str, index: u16, subindex: u8) -> Step {
    Step::Garbled {
        code: abort::COMMAND_SPECIFIER,
        why: format!("expected {expected} ({}), got {got:?}", Multiplexer(index, subindex)),
    }
}
