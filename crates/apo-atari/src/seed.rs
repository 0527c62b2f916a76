//! The ALE seed that Gymnasium's `ALE/*-v5` environments derive from a reset seed: NumPy's
//! `SeedSequence(seed).generate_state(2)[1]` as an `int32` (ale-py's `AtariEnv.seed_game`).
//!
//! `SeedSequence` (NumPy ≥ 1.17, after M. E. O'Neill's `seed_seq`): the seed's 32-bit words
//! (least significant first; 0 is the one word 0) are hashed into a pool of 4 words, mixed
//! pairwise, and the output words are hashed from the pool. All arithmetic is modulo 2³².

const INIT_A: u32 = 0x43b0_d7e5;
const MULT_A: u32 = 0x931e_8875;
const INIT_B: u32 = 0x8b51_f9dd;
const MULT_B: u32 = 0x58f3_8ded;
const MIX_MULT_L: u32 = 0xca01_f9dd;
const MIX_MULT_R: u32 = 0x4973_f715;
const XSHIFT: u32 = 16;
const POOL: usize = 4;

/// `SeedSequence(seed).generate_state(n)` as `u32` words.
pub fn generate_state(seed: u64, n: usize) -> Vec<u32> {
    let entropy: Vec<u32> = if seed == 0 {
        vec![0]
    } else {
        let (lo, hi) = (seed as u32, (seed >> 32) as u32);
        if hi == 0 {
            vec![lo]
        } else {
            vec![lo, hi]
        }
    };
    let mut hash_const = INIT_A;
    let mut hashmix = |value: u32| {
        let mut v = value ^ hash_const;
        hash_const = hash_const.wrapping_mul(MULT_A);
        v = v.wrapping_mul(hash_const);
        v ^ (v >> XSHIFT)
    };
    let mix = |x: u32, y: u32| {
        let r = MIX_MULT_L
            .wrapping_mul(x)
            .wrapping_sub(MIX_MULT_R.wrapping_mul(y));
        r ^ (r >> XSHIFT)
    };
    let mut pool = [0u32; POOL];
    for (i, slot) in pool.iter_mut().enumerate() {
        *slot = hashmix(entropy.get(i).copied().unwrap_or(0));
    }
    for src in 0..POOL {
        for dst in 0..POOL {
            if src != dst {
                let h = hashmix(pool[src]);
                pool[dst] = mix(pool[dst], h);
            }
        }
    }
    // a u64 seed has at most 2 words: NumPy's stage for entropy beyond the pool's 4 is empty
    let mut hash_b = INIT_B;
    (0..n)
        .map(|i| {
            let mut v = pool[i % POOL] ^ hash_b;
            hash_b = hash_b.wrapping_mul(MULT_B);
            v = v.wrapping_mul(hash_b);
            v ^ (v >> XSHIFT)
        })
        .collect()
}

/// The ALE `random_seed` of a v5 environment reset with `seed`.
pub fn ale_seed(seed: u64) -> i32 {
    generate_state(seed, 2)[1] as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_numpy() {
        // np.random.SeedSequence(s).generate_state(2), recorded with NumPy
        let cases: [(u64, [u32; 2]); 5] = [
            (0, [2_968_811_710, 3_677_149_159]),
            (1, [1_835_504_127, 1_731_038_949]),
            (42, [3_444_837_047, 2_669_555_309]),
            (123_456_789, [1_315_320_158, 1_391_606_125]),
            ((1 << 40) + 7, [238_885_397, 226_915_041]),
        ];
        for (seed, want) in cases {
            assert_eq!(generate_state(seed, 2), want, "seed {seed}");
        }
    }
}
