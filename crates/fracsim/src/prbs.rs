//! Pseudo-random binary sequences: maximum-length linear feedback shift registers of order 2 to 16.
//!
//! The register (Fibonacci form) holds `n` bits; each clock outputs its top bit and shifts in the
//! XOR of the tapped bits. With the taps of [`taps`] (the feedback polynomials of Xilinx XAPP052)
//! the sequence has the maximum period `2^n - 1`.

use crate::error::{finite, invalid, Result};

/// The most samples a PRBS signal is made of ([`Prbs::signal`], [`Prbs::samples`]).
pub const MAX_SAMPLES: usize = 100_000_000;

/// Feedback taps (bit positions, 1-based, the highest equal to the order) of a maximum-length
/// register of order `n` in 2..=16.
///
/// # Errors
/// An order outside 2..=16.
pub fn taps(n: u32) -> Result<&'static [u32]> {
    Ok(match n {
        2 => &[2, 1],
        3 => &[3, 2],
        4 => &[4, 3],
        5 => &[5, 3],
        6 => &[6, 5],
        7 => &[7, 6],
        8 => &[8, 6, 5, 4],
        9 => &[9, 5],
        10 => &[10, 7],
        11 => &[11, 9],
        12 => &[12, 6, 4, 1],
        13 => &[13, 4, 3, 1],
        14 => &[14, 5, 3, 1],
        15 => &[15, 14],
        16 => &[16, 15, 13, 4],
        _ => return invalid("PRBS order", format!("{n} (supported: 2 to 16)")),
    })
}

/// A Fibonacci linear feedback shift register.
///
/// ```
/// let mut r = fracsim::prbs::Lfsr::new(7, 1).unwrap();
/// let bits: Vec<bool> = (0..127).map(|_| r.next_bit()).collect();
/// assert_eq!(bits.iter().filter(|&&b| b).count(), 64); // 2^(n-1) ones in a period
/// ```
#[derive(Debug, Clone)]
pub struct Lfsr {
    order: u32,
    mask: u32,
    tap_mask: u32,
    state: u32,
}

impl Lfsr {
    /// A register of order `n` (2..=16) started from `seed` (taken modulo `2^n`, must not be 0).
    ///
    /// # Errors
    /// A bad order or a zero seed (the all-zero state never leaves itself).
    pub fn new(order: u32, seed: u32) -> Result<Self> {
        let t = taps(order)?;
        let mask = (1u32 << order) - 1;
        if seed & mask == 0 {
            return invalid("PRBS seed", "must be nonzero modulo 2^order");
        }
        let tap_mask = t.iter().fold(0, |m, &b| m | (1 << (b - 1)));
        Ok(Self {
            order,
            mask,
            tap_mask,
            state: seed & mask,
        })
    }

    /// The next output bit (the top bit of the register), then one shift.
    pub fn next_bit(&mut self) -> bool {
        let out = (self.state >> (self.order - 1)) & 1 == 1;
        let fb = (self.state & self.tap_mask).count_ones() & 1;
        self.state = ((self.state << 1) | fb) & self.mask;
        out
    }

    /// The period `2^n - 1`.
    pub fn period(&self) -> usize {
        self.mask as usize
    }
}

/// A PRBS test signal: a maximum-length sequence held for `clock` seconds per bit, levels
/// `offset +- amplitude`, repeated `periods` times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prbs {
    /// Register order (2..=16): the period is `2^order - 1` bits.
    pub order: u32,
    /// Bit duration in seconds.
    pub clock: f64,
    /// Half the peak-to-peak level.
    pub amplitude: f64,
    /// The mean level.
    pub offset: f64,
    /// Number of periods.
    pub periods: usize,
    /// Register seed (nonzero).
    pub seed: u32,
}

impl Prbs {
    /// The reference paper's experiment: order 7 (127 bits), 3 ms clock, one period, unit amplitude.
    pub const fn paper() -> Self {
        Self {
            order: 7,
            clock: 0.003,
            amplitude: 1.0,
            offset: 0.0,
            periods: 1,
            seed: 1,
        }
    }

    /// The bits of one period.
    ///
    /// # Errors
    /// A bad order or seed.
    pub fn bits(&self) -> Result<Vec<bool>> {
        let mut r = Lfsr::new(self.order, self.seed)?;
        Ok((0..r.period()).map(|_| r.next_bit()).collect())
    }

