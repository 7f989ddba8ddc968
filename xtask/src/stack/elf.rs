//! A minimal ELF32 little-endian reader: section headers, `.symtab`/`.strtab`, bytes
//! at a load address.

pub const SHT_SYMTAB: u32 = 2;
const SHT_NOBITS: u32 = 8;
pub const STT_OBJECT: u8 = 1;
pub const STT_FUNC: u8 = 2;

fn u16_at(b: &[u8], o: usize) -> Result<u16, String> {
    b.get(o..o + 2)
        .map(|s| u16::from_le_bytes([s[0], s[1]]))
        .ok_or_else(|| format!("ELF truncated at {o:#x}"))
}

fn u32_at(b: &[u8], o: usize) -> Result<u32, String> {
    b.get(o..o + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
        .ok_or_else(|| format!("ELF truncated at {o:#x}"))
}

fn cstr(b: &[u8], o: usize) -> String {
    let s = b.get(o..).unwrap_or(&[]);
    let end = s.iter().position(|&c| c == 0).unwrap_or(s.len());
    String::from_utf8_lossy(&s[..end]).into_owned()
}

#[derive(Debug, Clone)]
pub struct Section {
    pub name: String,
    pub kind: u32,
    pub addr: u32,
    pub offset: u32,
    pub size: u32,
    pub link: u32,
}

#[derive(Debug, Clone)]
pub struct Symbol {
    pub name: String,
    pub value: u32,
    pub size: u32,
    pub kind: u8,
}

pub struct Elf {
    bytes: Vec<u8>,
    pub sections: Vec<Section>,
}

impl Elf {
    pub fn parse(bytes: Vec<u8>) -> Result<Self, String> {
        if bytes.len() < 52 || bytes[..4] != *b"\x7fELF" {
            return Err("not an ELF file".into());
        }
        if bytes[4] != 1 || bytes[5] != 1 {
            return Err("not a little-endian ELF32 file".into());
        }
        let shoff = u32_at(&bytes, 0x20)? as usize;
        let shentsize = u16_at(&bytes, 0x2E)? as usize;
        let shnum = u16_at(&bytes, 0x30)? as usize;
        let shstrndx = u16_at(&bytes, 0x32)? as usize;
        if shentsize < 40 {
            return Err("bad section header size".into());
        }
        let mut raw = Vec::with_capacity(shnum);
        for i in 0..shnum {
            let h = shoff + i * shentsize;
            raw.push((
                u32_at(&bytes, h)?,
                Section {
                    name: String::new(),
                    kind: u32_at(&bytes, h + 4)?,
                    addr: u32_at(&bytes, h + 12)?,
                    offset: u32_at(&bytes, h + 16)?,
                    size: u32_at(&bytes, h + 20)?,
                    link: u32_at(&bytes, h + 24)?,
                },
            ));
        }
        let strtab = raw
            .get(shstrndx)
            .map(|(_, s)| s.clone())
            .ok_or("no section name table")?;
        let names = bytes
            .get(
                strtab.offset as usize
                    ..(strtab.offset as usize).saturating_add(strtab.size as usize),
            )
            .ok_or("section name table outside the file")?
            .to_vec();
        let sections = raw
            .into_iter()
            .map(|(n, mut s)| {
                s.name = cstr(&names, n as usize);
                s
            })
            .collect();
        Ok(Elf { bytes, sections })
    }

    pub fn section(&self, name: &str) -> Option<&Section> {
        self.sections.iter().find(|s| s.name == name)
    }

    pub fn data(&self, s: &Section) -> Result<&[u8], String> {
        if s.kind == SHT_NOBITS {
            return Ok(&[]);
        }
        let start = s.offset as usize;
        self.bytes
            .get(start..start.saturating_add(s.size as usize))
            .ok_or_else(|| format!("section {} outside the file", s.name))
    }

    pub fn symbols(&self) -> Result<Vec<Symbol>, String> {
        let symtab = self
            .sections
            .iter()
            .find(|s| s.kind == SHT_SYMTAB)
            .ok_or("no .symtab (stripped ELF?)")?;
        let strtab = self
            .sections
            .get(symtab.link as usize)
            .ok_or("no string table for .symtab")?;
        let (syms, strs) = (self.data(symtab)?, self.data(strtab)?);
        let mut out = Vec::with_capacity(syms.len() / 16);
        for e in syms.chunks_exact(16) {
            out.push(Symbol {
                name: cstr(strs, u32_at(e, 0)? as usize),
                value: u32_at(e, 4)?,
                size: u32_at(e, 8)?,
                kind: e[12] & 0xF,
            });
        }
        Ok(out)
    }

    /// `len` bytes at load address `addr` of an allocated section with contents.
    pub fn at(&self, addr: u32, len: u32) -> Option<&[u8]> {
        let s = self.sections.iter().find(|s| {
            s.addr != 0
                && s.kind != SHT_NOBITS
                && addr >= s.addr
                && u64::from(addr) + u64::from(len) <= u64::from(s.addr) + u64::from(s.size)
        })?;
        let o = s.offset as usize + (addr - s.addr) as usize;
        self.bytes.get(o..o + len as usize)
    }
}
