//! Seeded train/test splits and folds.
//!
//! The reference numbers of docs/model.md section 9 were produced with
//! `numpy.random.default_rng(seed).permutation(n)`, the first `n // 5` indices
//! being the test set. [`NumpyPermutation`] reproduces that permutation exactly
//! (PCG64 seeded through numpy's `SeedSequence`, and numpy's bounded-integer
//! Fisher-Yates shuffle), so the split of the reference implementation is
//! available in Rust bit for bit; a test pins the first indices against numpy.
//! [`chacha_permutation`] is an independent seeded shuffle (ChaCha8) for
//! checking how much a result depends on the particular split.

use rand::seq::SliceRandom;
use rand::SeedableRng;

/// numpy's `SeedSequence` with a single 32-bit entropy word and no spawn key:
/// the first `n_words` words of `generate_state`.
fn seed_sequence_u32(entropy: u32, n_words: usize) -> Vec<u32> {
    const INIT_A: u32 = 0x43b0_d7e5;
    const MULT_A: u32 = 0x931e_8875;
    const INIT_B: u32 = 0x8b51_f9dd;
    const MULT_B: u32 = 0x58f3_8ded;
    const MIX_MULT_L: u32 = 0xca01_f9dd;
    const MIX_MULT_R: u32 = 0x4973_f715;
    let mut hash_const = INIT_A;
    let mut hashmix = |v: u32| {
        let mut v = v ^ hash_const;
        hash_const = hash_const.wrapping_mul(MULT_A);
        v = v.wrapping_mul(hash_const);
        v ^ (v >> 16)
    };
    let mix = |x: u32, y: u32| {
        let r = MIX_MULT_L
            .wrapping_mul(x)
            .wrapping_sub(MIX_MULT_R.wrapping_mul(y));
        r ^ (r >> 16)
    };
    let mut pool = [0u32; 4];
    for (i, p) in pool.iter_mut().enumerate() {
        *p = hashmix(if i == 0 { entropy } else { 0 });
    }
    for src in 0..4 {
        for dst in 0..4 {
            if src != dst {
                let h = hashmix(pool[src]);
                pool[dst] = mix(pool[dst], h);
            }
        }
    }
    let mut hc = INIT_B;
    (0..n_words)
        .map(|i| {
            let mut v = pool[i % 4] ^ hc;
            hc = hc.wrapping_mul(MULT_B);
            v = v.wrapping_mul(hc);
            v ^ (v >> 16)
        })
        .collect()
}

/// numpy's PCG64 bit generator (XSL-RR output, 128-bit LCG) with its 32-bit
/// buffering, seeded like `numpy.random.default_rng(seed)` for seeds < 2^32.
#[derive(Clone, Debug)]
pub struct NumpyPcg64 {
    state: u128,
    inc: u128,
    buffered: Option<u32>,
}

impl NumpyPcg64 {
    const MULT: u128 = (2_549_297_995_355_413_924u128 << 64) | 4_865_540_595_714_422_341u128;

    /// The generator of `numpy.random.default_rng(seed)`.
    pub fn new(seed: u32) -> Self {
        let w = seed_sequence_u32(seed, 8);
        let u: Vec<u64> = (0..4)
            .map(|i| u64::from(w[2 * i]) | (u64::from(w[2 * i + 1]) << 32))
            .collect();
        let init = (u128::from(u[0]) << 64) | u128::from(u[1]);
        let seq = (u128::from(u[2]) << 64) | u128::from(u[3]);
        let mut g = Self {
            state: 0,
            inc: (seq << 1) | 1,
            buffered: None,
        };
        g.step();
        g.state = g.state.wrapping_add(init);
        g.step();
        g
    }

    fn step(&mut self) {
        self.state = self.state.wrapping_mul(Self::MULT).wrapping_add(self.inc);
    }

    /// Next 64-bit output.
    pub fn next_u64(&mut self) -> u64 {
        self.step();
        let s = self.state;
        let x = ((s >> 64) as u64) ^ (s as u64);
        x.rotate_right((s >> 122) as u32)
    }

