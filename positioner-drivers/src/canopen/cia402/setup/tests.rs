//! The set-up against a scripted drive on the in-memory bus that follows its
//! controlword and loses the responses a schedule names: each request is
//! asked again in place, and a reconnect with the drive's state known reads
//! the statusword only.

use super::*;
use crate::canopen::CanopenConfig;
use crate::canopen::frame::CanFrame;
use crate::canopen::memory_bus::MemoryBus;
use crate::canopen::objects::cw;
use crate::canopen::sdo::{InitData, SdoRequest, SdoResponse};
use std::sync::Arc;
use std::sync::atomic::{AtomicU16, AtomicU32, Ordering};

/// A drive that walks the CiA 402 state machine as its controlword says
/// (switch on disabled -> ready -> switched on -> operation enabled), shows
/// profile position mode once 0x6060 is written, and answers every SDO
/// request except those whose number (from 1) `lose` names: those get no
/// response (a dropped reply) or, with `refuse`, the abort 0x06060000.
struct Drive {
    statusword: Arc<AtomicU16>,
    requests: Arc<AtomicU32>,
}

fn drive(bus: &MemoryBus, lose: fn(u32) -> bool, refuse: bool) -> Drive {
    let statusword = Arc::new(AtomicU16::new(0x0250));
    let requests = Arc::new(AtomicU32::new(0));
    let (sw, n) = (statusword.clone(), requests.clone());
    let mut ep = bus.endpoint();
    tokio::spawn(async move {
        let mut mode = 0u8;
        while let Ok(f) = ep.recv().await {
            if f.id() != 0x605 {
                continue;
            }
            let request = SdoRequest::decode(f.data());
            if !matches!(request, Ok(SdoRequest::InitiateUpload { .. } | SdoRequest::InitiateDownload { .. })) {
                continue; // the client's abort after a timeout
            }
            let count = n.fetch_add(1, Ordering::SeqCst) + 1;
            let resp = match request {
                Ok(_) if lose(count) && !refuse => continue,
                Ok(
                    SdoRequest::InitiateUpload { index, subindex }
                    | SdoRequest::InitiateDownload { index, subindex, .. },
                ) if lose(count) => SdoResponse::Abort { index, subindex, code: 0x0606_0000 },
                Ok(SdoRequest::InitiateUpload { index, subindex }) => {
                    let data = match index {
                        index::STATUSWORD => sw.load(Ordering::SeqCst).to_le_bytes().to_vec(),
                        index::MODES_OF_OPERATION_DISPLAY => vec![mode],
                        _ => vec![0, 0, 0, 0],
                    };
                    SdoResponse::InitiateUpload {
                        index,
                        subindex,
                        data: InitData::Expedited { data, size_indicated: true },
                    }
                }
                Ok(SdoRequest::InitiateDownload { index, subindex, data: InitData::Expedited { data, .. } }) => {
                    match index {
                        index::MODES_OF_OPERATION => mode = data[0],
                        index::CONTROLWORD => {
                            let word = u16::from_le_bytes([data[0], data[1]]);
                            let next = match (sw.load(Ordering::SeqCst), word) {
                                (_, cw::SHUTDOWN) => 0x0221,
                                (0x0221, cw::SWITCH_ON_CMD) => 0x0233,
                                (0x0233 | 0x0237, w) if w & 0x0F == 0x0F => 0x0237,
                                (s, _) => s,
                            };
                            sw.store(next, Ordering::SeqCst);
                        }
                        _ => {}
                    }
                    SdoResponse::InitiateDownload { index, subindex }
                }
                _ => continue,
            };
            if ep.send(CanFrame::full(0x585, resp.encode()).unwrap()).await.is_err() {
                return;
            }
        }
    });
    Drive { statusword, requests }
}

fn cfg() -> CanopenConfig {
    CanopenConfig { node_id: 5, sdo_timeout_ms: 20, resync_grace_ms: 2, ..CanopenConfig::default() }
}

#[tokio::test]
async fn every_request_of_the_set_up_is_asked_again_and_a_reconnect_reads_the_statusword_only() {
    let bus = MemoryBus::new();
    // Every third request loses its response: no request meets three in a row.
    let d = drive(&bus, |n| n % 3 == 0, false);
    let memory = DriveMemory::new();
    let mut p = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
    assert_eq!(p.set_up(&memory).await.unwrap(), SetUp::Full);
    assert_eq!(d.statusword.load(Ordering::SeqCst), 0x0237, "operation enabled");
    assert!(memory.is_set_up());
    // A new connection (the old one dropped after a link fault): NMT start and one statusword read.
    let before = d.requests.load(Ordering::SeqCst);
    let mut again = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
    let how = again.set_up(&memory).await.unwrap();
    assert_eq!(how, SetUp::Rechecked);
    let asked = d.requests.load(Ordering::SeqCst) - before;
    assert!((1..=2).contains(&asked), "{asked} requests: the statusword (asked again once at most)");
}

#[tokio::test]
async fn refusals_are_asked_again_and_a_reset_drive_is_set_up_in_full() {
    let bus = MemoryBus::new();
    let d = drive(&bus, |n| n % 2 == 0, true);
    let memory = DriveMemory::new();
    let mut p = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
    assert_eq!(p.set_up(&memory).await.unwrap(), SetUp::Full);
    // The drive was power-cycled: switch on disabled again.
    d.statusword.store(0x0250, Ordering::SeqCst);
    let mut again = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
    assert_eq!(again.set_up(&memory).await.unwrap(), SetUp::Full);
    assert_eq!(d.statusword.load(Ordering::SeqCst), 0x0237);
}

#[tokio::test]
async fn a_drive_in_fault_is_connected_and_a_request_lost_every_time_fails_the_set_up() {
    let bus = MemoryBus::new();
    let d = drive(&bus, |_| false, false);
    // Fault (bit 3) with switch on disabled's bits: the set-up leaves it to the engine's recovery.
    d.statusword.store(0x0218, Ordering::SeqCst);
    let memory = DriveMemory::new();
    let mut p = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
    assert_eq!(p.set_up(&memory).await.unwrap(), SetUp::Faulted);
    assert!(memory.is_set_up());

    let bus = MemoryBus::new();
    let d = drive(&bus, |n| n >= 2, false);
    let memory = DriveMemory::new();
    let mut p = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
    let e = p.set_up(&memory).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert!(e.message.contains("0x6061:00"), "{e}");
    assert_eq!(d.requests.load(Ordering::SeqCst), 1 + SETUP_REQUEST_TRIES, "0x6060, then 0x6061 three times");
    assert!(!memory.is_set_up());
}
