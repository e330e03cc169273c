//! Small helpers shared by the whole crate.
pub mod error;
pub mod rng;

pub use error::FileError;

/// FNV-1a 64-bit hash: a stable fingerprint of bytes (waveforms, images) for tests.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// `x / d`, a shift when `d` is a power of two (cache geometries are, at the
/// defaults): the caches map every address they see, and 64-bit divisions
/// showed in the profile (the L1's bank and slot, the L2's set).
#[inline]
pub fn div(x: u64, d: u64) -> u64 {
    if d.is_power_of_two() {
        x >> d.trailing_zeros()
    } else {
        x / d
    }
}

/// `x % d`, a mask when `d` is a power of two.
#[inline]
pub fn rem(x: u64, d: u64) -> u64 {
    if d.is_power_of_two() {
        x & (d - 1)
    } else {
        x % d
    }
}

#[cfg(test)]
mod tests {
    use super::{div, rem};

    #[test]
    fn div_and_rem_are_the_operators_for_any_divisor() {
        for d in [1u64, 2, 3, 7, 8, 64, 100, 1 << 20, (1 << 40) + 1] {
            for x in [0u64, 1, 63, 64, 65, 12_345_678, u64::MAX - 1, u64::MAX] {
                assert_eq!(div(x, d), x / d, "{x} / {d}");
                assert_eq!(rem(x, d), x % d, "{x} % {d}");
            }
        }
    }
}