    /// Next 32-bit output (low half of a 64-bit output, then its high half).
    pub fn next_u32(&mut self) -> u32 {
        if let Some(v) = self.buffered.take() {
            return v;
        }
        let n = self.next_u64();
        self.buffered = Some((n >> 32) as u32);
        n as u32
    }

    /// Uniform integer in [0, max] by masked rejection (numpy's `random_interval`).
    pub fn interval(&mut self, max: u64) -> u64 {
        if max == 0 {
            return 0;
        }
        let mut mask = max;
        for s in [1, 2, 4, 8, 16, 32] {
            mask |= mask >> s;
        }
        loop {
            let v = if max <= u64::from(u32::MAX) {
                u64::from(self.next_u32()) & mask
            } else {
                self.next_u64() & mask
            };
            if v <= max {
                return v;
            }
        }
    }
}

/// `numpy.random.default_rng(seed).permutation(n)`.
pub struct NumpyPermutation;

impl NumpyPermutation {
    /// The permutation of 0..n that numpy returns for this seed.
    pub fn of(seed: u32, n: usize) -> Vec<usize> {
        let mut g = NumpyPcg64::new(seed);
        let mut a: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            let j = g.interval(i as u64) as usize;
            a.swap(i, j);
        }
        a
    }
}

/// A seeded permutation of 0..n by ChaCha8 (rand's Fisher-Yates shuffle).
pub fn chacha_permutation(seed: u64, n: usize) -> Vec<usize> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut a: Vec<usize> = (0..n).collect();
    a.shuffle(&mut rng);
    a
}

/// Which seeded shuffle defines a split.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shuffle {
    /// numpy's `default_rng(seed).permutation` (the reference implementation's split).
    Numpy,
    /// ChaCha8 Fisher-Yates (an independent split).
    ChaCha,
}

impl Shuffle {
    /// Permutation of 0..n for this seed.
    pub fn permutation(self, seed: u32, n: usize) -> Vec<usize> {
        match self {
            Self::Numpy => NumpyPermutation::of(seed, n),
            Self::ChaCha => chacha_permutation(u64::from(seed), n),
        }
    }
}

/// A train/test split of 0..n: the first `n / 5` permuted indices are the test
/// set (20 %), the rest the training set, both in permutation order.
pub fn split_80_20(shuffle: Shuffle, seed: u32, n: usize) -> (Vec<usize>, Vec<usize>) {
    let p = shuffle.permutation(seed, n);
    let n_test = n / 5;
    (p[n_test..].to_vec(), p[..n_test].to_vec())
}

/// `k` folds of 0..n: the permutation cut into `k` contiguous chunks whose sizes
/// differ by at most one (the first `n % k` chunks one longer).
pub fn k_folds(shuffle: Shuffle, seed: u32, n: usize, k: usize) -> Vec<Vec<usize>> {
    let p = shuffle.permutation(seed, n);
    let k = k.max(1);
    let (q, r) = (n / k, n % k);
    let mut out = Vec::with_capacity(k);
    let mut start = 0;
    for i in 0..k {
        let len = q + usize::from(i < r);
        out.push(p[start..start + len].to_vec());
        start += len;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pinned against numpy 2.x: `default_rng(7).integers(0, 2**64 - 1, dtype=np.uint64,
    /// endpoint=True)` and `default_rng(7).permutation(840)[:10]`.
    #[test]
    fn matches_numpy() {
        assert_eq!(NumpyPcg64::new(7).next_u64(), 11_530_976_094_092_348_043);
        assert_eq!(
            NumpyPermutation::of(7, 840)[..10],
            [577, 667, 35, 9, 755, 169, 599, 837, 254, 546]
        );
    }

    #[test]
    fn permutations_are_permutations() {
        for sh in [Shuffle::Numpy, Shuffle::ChaCha] {
            let mut p = sh.permutation(3, 1000);
            p.sort_unstable();
            assert_eq!(p, (0..1000).collect::<Vec<_>>());
        }
        let f = k_folds(Shuffle::Numpy, 1, 12, 5);
        assert_eq!(f.iter().map(Vec::len).collect::<Vec<_>>(), [3, 3, 2, 2, 2]);
        let (tr, te) = split_80_20(Shuffle::Numpy, 7, 840);
        assert_eq!((tr.len(), te.len()), (672, 168));
    }
}
