//! Frequency-domain identification: the paper's Table 1, round trips, bad input.

mod bad_input;
mod coverage;
mod round_trip;
mod table1;

use num_complex::Complex64;

/// Bode data `(omega_rad_s, G(j omega))` from rows `freq_hz, gain_db, phase_deg`.
pub fn from_hz_db_deg(rows: &[(f64, f64, f64)]) -> (Vec<f64>, Vec<Complex64>) {
    rows.iter()
        .map(|&(f, db, deg)| {
            (
                2.0 * std::f64::consts::PI * f,
                Complex64::from_polar(10f64.powf(db / 20.0), deg.to_radians()),
            )
        })
        .unzip()
}
