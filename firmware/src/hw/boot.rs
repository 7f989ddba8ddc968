//! Start-up set-up of the board's memory: the static slots the drive state is built
//! in, the chip's flash (parameter region, staged saves, firmware update), the slave
//! runtime over the ESC, and the control state of the current-loop interrupt. What
//! the drive does at start-up (DIP banks, parameters, alias) is
//! `firmware::runtime::Runtime::power_up`; this module only places things.

use core::mem::MaybeUninit;

use ecat_slave_stack::slave::Slave;
use firmware::drive::Drive;
use firmware::runtime::{self, Runtime};
use firmware::staged_flash::StagedRecords;

use crate::board;
use crate::hw;
use crate::hw::control::ControlCommand;
use crate::hw::esc::Esc;
use crate::hw::flash::{ParamFlash, Stage, StagedFlash};

/// The drive with its parameter store of this board.
pub type BoardDrive = Drive<hw::flash::BoardStore>;

/// The parameter-record store in the flash region (offsets relative to the region;
/// the layout of `firmware::storage::region`: parameters, then the fault history).
pub const PARAM_STORE: firmware::storage::Storage = firmware::storage::region::PARAMS;
const _: () = assert!(firmware::storage::region::SIZE == board::PARAM_FLASH_SIZE);

/// The ESC of this build, as update images name it.
#[cfg(not(feature = "esc-et1100"))]
const BOARD_ESC: efw::Esc = efw::Esc::Lan9252;
#[cfg(feature = "esc-et1100")]
const BOARD_ESC: efw::Esc = efw::Esc::Et1100;

/// RAM image of a parameter record being saved (see `hw::flash::StagedFlash`).
static mut STAGE_MEM: Stage = Stage::new();
/// The chip's flash, shared by the records and the update (`hw::flash::ChipFlash`).
static mut CHIP_FLASH_MEM: MaybeUninit<hw::flash::ChipFlash> = MaybeUninit::uninit();
/// embassy-boot's aligned state buffer and the firmware update's slot.
static mut UPDATE_ALIGNED: embassy_boot::AlignedBuffer<8> = embassy_boot::AlignedBuffer([0; 8]);
static mut UPDATE_MEM: MaybeUninit<hw::flash::BoardUpdate> = MaybeUninit::uninit();
/// The drive application's slot (written whole by `Drive::init_in`).
static mut DRIVE_MEM: MaybeUninit<BoardDrive> = MaybeUninit::uninit();
/// The slave runtime's slot (written whole when the ESC answered).
static mut SLAVE_MEM: MaybeUninit<Slave<Esc>> = MaybeUninit::uninit();

/// The chip's flash, shared by the parameter storage and the firmware update (`None`
/// without dual-bank mode); the parameter region (`None` likewise); the drive's view
/// of the region, which reads straight from it and stages saves in RAM.
pub fn start_flash(
    flash: embassy_stm32::Peri<'static, embassy_stm32::peripherals::FLASH>,
) -> (
    Option<&'static hw::flash::ChipFlash>,
    Option<ParamFlash>,
    StagedFlash,
) {
    // SAFETY: start-up calls this once, and nothing else takes a reference to
    // CHIP_FLASH_MEM: this one is unique.
    let chip_slot = unsafe { &mut *core::ptr::addr_of_mut!(CHIP_FLASH_MEM) };
    let chip = hw::flash::chip_flash(flash, chip_slot);
    let param_flash = chip.and_then(hw::flash::param_flash);
    if param_flash.is_none() {
        defmt::error!(
            "flash is not in dual-bank mode (option byte DBANK = 0): parameter storage off"
        );
    }
    // SAFETY: start-up calls this once, and nothing else takes a reference to
    // STAGE_MEM: this one is unique.
    let stage: &'static mut Stage = unsafe { &mut *core::ptr::addr_of_mut!(STAGE_MEM) };
    let mut staged = StagedFlash::new(hw::flash::ecc_region(), stage, param_flash.is_some());
    if param_flash.is_some() {
        hw::log::param_region(&PARAM_STORE, &mut staged);
    }
    (chip, param_flash, staged)
}

/// The drive (with its firmware update when the flash allows one) and, when the ESC
/// answered, the slave runtime, each written whole into its static slot: the drive
/// state is ≈ 5 KiB, and building it on the stack and moving it would add that
/// (twice) to the stack peak. Not inlined: start-up code that runs once.
#[inline(never)]
// The mutable references come from this module's static slots, not from `chip`.
#[allow(clippy::mut_from_ref)]
pub fn place_drive_and_slave(
    chip: Option<&'static hw::flash::ChipFlash>,
    staged: StagedFlash,
    esc: Option<Esc>,
) -> (&'static mut BoardDrive, Option<&'static mut Slave<Esc>>) {
    // SAFETY: start-up calls this once and is the only place that takes references to
    // DRIVE_MEM and SLAVE_MEM: these are unique.
    let (drive_slot, slave_slot) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(DRIVE_MEM),
            &mut *core::ptr::addr_of_mut!(SLAVE_MEM),
        )
    };
    let serial = firmware::identity::serial_from_unique_id(&embassy_stm32::uid::uid());
    let drive = Drive::init_in(
        drive_slot,
        firmware::identity::BOARD_VARIANT,
        serial,
        StagedRecords {
            storage: PARAM_STORE,
            history: Some(firmware::storage::region::HISTORY),
            flash: staged,
        },
    );
    // 0x6076 (rated torque) from the board's motor.
    drive.cia402.set_torque_constant(board::MOTOR.kt);
    if let Some(chip) = chip {
        attach_update(drive, chip);
    }
    let slave =
        esc.map(|e| &mut *slave_slot.write(Slave::new(e, firmware::identity::slave_config())));
    (drive, slave)
}

/// Firmware update over FoE; embassy-boot's state tells whether this image is on
/// trial (confirmed once the start-up checks passed and Pre-Op is reached).
fn attach_update(drive: &mut BoardDrive, chip: &'static hw::flash::ChipFlash) {
    // SAFETY: called once, from start-up, and nothing else takes a reference to
    // UPDATE_ALIGNED or UPDATE_MEM: these are unique.
    let (aligned, update_slot) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(UPDATE_ALIGNED),
            &mut *core::ptr::addr_of_mut!(UPDATE_MEM),
        )
    };
    let update = hw::flash::board_update(chip, aligned, update_slot, BOARD_ESC);
    defmt::info!(
        "firmware: boot state {=u8} (0 confirmed, 1 trial, 2 reverted), header version {}",
        firmware::update::FirmwareUpdate::boot_state(update) as u8,
        firmware::update::FirmwareUpdate::running_version(update)
    );
    drive.attach_update(update);
}

/// The current-loop interrupt's control state from the drive's parameters, and the
/// runtime's first command published to it (power not permitted yet).
pub fn start_control(rt: &Runtime, drive: &BoardDrive) -> ControlCommand {
    let spec = rt.spec();
    let mcfg = runtime::motion_config(spec, drive);
    let motor = firmware::control_core::LoopMotor::from_params(
        &drive.params,
        (board::MOTOR_R_OHM, board::MOTOR_L_H),
        board::MOTOR.kt,
        mcfg.counts_per_rev / 4,
    );
    hw::control::init(
        mcfg,
        runtime::align_wiggle(drive),
        runtime::supervisor_config(spec, drive),
        motor,
    );
    let ctl = *rt.command();
    hw::control::send_command(&ctl);
    ctl
}
