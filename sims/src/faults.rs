//! What the fault-injection handles of the protocol simulators have in common:
//! a plan of armed faults behind a cheap handle that a test and a server share
//! ([`FaultPlan`]), and the count of the next requests or replies an armed fault
//! still applies to ([`Countdown`]).
//!
//! Each server keeps its own handle ([`ScpiFaults`](crate::scpi_server::ScpiFaults),
//! [`EmsconFaults`](crate::emscon_server::EmsconFaults),
//! [`ModbusFaults`](crate::modbus_server::ModbusFaults),
//! [`NodeFaults`](crate::canopen_node::NodeFaults)) with its own arming
//! methods and its own plan: what can be armed, and in which order the armed
//! faults are checked, is each protocol's. A one-shot fault ("close during the
//! next reply") is a `bool` taken with [`std::mem::take`], and faults armed one
//! per call ("reject the next command with this code") queue in a
//! [`VecDeque`](std::collections::VecDeque).

use std::fmt;
use std::sync::{Arc, Mutex, MutexGuard};

/// A plan of armed faults `P`, shared by clones: the test arms faults on its
/// clone, the server takes them from its own.
pub struct FaultPlan<P> {
    plan: Arc<Mutex<P>>,
}

impl<P> FaultPlan<P> {
    /// Lock the plan. A lock poisoned by a panicking test is taken over: a plan
    /// is plain data, consistent after every statement.
    pub fn lock(&self) -> MutexGuard<'_, P> {
        self.plan.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl<P: Default> Default for FaultPlan<P> {
    /// A new plan with nothing armed (`P::default()`).
    fn default() -> Self {
        Self { plan: Arc::default() }
    }
}

impl<P> Clone for FaultPlan<P> {
    /// Another handle on the same plan.
    fn clone(&self) -> Self {
        Self { plan: Arc::clone(&self.plan) }
    }
}

impl<P: fmt::Debug> fmt::Debug for FaultPlan<P> {
    /// As the shared mutex it wraps.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.plan.fmt(f)
    }
}

/// How many of the next requests (or replies) an armed fault applies to, e.g.
/// "drop the next `n` replies". Arming adds up; each [`take`](Self::take) that
/// finds one left uses it.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
pub struct Countdown(usize);

impl Countdown {
    /// Apply the fault to `n` more.
    pub fn add(&mut self, n: usize) {
        self.0 += n;
    }

    /// Whether the fault applies to this request (or reply); if it does, it is
    /// used up once.
    pub fn take(&mut self) -> bool {
        if self.0 > 0 {
            self.0 -= 1;
            true
        } else {
            false
        }
    }
}

impl fmt::Debug for Countdown {
    /// As the count.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
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
    counts: Arc<[std::sync::atomic::AtomicU64; 7]>,
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
