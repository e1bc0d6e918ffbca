//! Checksums of what is stored on disk (images, bakes, scene content), one
//! hash for all of them, below every stage that writes or checks one.

/// FNV-1a, 64 bit: stable across builds and platforms, unlike the standard
/// library's hasher, which is what a key on disk needs. Not cryptographic,
/// but it catches flipped and shifted bytes.
#[derive(Clone, Copy, Debug)]
pub struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    pub fn floats(&mut self, values: impl IntoIterator<Item = f32>) {
        for v in values {
            self.write(&v.to_le_bytes());
        }
    }

    pub fn finish(&self) -> u64 {
        self.0
    }

    /// The hash as 16 hex digits.
    pub fn hex(&self) -> String {
        hex(self.0)
    }
}

/// A hash as every file here writes it: 16 hex digits, so that checksums
/// compare as strings.
pub fn hex(sum: u64) -> String {
    format!("{sum:016x}")
}

/// FNV-1a of a byte string.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h = Fnv::default();
    h.write(bytes);
    h.finish()
}
