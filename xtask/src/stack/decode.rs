//! Thumb-2 decoding (only what the analysis needs) and the per-function scan.

use super::elf::Elf;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Insn {
    /// SP moves down by this many bytes.
    SpDown(u32),
    /// SP moved by a register amount (`SUB SP, SP, Rm`): not bounded statically.
    SpByRegister,
    /// BL to this address.
    Call(u32),
    /// B / B.W / B<c> / CBZ / CBNZ to this address (a tail call when it leaves the function).
    Branch(u32),
    /// BLX Rm.
    IndirectCall,
    /// BX Rm (not LR), MOV PC, Rm, LDR PC from a register other than SP.
    IndirectJump,
    /// MOVW Rd, #imm16.
    Movw(u8, u16),
    /// MOVT Rd, #imm16.
    Movt(u8, u16),
    /// LDR Rt, [PC, #imm] — the literal's address.
    LdrLiteral(u8, u32),
    Other,
}

/// A first halfword whose top five bits are 0b11101, 0b11110 or 0b11111 starts a
/// 32-bit instruction.
pub fn is_32bit(hw1: u16) -> bool {
    matches!(hw1 >> 11, 0b11101..=0b11111)
}

fn sext(v: u32, bits: u32) -> i32 {
    let shift = 32 - bits;
    ((v << shift) as i32) >> shift
}

fn rel(pc: u32, off: i32) -> u32 {
    pc.wrapping_add(4).wrapping_add(off as u32)
}

/// ThumbExpandImm of a 12-bit modified immediate (ARMv7-M ARM A5.3.2).
pub fn thumb_expand_imm(imm12: u32) -> u32 {
    let imm8 = imm12 & 0xFF;
    if imm12 >> 10 == 0 {
        match (imm12 >> 8) & 3 {
            0 => imm8,
            1 => (imm8 << 16) | imm8,
            2 => (imm8 << 24) | (imm8 << 8),
            _ => imm8 * 0x0101_0101,
        }
    } else {
        (0x80 | (imm12 & 0x7F)).rotate_right((imm12 >> 7) & 0x1F)
    }
}

/// A 16-bit instruction at `pc`.
pub fn decode16(hw: u16, pc: u32) -> Insn {
    let h = u32::from(hw);
    if hw & 0xFE00 == 0xB400 {
        // PUSH {reglist} (+ LR with the M bit)
        return Insn::SpDown(4 * ((h & 0xFF).count_ones() + ((h >> 8) & 1)));
    }
    if hw & 0xFF80 == 0xB080 {
        // SUB SP, SP, #imm7*4
        return Insn::SpDown((h & 0x7F) * 4);
    }
    if hw & 0xFF87 == 0x4780 {
        return Insn::IndirectCall; // BLX Rm
    }
    if hw & 0xFF87 == 0x4700 {
        // BX Rm: BX LR is a return
        return if (h >> 3) & 0xF == 14 {
            Insn::Other
        } else {
            Insn::IndirectJump
        };
    }
    if hw & 0xFF87 == 0x4687 {
        return Insn::IndirectJump; // MOV PC, Rm
    }
    if hw & 0xF800 == 0xE000 {
        return Insn::Branch(rel(pc, sext((h & 0x7FF) << 1, 12)));
    }
    if hw & 0xF000 == 0xD000 && (h >> 8) & 0xF < 0xE {
        return Insn::Branch(rel(pc, sext((h & 0xFF) << 1, 9)));
    }
    if hw & 0xF500 == 0xB100 {
        // CBZ / CBNZ: forward only
        let off = (((h >> 9) & 1) << 6) | (((h >> 3) & 0x1F) << 1);
        return Insn::Branch(rel(pc, off as i32));
    }
    if hw & 0xF800 == 0x4800 {
        let base = (pc.wrapping_add(4)) & !3;
        return Insn::LdrLiteral(((h >> 8) & 7) as u8, base.wrapping_add((h & 0xFF) * 4));
    }
    Insn::Other
}

