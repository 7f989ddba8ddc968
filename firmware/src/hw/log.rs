//! What the board logs over defmt: the texts of its error values, the start-up report
//! of the parameter-record slots, the event counters and the status line (once a
//! second, see docs/board/bring-up.md, "Flashing with probe-rs").
//!
//! The texts are interned by defmt (`{=istr}`): they stay in the ELF's .defmt section
//! for the host decoder, not in flash, and no `core::fmt` (which `Debug2Format` would
//! need) is linked into the image.
use core::sync::atomic::{AtomicU32, Ordering};

use firmware::sampling::RawSample;
use firmware::storage::{Storage, StorageError};

use crate::board;
use crate::hw;

/// SYNC0 edges seen by the cyclic task.
pub static SYNC0S: AtomicU32 = AtomicU32::new(0);
/// ESC IRQ edges seen by the EtherCAT task.
pub static ESC_IRQS: AtomicU32 = AtomicU32::new(0);
/// ESC accesses that failed (`Slave::init`, `poll`, `cycle`).
pub static ESC_ERRORS: AtomicU32 = AtomicU32::new(0);
/// Flash records that could not be staged or programmed.
pub static FLASH_ERRORS: AtomicU32 = AtomicU32::new(0);

/// Log text of an ESC access error.
pub fn esc_error(e: ecat_slave_stack::EscError) -> defmt::Str {
    use ecat_slave_stack::EscError;
    match e {
        EscError::Bus => defmt::intern!("SPI bus error"),
        EscError::NotDetected => defmt::intern!("chip not detected"),
        EscError::Timeout => defmt::intern!("timeout"),
        EscError::OutOfRange => defmt::intern!("address out of range"),
    }
}

/// Log text of a parameter-store error.
pub fn storage_error(e: StorageError) -> defmt::Str {
    match e {
        StorageError::Flash(_) => defmt::intern!("flash driver error"),
        StorageError::Geometry => defmt::intern!("flash geometry does not fit the record layout"),
        StorageError::RecordTooLarge => defmt::intern!("record larger than a slot"),
    }
}

/// Validates both record slots of `store` at start-up (magic, version, CRC) and logs
/// what they hold (the drive's power-up load applies the newest).
///
/// Reads through the drive's own view of the region (the same bytes as the flash
/// driver's), so the storage code exists once, for that one flash type.
pub fn param_region(store: &Storage, f: &mut hw::flash::StagedFlash) {
    use firmware::storage::SlotStatus;
    if let Err(e) = store.check(f) {
        defmt::error!("parameter store layout: {=istr}", storage_error(e));
        return;
    }
    let (slots, newest) = store.scan(f);
    for (i, s) in slots.iter().enumerate() {
        let at = board::PARAM_FLASH_OFFSET + store.slot_address(i);
        match *s {
            SlotStatus::Erased => {
                defmt::info!("parameter slot {=usize} @ {=u32:#x}: erased", i, at)
            }
            SlotStatus::Valid {
                sequence,
                payload_len,
            } => defmt::info!(
                "parameter slot {=usize} @ {=u32:#x}: record {=u32}, {=u32} bytes",
                i,
                at,
                sequence,
                payload_len
            ),
            SlotStatus::Corrupt => {
                defmt::warn!("parameter slot {=usize} @ {=u32:#x}: corrupt", i, at)
            }
        }
    }
    if newest.is_none() {
        defmt::info!("parameters: no saved record, defaults apply");
    }
}

/// The EtherCAT side of the status line: AL status and AL status code (0 without a
/// slave runtime), and whether the bridges are on.
#[derive(Default)]
pub struct LinkStatus {
    pub al_status: u16,
    pub al_code: u16,
    pub bridges_on: bool,
}

/// The status line: the newest current sample (`sample`: its number and the raw
/// counts), the encoder count, `link`, the event counters, the board faults, the ISR
/// time and the stack high-water mark; then the commutation and touch-probe line from
/// the interrupt's `feedback`.
pub fn status_line(
    sample: Option<(u32, RawSample)>,
    encoder_count: u32,
    link: LinkStatus,
    feedback: Option<hw::control::Feedback>,
) {
    let (used, avail) = hw::stack::high_water();
    match sample {
        Some((n, s)) => defmt::info!(
            "samples {=u32}: I_A {=u16} I_B {=u16} V_BUS {=f32} V | enc {=u32} | AL status {=u16:#x} code {=u16:#x} irq {=u32} sync0 {=u32} err {=u32} | bridges {=bool} break {=u8} hw-fault {=u8} adc2-late {=u32} flash-err {=u32} | ISR max {=u32} cycles | stack {=usize}/{=usize} B",
            n,
            s.ia,
            s.ib,
            board::ANALOG.volts(s.vbus),
            encoder_count,
            link.al_status,
            link.al_code,
            ESC_IRQS.load(Ordering::Relaxed),
            SYNC0S.load(Ordering::Relaxed),
            ESC_ERRORS.load(Ordering::Relaxed),
            link.bridges_on,
            hw::pwm::break_latched(),
            hw::safety::active_fault(),
            hw::adc::adc2_late_count(),
            FLASH_ERRORS.load(Ordering::Relaxed),
            hw::adc::isr_max_cycles(),
            used,
            avail
        ),
        None => defmt::warn!("no current samples (PWM/ADC chain not running)"),
    }
    if let Some(f) = feedback {
        let (p1, p2) = (f.probe1, f.probe2);
        defmt::info!(
            "commutation aligned {=bool}, failed {=u32} | probe edges (active/inactive, last units): IN1 {=u32}/{=u32} {=i32}/{=i32}, IN2 {=u32}/{=u32} {=i32}/{=i32}",
            f.aligned,
            f.align_failures,
            p1.active_seq,
            p1.inactive_seq,
            p1.active,
            p1.inactive,
            p2.active_seq,
            p2.inactive_seq,
            p2.active,
            p2.inactive
        );
    }
}

/// The power-up's log line: DIP banks, station alias and the parameter load.
pub fn power_up(up: &firmware::runtime::PowerUp, banks: hw::io::DipBanks) {
    defmt::info!(
        "DIP banks: {}, station address {=u16}; alias {} ({})",
        banks,
        up.dip.address,
        up.alias,
        up.alias_source
    );
    defmt::info!(
        "parameters: {=u16} applied, {=u16} skipped, from slot {}",
        up.report.applied,
        up.report.skipped,
        up.report.source.map(|(slot, seq)| (slot as u8, seq))
    );
}

/// The status line's view of the ESM and the bridges.
pub fn link_status(slave: Option<&ecat_slave_stack::slave::Slave<hw::esc::Esc>>) -> LinkStatus {
    let (al_status, al_code) = slave.map_or((0, 0), |sl| (sl.esm().status_word(), sl.esm().code()));
    LinkStatus {
        al_status,
        al_code,
        bridges_on: hw::control::feedback().is_some_and(|(_, f)| f.bridges_on),
    }
}
