//! The register logic of the simulated controller: requests in, outcomes out,
//! the physics from a [`SimPositioner`].

use super::MAX_TABLE_ROWS;
use std::collections::HashMap;
use survey_drivers::error::{DriverError, ErrorKind};
use survey_drivers::traits::{Positioner, PositionerStatus};
use survey_positioner_drivers::modbus::{
    ExceptionCode, Item, MAX_READ_REGISTERS, MAX_WRITE_REGISTERS, RegisterMap, RegisterTable, Request, Response, Span,
    WINDOW_HEADER_WORDS, fault_code_register, table_checksum,
};
use survey_processing::table::CorrectionTable;
use survey_sims::positioner::SimPositioner;
use tokio_modbus::prelude::{ConformityLevel, DeviceIdObject, ReadCode, ReadDeviceIdentificationResponse};

/// What became of one request.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Outcome {
    /// A normal reply.
    Reply(Response),
    /// An exception reply.
    Exception(ExceptionCode),
    /// No reply (the simulated positioner timed out).
    Silent,
    /// Close the link (the simulated positioner disconnected).
    Close,
    /// A reply that does not match the request (the simulated positioner
    /// garbled its answer).
    Garble,
}

/// The table being staged: `cells[column * rows + row]`.
#[derive(Debug, Clone)]
struct Staging {
    rows: usize,
    columns: usize,
    cells: Vec<Option<[u16; 2]>>,
}

impl Staging {
    /// CRC over the staged value registers, forward rows then reverse rows;
    /// a row not written counts as `0xFFFF 0xFFFF`.
    fn checksum(&self) -> u16 {
        let words: Vec<u16> = self.cells.iter().flat_map(|c| c.unwrap_or([0xFFFF, 0xFFFF])).collect();
        table_checksum(&words)
    }
}

/// The controller: the simulated axis, the holding-register image and the
/// staged table.
#[derive(Debug)]
pub(super) struct DeviceState {
    pub(super) sim: SimPositioner,
    map: RegisterMap,
    holding: HashMap<u16, u16>,
    staging: Option<Staging>,
}

fn exc(code: ExceptionCode) -> Outcome {
    Outcome::Exception(code)
}

/// A failure of the simulated positioner on the wire.
fn sim_outcome(e: DriverError) -> Outcome {
    tracing::debug!(error = %e, "sim Modbus controller: the simulated positioner refused or failed");
    match e.kind {
        ErrorKind::Usage => exc(ExceptionCode::IllegalDataValue),
        ErrorKind::Device => exc(ExceptionCode::ServerDeviceFailure),
        ErrorKind::Timeout => Outcome::Silent,
        ErrorKind::Disconnected => Outcome::Close,
        ErrorKind::Garbled => Outcome::Garble,
    }
}

impl DeviceState {
    pub(super) fn new(sim: SimPositioner, map: RegisterMap) -> Self {
        Self { sim, map, holding: HashMap::new(), staging: None }
    }

    /// The stored value of a holding register (0 when never written).
    pub(super) fn holding(&self, address: u16) -> u16 {
        self.holding.get(&address).copied().unwrap_or(0)
    }

    /// Serve one request; `discard`: acknowledge a valid write without
    /// applying it (fault injection).
    pub(super) async fn handle(&mut self, request: &Request<'_>, discard: bool) -> Outcome {
        let result = match request {
            Request::ReadHoldingRegisters(a, n) => {
                self.read(RegisterTable::Holding, *a, *n).await.map(Response::ReadHoldingRegisters)
            }
            Request::ReadInputRegisters(a, n) => {
                self.read(RegisterTable::Input, *a, *n).await.map(Response::ReadInputRegisters)
            }
            Request::WriteSingleRegister(a, v) => {
                self.write(*a, &[*v], discard).await.map(|()| Response::WriteSingleRegister(*a, *v))
            }
            Request::WriteMultipleRegisters(a, words) => {
                self.write(*a, words, discard).await.map(|()| Response::WriteMultipleRegisters(*a, words.len() as u16))
            }
            Request::ReadDeviceIdentification(code, object) => identification(*code, *object),
            other => {
                tracing::debug!(request = ?other, "sim Modbus controller: function not served");
                Err(exc(ExceptionCode::IllegalFunction))
            }
        };
        match result {
            Ok(r) => Outcome::Reply(r),
            Err(o) => o,
        }
    }