    /// Number of samples of step `dt` per bit (the clock must be a whole multiple of `dt`,
    /// within 1e-6 relative).
    ///
    /// # Errors
    /// A bad step or a clock that is not a multiple of it.
    pub fn samples_per_bit(&self, dt: f64) -> Result<usize> {
        finite("dt", dt)?;
        finite("PRBS clock", self.clock)?;
        if dt <= 0.0 || self.clock <= 0.0 {
            return invalid("PRBS clock", "clock and dt must be positive");
        }
        let r = self.clock / dt;
        let n = r.round();
        if n < 1.0 || (r - n).abs() > 1e-6 * r {
            return invalid(
                "PRBS clock",
                format!("{} s is not a whole multiple of dt = {dt} s", self.clock),
            );
        }
        Ok(n as usize)
    }

    /// The sampled signal: `periods * (2^order - 1) * clock/dt` samples (at most
    /// [`MAX_SAMPLES`]).
    ///
    /// ```
    /// let p = fracsim::prbs::Prbs { periods: 2, ..fracsim::prbs::Prbs::paper() };
    /// let u = p.signal(1e-3).unwrap();
    /// assert_eq!(u.len(), 2 * 127 * 3);
    /// ```
    ///
    /// # Errors
    /// As [`Prbs::bits`] and [`Prbs::samples_per_bit`]; non-finite levels; more than 1e8 samples.
    pub fn signal(&self, dt: f64) -> Result<Vec<f64>> {
        let spb = self.samples_per_bit(dt)?;
        let period = Lfsr::new(self.order, self.seed)?.period();
        let total = match period
            .checked_mul(spb)
            .and_then(|n| n.checked_mul(self.periods))
        {
            Some(total) => total,
            None => usize::MAX,
        };
        if total > MAX_SAMPLES {
            let total = period as f64 * spb as f64 * self.periods as f64;
            return invalid(
                "PRBS",
                format!("{total:.3e} samples is too many (at most {MAX_SAMPLES:.0e})"),
            );
        }
        self.samples(dt, total)
    }

    /// The first `n` samples of the signal repeated without end, `n` more or fewer than
    /// [`Prbs::signal`]'s periods hold (`periods` is not used): a record of any length with no
    /// whole period made first (a period of order 16 at a fine step is 1e8 samples).
    ///
    /// ```
    /// let p = fracsim::prbs::Prbs::paper();
    /// let u = p.samples(1e-3, 1000).unwrap();
    /// assert_eq!(&u[..381], &p.signal(1e-3).unwrap()[..]);
    /// assert_eq!(&u[381..762], &u[..381]);
    /// ```
    ///
    /// # Errors
    /// As [`Prbs::signal`].
    pub fn samples(&self, dt: f64, n: usize) -> Result<Vec<f64>> {
        finite("PRBS amplitude", self.amplitude)?;
        finite("PRBS offset", self.offset)?;
        let spb = self.samples_per_bit(dt)?;
        if n > MAX_SAMPLES {
            return invalid(
                "PRBS",
                format!(
                    "{:.3e} samples is too many (at most {MAX_SAMPLES:.0e})",
                    n as f64
                ),
            );
        }
        let mut r = Lfsr::new(self.order, self.seed)?;
        let period = r.period();
        let mut bits = Vec::with_capacity(period.min(n / spb + 1));
        let mut u = Vec::with_capacity(n);
        while u.len() < n {
            // the bits of one period, made once (at most those the n samples need)
            let k = u.len() / spb;
            let b = if k < period {
                let b = r.next_bit();
                bits.push(b);
                b
            } else {
                bits[k % period]
            };
            let v = if b {
                self.offset + self.amplitude
            } else {
                self.offset - self.amplitude
            };
            let m = spb.min(n - u.len());
            u.extend(std::iter::repeat_n(v, m));
        }
        Ok(u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_order_has_the_maximum_period() {
        for n in 2..=16 {
            let mut r = Lfsr::new(n, 1).unwrap();
            let start = r.state;
            let mut period = 0;
            loop {
                r.next_bit();
                period += 1;
                if r.state == start {
                    break;
                }
                assert!(period <= r.period(), "order {n} is not maximal");
            }
            assert_eq!(period, (1 << n) - 1, "order {n}");
        }
    }

    #[test]
    fn bad_prbs_settings_are_errors() {
        assert!(Lfsr::new(1, 1).is_err());
        assert!(Lfsr::new(17, 1).is_err());
        assert!(Lfsr::new(7, 128).is_err());
        let p = Prbs::paper();
        assert!(p.signal(0.0007).is_err());
        assert!(p.signal(-1.0).is_err());
        // clock/dt saturates usize: the sample count overflowed (a panic) before it was checked
        let huge = Prbs {
            clock: 1e300,
            ..Prbs::paper()
        };
        let err = huge.signal(1e-4).unwrap_err().to_string();
        assert!(err.contains("samples is too many"), "{err}");
        let many = Prbs {
            periods: usize::MAX,
            ..Prbs::paper()
        };
        assert!(many.signal(1e-3).is_err());
    }
}
