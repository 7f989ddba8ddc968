//! The EtherCAT slave controller on SPI2 (with DMA), its IRQ and SYNC0 lines, and
//! the ESC driver flavour chosen by cargo feature:
//!
//! * `esc-lan9252` → [`ecat_slave_stack::lan9252::Lan9252`] (the default board, also
//!   chosen when neither feature is given, e.g. by a plain `cargo flash`);
//! * `esc-et1100` → [`ecat_slave_stack::et1100::Et1100`]. Both at once is a build
//!   error (below).
//!
//! [`EscSpi`] is the embedded-hal 1.0 `SpiDevice` both drivers take: software chip
//! select on PB12 around each transaction; data phases of [`DMA_MIN_LEN`] bytes or
//! more (of the operation kinds the build's driver uses, see `DMA_READ`) run on DMA1
//! channels 1 (RX) / 2 (TX) and are driven to completion in place
//! (the DMA interrupt is more urgent than every caller, see main.rs), shorter ones
//! (address/command phases) are polled because setting up a DMA transfer costs more
//! than clocking a few bytes. SPI mode 3, [`board::ESC_SPI_HZ`].
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::gpio::{Level, Output, Pull, Speed};
use embassy_stm32::mode::Async;
use embassy_stm32::spi::{self, mode::Master, Spi};
use embassy_stm32::time::Hertz;
use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};
use firmware::identity::PulseEdge;

use crate::board;

/// Shortest data phase moved by DMA.
pub const DMA_MIN_LEN: usize = 8;

#[cfg(all(feature = "esc-lan9252", feature = "esc-et1100"))]
compile_error!("features `esc-lan9252` and `esc-et1100` exclude each other: the board has one ESC");

/// The ESC driver of this build is the ET1100 one (see [`Esc`]).
const ET1100: bool = cfg!(feature = "esc-et1100");
/// Operation kinds whose long data phases go by DMA in this build: the ones its ESC
/// driver issues with [`DMA_MIN_LEN`] bytes or more (LAN9252: `Read` and `Write`;
/// ET1100: `Write` and `TransferInPlace`; neither sends a long `Transfer`, only
/// address phases). Other kinds still work, polled, and their DMA paths are not
/// compiled in.
const DMA_READ: bool = !ET1100;
const DMA_TRANSFER_IN_PLACE: bool = ET1100;
const DMA_TRANSFER: bool = false;

/// SPI device for the ESC driver (see the module docs).
pub struct EscSpi {
    bus: Spi<'static, Async, Master>,
    cs: Output<'static>,
}

/// The SPI configuration of the ESC bus.
pub fn spi_config() -> spi::Config {
    let mut c = spi::Config::default();
    c.mode = spi::MODE_3;
    c.frequency = Hertz(board::ESC_SPI_HZ);
    c.miso_pull = Pull::Up;
    c
}

impl EscSpi {
    /// Wraps the bus and the chip-select pin (driven high = deselected).
    pub fn new(bus: Spi<'static, Async, Master>, cs: Output<'static>) -> Self {
        let mut cs = cs;
        cs.set_high();
        EscSpi { bus, cs }
    }

    fn transfer(&mut self, read: &mut [u8], write: &[u8]) -> Result<(), spi::Error> {
        if !DMA_TRANSFER {
            // All polled: the same bytes on the wire as the split below (whose reads
            // clock out zeros), in one loop.
            return self.polled_transfer(read, write);
        }
        let n = read.len().min(write.len());
        let (r0, r1) = read.split_at_mut(n);
        let (w0, w1) = write.split_at(n);
        if DMA_TRANSFER && n >= DMA_MIN_LEN {
            embassy_futures::block_on(self.bus.transfer(r0, w0))?;
        } else if n > 0 {
            self.bus.blocking_transfer(r0, w0)?;
        }
        self.read(r1)?;
        self.write(w1)
    }

    /// Polled transfer of max(`read`, `write`) bytes: embassy's blocking transfer pads
    /// `write` with zeros and drops what comes after `read` is full, so with an empty
    /// `write` it is exactly its blocking read (same register accesses, zeros
    /// clocked out). Nothing for two empty buffers. The polled reads and transfers
    /// share it.
    fn polled_transfer(&mut self, read: &mut [u8], write: &[u8]) -> Result<(), spi::Error> {
        if read.is_empty() && write.is_empty() {
            return Ok(());
        }
        self.bus.blocking_transfer(read, write)
    }

    fn read(&mut self, buf: &mut [u8]) -> Result<(), spi::Error> {
        if DMA_READ && buf.len() >= DMA_MIN_LEN {
            embassy_futures::block_on(self.bus.read(buf))
        } else {
            self.polled_transfer(buf, &[])
        }
    }

    fn write(&mut self, buf: &[u8]) -> Result<(), spi::Error> {
        if buf.len() >= DMA_MIN_LEN {
            embassy_futures::block_on(self.bus.write(buf))
        } else if !buf.is_empty() {
            self.bus.blocking_write(buf)
        } else {
            Ok(())
        }
    }

    fn transfer_in_place(&mut self, buf: &mut [u8]) -> Result<(), spi::Error> {
        if DMA_TRANSFER_IN_PLACE && buf.len() >= DMA_MIN_LEN {
            embassy_futures::block_on(self.bus.transfer_in_place(buf))
        } else if !buf.is_empty() {
            self.bus.blocking_transfer_in_place(buf)
        } else {
            Ok(())
        }
    }
}

impl ErrorType for EscSpi {
    type Error = ErrorKind;
}

