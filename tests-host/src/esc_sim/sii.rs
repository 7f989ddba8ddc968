//! The SII EEPROM interface (0x0500-0x050F) of the simulated ESC: the configuration
//! area loaded at power-up and on reload, and the read / write / reload commands.
use super::{get_u16, get_u32, put_u16, reg, EscSim};

/// The SII checksum: CRC-8, polynomial 0x07, init 0xFF, MSB first (ETG.1000.6 / ETG.2010).
pub fn sii_crc8(bytes: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

const SII_CTRL_WRITE_ENABLE: u16 = 1 << 0;
const SII_CTRL_READ_8: u16 = 1 << 6;
const SII_CTRL_ADDR_2BYTES: u16 = 1 << 7;
const SII_CTRL_CMD_MASK: u16 = 0x0700;
const SII_CTRL_CHECKSUM_ERR: u16 = 1 << 11;
const SII_CTRL_NOT_LOADED: u16 = 1 << 12;
const SII_CTRL_ACK_ERR: u16 = 1 << 13;
const SII_CTRL_WE_ERR: u16 = 1 << 14;
pub(super) const SII_CTRL_BUSY: u16 = 1 << 15;

impl EscSim {
    /// (Re)loads the ESC configuration area from the SII image: PDI control and
    /// configuration, SYNC pulse length, station alias (word 4).
    pub(super) fn load_sii_config(&mut self) {
        let mut ctrl = get_u16(&self.mem, reg::SII_CONTROL.addr() as usize)
            & !(SII_CTRL_CHECKSUM_ERR
                | SII_CTRL_NOT_LOADED
                | SII_CTRL_READ_8
                | SII_CTRL_ADDR_2BYTES);
        if self.flavour.sii_reads_8_bytes() {
            ctrl |= SII_CTRL_READ_8;
        }
        if self.sii.len() > 2048 {
            ctrl |= SII_CTRL_ADDR_2BYTES;
        }
        let ok = self.sii.len() >= 16 && sii_crc8(&self.sii[0..14]) == self.sii[14];
        let dl = reg::DL_STATUS.addr() as usize;
        if ok {
            let s = &self.sii;
            let w = |i: usize| u16::from_le_bytes([s[2 * i], s[2 * i + 1]]);
            let (w0, w1, w2, w3, w4) = (w(0), w(1), w(2), w(3), w(4));
            put_u16(&mut self.mem, reg::PDI_CONTROL.addr() as usize, w0);
            put_u16(&mut self.mem, reg::PDI_CONFIG.addr() as usize, w1);
            put_u16(&mut self.mem, reg::DC_PULSE_LENGTH.addr() as usize, w2);
            put_u16(&mut self.mem, reg::PDI_CONFIG.addr() as usize + 2, w3);
            put_u16(&mut self.mem, reg::STATION_ALIAS.addr() as usize, w4);
            self.mem[dl] |= 0x01;
        } else {
            if self.sii.len() >= 16 {
                ctrl |= SII_CTRL_CHECKSUM_ERR;
            }
            ctrl |= SII_CTRL_NOT_LOADED;
            self.mem[dl] &= !0x01;
        }
        put_u16(&mut self.mem, reg::SII_CONTROL.addr() as usize, ctrl);
    }

    pub(super) fn sii_reg_write(&mut self, a: usize, v: u8) {
        match a {
            0x0502 => {
                // Only write enable is writable in the low byte.
                self.mem[a] = (self.mem[a] & !0x01) | (v & 0x01);
            }
            0x0503 => {
                // Command bits 10:8; status bits are read-only.
                self.mem[a] = (self.mem[a] & !0x07) | (v & 0x07);
            }
            _ => self.mem[a] = v,
        }
    }

    pub(super) fn sii_execute(&mut self) {
        let ca = reg::SII_CONTROL.addr() as usize;
        let mut ctl = get_u16(&self.mem, ca);
        let cmd = (ctl & SII_CTRL_CMD_MASK) >> 8;
        ctl &= !SII_CTRL_CMD_MASK;
        let word = get_u32(&self.mem, reg::SII_ADDRESS.addr() as usize) as usize;
        match cmd {
            0 => {
                // No command: clears the error bits.
                ctl &= !(SII_CTRL_ACK_ERR | SII_CTRL_WE_ERR);
                put_u16(&mut self.mem, ca, ctl);
                return;
            }
            1 => {
                ctl &= !(SII_CTRL_ACK_ERR | SII_CTRL_WE_ERR);
                let n = if self.flavour.sii_reads_8_bytes() {
                    8
                } else {
                    4
                };
                for i in 0..8 {
                    let b = if i < n {
                        word.checked_mul(2)
                            .and_then(|o| o.checked_add(i))
                            .and_then(|o| self.sii.get(o).copied())
                            .unwrap_or(0xFF)
                    } else {
                        0
                    };
                    self.mem[reg::SII_DATA.addr() as usize + i] = b;
                }
            }
            2 => {
                if ctl & SII_CTRL_WRITE_ENABLE == 0 {
                    ctl |= SII_CTRL_WE_ERR;
                } else {
                    let o = word.saturating_mul(2);
                    let cap = self.sii_capacity();
                    if o + 2 <= cap {
                        if self.sii.len() < o + 2 {
                            self.sii.resize(o + 2, 0xFF);
                        }
                        let d = reg::SII_DATA.addr() as usize;
                        self.sii[o] = self.mem[d];
                        self.sii[o + 1] = self.mem[d + 1];
                        ctl &= !(SII_CTRL_ACK_ERR | SII_CTRL_WE_ERR);
                    } else {
                        ctl |= SII_CTRL_ACK_ERR;
                    }
                }
                ctl &= !SII_CTRL_WRITE_ENABLE;
            }
            4 => {
                put_u16(&mut self.mem, ca, ctl);
                self.load_sii_config();
                ctl = get_u16(&self.mem, ca);
                if self.flavour.sii_reads_8_bytes() {
                    // Reload with 8-byte reads supplies words 0..3 in the data register.
                    for i in 0..8 {
                        self.mem[reg::SII_DATA.addr() as usize + i] =
                            self.sii.get(i).copied().unwrap_or(0xFF);
                    }
                }
            }
            _ => {
                ctl |= SII_CTRL_ACK_ERR;
            }
        }
        self.stats.sii_commands += 1;
        // Busy for the next status read: the master must poll.
        ctl |= SII_CTRL_BUSY;
        self.sii_busy_reads = 1;
        put_u16(&mut self.mem, ca, ctl);
    }

    pub(super) fn sii_finish_busy(&mut self) {
        let ca = reg::SII_CONTROL.addr() as usize;
        let ctl = get_u16(&self.mem, ca) & !SII_CTRL_BUSY;
        put_u16(&mut self.mem, ca, ctl);
        self.sii_busy_reads = 0;
    }

    /// EEPROM capacity in bytes from SII word 0x3E (KiBit − 1), at least the image.
    pub(super) fn sii_capacity(&self) -> usize {
        let declared = if self.sii.len() >= 0x80 {
            (u16::from_le_bytes([self.sii[0x7C], self.sii[0x7D]]) as usize + 1) * 128
        } else {
            128
        };
        declared.max(self.sii.len()).min(1 << 20)
    }
}
