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
