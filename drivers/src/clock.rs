//! The clock instruments and the survey engine share.
//!
//! Real instruments run on [`SystemClock`]. Simulated instruments run on a
//! [`VirtualClock`]: sleeping advances virtual time at once, so hours of
//! instrument time pass in seconds and every run is deterministic. Time is read
//! only through the clock, never from the OS inside a simulator or the engine.

use crate::error::{DriverError, Result};
use std::fmt::Debug;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

/// A clock's sleep. On the virtual clock a plain future (a simulated survey
/// sleeps millions of times: no allocation each), else a boxed tokio timer.
#[must_use = "a sleep does nothing unless awaited"]
pub struct Sleep<'a>(SleepOn<'a>);

enum SleepOn<'a> {
    Virtual(VirtualSleep<'a>),
    Timer(Pin<Box<tokio::time::Sleep>>),
}

impl<'a> Sleep<'a> {
    /// A sleep of `d` on tokio's timer.
    fn timer(d: Duration) -> Self {
        Sleep(SleepOn::Timer(Box::pin(tokio::time::sleep(d))))
    }
}

impl Future for Sleep<'_> {
    type Output = ();
    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        match &mut self.0 {
            SleepOn::Virtual(s) => Pin::new(s).poll(cx),
            SleepOn::Timer(s) => s.as_mut().poll(cx),
        }
    }
}

impl Debug for Sleep<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self.0 {
            SleepOn::Virtual(_) => "Sleep(virtual)",
            SleepOn::Timer(_) => "Sleep(timer)",
        })
    }
}

/// A source of time and of waiting.
pub trait Clock: Send + Sync + Debug {
    /// Time since the clock's epoch.
    fn now(&self) -> Duration;
    /// Wait for `d` of this clock's time.
    fn sleep(&self, d: Duration) -> Sleep<'_>;
    /// Whether this clock's time is simulated (it then runs much faster than
    /// the wall clock).
    fn is_virtual(&self) -> bool;
}

/// The wall clock, for real instruments.
#[derive(Debug, Clone)]
pub struct SystemClock {
    epoch: Instant,
    offset: Duration,
}

impl SystemClock {
    pub fn new() -> Self {
        Self { epoch: Instant::now(), offset: Duration::ZERO }
    }

    /// A clock whose time starts at `offset` (a resumed survey's time goes on).
    pub fn starting_at(offset: Duration) -> Self {
        Self { epoch: Instant::now(), offset }
    }
}

impl Default for SystemClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for SystemClock {
    fn now(&self) -> Duration {
        self.offset + self.epoch.elapsed()
    }
    fn sleep(&self, d: Duration) -> Sleep<'_> {
        Sleep::timer(d)
    }
    fn is_virtual(&self) -> bool {
        false
    }
}

/// The wall clock sped up `scale` times: `now()` is the real time elapsed
/// times `scale`, and `sleep(d)` waits `d / scale` of real time. What
/// `survey sim --time-scale X` runs its simulators on, so a client in another
/// process (on the wall clock) rehearses a survey in a fraction of its time.
#[derive(Debug, Clone)]
pub struct ScaledClock {
    epoch: Instant,
    scale: f64,
}

impl ScaledClock {
    /// A clock running `scale` times faster than the wall clock (`scale`
    /// finite and positive; 1 is the wall clock).
    pub fn new(scale: f64) -> Self {
        assert!(scale.is_finite() && scale > 0.0, "a time scale is finite and positive, got {scale}");
        Self { epoch: Instant::now(), scale }
    }

    /// How many times faster than the wall clock.
    pub fn scale(&self) -> f64 {
        self.scale
    }
}

impl Clock for ScaledClock {
    fn now(&self) -> Duration {
        self.epoch.elapsed().mul_f64(self.scale)
    }
    fn sleep(&self, d: Duration) -> Sleep<'_> {
        Sleep::timer(d.div_f64(self.scale))
    }
    fn is_virtual(&self) -> bool {
        false
    }
}

