//! The seed streams of a run.
//!
//! Everything random in a run is drawn from streams derived from the run seed, so that an
//! epoch depends only on the seed, the epoch number and the networks: a resumed run reproduces
//! an uninterrupted one, and the number of threads changes nothing.

/// A seed for stream `stream` of epoch `epoch` of a run seeded `seed` (SplitMix64 mixing).
pub fn derive_seed(seed: u64, epoch: u64, stream: u64) -> u64 {
    let mut z = seed
        ^ epoch.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
