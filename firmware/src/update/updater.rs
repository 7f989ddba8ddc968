//! The flash side of an update: what [`super::Update`] needs from the flash and
//! embassy-boot ([`Updater`]), its boot states and errors, and [`EmbassyUpdater`],
//! the implementation over embassy-boot for the board and the host alike.

use efw::HEADER_LEN;

use crate::flash_layout;

/// Where the running image stands with embassy-boot (0x2320 reports it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BootState {
    /// Confirmed (or never updated): updates are taken.
    Confirmed = 0,
    /// A new image on trial: not yet confirmed; a reset now reverts it.
    Trial = 1,
    /// The bootloader reverted an unconfirmed image: the previous image runs.
    Reverted = 2,
}

impl BootState {
    /// Its text in [`INFO_FILE`](super::INFO_FILE).
    pub const fn name(self) -> &'static str {
        match self {
            BootState::Confirmed => "confirmed",
            BootState::Trial => "trial",
            BootState::Reverted => "reverted",
        }
    }
}

/// Errors of an [`Updater`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpdaterError {
    /// The flash failed (or an access was out of bounds).
    Flash,
    /// The image signature does not verify.
    Signature,
    /// The running image is not confirmed (no update while on trial).
    NotConfirmed,
}

/// What the update needs from the flash and embassy-boot (implemented by
/// [`EmbassyUpdater`] for the board and the host alike).
pub trait Updater {
    /// Size of the DFU partition.
    fn capacity(&self) -> u32;
    /// Erases the page ([`flash_layout::PAGE`]) at `offset` of the DFU partition.
    fn erase_page(&mut self, offset: u32) -> Result<(), UpdaterError>;
    /// Writes `data` (a multiple of 8 bytes, into erased flash) at `offset` of the DFU
    /// partition.
    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), UpdaterError>;
    /// Reads `buf.len()` bytes at `offset` of the DFU partition.
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), UpdaterError>;
    /// Marks the DFU partition for the swap (the image was checked before);
    /// [`UpdaterError::NotConfirmed`] while the running image is on trial.
    fn mark_updated(&mut self) -> Result<(), UpdaterError>;
    /// The boot state.
    fn boot_state(&mut self) -> Result<BootState, UpdaterError>;
    /// Confirms the running image.
    fn mark_booted(&mut self) -> Result<(), UpdaterError>;
    /// Reads the running image's header page (its first [`HEADER_LEN`] bytes).
    fn read_running_header(&mut self, buf: &mut [u8; HEADER_LEN]) -> Result<(), UpdaterError>;
}

/// [`Updater`] over embassy-boot: its firmware state (the state partition: marking,
/// boot state), the DFU partition for the writes and the check's reads, and the
/// active partition, read for the running image's header. The image check itself is
/// [`Update`](super::Update)'s, in steps (embassy-boot's `verify_and_mark_updated`
/// would hash the whole image in one call).
///
/// The image is written page by page here rather than by embassy-boot's
/// `write_firmware`: that one erases a page only when it is not the last page it
/// erased, so a transfer that starts again after an aborted one would write into a
/// programmed page. Here every transfer erases what it writes, one page per FoE
/// DATA at most (answered BUSY), so no call blocks for more than one page erase.
pub struct EmbassyUpdater<'d, DFU, STATE, ACTIVE>
where
    DFU: embedded_storage::nor_flash::NorFlash,
    STATE: embedded_storage::nor_flash::NorFlash,
{
    state: embassy_boot::BlockingFirmwareState<'d, STATE>,
    dfu: DFU,
    active: ACTIVE,
}

impl<'d, DFU, STATE, ACTIVE> EmbassyUpdater<'d, DFU, STATE, ACTIVE>
where
    DFU: embedded_storage::nor_flash::NorFlash,
    STATE: embedded_storage::nor_flash::NorFlash,
    ACTIVE: embedded_storage::nor_flash::ReadNorFlash,
{
    /// The updater of the `dfu` and `state` partitions (`aligned`: at least the
    /// state partition's write size, aligned to it) and the `active` partition
    /// (partitions of one flash, e.g. embassy's `BlockingPartition`).
    pub fn new(dfu: DFU, state: STATE, active: ACTIVE, aligned: &'d mut [u8]) -> Self {
        EmbassyUpdater {
            state: embassy_boot::BlockingFirmwareState::new(state, aligned),
            dfu,
            active,
        }
    }
}

fn updater_error(e: embassy_boot::FirmwareUpdaterError) -> UpdaterError {
    match e {
        embassy_boot::FirmwareUpdaterError::Flash(_) => UpdaterError::Flash,
        embassy_boot::FirmwareUpdaterError::Signature(_) => UpdaterError::Signature,
        embassy_boot::FirmwareUpdaterError::BadState => UpdaterError::NotConfirmed,
    }
}

impl<DFU, STATE, ACTIVE> Updater for EmbassyUpdater<'_, DFU, STATE, ACTIVE>
where
    DFU: embedded_storage::nor_flash::NorFlash,
    STATE: embedded_storage::nor_flash::NorFlash,
    ACTIVE: embedded_storage::nor_flash::ReadNorFlash,
{
    fn capacity(&self) -> u32 {
        self.dfu.capacity() as u32
    }

    fn erase_page(&mut self, offset: u32) -> Result<(), UpdaterError> {
        let end = offset
            .checked_add(flash_layout::PAGE)
            .ok_or(UpdaterError::Flash)?;
        self.dfu.erase(offset, end).map_err(|_| UpdaterError::Flash)
    }

    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), UpdaterError> {
        self.dfu
            .write(offset, data)
            .map_err(|_| UpdaterError::Flash)
    }

    fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), UpdaterError> {
        self.dfu.read(offset, buf).map_err(|_| UpdaterError::Flash)
    }

    fn mark_updated(&mut self) -> Result<(), UpdaterError> {
        // embassy-boot's rule (its `verify_booted`): no swap is marked over an image
        // that is still on trial.
        match self.state.get_state().map_err(updater_error)? {
            embassy_boot::State::Swap => Err(UpdaterError::NotConfirmed),
            _ => self.state.mark_updated().map_err(updater_error),
        }
    }

    fn boot_state(&mut self) -> Result<BootState, UpdaterError> {
        Ok(match self.state.get_state().map_err(updater_error)? {
            embassy_boot::State::Swap => BootState::Trial,
            embassy_boot::State::Revert => BootState::Reverted,
            embassy_boot::State::Boot | embassy_boot::State::DfuDetach => BootState::Confirmed,
        })
    }

    fn mark_booted(&mut self) -> Result<(), UpdaterError> {
        self.state.mark_booted().map_err(updater_error)
    }

    fn read_running_header(&mut self, buf: &mut [u8; HEADER_LEN]) -> Result<(), UpdaterError> {
        self.active
            .read(flash_layout::HEADER_OFFSET, buf)
            .map_err(|_| UpdaterError::Flash)
    }
}
