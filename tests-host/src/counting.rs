//! A counting wrapper around any [`SlaveApplication`], and a segment of the product
//! drive ([`SimDrive`]) wrapped in it.
//!
//! [`Counting`] forwards every call to the wrapped application and counts the
//! application cycles the runtime ran (by synchronisation mode), so a test can check
//! "exactly one cycle per SYNC0" against the ESC simulator's SYNC0 pulse counter
//! ([`crate::esc_sim::SimStats::sync0_pulses`]).

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{Dictionary, Object, ObjectKey, SdoAbort};
use ecat_slave_stack::pdo::ProcessData;
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};
use ecat_slave_stack::sync::SyncMode;
use firmware::identity::{self, Variant};

use crate::esc_sim::Flavour;
use crate::file_flash::FileFlash;
use crate::segment::{sii_image_with_pdos, Segment, SegmentConfig};
use crate::sim_axis::AxisModel;
use crate::sim_drive::{esc_flavour, slave_config, Motor, SimDrive};

/// Application cycles seen by [`Counting`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CycleCounts {
    /// All cycles.
    pub total: u64,
    /// Cycles in free-run mode.
    pub free_run: u64,
    /// Cycles in SM-synchronous mode.
    pub sm_sync: u64,
    /// Cycles in DC SYNC0 mode.
    pub dc_sync0: u64,
    /// Cycles in Op.
    pub in_op: u64,
}

/// Forwards everything to `inner` and counts its cycles.
pub struct Counting<A> {
    /// The wrapped application.
    pub inner: A,
    /// Cycles so far.
    pub counts: CycleCounts,
}

impl<A> Counting<A> {
    /// Wraps `inner` with zero counts.
    pub fn new(inner: A) -> Self {
        Counting {
            inner,
            counts: CycleCounts::default(),
        }
    }
}

impl<A: Dictionary> Dictionary for Counting<A> {
    fn objects(&self) -> &'static [Object] {
        self.inner.objects()
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        self.inner.read(key, buf)
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        self.inner.write(key, data, state)
    }
    fn write_with_runtime(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        state: EsmState,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        self.inner.write_with_runtime(key, data, state, runtime)
    }
}

impl<A: ProcessData> ProcessData for Counting<A> {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        self.inner.rx_slot(key)
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        self.inner.tx_slot(key)
    }
    fn set_rx(&mut self, slot: u16, raw: u64) {
        self.inner.set_rx(slot, raw)
    }
    fn get_tx(&self, slot: u16) -> u64 {
        self.inner.get_tx(slot)
    }
}

impl<A: EsmHooks> EsmHooks for Counting<A> {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.inner.on_state_change(from, to)
    }
    fn on_enter_bootstrap(&mut self) {
        self.inner.on_enter_bootstrap()
    }
    fn on_leave_bootstrap(&mut self) {
        self.inner.on_leave_bootstrap()
    }
}

impl<A: SlaveApplication> SlaveApplication for Counting<A> {
    fn cycle(&mut self, info: &CycleInfo) {
        let c = &mut self.counts;
        c.total += 1;
        match info.mode {
            SyncMode::FreeRun => c.free_run += 1,
            SyncMode::SmSync => c.sm_sync += 1,
            SyncMode::DcSync0 => c.dc_sync0 += 1,
        }
        if info.state == EsmState::Op {
            c.in_op += 1;
        }
        self.inner.cycle(info)
    }
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.inner.on_outputs_lost(code)
    }
    fn device_id(&mut self) -> Option<u16> {
        self.inner.device_id()
    }
    fn local_error(&mut self) -> Option<AlStatusCode> {
        self.inner.local_error()
    }
    fn sync_error_limit(&self) -> u16 {
        self.inner.sync_error_limit()
    }
    fn now_us(&mut self) -> Option<u64> {
        self.inner.now_us()
    }
    fn foe(&mut self) -> Option<&mut dyn ecat_slave_stack::foe::FoeFiles> {
        self.inner.foe()
    }
}

/// A segment of `n` product drives (the SII, PDO defaults and power-up of
/// [`crate::sim_drive::segment`]; in-memory parameter flash; kinematic axis, which
/// is cheap enough for many short bring-ups), each behind a [`Counting`] wrapper.
pub fn product_segment(flavour: Flavour, n: usize) -> Result<Segment<Counting<SimDrive>>, String> {
    let desc = identity::device_description(Variant::HybridServo, esc_flavour(flavour), 0);
    let sii = sii_image_with_pdos(
        &desc,
        firmware::dictionary::OBJECTS,
        &firmware::pdo_defaults::PDO_DEFAULTS,
    )
    .map_err(|e| format!("SII image: {e:?}"))?;
    let apps = (0..n)
        .map(|i| {
            let axis = crate::sim_axis::boxed_model(Motor::Ecn57_20, AxisModel::Kinematic, n);
            Counting::new(SimDrive::new(
                0x1000 + i as u32,
                FileFlash::in_memory(),
                axis,
            ))
        })
        .collect();
    let mut seg = Segment::new(
        SegmentConfig::new(flavour),
        &sii,
        apps,
        slave_config(),
        None,
    )
    .map_err(|e| format!("ESC start-up: {e:?}"))?;
    for d in seg.drives_mut() {
        let mut runtime = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
        d.app.inner.drive.power_up(&mut runtime);
        d.app.inner.axis.parameters(&d.app.inner.drive.params);
    }
    Ok(seg)
}

/// Advances a [`product_segment`] by `dt_ns` (≤ 100 µs steps, with each drive's
/// housekeeping and emergencies, as [`crate::sim_drive::advance`] does).
pub fn advance(seg: &mut Segment<Counting<SimDrive>>, dt_ns: u64) {
    let mut left = dt_ns;
    while left > 0 {
        let step = left.min(100_000);
        seg.advance(step);
        let now_us = seg.now_ns() / 1000;
        for d in seg.drives_mut() {
            d.app.inner.catch_up(now_us);
            while let Some(e) = d.app.inner.drive.pop_emergency() {
                d.slave.emergency(e.code, e.register, e.data);
            }
        }
        left -= step;
    }
}
