//! ESC driver rows: the CPU cost of the drivers' framing, polling and byte shuffling
//! per access, with the SPI device stubbed (a real bus adds its transfer time).

use core::hint::black_box;

use ecat_slave_stack::et1100::{Et1100, Et1100Config};
use ecat_slave_stack::lan9252::{Lan9252, Lan9252Config};
use ecat_slave_stack::EscAccess;
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};

/// An SPI device that answers every read with the word 0x0000_1001: for the LAN9252
/// that is "not busy, FIFO ready with 16 words", so CSR and PRAM accesses complete at
/// the first poll; for the ET1100 it is just data.
struct StubSpi;

impl ErrorType for StubSpi {
    type Error = core::convert::Infallible;
}

impl SpiDevice for StubSpi {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        for op in ops.iter_mut() {
            let buf: &mut [u8] = match op {
                Operation::Read(r) | Operation::TransferInPlace(r) => r,
                Operation::Transfer(r, _) => r,
                _ => continue,
            };
            for (i, b) in buf.iter_mut().enumerate() {
                *b = [0x01, 0x10, 0x00, 0x00][i % 4];
            }
        }
        black_box(&ops);
        Ok(())
    }
}

pub fn run() {
    let mut lan = Lan9252::new(StubSpi, Lan9252Config::default());
    let mut buf = [0u8; 8];
    // The first PRAM access after start-up aborts the FIFO; measure a later one.
    let _ = lan.read(0x1100, &mut buf);
    let r1 = crate::bench("LAN9252 driver: read 8 B process RAM (SPI stubbed)", || {
        lan.read(black_box(0x1100), &mut buf)
    });
    let r2 = crate::bench(
        "LAN9252 driver: read AL event via CSR (SPI stubbed)",
        || lan.al_event(),
    );
    let mut et = Et1100::new(StubSpi, Et1100Config::default());
    let r3 = crate::bench("ET1100 driver: read 8 B process RAM (SPI stubbed)", || {
        et.read(black_box(0x1100), &mut buf)
    });
    let r4 = crate::bench(
        "ET1100 driver: AL event from the last address phase",
        || et.al_event(),
    );
    assert!(
        r1.is_ok() && r2.is_ok() && r3.is_ok() && r4.is_ok(),
        "stubbed ESC access failed"
    );
    black_box(buf);
}