/// Simulated time. `sleep(d)` reads the time when it is first polled, yields
/// once, then advances the clock to at least that time plus `d`. Sequential
/// sleeps add up; sleeps that run concurrently (`join!`) overlap, so two
/// instruments read at the same time cost the longer of the two, as they
/// would on hardware.
#[derive(Debug, Clone, Default)]
pub struct VirtualClock {
    nanos: Arc<AtomicU64>,
}

impl VirtualClock {
    pub fn new() -> Self {
        Self::default()
    }

    /// A clock that starts at `t`.
    pub fn starting_at(t: Duration) -> Self {
        let c = Self::new();
        c.advance_to(t);
        c
    }

    /// Move time forward to `t` (never backward).
    pub fn advance_to(&self, t: Duration) {
        self.nanos.fetch_max(t.as_nanos().min(u64::MAX as u128) as u64, Ordering::SeqCst);
    }

    /// Move time forward by `d`.
    pub fn advance(&self, d: Duration) {
        self.advance_to(self.now() + d);
    }
}

impl Clock for VirtualClock {
    fn now(&self) -> Duration {
        Duration::from_nanos(self.nanos.load(Ordering::SeqCst))
    }
    fn sleep(&self, d: Duration) -> Sleep<'_> {
        Sleep(SleepOn::Virtual(VirtualSleep { clock: self, d, start: None }))
    }
    fn is_virtual(&self) -> bool {
        true
    }
}

struct VirtualSleep<'a> {
    clock: &'a VirtualClock,
    d: Duration,
    start: Option<Duration>,
}

impl Future for VirtualSleep<'_> {
    type Output = ();
    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        match self.start {
            None => {
                self.start = Some(self.clock.now());
                cx.waker().wake_by_ref();
                Poll::Pending
            }
            Some(start) => {
                self.clock.advance_to(start + self.d);
                Poll::Ready(())
            }
        }
    }
}

/// How long a call on a virtual clock may take in real time before it is
/// declared hung: simulated instruments answer at once in real time, so this
/// only catches a simulator that never answers.
pub const VIRTUAL_REAL_TIME_GUARD: Duration = Duration::from_secs(30);

/// Run one instrument call with a deadline of `limit` on `clock`.
///
/// On the system clock the call is cancelled at the deadline. On a virtual
/// clock the call is also failed when it took more than `limit` of virtual
/// time (a simulated instrument that is too slow), and cancelled if it takes
/// longer than [`VIRTUAL_REAL_TIME_GUARD`] in real time (one that never answers).
pub async fn with_timeout<T, F>(clock: &dyn Clock, limit: Duration, instrument: &str, what: &str, call: F) -> Result<T>
where
    F: Future<Output = Result<T>>,
{
    let started = clock.now();
    let outcome = if clock.is_virtual() {
        guarded(VIRTUAL_REAL_TIME_GUARD, call).await
    } else {
        tokio::time::timeout(limit, call).await.ok()
    };
    match outcome {
        None => {
            tracing::warn!(instrument, what, ?limit, "instrument call timed out");
            Err(DriverError::timeout(instrument, what, limit))
        }
        Some(result) => {
            if clock.is_virtual() && clock.now().saturating_sub(started) > limit {
                tracing::warn!(instrument, what, ?limit, "simulated instrument call exceeded its deadline");
                return Err(DriverError::timeout(instrument, what, limit));
            }
            result
        }
    }
}

/// How many times in a row a call may be pending having woken itself (a
/// simulated instrument sleeping on the virtual clock: it is polled again at
/// once) before [`guarded`] arms its real-time timer anyway.
const SELF_WOKEN_POLLS: u32 = 64;

/// Whether the call woke its task while it was being polled, forwarding the
/// wake to the task.
struct SelfWake {
    woke: std::sync::atomic::AtomicBool,
    /// The task polling the call; none while the [`SelfWake`] is spare.
    task: Option<std::task::Waker>,
}

