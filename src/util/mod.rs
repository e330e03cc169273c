//! Small helpers shared by the whole crate.
pub mod rng;

/// FNV-1a 64-bit hash: a stable fingerprint of bytes (waveforms, images) for tests.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}
