//! The one fault vocabulary of the simulated instruments and the relays in
//! front of them: a [`Fault`] names what goes wrong with one reply (a link
//! fault, injected by a [`relay`](crate::relay) only) or with one request (a
//! device fault, injected by the simulator that answers it only); a
//! [`Faults`] handle, shared by the test (or `survey sim`), the relay and the
//! simulator, holds the faults armed and counts every fault injected
//! ([`Injected`], by [`FaultKind`]). Faults at a rate ([`FaultRates`]) are
//! drawn by the relay, which arms the device faults it draws in the
//! simulator behind it through the same handle.

use std::collections::VecDeque;
use std::fmt;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use survey_drivers::traits::DeviceFault;

/// One fault to inject.
#[derive(Clone)]
pub enum Fault {
    /// Link: the reply is lost (the client's deadline fires).
    Drop,
    /// Link: the reply is changed ([`Garble`]).
    Garble(Garble),
    /// Link: the link closes halfway through the reply.
    Disconnect,
    /// Link: the reply is held this long, then delivered (a late reply: it
    /// must not be taken for the next request's).
    Stall(Duration),
    /// Link: these bytes follow the reply at once (a duplicated or stale
    /// answer the client must not take for its next reply).
    Trailing(Vec<u8>),
    /// Link: the reply passes unharmed (the faults armed after it land on
    /// the replies after it).
    Pass,
    /// Device: the next request (on an SCPI controller, the next axis
    /// command) is not executed and is refused with the instrument's own
    /// fault code and text; `None`: the instrument's usual device fault (a
    /// Modbus exception 4, SDO abort 0x06060000, SCPI error -310, emScon
    /// `ES_RS_SensorNotStable`).
    Refuse(Option<DeviceFault>),
    /// Device: as [`Fault::Refuse`], in the protocol's error message where
    /// it has one besides the command's own answer (emScon's
    /// `ErrorResponseT`); elsewhere the same as `Refuse`.
    RefuseWithError(DeviceFault),
    /// Device: at the next request the axis latches this fault and stops.
    Trip(DeviceFault),
    /// Device: an unsolicited state change announced before the next answer
    /// (an emScon `SystemStatusChangeT`); the instrument's state does not change.
    Event(i64),
    /// Device: the n-th write from now (1: the next) is acknowledged but
    /// lost inside the device.
    LoseWrite(usize),
}

impl Fault {
    /// Whether a relay injects it (a reply's fault); else the simulator does.
    pub fn is_link(&self) -> bool {
        matches!(
            self,
            Fault::Drop | Fault::Garble(_) | Fault::Disconnect | Fault::Stall(_) | Fault::Trailing(_) | Fault::Pass
        )
    }

    /// The kind it is counted as (`None`: [`Fault::Pass`]).
    pub fn kind(&self) -> Option<FaultKind> {
        Some(match self {
            Fault::Drop => FaultKind::Timeout,
            Fault::Garble(_) => FaultKind::Garbled,
            Fault::Disconnect => FaultKind::Disconnect,
            Fault::Stall(_) | Fault::Trailing(_) => FaultKind::Stall,
            Fault::Pass => return None,
            Fault::Refuse(_) | Fault::RefuseWithError(_) | Fault::Trip(_) | Fault::Event(_) | Fault::LoseWrite(_) => {
                FaultKind::Device
            }
        })
    }
}

impl fmt::Debug for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::Drop => f.write_str("Drop"),
            Fault::Garble(g) => write!(f, "Garble({g:?})"),
            Fault::Disconnect => f.write_str("Disconnect"),
            Fault::Stall(d) => write!(f, "Stall({d:?})"),
            Fault::Trailing(b) => write!(f, "Trailing({:?})", String::from_utf8_lossy(b)),
            Fault::Pass => f.write_str("Pass"),
            Fault::Refuse(d) => write!(f, "Refuse({d:?})"),
            Fault::RefuseWithError(d) => write!(f, "RefuseWithError({d:?})"),
            Fault::Trip(d) => write!(f, "Trip({d:?})"),
            Fault::Event(e) => write!(f, "Event({e})"),
            Fault::LoseWrite(n) => write!(f, "LoseWrite({n})"),
        }
    }
}