impl std::task::Wake for SelfWake {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        self.woke.store(true, Ordering::Relaxed);
        if let Some(task) = &self.task {
            task.wake_by_ref();
        }
    }
}

thread_local! {
    /// A spare [`SelfWake`] for [`guarded`]'s next poll on this thread: a
    /// simulated survey polls millions of calls, each one allocation less.
    static SPARE_WAKE: std::cell::Cell<Option<Arc<SelfWake>>> = const { std::cell::Cell::new(None) };
}

impl SelfWake {
    /// A [`SelfWake`] for `task`, not yet woken: the spare one when nothing
    /// else holds it (a call that keeps a clone of its waker), else a new one.
    fn for_task(task: &std::task::Waker) -> Arc<SelfWake> {
        if let Some(mut spare) = SPARE_WAKE.take()
            && let Some(w) = Arc::get_mut(&mut spare)
        {
            *w.woke.get_mut() = false;
            w.task = Some(task.clone());
            return spare;
        }
        Arc::new(SelfWake { woke: false.into(), task: Some(task.clone()) })
    }

    /// Give `wake` back as this thread's spare, unless the call kept a clone
    /// of its waker (it may still wake it: that one stays with the call).
    fn give_back(mut wake: Arc<SelfWake>) {
        if let Some(w) = Arc::get_mut(&mut wake) {
            w.task = None;
            SPARE_WAKE.set(Some(wake));
        }
    }
}