/// A 32-bit instruction (halfwords `hw1`, `hw2`) at `pc`.
pub fn decode32(hw1: u16, hw2: u16, pc: u32) -> Insn {
    let (a, b) = (u32::from(hw1), u32::from(hw2));
    let rd_is_sp = b & 0x8F00 == 0x0D00;
    if hw1 == 0xE92D {
        // STMDB SP!, {reglist} (PUSH.W)
        return Insn::SpDown(4 * (b & 0x5FFF).count_ones());
    }
    if hw1 == 0xF84D && b & 0x0F00 == 0x0D00 {
        // STR.W Rt, [SP, #-imm8]!
        return Insn::SpDown(b & 0xFF);
    }
    if hw1 == 0xE96D {
        // STRD Rt, Rt2, [SP, #-imm8*4]!
        return Insn::SpDown((b & 0xFF) * 4);
    }
    if hw1 & 0xFFBF == 0xED2D && b & 0x0E00 == 0x0A00 {
        // VPUSH (double 0x0B00 / single 0x0A00 form): imm8 words
        return Insn::SpDown((b & 0xFF) * 4);
    }
    let imm12 = ((a >> 10) & 1) << 11 | ((b >> 12) & 7) << 8 | (b & 0xFF);
    if hw1 & 0xFBEF == 0xF1AD && rd_is_sp {
        // SUB.W SP, SP, #ThumbExpandImm
        return Insn::SpDown(thumb_expand_imm(imm12));
    }
    if hw1 & 0xFBFF == 0xF2AD && rd_is_sp {
        // SUBW SP, SP, #imm12
        return Insn::SpDown(imm12);
    }
    if hw1 & 0xFFEF == 0xEBAD && rd_is_sp {
        return Insn::SpByRegister; // SUB.W SP, SP, Rm
    }
    if hw1 & 0xF800 == 0xF000 && b & 0x8000 != 0 {
        let s = (a >> 10) & 1;
        let (j1, j2) = ((b >> 13) & 1, (b >> 11) & 1);
        match b & 0xD000 {
            0xD000 | 0x9000 => {
                let (i1, i2) = (!(j1 ^ s) & 1, !(j2 ^ s) & 1);
                let off =
                    (s << 24) | (i1 << 23) | (i2 << 22) | ((a & 0x3FF) << 12) | ((b & 0x7FF) << 1);
                let target = rel(pc, sext(off, 25));
                return if b & 0xD000 == 0xD000 {
                    Insn::Call(target)
                } else {
                    Insn::Branch(target)
                };
            }
            0x8000 if (a >> 6) & 0xF < 0xE => {
                let off =
                    (s << 20) | (j2 << 19) | (j1 << 18) | ((a & 0x3F) << 12) | ((b & 0x7FF) << 1);
                return Insn::Branch(rel(pc, sext(off, 21)));
            }
            _ => return Insn::Other,
        }
    }
    if hw1 & 0xFBF0 == 0xF240 && b & 0x8000 == 0 {
        let imm16 = ((a & 0xF) << 12) | ((a >> 10) & 1) << 11 | ((b >> 12) & 7) << 8 | (b & 0xFF);
        return Insn::Movw(((b >> 8) & 0xF) as u8, imm16 as u16);
    }
    if hw1 & 0xFBF0 == 0xF2C0 && b & 0x8000 == 0 {
        let imm16 = ((a & 0xF) << 12) | ((a >> 10) & 1) << 11 | ((b >> 12) & 7) << 8 | (b & 0xFF);
        return Insn::Movt(((b >> 8) & 0xF) as u8, imm16 as u16);
    }
    if hw1 & 0xFF7F == 0xF85F {
        // LDR.W Rt, [PC, #±imm12]
        let base = (pc.wrapping_add(4)) & !3;
        let addr = if a & 0x80 != 0 {
            base.wrapping_add(b & 0xFFF)
        } else {
            base.wrapping_sub(b & 0xFFF)
        };
        return if b >> 12 == 15 {
            Insn::IndirectJump
        } else {
            Insn::LdrLiteral((b >> 12) as u8, addr)
        };
    }
    if (hw1 & 0xFFF0 == 0xF8D0 || hw1 & 0xFFF0 == 0xF850) && b >> 12 == 15 && a & 0xF != 13 {
        return Insn::IndirectJump; // LDR PC, [Rn, ...] with Rn != SP (not a pop)
    }
    Insn::Other
}

// ---------------------------------------------------------------------------------------
// Per-function scan
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, Default)]
pub struct Func {
    pub name: String,
    pub addr: u32,
    pub size: u32,
    pub frame: u32,
    pub calls: Vec<u32>,
    pub branches: Vec<u32>,
    pub indirect: u32,
    pub sp_by_register: bool,
    /// 32-bit constants the function builds (MOVW/MOVT pairs, literal loads), in order.
    pub constants: Vec<u32>,
}

/// Walks `code` (the function's bytes at `addr`); `is_data(pc)` tells mapping-symbol
/// data regions, which are skipped.
pub fn scan(
    name: &str,
    addr: u32,
    code: &[u8],
    elf: Option<&Elf>,
    is_data: &dyn Fn(u32) -> bool,
) -> Func {
    let mut f = Func {
        name: name.to_string(),
        addr,
        size: code.len() as u32,
        ..Func::default()
    };
    let mut regs: [Option<u32>; 16] = [None; 16];
    let mut i = 0usize;
    while i + 2 <= code.len() {
        let pc = addr.wrapping_add(i as u32);
        if is_data(pc) {
            i += 2;
            continue;
        }
        let hw1 = u16::from_le_bytes([code[i], code[i + 1]]);
        let insn = if is_32bit(hw1) {
            if i + 4 > code.len() {
                break;
            }
            let hw2 = u16::from_le_bytes([code[i + 2], code[i + 3]]);
            i += 4;
            decode32(hw1, hw2, pc)
        } else {
            i += 2;
            decode16(hw1, pc)
        };
        match insn {
            Insn::SpDown(n) => f.frame = f.frame.saturating_add(n),
            Insn::SpByRegister => f.sp_by_register = true,
            Insn::Call(t) => f.calls.push(t),
            Insn::Branch(t) => f.branches.push(t),
            Insn::IndirectCall | Insn::IndirectJump => f.indirect += 1,
            Insn::Movw(r, v) => regs[r as usize & 15] = Some(u32::from(v)),
            Insn::Movt(r, v) => {
                if let Some(lo) = regs[r as usize & 15].take() {
                    f.constants.push((lo & 0xFFFF) | (u32::from(v) << 16));
                }
            }
            Insn::LdrLiteral(_, at) => {
                if let Some(w) = elf.and_then(|e| e.at(at, 4)) {
                    f.constants
                        .push(u32::from_le_bytes([w[0], w[1], w[2], w[3]]));
                }
            }
            Insn::Other => {}
        }
    }
    f
}