/// How a reply is garbled.
#[derive(Clone)]
pub enum Garble {
    /// One byte XOR 0x5A, at a place drawn from the relay's fault stream
    /// (what the rates inject).
    Byte,
    /// The instrument's own way, named: the garbled reply, or `None` when it
    /// does not fit this reply (the fault then waits for the next reply it
    /// fits). Each simulator offers its own (`scpi_server::garbled`, ...).
    Edit(&'static str, Edit),
}

/// A reply's edit: the garbled reply, or `None` when it does not fit.
pub type Edit = Arc<dyn Fn(&[u8]) -> Option<Vec<u8>> + Send + Sync>;

impl Garble {
    /// An edit named `name` (see [`Garble::Edit`]).
    pub fn edit(name: &'static str, f: impl Fn(&[u8]) -> Option<Vec<u8>> + Send + Sync + 'static) -> Garble {
        Garble::Edit(name, Arc::new(f))
    }
}

impl fmt::Debug for Garble {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Garble::Byte => f.write_str("Byte"),
            Garble::Edit(name, _) => f.write_str(name),
        }
    }
}

/// The faults armed and the counts: a cheap handle, shared by clones (the
/// test arms on its clone, the relay and the simulator take from theirs).
/// Armed faults apply in the order armed, each to the next reply (link) or
/// the next request it fits (device).
#[derive(Clone, Default)]
pub struct Faults {
    armed: Arc<Mutex<Armed>>,
    injected: Injected,
}

#[derive(Default)]
struct Armed {
    link: VecDeque<Fault>,
    device: VecDeque<Fault>,
}

impl fmt::Debug for Faults {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.lock();
        f.debug_struct("Faults").field("link", &a.link).field("device", &a.device).finish_non_exhaustive()
    }
}

impl Faults {
    /// Nothing armed, counts at zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// Nothing armed; the faults injected are counted in `injected` (a
    /// count shared with other handles and simulators).
    pub fn counting(injected: Injected) -> Self {
        Self { armed: Arc::default(), injected }
    }

    /// A poisoned lock (a panicking test) is taken over: the plan is plain
    /// data, consistent after every statement.
    fn lock(&self) -> MutexGuard<'_, Armed> {
        self.armed.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Arm `fault` after those already armed.
    pub fn arm(&self, fault: Fault) {
        let mut a = self.lock();
        if fault.is_link() { a.link.push_back(fault) } else { a.device.push_back(fault) }
    }

    /// Arm `fault` `n` times.
    pub fn arm_n(&self, fault: Fault, n: usize) {
        for _ in 0..n {
            self.arm(fault.clone());
        }
    }

    /// The counts of the faults injected.
    pub fn injected(&self) -> &Injected {
        &self.injected
    }

    /// For a relay: the next armed link fault, if any, taken out and counted
    /// when `apply` applies it (`apply` returns `None` when the fault does
    /// not fit this reply: it stays armed).
    pub fn next_link<T>(&self, apply: impl FnOnce(&Fault) -> Option<T>) -> Option<T> {
        let mut a = self.lock();
        let applied = apply(a.link.front()?)?;
        if let Some(kind) = a.link.pop_front().and_then(|f| f.kind()) {
            self.injected.add(kind);
        }
        Some(applied)
    }

    /// For a simulator: the first armed device fault `fits` this request,
    /// taken out and counted (`fits` may step a fault that waits for its
    /// turn, as [`Fault::LoseWrite`] counts writes down).
    pub fn take_device(&self, fits: impl FnMut(&mut Fault) -> bool) -> Option<Fault> {
        let mut a = self.lock();
        let at = a.device.iter_mut().position(fits)?;
        let fault = a.device.remove(at)?;
        if let Some(kind) = fault.kind() {
            self.injected.add(kind);
        }
        Some(fault)
    }
}