/// `call`, cancelled (`None`) once it has been pending for `limit` of real
/// time. A call on the virtual clock is pending only while a simulated
/// instrument's sleep yields once (it wakes itself and is polled again at
/// once); a timer for every such call (a clock read and the timer wheel's
/// locks, about a tenth of a simulated survey's CPU) is armed only when the
/// call is pending without having woken itself (waiting on something
/// outside: a socket, a pty, a simulator that never answers), or has woken
/// itself [`SELF_WOKEN_POLLS`] times in a row. The limit then runs from that
/// poll: a hang is still cut after `limit`.
async fn guarded<T>(limit: Duration, call: impl Future<Output = T>) -> Option<T> {
    let mut call = std::pin::pin!(call);
    let mut timer: Option<Pin<Box<tokio::time::Sleep>>> = None;
    let mut self_woken = 0;
    std::future::poll_fn(|cx| {
        if timer.is_none() {
            let wake = SelfWake::for_task(cx.waker());
            let waker = std::task::Waker::from(wake.clone());
            let polled = call.as_mut().poll(&mut Context::from_waker(&waker));
            drop(waker);
            let woke = wake.woke.load(Ordering::Relaxed);
            SelfWake::give_back(wake);
            if let Poll::Ready(out) = polled {
                return Poll::Ready(Some(out));
            }
            if woke && self_woken < SELF_WOKEN_POLLS {
                self_woken += 1;
                return Poll::Pending;
            }
            timer = Some(Box::pin(tokio::time::sleep(limit)));
        } else if let Poll::Ready(out) = call.as_mut().poll(cx) {
            return Poll::Ready(Some(out));
        }
        match timer.as_mut().map(|t| t.as_mut().poll(cx)) {
            Some(Poll::Ready(())) => Poll::Ready(None),
            _ => Poll::Pending,
        }
    })
    .await
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ErrorKind;

    #[tokio::test]
    async fn sequential_sleeps_add_and_concurrent_ones_overlap() {
        let c = VirtualClock::new();
        c.sleep(Duration::from_millis(10)).await;
        c.sleep(Duration::from_millis(20)).await;
        assert_eq!(c.now(), Duration::from_millis(30));
        tokio::join!(c.sleep(Duration::from_secs(1)), c.sleep(Duration::from_millis(5)));
        assert_eq!(c.now(), Duration::from_millis(1030));
        c.advance_to(Duration::from_millis(1)); // never backward
        assert_eq!(c.now(), Duration::from_millis(1030));
    }

    #[tokio::test]
    async fn virtual_timeout_fails_a_slow_simulated_call() {
        let c = VirtualClock::new();
        let slow = async {
            c.sleep(Duration::from_secs(5)).await;
            Ok(1)
        };
        let e = with_timeout(&c, Duration::from_secs(2), "tracker", "measure", slow).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout);
        assert!(e.is_link());
        let fast = async {
            c.sleep(Duration::from_secs(1)).await;
            Ok(2)
        };
        assert_eq!(with_timeout(&c, Duration::from_secs(2), "tracker", "measure", fast).await, Ok(2));
    }

    #[tokio::test(start_paused = true)]
    async fn virtual_timeout_cancels_a_simulator_that_never_answers() {
        // Waiting on something outside (no wake of its own): the timer is
        // armed at the first poll and cuts it after the real-time guard
        // (tokio's paused clock runs it forward).
        let c = VirtualClock::new();
        let started = tokio::time::Instant::now();
        let never = std::future::pending::<Result<()>>();
        let e = with_timeout(&c, Duration::from_millis(50), "tracker", "measure", never).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout);
        assert_eq!(started.elapsed(), VIRTUAL_REAL_TIME_GUARD);
        assert_eq!(c.now(), Duration::ZERO);
    }

    #[tokio::test]
    async fn the_real_time_guard_cuts_a_call_that_keeps_waking_itself() {
        // A simulator polling forever on the virtual clock wakes itself on
        // every poll: after SELF_WOKEN_POLLS the real-time timer is armed.
        let c = VirtualClock::new();
        let spinning = async {
            loop {
                c.sleep(Duration::from_millis(1)).await;
            }
        };
        assert_eq!(guarded(Duration::from_millis(20), spinning).await, None::<()>);
        let answering = async {
            c.sleep(Duration::from_secs(1)).await;
            7
        };
        assert_eq!(guarded(Duration::from_millis(20), answering).await, Some(7));
    }

    #[tokio::test(start_paused = true)]
    async fn a_reused_wake_does_not_carry_the_previous_calls_wake() {
        // The spare SelfWake of a call that woke itself, reused for one that
        // waits on something outside: the timer must still be armed at once.
        let c = VirtualClock::new();
        let answering = async {
            c.sleep(Duration::from_millis(1)).await;
            1
        };
        assert_eq!(guarded(Duration::from_secs(5), answering).await, Some(1));
        let started = tokio::time::Instant::now();
        let never = guarded(Duration::from_secs(5), std::future::pending::<()>());
        let cut = tokio::time::timeout(Duration::from_secs(6), never).await;
        assert_eq!(cut, Ok(None), "cut by its own guard, not the outer timeout");
        assert_eq!(started.elapsed(), Duration::from_secs(5));
    }

    #[tokio::test]
    async fn a_call_that_keeps_its_waker_is_woken_through_it() {
        // A call that keeps its waker and is woken from another thread later
        // (a socket's reply): its wake is not taken back as the spare.
        let slot: Arc<std::sync::Mutex<Option<std::task::Waker>>> = Arc::default();
        let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let (s2, d2) = (slot.clone(), done.clone());
        let outside = std::future::poll_fn(move |cx| {
            if d2.load(Ordering::SeqCst) {
                return Poll::Ready(2);
            }
            *s2.lock().unwrap() = Some(cx.waker().clone());
            Poll::Pending
        });
        let waker_thread = std::thread::spawn(move || {
            loop {
                if let Some(w) = slot.lock().unwrap().take() {
                    done.store(true, Ordering::SeqCst);
                    w.wake();
                    return;
                }
                std::thread::yield_now();
            }
        });
        assert_eq!(guarded(Duration::from_secs(5), outside).await, Some(2));
        waker_thread.join().unwrap();
    }

    #[tokio::test(start_paused = true)]
    async fn system_timeout_cancels_a_call_that_never_answers() {
        let c = SystemClock::new();
        let never = std::future::pending::<Result<()>>();
        let e = with_timeout(&c, Duration::from_millis(50), "positioner", "status", never).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout);
        assert!(e.to_string().contains("positioner: timeout"), "{e}");
    }
}
