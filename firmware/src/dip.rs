//! DIP switches and the station alias (0x2150-0x2158 in `docs/object-dictionary.md`).
//!
//! Switch states are passed as a byte: bit n set = switch n+1 is **ON** (as the board
//! reads it after its own electrical polarity).
//!
//! * **ID bank** (E5 board): S1-S7 have weights 1, 2, 4 … 64; a switch that is OFF
//!   contributes its weight, so all ON = 0 = "no DIP address". S8 is reserved.
//! * **Function bank** (EST-584 board): SW1-SW3 select the peak current, SW4 the
//!   standstill current, SW5 the direction, SW6-SW7 the command smoothing time. Used
//!   only when 0x2025 = 0.
//! * **Single bank** (Xinje DP3CL-705 board): SW8 OFF → SW1-SW7 are the function
//!   switches of that board; SW8 ON → SW1-SW7 are a station number (ON = 1, SW1 the
//!   least significant bit), stored when SW8 returns OFF ([`SingleBank`]).
//!
//! DIP positions are read once at power-up (and the single bank's SW8 edge at run
//! time); nothing here touches hardware.

/// Peak current table of the EST-584 function bank (mA), index = SW1 OFF + 2·SW2 OFF +
/// 4·SW3 OFF.
pub const EST584_CURRENT_MA: [u16; 8] = [2000, 3500, 4500, 5200, 5800, 6700, 7700, 8400];
/// Smoothing time of the EST-584 function bank (ms), index = SW6 OFF + 2·SW7 OFF.
pub const EST584_SMOOTHING_MS: [u16; 4] = [0, 2, 12, 25];
/// Peak current table of the DP3CL-705 single bank (mA), index = SW1 ON + 2·SW2 ON +
/// 4·SW3 ON.
pub const DP3CL705_CURRENT_MA: [u16; 8] = [3000, 2500, 3400, 4200, 5000, 5600, 6400, 7000];
/// Peak current table of the DP3CL-305 single bank (mA), indexed as
/// [`DP3CL705_CURRENT_MA`].
pub const DP3CL305_CURRENT_MA: [u16; 8] = [1000, 560, 840, 1400, 1820, 2100, 2660, 3000];
/// Peak current table of the DP3CL-808 single bank (mA), indexed as
/// [`DP3CL705_CURRENT_MA`].
pub const DP3CL808_CURRENT_MA: [u16; 8] = [4400, 2700, 3600, 4600, 5500, 6400, 7300, 8400];
/// Filter time of the DP3CL single bank (µs), index = SW5 ON·2 + SW6 ON:
/// OFF/OFF 1.5 ms, OFF/ON 3 ms, ON/OFF 12 ms, ON/ON off.
pub const DP3CL705_FILTER_US: [u32; 4] = [1500, 3000, 12_000, 0];

fn on(bits: u8, switch: u8) -> bool {
    bits & (1 << (switch - 1)) != 0
}

/// Station address of the E5 ID bank: sum of the weights of S1-S7 that are OFF.
pub fn id_bank_address(bits: u8) -> u16 {
    u16::from(!bits & 0x7F)
}

/// Standstill current selection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Standstill {
    /// From the software (0x2026 % of peak).
    Software,
    /// Same as the running current.
    Full,
    /// Half the running current.
    Half,
}

/// What a function bank selects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DipFunctions {
    /// Peak (running) current, mA.
    pub peak_current_ma: u16,
    /// Standstill current.
    pub standstill: Standstill,
    /// Direction: true = CW (reversed with respect to the default CCW).
    pub direction_cw: bool,
    /// Command smoothing time, µs.
    pub smoothing_us: u32,
}

/// Decodes the EST-584 function bank.
pub fn est584_functions(bits: u8) -> DipFunctions {
    let ci =
        usize::from(!on(bits, 1)) | usize::from(!on(bits, 2)) << 1 | usize::from(!on(bits, 3)) << 2;
    let si = usize::from(!on(bits, 6)) | usize::from(!on(bits, 7)) << 1;
    DipFunctions {
        peak_current_ma: EST584_CURRENT_MA[ci],
        standstill: if on(bits, 4) {
            Standstill::Full
        } else {
            Standstill::Software
        },
        direction_cw: on(bits, 5),
        smoothing_us: u32::from(EST584_SMOOTHING_MS[si]) * 1000,
    }
}