    async fn read(&mut self, table: RegisterTable, address: u16, count: u16) -> Result<Vec<u16>, Outcome> {
        if count == 0 || count > MAX_READ_REGISTERS {
            return Err(exc(ExceptionCode::IllegalDataValue));
        }
        let spans = self.spans_of(table, address, usize::from(count), |_| true)?;
        let mut status: Option<PositionerStatus> = None;
        let mut out = Vec::with_capacity(usize::from(count));
        for (span, first, len) in spans {
            let values: Vec<u16> = match span.item {
                Item::ActualPosition => {
                    let deg = self.sim.readout().await.map_err(sim_outcome)?;
                    let words = self.map.encode_position(deg).map_err(|e| {
                        tracing::warn!(error = %e, deg, "sim Modbus controller: the readout does not fit the encoding");
                        exc(ExceptionCode::ServerDeviceFailure)
                    })?;
                    words.to_vec()
                }
                Item::Status | Item::FaultCode => {
                    if status.is_none() {
                        status = Some(self.sim.status().await.map_err(sim_outcome)?);
                    }
                    let s = status.as_ref().unwrap_or_else(|| unreachable!("just read"));
                    vec![if span.item == Item::Status { self.map.encode_status(s) } else { fault_code_register(s) }]
                }
                Item::TableChecksum => vec![self.staging.as_ref().map_or(table_checksum(&[]), Staging::checksum)],
                _ => (0..span.len).map(|i| self.holding(span.address + i)).collect(),
            };
            out.extend_from_slice(&values[first..first + len]);
        }
        Ok(out)
    }

    /// The spans `count` registers from `address` touch, each with the first
    /// register and how many of its registers the request covers. Every
    /// register must belong to an item that passes `allowed`.
    fn spans_of(
        &self,
        table: RegisterTable,
        address: u16,
        count: usize,
        allowed: impl Fn(Item) -> bool,
    ) -> Result<Vec<(Span, usize, usize)>, Outcome> {
        if usize::from(address) + count > 65_536 {
            return Err(exc(ExceptionCode::IllegalDataAddress));
        }
        let mut spans = Vec::new();
        let mut i = 0;
        while i < count {
            let addr = address + i as u16;
            let span = self
                .map
                .span_at(table, addr)
                .filter(|s| allowed(s.item))
                .ok_or(exc(ExceptionCode::IllegalDataAddress))?;
            let first = usize::from(addr - span.address);
            let len = (count - i).min(usize::from(span.len) - first);
            spans.push((span, first, len));
            i += len;
        }
        Ok(spans)
    }

    async fn write(&mut self, address: u16, words: &[u16], discard: bool) -> Result<(), Outcome> {
        if words.is_empty() || words.len() > usize::from(MAX_WRITE_REGISTERS) {
            return Err(exc(ExceptionCode::IllegalDataValue));
        }
        let spans = self.spans_of(RegisterTable::Holding, address, words.len(), Item::is_writable)?;
        // A 32-bit value (or the header) is written whole; the window from
        // its start, with at least one row and whole values.
        for &(span, first, len) in &spans {
            let whole = match span.item {
                Item::TableWindow => first == 0 && len >= 4 && len % 2 == 0,
                _ => first == 0 && len == usize::from(span.len),
            };
            if !whole {
                tracing::debug!(item = span.item.name(), first, len, "sim Modbus controller: partial write refused");
                return Err(exc(ExceptionCode::IllegalDataAddress));
            }
        }
        if discard {
            tracing::debug!(address, count = words.len(), "sim Modbus controller discards a write (injected)");
            return Ok(());
        }
        let mut at = 0;
        for (span, _, len) in spans {
            self.apply(span, &words[at..at + len]).await?;
            at += len;
        }
        Ok(())
    }

    fn store(&mut self, address: u16, words: &[u16]) {
        for (i, w) in words.iter().enumerate() {
            self.holding.insert(address + i as u16, *w);
        }
    }

    async fn apply(&mut self, span: Span, w: &[u16]) -> Result<(), Outcome> {
        match span.item {
            Item::CommandPosition => {
                self.map.decode_position([w[0], w[1]]).map_err(|_| exc(ExceptionCode::IllegalDataValue))?;
            }
            Item::Velocity => {
                let v = self.map.decode_velocity([w[0], w[1]]).map_err(|_| exc(ExceptionCode::IllegalDataValue))?;
                self.sim.set_velocity(v).await.map_err(sim_outcome)?;
            }
            Item::Command => self.execute(w[0]).await?,
            Item::TableHeader => {
                let (rows, columns) = (usize::from(w[0]), usize::from(w[1]));
                if !(2..=usize::from(MAX_TABLE_ROWS)).contains(&rows) || !(1..=2).contains(&columns) {
                    return Err(exc(ExceptionCode::IllegalDataValue));
                }
                self.staging = Some(Staging { rows, columns, cells: vec![None; rows * columns] });
            }
            Item::TableWindow => {
                let Some(st) = self.staging.as_mut() else {
                    return Err(exc(ExceptionCode::IllegalDataValue));
                };
                let (column, first) = (usize::from(w[0]), usize::from(w[1]));
                let values = &w[usize::from(WINDOW_HEADER_WORDS)..];
                if column >= st.columns || first + values.len() / 2 > st.rows {
                    return Err(exc(ExceptionCode::IllegalDataValue));
                }
                for (k, pair) in values.chunks(2).enumerate() {
                    let cell = [pair[0], pair[1]];
                    self.map.decode_table_value(cell).map_err(|_| exc(ExceptionCode::IllegalDataValue))?;
                    st.cells[column * st.rows + first + k] = Some(cell);
                }
            }
            Item::ActualPosition | Item::Status | Item::FaultCode | Item::TableChecksum => {
                return Err(exc(ExceptionCode::IllegalDataAddress));
            }
        }
        self.store(span.address, w);
        Ok(())
    }

