//! The CRC-32 of the parameter records.

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, init and final XOR
/// 0xFFFFFFFF), with a 16-entry nibble table.
#[derive(Debug, Clone, Copy)]
pub struct Crc32(u32);

const CRC_NIBBLE: [u32; 16] = {
    let mut t = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 4 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// A fresh CRC.
    pub const fn new() -> Self {
        Crc32(0xFFFF_FFFF)
    }
    /// Adds bytes.
    pub fn update(&mut self, data: &[u8]) {
        let mut c = self.0;
        for &b in data {
            c ^= u32::from(b);
            c = (c >> 4) ^ CRC_NIBBLE[(c & 0xF) as usize];
            c = (c >> 4) ^ CRC_NIBBLE[(c & 0xF) as usize];
        }
        self.0 = c;
    }
    /// The CRC of everything added.
    pub const fn finish(self) -> u32 {
        !self.0
    }
}

/// CRC-32 of `data` (see [`Crc32`]).
pub fn crc32(data: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(data);
    c.finish()
}