/// The DP3CL single-bank boards: the same switch layout, a current table each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dp3cl {
    /// DP3CL-305 (up to 3.0 A).
    D305,
    /// DP3CL-705 (up to 7.0 A).
    D705,
    /// DP3CL-808 (up to 8.4 A).
    D808,
}

impl Dp3cl {
    /// The board's peak current table, index = SW1 ON + 2·SW2 ON + 4·SW3 ON.
    pub const fn current_table(self) -> &'static [u16; 8] {
        match self {
            Dp3cl::D305 => &DP3CL305_CURRENT_MA,
            Dp3cl::D705 => &DP3CL705_CURRENT_MA,
            Dp3cl::D808 => &DP3CL808_CURRENT_MA,
        }
    }
}

/// Decodes SW1-SW7 of the DP3CL-705 single bank (meaningful while SW8 is OFF).
pub fn dp3cl705_functions(bits: u8) -> DipFunctions {
    dp3cl_functions(Dp3cl::D705, bits)
}

/// Decodes SW1-SW7 of a DP3CL single bank (meaningful while SW8 is OFF).
pub fn dp3cl_functions(board: Dp3cl, bits: u8) -> DipFunctions {
    let ci =
        usize::from(on(bits, 1)) | usize::from(on(bits, 2)) << 1 | usize::from(on(bits, 3)) << 2;
    let fi = usize::from(on(bits, 5)) << 1 | usize::from(on(bits, 6));
    DipFunctions {
        peak_current_ma: board.current_table()[ci],
        standstill: if on(bits, 4) {
            Standstill::Full
        } else {
            Standstill::Half
        },
        direction_cw: on(bits, 7),
        smoothing_us: DP3CL705_FILTER_US[fi],
    }
}

/// Board DIP layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Board {
    /// ID bank (E5) plus function bank (EST-584).
    TwoBanks,
    /// One bank with SW8 station entry (the DP3CL boards; the current table of
    /// which).
    SingleBank(Dp3cl),
}

/// DIP-derived values latched at power-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DipConfig {
    /// Station number from the switches (0 = none).
    pub address: u16,
    /// Function switches (`None` while a single bank is in station entry mode).
    pub functions: Option<DipFunctions>,
}

/// Reads the board's switches at power-up. `id_bits` is the ID bank (ignored on a
/// single bank), `fn_bits` the function / single bank, `stored_station` the station
/// number a single bank stored earlier.
pub fn power_up(board: Board, id_bits: u8, fn_bits: u8, stored_station: u16) -> DipConfig {
    match board {
        Board::TwoBanks => DipConfig {
            address: id_bank_address(id_bits),
            functions: Some(est584_functions(fn_bits)),
        },
        Board::SingleBank(b) => DipConfig {
            address: stored_station,
            functions: if on(fn_bits, 8) {
                None
            } else {
                Some(dp3cl_functions(b, fn_bits))
            },
        },
    }
}

/// The motor settings in effect: from the function DIPs when 0x2025 = 0 (and the board
/// has function switches in that position), otherwise from the parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Settings {
    /// Peak (running) current, mA (0x2000 or the DIP table).
    pub peak_current_ma: u16,
    /// Holding current in % of the running current (0x2026, or 100 / 50 from SW4).
    pub holding_percent: u8,
    /// Direction reversed (0x2051, or SW5 / SW7 ON = CW).
    pub direction_reversed: bool,
    /// Command smoothing time, µs (0x2010:02 when 0x2009 = 1, or the DIP time; 0 = off).
    pub smoothing_us: u32,
}

/// Station-number entry of a single bank: while SW8 is ON, SW1-SW7 (ON = 1) are the
/// station number; when SW8 returns OFF that number is to be stored (the caller saves
/// it in flash and uses it as the DIP address from the next power-up).
#[derive(Debug, Clone, Copy, Default)]
pub struct SingleBank {
    entry: Option<u8>,
}

impl SingleBank {
    /// No entry in progress.
    pub const fn new() -> Self {
        SingleBank { entry: None }
    }
    /// Feeds the current switch byte; returns the station number to store on the SW8
    /// ON → OFF edge.
    pub fn update(&mut self, bits: u8) -> Option<u16> {
        if on(bits, 8) {
            self.entry = Some(bits & 0x7F);
            None
        } else {
            self.entry.take().map(u16::from)
        }
    }
    /// True while SW8 is ON (station entry mode).
    pub fn entering(&self) -> bool {
        self.entry.is_some()
    }
}

