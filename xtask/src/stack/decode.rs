//! Thumb-2 decoding (only what the analysis needs) and the per-function scan. The
//! instruction length comes from the first halfword (so data halfwords can be stepped
//! over); capstone (Thumb, M-class) decodes the instruction, which is then reduced to
//! the few kinds the analysis uses ([`Insn`]).

use capstone::arch::arm::{ArchExtraMode, ArchMode, ArmInsn, ArmOperandType, ArmReg};
use capstone::arch::ArchDetail;
use capstone::prelude::*;

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

thread_local! {
    static CS: Capstone = Capstone::new()
        .arm()
        .mode(ArchMode::Thumb)
        .extra_mode([ArchExtraMode::MClass].into_iter())
        .detail(true)
        .build()
        .expect("capstone: Thumb, M-class");
}

/// Register number 0..=15 of a capstone core register.
fn core_reg(r: RegId) -> Option<u8> {
    let r = u32::from(r.0);
    match r {
        _ if (ArmReg::ARM_REG_R0..=ArmReg::ARM_REG_R12).contains(&r) => {
            Some((r - ArmReg::ARM_REG_R0) as u8)
        }
        ArmReg::ARM_REG_SP => Some(13),
        ArmReg::ARM_REG_LR => Some(14),
        ArmReg::ARM_REG_PC => Some(15),
        _ => None,
    }
}

/// Bytes a VPUSH register takes.
fn fp_reg_bytes(r: RegId) -> u32 {
    let r = u32::from(r.0);
    if (ArmReg::ARM_REG_D0..=ArmReg::ARM_REG_D31).contains(&r) {
        8
    } else {
        4
    }
}

/// The instruction in `bytes` (2 or 4) at `pc`; `Other` for whatever capstone cannot
/// decode.
pub fn classify(bytes: &[u8], pc: u32) -> Insn {
    CS.with(|cs| Decoded::new(cs, bytes, pc))
        .and_then(|d| {
            d.stack_change()
                .or_else(|| d.control_flow())
                .or_else(|| d.constant(pc))
        })
        .unwrap_or(Insn::Other)
}

const SP: u8 = 13;
const LR: u8 = 14;
const PC: u8 = 15;

/// What the classification looks at in one capstone instruction.
struct Decoded {
    id: u32,
    /// Capstone 5 gives MOVW the id of MOV; its mnemonic tells it from MOV.W #imm.
    movw: bool,
    ops: Vec<ArmOperandType>,
    wide: bool,
    writeback: bool,
}

impl Decoded {
    fn new(cs: &Capstone, bytes: &[u8], pc: u32) -> Option<Self> {
        let insns = cs.disasm_count(bytes, u64::from(pc), 1).ok()?;
        let i = insns.iter().next()?;
        if i.bytes().len() != bytes.len() {
            return None;
        }
        let detail = cs.insn_detail(i).ok()?;
        let ArchDetail::ArmDetail(arm) = detail.arch_detail() else {
            return None;
        };
        let id = i.id().0;
        Some(Decoded {
            id,
            movw: id == ArmInsn::ARM_INS_MOVW as u32
                || (id == ArmInsn::ARM_INS_MOV as u32 && i.mnemonic() == Some("movw")),
            ops: arm.operands().map(|o| o.op_type).collect(),
            wide: bytes.len() == 4,
            writeback: arm.writeback(),
        })
    }

    fn is(&self, x: ArmInsn) -> bool {
        self.id == x as u32
    }

    /// Operand `k` as a core register number.
    fn reg(&self, k: usize) -> Option<u8> {
        match self.ops.get(k) {
            Some(ArmOperandType::Reg(r)) => core_reg(*r),
            _ => None,
        }
    }

    fn imm(&self, k: usize) -> Option<i32> {
        match self.ops.get(k) {
            Some(ArmOperandType::Imm(v)) => Some(*v),
            _ => None,
        }
    }

    /// Operand `k` as a memory operand: base register, displacement.
    fn mem(&self, k: usize) -> Option<(Option<u8>, i32)> {
        match self.ops.get(k) {
            Some(ArmOperandType::Mem(m)) => Some((core_reg(m.base()), m.disp())),
            _ => None,
        }
    }