    async fn execute(&mut self, code: u16) -> Result<(), Outcome> {
        let c = self.map.command_codes;
        let r = if code == c.move_absolute {
            let at = self.map.command_position;
            let words = [self.holding(at), self.holding(at + 1)];
            let target = self.map.decode_position(words).map_err(|_| exc(ExceptionCode::IllegalDataValue))?;
            self.sim.move_to(target).await
        } else if code == c.stop {
            self.sim.stop().await
        } else if code == c.clear_fault {
            self.sim.clear_fault().await
        } else if code == c.correction_enable {
            self.sim.enable_correction(true).await
        } else if code == c.correction_disable {
            self.sim.enable_correction(false).await
        } else if code == c.load_table {
            let table = self.staged_table()?;
            self.sim.load_correction_table(&table).await
        } else {
            tracing::debug!(code, "sim Modbus controller: unknown command code");
            return Err(exc(ExceptionCode::IllegalDataValue));
        };
        r.map_err(sim_outcome)
    }

    /// The staged table, when every row of every column was written.
    fn staged_table(&self) -> Result<CorrectionTable, Outcome> {
        let refuse = |why: &str| {
            tracing::debug!(why, "sim Modbus controller refuses to load the table");
            exc(ExceptionCode::IllegalDataValue)
        };
        let st = self.staging.as_ref().ok_or_else(|| refuse("no table staged"))?;
        let mut cols: Vec<Vec<f64>> = Vec::with_capacity(st.columns);
        for c in 0..st.columns {
            let mut col = Vec::with_capacity(st.rows);
            for cell in &st.cells[c * st.rows..(c + 1) * st.rows] {
                let words = cell.ok_or_else(|| refuse("rows missing"))?;
                col.push(self.map.decode_table_value(words).map_err(|_| refuse("a value is not finite"))?);
            }
            cols.push(col);
        }
        let reverse = if st.columns == 2 { cols.pop() } else { None };
        let forward = cols.pop().unwrap_or_default();
        let table = match reverse {
            Some(r) => CorrectionTable::directional(forward, r),
            None => CorrectionTable::new(forward),
        };
        table.map_err(|e| refuse(&e.to_string()))
    }
}

/// What the simulated controller says it is (Read Device Identification,
/// 0x2B / MEI 0x0E): the basic objects and two of the regular ones. That it
/// is simulated it says in its product name: a rehearsal's survey records it.
pub const IDENTIFICATION: [(u8, &str); 5] = [
    (0x00, "survey-sims"),
    (0x01, "SIM-MB-1"),
    (0x02, "1.0"),
    (0x04, "Modbus positioner controller (simulated)"),
    (0x05, "servo drive, register map of survey (simulated)"),
];

/// Read Device Identification as the Modbus application protocol (V1.1b3,
/// 6.21) has a server answer it: stream access by category (basic 0x01:
/// objects 0-2; regular 0x02: 0-0x7F, extended 0x03: all) from the object
/// asked for, restarting at object 0 when that object is not one of the
/// category's; individual access (0x04) one object, an unknown one illegal
/// data address. Conformity level 0x82: regular identification, stream and
/// individual access. Every object fits one reply (no "more follows").
fn identification(code: ReadCode, object: u8) -> Result<Response, Outcome> {
    let last = match code {
        ReadCode::Basic => 0x02,
        ReadCode::Regular => 0x7F,
        ReadCode::Extended => 0xFF,
        ReadCode::Specific => {
            let Some(&(id, text)) = IDENTIFICATION.iter().find(|(id, _)| *id == object) else {
                return Err(exc(ExceptionCode::IllegalDataAddress));
            };
            return Ok(identification_reply(code, vec![(id, text)]));
        }
    };
    let in_category = |id: u8| id <= last;
    let known = IDENTIFICATION.iter().any(|(id, _)| *id == object && in_category(*id));
    let first = if known { object } else { 0 };
    let objects = IDENTIFICATION.iter().copied().filter(|(id, _)| *id >= first && in_category(*id)).collect();
    Ok(identification_reply(code, objects))
}

fn identification_reply(read_code: ReadCode, objects: Vec<(u8, &str)>) -> Response {
    Response::ReadDeviceIdentification(ReadDeviceIdentificationResponse {
        read_code,
        conformity_level: ConformityLevel::RegularIdentification,
        more_follows: false,
        next_object_id: 0,
        device_id_objects: objects
            .into_iter()
            .map(|(id, text)| DeviceIdObject { id, value: text.as_bytes().to_vec().into() })
            .collect(),
    })
}