/// Which value becomes the station alias.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "board", derive(defmt::Format))]
pub enum AliasSource {
    /// The DIP address.
    Dip,
    /// The alias the ESC loaded from SII word 4 (DIP = 0).
    Sii,
    /// Object 0x2150 (0x2151 = 1).
    Object,
}

/// The station alias to write to ESC register 0x0012 at start-up, from the *active*
/// (power-up) values of 0x2151 and 0x2150, the DIP address and SII word 4.
pub fn station_alias(
    alias_source_2151: u8,
    alias_2150: u16,
    dip_address: u16,
    sii_word4: u16,
) -> (u16, AliasSource) {
    if alias_source_2151 == 1 {
        (alias_2150, AliasSource::Object)
    } else if dip_address != 0 {
        (dip_address, AliasSource::Dip)
    } else {
        (sii_word4, AliasSource::Sii)
    }
}

/// The Explicit Device ID answered in AL status code 0x0134 when the master sets AL
/// control bit 5: the DIP address when one is set, else the station alias in use.
pub fn explicit_device_id(dip_address: u16, alias: u16) -> u16 {
    if dip_address != 0 {
        dip_address
    } else {
        alias
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn id_bank_table() {
        // bits: bit n = S(n+1) ON
        let cases: &[(u8, u16)] = &[
            (0x7F, 0),
            (0xFF, 0), // S8 reserved
            (0x7E, 1), // S1 OFF
            (0x7D, 2), // S2 OFF
            (0x7C, 3), // S1, S2 OFF
            (0x7B, 4),
            (0x7A, 5),
            (0x01, 126), // only S1 ON
            (0x00, 127),
            (0x80, 127),
            (0x3F, 64), // S7 OFF
        ];
        for &(bits, addr) in cases {
            assert_eq!(id_bank_address(bits), addr, "bits {bits:#04x}");
        }
        for bits in 0..=255u8 {
            assert!(id_bank_address(bits) <= 127);
        }
    }

    #[test]
    fn est584_current_table() {
        // (SW1, SW2, SW3) ON/OFF → mA, as the EST-584 table.
        let t: &[(bool, bool, bool, u16)] = &[
            (true, true, true, 2000),
            (false, true, true, 3500),
            (true, false, true, 4500),
            (false, false, true, 5200),
            (true, true, false, 5800),
            (false, true, false, 6700),
            (true, false, false, 7700),
            (false, false, false, 8400),
        ];
        for &(s1, s2, s3, ma) in t {
            let bits = u8::from(s1) | u8::from(s2) << 1 | u8::from(s3) << 2;
            assert_eq!(est584_functions(bits).peak_current_ma, ma);
        }
    }

    #[test]
    fn est584_other_switches() {
        let base = 0b0110_0000; // SW6, SW7 ON → 0 ms
        assert_eq!(est584_functions(base).smoothing_us, 0);
        assert_eq!(est584_functions(0b0100_0000).smoothing_us, 2000); // SW6 OFF
        assert_eq!(est584_functions(0b0010_0000).smoothing_us, 12_000); // SW7 OFF
        assert_eq!(est584_functions(0).smoothing_us, 25_000);
        assert_eq!(est584_functions(0).standstill, Standstill::Software);
        assert_eq!(est584_functions(0b1000).standstill, Standstill::Full);
        assert!(!est584_functions(0).direction_cw);
        assert!(est584_functions(0b1_0000).direction_cw);
        for bits in 0..=255u8 {
            let f = est584_functions(bits);
            assert!(f.peak_current_ma >= 2000 && f.peak_current_ma <= 8400);
        }
    }

    #[test]
    fn dp3cl705_single_bank() {
        assert_eq!(dp3cl705_functions(0).peak_current_ma, 3000);
        assert_eq!(dp3cl705_functions(0b001).peak_current_ma, 2500);
        assert_eq!(dp3cl705_functions(0b111).peak_current_ma, 7000);
        assert_eq!(dp3cl705_functions(0).smoothing_us, 1500);
        assert_eq!(dp3cl705_functions(0b10_0000).smoothing_us, 3000);
        assert_eq!(dp3cl705_functions(0b01_0000).smoothing_us, 12_000);
        assert_eq!(dp3cl705_functions(0b11_0000).smoothing_us, 0);
        assert_eq!(dp3cl705_functions(0).standstill, Standstill::Half);
        assert_eq!(dp3cl705_functions(0b1000).standstill, Standstill::Full);
        assert!(dp3cl705_functions(0x40).direction_cw);
        assert_eq!(dp3cl_functions(Dp3cl::D305, 0).peak_current_ma, 1000);
        assert_eq!(dp3cl_functions(Dp3cl::D305, 0b111).peak_current_ma, 3000);
        assert_eq!(dp3cl_functions(Dp3cl::D808, 0).peak_current_ma, 4400);
        assert_eq!(dp3cl_functions(Dp3cl::D808, 0b001).peak_current_ma, 2700);
        assert_eq!(dp3cl_functions(Dp3cl::D808, 0b111).peak_current_ma, 8400);
        let mut sb = SingleBank::new();
        assert_eq!(sb.update(0x05), None);
        assert_eq!(sb.update(0x80 | 0x05), None);
        assert!(sb.entering());
        assert_eq!(sb.update(0x80 | 0x23), None);
        assert_eq!(sb.update(0x23), Some(0x23), "stored when SW8 returns OFF");
        assert_eq!(sb.update(0x23), None);
        assert!(!sb.entering());
        assert_eq!(
            power_up(Board::SingleBank(Dp3cl::D705), 0, 0x80 | 0x11, 9).functions,
            None
        );
        assert_eq!(
            power_up(Board::SingleBank(Dp3cl::D705), 0, 0x01, 9),
            DipConfig {
                address: 9,
                functions: Some(dp3cl705_functions(1))
            }
        );
        assert_eq!(power_up(Board::TwoBanks, 0x7E, 0, 9).address, 1);
    }

    #[test]
    fn dip_functions_only_with_control_mode_zero() {
        use crate::identity::Variant;
        use crate::params::{Param, Params};
        let mut p = Params::new(Variant::OpenLoop);
        let f = est584_functions(0b0001_1000); // SW4, SW5 ON; SW1-3 OFF: 8.4 A; 25 ms
        assert_eq!(p.get(Param::ControlMode), 5);
        let s = p.settings_with(Some(f));
        assert_eq!(
            s,
            Settings {
                peak_current_ma: 3200,
                holding_percent: 50,
                direction_reversed: false,
                smoothing_us: 0
            }
        );
        p.set_internal(Param::ControlMode, 0);
        let s = p.settings_with(Some(f));
        assert_eq!(
            s,
            Settings {
                peak_current_ma: 8400,
                holding_percent: 100,
                direction_reversed: true,
                smoothing_us: 25_000
            }
        );
        // SW4 OFF: the software holding current.
        p.set_internal(Param::HoldingCurrent, 30);
        assert_eq!(
            p.settings_with(Some(est584_functions(0))).holding_percent,
            30
        );
        assert_eq!(
            p.settings_with(Some(dp3cl705_functions(0))).holding_percent,
            50
        );
        // No function switches (station entry, or none on the board): parameters rule.
        p.set_internal(Param::CmdFilterEnable, 1);
        assert_eq!(p.settings_with(None).smoothing_us, 1000);
        assert_eq!(p.settings_with(None).peak_current_ma, 3200);
    }

    #[test]
    fn alias_source_combinations() {
        // (2151, 2150, DIP, SII word 4) → (alias, source)
        let t: &[(u8, u16, u16, u16, u16, AliasSource)] = &[
            (0, 1, 0, 0, 0, AliasSource::Sii),
            (0, 1, 0, 0x1234, 0x1234, AliasSource::Sii),
            (0, 1, 5, 0x1234, 5, AliasSource::Dip),
            (0, 99, 127, 0, 127, AliasSource::Dip),
            (1, 99, 5, 0x1234, 99, AliasSource::Object),
            (1, 65535, 0, 0, 65535, AliasSource::Object),
        ];
        for &(src, obj, dip, sii, alias, s) in t {
            assert_eq!(station_alias(src, obj, dip, sii), (alias, s));
        }
        assert_eq!(explicit_device_id(7, 99), 7);
        assert_eq!(explicit_device_id(0, 99), 99);
    }
}