    /// PUSH (STMDB SP!), VPUSH, STR/STRD pre-indexed on SP, SUB SP.
    fn stack_change(&self) -> Option<Insn> {
        if self.is(ArmInsn::ARM_INS_PUSH) {
            return Some(Insn::SpDown(4 * self.ops.len() as u32));
        }
        if self.is(ArmInsn::ARM_INS_VPUSH) {
            let n = self
                .ops
                .iter()
                .map(|o| match o {
                    ArmOperandType::Reg(r) => fp_reg_bytes(*r),
                    _ => 0,
                })
                .sum();
            return Some(Insn::SpDown(n));
        }
        if (self.is(ArmInsn::ARM_INS_STR) || self.is(ArmInsn::ARM_INS_STRD)) && self.writeback {
            // Pre-indexed: the memory operand is the last one (post-indexed adds an offset).
            let k = if self.is(ArmInsn::ARM_INS_STR) { 1 } else { 2 };
            if let Some((Some(SP), d)) = self.mem(k) {
                if d < 0 && self.ops.len() == k + 1 {
                    return Some(Insn::SpDown(d.unsigned_abs()));
                }
            }
        }
        if self.is(ArmInsn::ARM_INS_SUB) || self.is(ArmInsn::ARM_INS_SUBW) {
            let sp_sp = self.reg(0) == Some(SP) && self.reg(1) == Some(SP);
            match (sp_sp, self.imm(2), self.reg(2)) {
                (true, Some(v), _) => return Some(Insn::SpDown(v as u32)),
                (true, None, Some(_)) if self.wide => return Some(Insn::SpByRegister),
                _ => {}
            }
            // The 16-bit form is printed `sub sp, #imm`.
            if !self.wide && self.reg(0) == Some(SP) && self.ops.len() == 2 {
                return self.imm(1).map(|v| Insn::SpDown(v as u32));
            }
        }
        None
    }

    /// BL, B / B<c> / CBZ / CBNZ, BLX Rm, BX Rm, MOV PC, Rm.
    fn control_flow(&self) -> Option<Insn> {
        if self.is(ArmInsn::ARM_INS_BL) {
            return self.imm(0).map(|t| Insn::Call(t as u32));
        }
        if self.is(ArmInsn::ARM_INS_B) {
            return self.imm(0).map(|t| Insn::Branch(t as u32));
        }
        if self.is(ArmInsn::ARM_INS_CBZ) || self.is(ArmInsn::ARM_INS_CBNZ) {
            return self.imm(1).map(|t| Insn::Branch(t as u32));
        }
        if self.is(ArmInsn::ARM_INS_BLX) && self.reg(0).is_some() {
            return Some(Insn::IndirectCall);
        }
        if self.is(ArmInsn::ARM_INS_BX) {
            // BX LR is a return.
            return (self.reg(0) != Some(LR)).then_some(Insn::IndirectJump);
        }
        if self.is(ArmInsn::ARM_INS_MOV) && !self.wide && self.reg(0) == Some(PC) {
            return Some(Insn::IndirectJump);
        }
        None
    }

    /// MOVW / MOVT, LDR from a literal, and LDR PC (a jump unless it is a pop).
    fn constant(&self, pc: u32) -> Option<Insn> {
        if self.movw || self.is(ArmInsn::ARM_INS_MOVT) {
            let (r, v) = (self.reg(0)?, self.imm(1)? as u16);
            return Some(if self.movw {
                Insn::Movw(r, v)
            } else {
                Insn::Movt(r, v)
            });
        }
        if !self.is(ArmInsn::ARM_INS_LDR) {
            return None;
        }
        match (self.reg(0), self.mem(1)) {
            (Some(PC), Some((Some(PC), _))) => Some(Insn::IndirectJump),
            (Some(r), Some((Some(PC), d))) => {
                let base = (pc.wrapping_add(4)) & !3;
                Some(Insn::LdrLiteral(r, base.wrapping_add(d as u32)))
            }
            (Some(PC), Some((Some(b), _))) if self.wide && b != SP => Some(Insn::IndirectJump),
            _ => None,
        }
    }
}

/// A 16-bit instruction at `pc` (the unit tests' view of [`classify`]).
#[cfg(test)]
pub fn decode16(hw: u16, pc: u32) -> Insn {
    classify(&hw.to_le_bytes(), pc)
}

/// A 32-bit instruction (halfwords `hw1`, `hw2`) at `pc`.
#[cfg(test)]
pub fn decode32(hw1: u16, hw2: u16, pc: u32) -> Insn {
    let ([a, b], [c, d]) = (hw1.to_le_bytes(), hw2.to_le_bytes());
    classify(&[a, b, c, d], pc)
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
        let len = if is_32bit(hw1) { 4 } else { 2 };
        if i + len > code.len() {
            break;
        }
        let insn = classify(&code[i..i + len], pc);
        i += len;
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
