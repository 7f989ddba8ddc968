//! ethercrab 0.7 as an in-process master on a simulated segment.
//!
//! The transport seam (as ethercrab 0.7 requires): ethercrab's `PduStorage` is split once per
//! process into `(PduTx, PduRx, PduLoop)`. [`SimNetwork`] is the "network": a future
//! that, on every poll, registers its waker (`replace_waker`), takes every
//! `next_sendable_frame()`, copies the frame out in `send_blocking`, lets the
//! [`Wire`] (the segment) process it, and hands the returned frame to
//! `receive_frame` **after** `send_blocking` has returned. The first ESC sets the
//! locally administered bit in the source MAC, so ethercrab does not drop the
//! returned frame as its own.
//!
//! [`MasterHarness`] owns the split storage for a whole test binary and runs one
//! scenario after another: each gets a fresh `MainDevice` (released afterwards so the
//! `PduLoop` can be reused), a segment and the network future, all on one thread with
//! `futures_lite::future::block_on` (ethercrab's timers are `async-io` timers, which
//! run without a particular executor).
//!
//! Simulated time: each frame advances the segment by its frame time; the scenario
//! moves time explicitly (e.g. one cycle per `tx_rx`). [`sim_now_ns`] is the segment
//! time of the last frame, handed to ethercrab as its `ethercat_now` clock.

use crate::esc_sim::frame::{FrameOutcome, Wire};
use ethercrab::{MainDevice, MainDeviceConfig, PduLoop, PduRx, PduStorage, PduTx, Timeouts};
use std::cell::RefCell;
use std::future::Future;
use std::pin::Pin;
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;

static SIM_NOW_NS: AtomicU64 = AtomicU64::new(0);

/// Simulated time of the last frame (ns); pass `sim_now_ns` as ethercrab's clock.
pub fn sim_now_ns() -> u64 {
    SIM_NOW_NS.load(Ordering::Relaxed)
}

/// Frame counters of one network.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NetStats {
    /// Frames ethercrab sent.
    pub sent: u64,
    /// Frames ethercrab accepted back.
    pub received: u64,
    /// Frames ethercrab refused (`receive_frame` error) or ignored.
    pub rejected: u64,
    /// Frames the segment found malformed.
    pub malformed: u64,
}

/// The network future: never completes; run it next to the scenario.
pub struct SimNetwork<'a, W: Wire> {
    tx: &'a mut PduTx<'static>,
    rx: &'a mut PduRx<'static>,
    wire: Rc<RefCell<W>>,
    stats: Rc<RefCell<NetStats>>,
    buf: Vec<u8>,
}

impl<W: Wire> Future for SimNetwork<'_, W> {
    type Output = ();

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        let this = self.get_mut();
        this.tx.replace_waker(cx.waker());
        while let Some(frame) = this.tx.next_sendable_frame() {
            this.buf.clear();
            let buf = &mut this.buf;
            let sent = frame.send_blocking(|bytes| {
                buf.extend_from_slice(bytes);
                Ok(bytes.len())
            });
            let mut st = this.stats.borrow_mut();
            if sent.is_err() {
                st.rejected += 1;
                continue;
            }
            st.sent += 1;
            let outcome = {
                let mut w = this.wire.borrow_mut();
                let o = w.transfer(&mut this.buf);
                SIM_NOW_NS.store(w.now_ns(), Ordering::Relaxed);
                o
            };
            match outcome {
                FrameOutcome::Malformed(_) => st.malformed += 1,
                FrameOutcome::Destroyed { .. } => {
                    // Nothing comes back: ethercrab will time the PDU out.
                    st.rejected += 1;
                    continue;
                }
                _ => {}
            }
            match this.rx.receive_frame(&this.buf) {
                Ok(ethercrab::ReceiveAction::Processed) => st.received += 1,
                _ => st.rejected += 1,
            }
        }
        Poll::Pending
    }
}

/// Timeouts for simulated segments: the simulator answers at once, so the waits
/// only guard against a hang.
pub fn sim_timeouts() -> Timeouts {
    Timeouts {
        state_transition: Duration::from_secs(5),
        pdu: Duration::from_millis(200),
        eeprom: Duration::from_millis(200),
        wait_loop_delay: Duration::from_micros(0),
        mailbox_echo: Duration::from_millis(500),
        mailbox_response: Duration::from_millis(1000),
    }
}

/// A master configuration for tests: few DC static-sync frames (the default sends
/// 10 000), no retries.
pub fn sim_config() -> MainDeviceConfig {
    MainDeviceConfig {
        dc_static_sync_iterations: 16,
        ..MainDeviceConfig::default()
    }
}

/// Owns the split `PduStorage` of a test binary and runs scenarios one after another.
pub struct MasterHarness {
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    pdu_loop: Option<PduLoop<'static>>,
}

impl MasterHarness {
    /// Splits `storage` (once per process; `None` if it was split before).
    pub fn new<const N: usize, const D: usize>(storage: &'static PduStorage<N, D>) -> Option<Self> {
        let (tx, rx, pdu_loop) = storage.try_split().ok()?;
        Some(MasterHarness {
            tx,
            rx,
            pdu_loop: Some(pdu_loop),
        })
    }

    /// Runs `scenario` with a fresh `MainDevice` on `wire`; returns its result and the
    /// frame counters. The `MainDevice` is released afterwards, so the next scenario
    /// can reuse the storage.
    pub fn run<W, F, Fut, T>(
        &mut self,
        wire: Rc<RefCell<W>>,
        timeouts: Timeouts,
        config: MainDeviceConfig,
        scenario: F,
    ) -> (T, NetStats)
    where
        W: Wire,
        F: FnOnce(Rc<MainDevice<'static>>) -> Fut,
        Fut: Future<Output = T>,
    {
        let pdu_loop = self
            .pdu_loop
            .take()
            .expect("PduLoop in use by another scenario");
        let md = Rc::new(MainDevice::new(pdu_loop, timeouts, config));
        let stats = Rc::new(RefCell::new(NetStats::default()));
        let net = SimNetwork {
            tx: &mut self.tx,
            rx: &mut self.rx,
            wire,
            stats: stats.clone(),
            buf: Vec::with_capacity(1536),
        };
        let fut = scenario(md.clone());
        let out = futures_lite::future::block_on(futures_lite::future::or(fut, async {
            net.await;
            unreachable!("the network future never completes")
        }));
        let Ok(md) = Rc::try_unwrap(md) else {
            panic!("the scenario kept a MainDevice reference");
        };
        // SAFETY: no frame is in flight (the scenario has completed and the network
        // future is dropped); groups of this MainDevice are not used again.
        let pdu_loop = unsafe { md.release() };
        self.pdu_loop = Some(pdu_loop);
        let st = *stats.borrow();
        (out, st)
    }
}