/// The kinds of fault injected at a rate (see [`FaultRates`]), in the order
/// their counts are reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FaultKind {
    /// No reply: the request is lost (the client's deadline fires).
    Timeout,
    /// A reply with a byte changed (or a wrong reply): undecodable.
    Garbled,
    /// The link closed halfway through a reply.
    Disconnect,
    /// A reply held past the client's deadline, then delivered (it must not
    /// be taken for the next request's reply).
    Stall,
    /// A request refused with the instrument's own fault code (a Modbus
    /// exception, an SDO abort, an SCPI error, an emScon result status; the
    /// autocollimator: no reflection).
    Device,
    /// The drive trips halfway through a move (following error).
    Move,
    /// The tracker's beam breaks during a measurement.
    Beam,
}

impl FaultKind {
    /// Every kind, in report order.
    pub const ALL: [FaultKind; 7] = [
        FaultKind::Timeout,
        FaultKind::Garbled,
        FaultKind::Disconnect,
        FaultKind::Stall,
        FaultKind::Device,
        FaultKind::Move,
        FaultKind::Beam,
    ];

    /// The kind's name in `--fault-rates` and in the counts.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Timeout => "timeout",
            FaultKind::Garbled => "garbled",
            FaultKind::Disconnect => "disconnect",
            FaultKind::Stall => "stall",
            FaultKind::Device => "device",
            FaultKind::Move => "move",
            FaultKind::Beam => "beam",
        }
    }

    fn index(self) -> usize {
        FaultKind::ALL.iter().position(|k| *k == self).unwrap_or(0)
    }
}

/// Fault rates per kind, each a probability per event of its own: a reply
/// (timeout, garbled, disconnect, stall), a request (device), a move (move),
/// a tracker measurement (beam). `beam_hold` is how long a broken beam stays
/// broken (someone standing in it): re-acquiring it fails until then.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct FaultRates {
    /// Replies dropped.
    pub timeout: f64,
    /// Replies garbled.
    pub garbled: f64,
    /// Links cut halfway through a reply.
    pub disconnect: f64,
    /// Replies held past the client's deadline.
    pub stall: f64,
    /// Requests refused with the instrument's own fault code.
    pub device: f64,
    /// Moves on which the drive trips.
    pub r#move: f64,
    /// Tracker measurements that break the beam.
    pub beam: f64,
    /// How long a broken beam stays broken, seconds of instrument time (0: it
    /// can be re-acquired at once).
    pub beam_hold_s: f64,
}

impl FaultRates {
    /// `rate` shared evenly among the four link kinds, and the same `rate`
    /// of requests refused, moves tripped and measurements broken (what
    /// `survey sim --faults RATE` injects).
    pub fn uniform(rate: f64) -> FaultRates {
        let link = rate / 4.0;
        FaultRates {
            timeout: link,
            garbled: link,
            disconnect: link,
            stall: link,
            device: rate,
            r#move: rate,
            beam: rate,
            beam_hold_s: 0.0,
        }
    }

    /// The rate of one kind.
    pub fn rate(&self, kind: FaultKind) -> f64 {
        match kind {
            FaultKind::Timeout => self.timeout,
            FaultKind::Garbled => self.garbled,
            FaultKind::Disconnect => self.disconnect,
            FaultKind::Stall => self.stall,
            FaultKind::Device => self.device,
            FaultKind::Move => self.r#move,
            FaultKind::Beam => self.beam,
        }
    }

    fn rate_mut(&mut self, kind: FaultKind) -> &mut f64 {
        match kind {
            FaultKind::Timeout => &mut self.timeout,
            FaultKind::Garbled => &mut self.garbled,
            FaultKind::Disconnect => &mut self.disconnect,
            FaultKind::Stall => &mut self.stall,
            FaultKind::Device => &mut self.device,
            FaultKind::Move => &mut self.r#move,
            FaultKind::Beam => &mut self.beam,
        }
    }

    /// Whether any fault is injected.
    pub fn any(&self) -> bool {
        FaultKind::ALL.iter().any(|k| self.rate(*k) > 0.0)
    }

    /// Whether any link fault (timeout, garbled, disconnect, stall) is injected.
    pub fn any_link(&self) -> bool {
        self.timeout + self.garbled + self.disconnect + self.stall > 0.0
    }