impl SpiDevice for EscSpi {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), ErrorKind> {
        self.cs.set_low();
        let mut result = Ok(());
        for op in operations.iter_mut() {
            let r = match op {
                Operation::Read(buf) => self.read(buf),
                Operation::Write(buf) => self.write(buf),
                Operation::Transfer(read, write) => self.transfer(read, write),
                Operation::TransferInPlace(buf) => self.transfer_in_place(buf),
                Operation::DelayNs(ns) => {
                    // 170 cycles per µs; round up.
                    cortex_m::asm::delay(
                        ns.saturating_mul(board::SYSCLK_HZ / 1_000_000) / 1000 + 1,
                    );
                    Ok(())
                }
            };
            if let Err(e) = r {
                result = Err(match e {
                    spi::Error::Overrun => ErrorKind::Overrun,
                    spi::Error::ModeFault => ErrorKind::ModeFault,
                    spi::Error::Framing => ErrorKind::FrameFormat,
                    _ => ErrorKind::Other,
                });
                break;
            }
        }
        self.cs.set_high();
        result
    }
}

/// The pull of the SYNC0 input: the ESC drives SYNC0 push-pull once it has loaded the
/// SII; until then the pull holds it at its idle level (low for an active-high pulse).
pub const SYNC0_IDLE_PULL: Pull = match firmware::identity::SYNC0_ACTIVE_EDGE {
    PulseEdge::Rising => Pull::Down,
    PulseEdge::Falling => Pull::Up,
};

/// Waits for the leading edge of the next SYNC0 pulse: the edge
/// [`firmware::identity::SYNC0_ACTIVE_EDGE`] derives from the SII's 0x0151 value (the
/// one definition of the polarity, `firmware::identity::SYNC0_DRIVE`).
pub async fn sync0_edge(pin: &mut ExtiInput<'static, Async>) {
    match firmware::identity::SYNC0_ACTIVE_EDGE {
        PulseEdge::Rising => pin.wait_for_rising_edge().await,
        PulseEdge::Falling => pin.wait_for_falling_edge().await,
    }
}

/// The chip-select pin, idle high.
pub fn cs_pin(
    pin: embassy_stm32::Peri<'static, embassy_stm32::peripherals::PB12>,
) -> Output<'static> {
    Output::new(pin, Level::High, Speed::VeryHigh)
}

/// The ESC driver of this build.
#[cfg(not(feature = "esc-et1100"))]
pub type Esc = ecat_slave_stack::lan9252::Lan9252<EscSpi>;
/// The ESC driver of this build.
#[cfg(feature = "esc-et1100")]
pub type Esc = ecat_slave_stack::et1100::Et1100<EscSpi>;

/// Name of the ESC of this build, for logs.
pub const ESC_NAME: &str = if cfg!(feature = "esc-et1100") {
    "ET1100"
} else {
    "LAN9252"
};

/// ESC type register value of this build's chip (the self-test's identity check).
#[cfg(feature = "selftest")]
pub const ESC_TYPE: u8 = if cfg!(feature = "esc-et1100") {
    ecat_slave_stack::et1100::ET1100_TYPE
} else {
    ecat_slave_stack::lan9252::LAN9252_TYPE
};

/// Builds the driver of this flavour over `spi`.
pub fn new_esc(spi: EscSpi) -> Esc {
    Esc::new(spi, Default::default())
}

/// Probes the chip: the driver's start-up sequence (LAN9252: BYTE_TEST, READY, reset,
/// ID_REV, then its IRQ pin configuration; ET1100: type register and PDI-operational
/// bit), then the ESC type and
/// revision registers through the common `EscAccess` path. One defmt line says what
/// answered.
pub fn probe(esc: &mut Esc) -> Result<(), ecat_slave_stack::EscError> {
    use ecat_slave_stack::EscAccess;
    esc.init(&mut embassy_time::Delay)?;
    // LAN9252: drive the IRQ pin (open drain, active low; the board pulls it up).
    // The ET1100's PDI IRQ is set up by its SII configuration.
    #[cfg(not(feature = "esc-et1100"))]
    esc.configure_irq(ecat_slave_stack::lan9252::IrqConfig {
        enable: true,
        active_high: false,
        push_pull: false,
        deassert_interval: 0,
    })?;
    let ty = esc.get(ecat_slave_stack::registers::ESC_TYPE)?;
    let rev = esc.get(ecat_slave_stack::registers::ESC_REVISION)?;
    let build = esc.get(ecat_slave_stack::registers::ESC_BUILD)?;
    #[cfg(not(feature = "esc-et1100"))]
    defmt::info!(
        "ESC {=str}: ID_REV {=u32:#010x}, type {=u8:#04x} rev {=u8} build {=u16}",
        ESC_NAME,
        esc.id_rev(),
        ty,
        rev,
        build
    );
    #[cfg(feature = "esc-et1100")]
    defmt::info!(
        "ESC {=str}: type {=u8:#04x} rev {=u8} build {=u16}",
        ESC_NAME,
        ty,
        rev,
        build
    );
    Ok(())
}

/// [`probe`], logging why the ESC does not answer.
pub fn probe_logged(esc: &mut Esc) -> bool {
    match probe(esc) {
        Ok(()) => true,
        Err(e) => {
            defmt::error!(
                "ESC {=str} not answering: {=istr}",
                ESC_NAME,
                crate::hw::log::esc_error(e)
            );
            false
        }
    }
}

/// `Slave::init` (after the station alias was set), logged.
pub fn init_logged(slave: &mut ecat_slave_stack::slave::Slave<Esc>) {
    match slave.init() {
        Ok(info) => defmt::info!(
            "slave runtime: ESC type {=u8:#04x}, {=u8} SMs, {=u8} KiB RAM",
            info.esc_type,
            info.sync_managers,
            info.ram_kib
        ),
        Err(e) => {
            crate::hw::log::ESC_ERRORS.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
            defmt::error!("slave init: {=istr}", crate::hw::log::esc_error(e));
        }
    }
}
