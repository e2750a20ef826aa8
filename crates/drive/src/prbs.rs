//! The drive's PRBS: a maximum-length Fibonacci LFSR (crate docs, section 5), the same sequence
//! as [`fracsim::prbs::Lfsr`] (same taps, same seed, bit for bit; tested).
//!
//! State `s` of n bits; per bit: `out = (s >> (n-1)) & 1; fb = parity(s & taps);
//! s = ((s << 1) | fb) & (2^n - 1)`. Taps are the XAPP052 positions p (1-based) as a mask of bits
//! p - 1; the highest tap is n, so bit n-1 of the mask is always set.

/// Default feedback tap mask for LFSR length `order` (2..=16): maximum length (period 2^n - 1),
/// from [`fracsim::prbs::taps`]. Order 7 gives 0x60 (taps 7, 6).
pub fn default_taps(order: u8) -> Option<u32> {
    let t = fracsim::prbs::taps(order as u32).ok()?;
    Some(t.iter().fold(0u32, |m, &p| m | (1 << (p - 1))))
}

/// A Fibonacci LFSR as run by the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lfsr {
    order: u8,
    taps: u32,
    mask: u32,
    state: u32,
    seed: u32,
}

impl Lfsr {
    /// A new LFSR; None if `order` is not in 2..=31, `seed` is 0 or does not fit in n bits, or
    /// `taps` lacks bit n-1 or does not fit.
    pub fn new(order: u8, taps: u32, seed: u32) -> Option<Self> {
        if !(2..=31).contains(&order) {
            return None;
        }
        let mask = (1u32 << order) - 1;
        if seed == 0 || seed & !mask != 0 || taps & (1 << (order - 1)) == 0 || taps & !mask != 0 {
            return None;
        }
        Some(Self {
            order,
            taps,
            mask,
            state: seed,
            seed,
        })
    }

    /// The next bit.
    pub fn next_bit(&mut self) -> bool {
        let out = (self.state >> (self.order - 1)) & 1 == 1;
        let fb = (self.state & self.taps).count_ones() & 1;
        self.state = ((self.state << 1) | fb) & self.mask;
        out
    }

    /// Back to the seed (start of a period).
    pub fn restart(&mut self) {
        self.state = self.seed;
    }

    /// Period of a maximum-length sequence, 2^n - 1.
    pub fn period(&self) -> u64 {
        self.mask as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_sequence_as_fracsim() {
        for order in 2..=16u8 {
            let taps = default_taps(order).unwrap();
            for seed in [1u32, 5, (1 << order) - 1]
                .into_iter()
                .filter(|&s| s < (1 << order))
            {
                let mut a = Lfsr::new(order, taps, seed).unwrap();
                let mut b = fracsim::prbs::Lfsr::new(order as u32, seed).unwrap();
                for _ in 0..(2 * a.period() + 3) {
                    assert_eq!(a.next_bit(), b.next_bit(), "order {order} seed {seed}");
                }
            }
        }
        assert_eq!(default_taps(7), Some(0x60));
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(Lfsr::new(1, 1, 1).is_none());
        assert!(Lfsr::new(7, 0x60, 0).is_none());
        assert!(Lfsr::new(7, 0x60, 128).is_none());
        assert!(Lfsr::new(7, 0x03, 1).is_none());
    }
}
