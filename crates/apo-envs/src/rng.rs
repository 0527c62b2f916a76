//! The random-number generator every environment owns.
//!
//! [`EnvRng`] is ChaCha8 from `rand_chacha`, whose output stream is specified and portable:
//! the same seed gives the same numbers on every platform and in every release of the crate,
//! so a seeded episode is reproducible.
//!
//! An environment of your own needs nothing more: [`EnvRng`], [`reseed`] in its
//! [`crate::Env::reset`], and the [`Rng`] trait re-exported here to draw from it
//! (`rng.random_range(-1.0..1.0)`), without a direct `rand` dependency.

pub use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The generator type an environment owns (portable ChaCha8).
pub type EnvRng = ChaCha8Rng;

/// A generator seeded from the thread's entropy source, for environments that were never
/// given a seed (as Gymnasium does before the first `reset(seed=…)`).
pub fn entropy_rng() -> EnvRng {
    EnvRng::from_rng(&mut rand::rng())
}

/// Applies the `seed` argument of [`crate::Env::reset`]: with `Some(seed)` replaces `rng` by a
/// generator seeded with `seed`; with `None` leaves it alone so its stream continues.
pub fn reseed(rng: &mut EnvRng, seed: Option<u64>) {
    if let Some(seed) = seed {
        *rng = EnvRng::seed_from_u64(seed);
    }
}