    /// Parse `kind=rate,kind=rate,...` (kinds: `timeout`, `garbled`,
    /// `disconnect`, `stall`, `device`, `move`, `beam`; and `beam_hold_s=S`)
    /// over `self`: the kinds named replace their rate, the others keep it.
    /// Each rate is from 0 to 0.5; the four link rates together at most 0.5;
    /// `beam_hold_s` from 0 to 86400. The error names the item.
    pub fn parse_over(mut self, spec: &str) -> Result<FaultRates, String> {
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (key, value) =
                item.split_once('=').ok_or_else(|| format!("'{item}' is not kind=rate (e.g. timeout=0.01)"))?;
            let (key, value) = (key.trim(), value.trim());
            let x: f64 = value.parse().map_err(|_| format!("'{item}': '{value}' is not a number"))?;
            if key == "beam_hold_s" {
                if !(0.0..=86_400.0).contains(&x) {
                    return Err(format!("'{item}': beam_hold_s is seconds from 0 to 86400"));
                }
                self.beam_hold_s = x;
                continue;
            }
            let kind = FaultKind::ALL.iter().copied().find(|k| k.name() == key).ok_or_else(|| {
                let names: Vec<_> = FaultKind::ALL.iter().map(|k| k.name()).collect();
                format!("'{item}': unknown fault kind '{key}' (kinds: {}, and beam_hold_s)", names.join(", "))
            })?;
            if !(0.0..=0.5).contains(&x) {
                return Err(format!("'{item}': a rate is a fraction from 0 to 0.5"));
            }
            *self.rate_mut(kind) = x;
        }
        if self.timeout + self.garbled + self.disconnect + self.stall > 0.5 {
            return Err("the link fault rates (timeout, garbled, disconnect, stall) add up to more than 0.5".into());
        }
        Ok(self)
    }
}

/// Counts of the faults injected, by kind, shared by clones: every simulator
/// given a handle counts each fault it injects.
#[derive(Debug, Clone, Default)]
pub struct Injected {
    counts: Arc<[std::sync::atomic::AtomicU64; 8]>,
}

impl Injected {
    /// A new count, all zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// Count one fault of `kind`.
    pub fn add(&self, kind: FaultKind) {
        self.counts[kind.index()].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// The count of one kind.
    pub fn get(&self, kind: FaultKind) -> u64 {
        self.counts[kind.index()].load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Count one reply that passed a relay (faulted or not).
    pub fn count_reply(&self) {
        self.counts[7].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// The replies that passed the relays counting here.
    pub fn replies(&self) -> u64 {
        self.counts[7].load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Every fault counted.
    pub fn total(&self) -> u64 {
        FaultKind::ALL.iter().map(|k| self.get(*k)).sum()
    }

    /// `(name, count)` of every kind, in report order.
    pub fn by_kind(&self) -> Vec<(&'static str, u64)> {
        FaultKind::ALL.iter().map(|k| (k.name(), self.get(*k))).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_parse_per_kind_over_a_base() {
        let r = FaultRates::uniform(0.04).parse_over("stall=0.005, beam=0.1,beam_hold_s=30").unwrap();
        assert_eq!((r.timeout, r.stall, r.beam, r.beam_hold_s, r.r#move), (0.01, 0.005, 0.1, 30.0, 0.04));
        assert_eq!(FaultRates::default().parse_over("").unwrap(), FaultRates::default());
        assert!(!FaultRates::default().any());
        for (bad, says) in [
            ("timeout", "is not kind=rate"),
            ("timeout=x", "is not a number"),
            ("lightning=0.1", "unknown fault kind 'lightning'"),
            ("device=0.7", "from 0 to 0.5"),
            ("timeout=0.2,stall=0.2,garbled=0.2", "more than 0.5"),
            ("beam_hold_s=-1", "beam_hold_s"),
        ] {
            let e = FaultRates::default().parse_over(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn injected_counts_by_kind_across_clones() {
        let a = Injected::new();
        let b = a.clone();
        a.add(FaultKind::Beam);
        b.add(FaultKind::Beam);
        b.add(FaultKind::Stall);
        assert_eq!((a.get(FaultKind::Beam), a.get(FaultKind::Stall), a.total()), (2, 1, 3));
        assert_eq!(a.by_kind()[6], ("beam", 2));
        assert_eq!(a.by_kind()[0], ("timeout", 0));
    }
}
