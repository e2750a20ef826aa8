//! The paper's Table 1 (Yu, Pi, Wang): reference values of docs/design.md §4.

use super::from_hz_db_deg;
use fracsim::FracTf;
use ident::levy::{error_index, fit_bode, levy_fixed_q, vinagre_weights, FreqOptions, OrderChoice};

/// Table 1 of the paper, as in `data/paper_table1_bode.csv`.
pub const TABLE1: [(f64, f64, f64); 10] = [
    (0.1, 16.62, -0.23),
    (0.5, 16.63, -0.95),
    (1.0, 16.63, -1.83),
    (2.0, 16.55, -3.4),
    (5.0, 16.47, -7.95),
    (10.0, 16.26, -16.3),
    (20.0, 15.96, -29.2),
    (50.0, 13.48, -68.9),
    (80.0, 9.5, -95.6),
    (100.0, 6.91, -107.0),
];

fn rel(x: f64, y: f64) -> f64 {
    ((x - y) / y).abs()
}

#[test]
fn levy_at_q_089_matches_reference() {
    let (omega, h) = from_hz_db_deg(&TABLE1);
    let fit = levy_fixed_q(&omega, &h, 0.89, 0, 2, &vinagre_weights(&omega), 0).unwrap();
    // 0.5 %: the brief's tolerance; the table is given to 3-4 digits.
    assert!(rel(fit.b[0], 6.7853) < 5e-3, "b0 = {}", fit.b[0]);
    assert!(rel(fit.a[0], 6.632e-3) < 5e-3, "a1 = {}", fit.a[0]);
    assert!(rel(fit.a[1], 2.5906e-5) < 5e-3, "a2 = {}", fit.a[1]);
    // 1 %: J is printed to 4 digits.
    assert!(rel(fit.j, 3.675e-3) < 1e-2, "J = {}", fit.j);
}

#[test]
fn grid_picks_q_091() {
    let (omega, h) = from_hz_db_deg(&TABLE1);
    let opts = FreqOptions {
        order: OrderChoice::Search {
            step: 0.01,
            q_max: 1.0,
            refine: true,
        },
        ..FreqOptions::default()
    };
    let fit = fit_bode(&omega, &h, &opts).unwrap();
    assert_eq!(fit.levy_grid.q, 0.91);
    assert!(
        rel(fit.levy_grid.j, 3.555e-3) < 1e-2,
        "J = {}",
        fit.levy_grid.j
    );
    assert!(rel(fit.levy_grid.b[0], 6.7832) < 5e-3);
    assert!(rel(fit.levy_grid.a[0], 6.208e-3) < 5e-3);
    assert!(rel(fit.levy_grid.a[1], 1.9176e-5) < 5e-3);
    assert_eq!(fit.curve.len(), 100);
    // the refined q is near the grid point and no worse
    assert!((fit.levy.q - 0.91).abs() <= 0.01);
    assert!(fit.levy.j <= fit.levy_grid.j);
}

#[test]
fn refined_fit_beats_levy_and_paper() {
    let (omega, h) = from_hz_db_deg(&TABLE1);
    let opts = FreqOptions {
        refine: true,
        sk_iterations: 5,
        ..FreqOptions::default()
    };
    let fit = fit_bode(&omega, &h, &opts).unwrap();
    let r = fit.refined.as_ref().unwrap();
    assert!(r.j <= 2.0e-3, "refined J = {}", r.j);
    assert!(r.j < fit.levy.j);
    assert!(r.zeta > 0.0 && r.zeta < 2.0 && r.theta > 0.0 && r.theta < 2.0);
    let paper: FracTf = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"
        .parse()
        .unwrap();
    let jp = error_index(&omega, &h, &paper);
    // 1 %: docs/design.md quotes 2.06e-2 to three digits.
    assert!(rel(jp, 2.06e-2) < 1e-2, "paper J = {jp}");
    eprintln!(
        "Table 1: Levy grid q = {} J = {:.4e}; Levy refined q = {:.4} J = {:.4e}; SK J = {:.4e}; \
         refit {} J = {:.4e}; paper J = {:.4e}",
        fit.levy_grid.q,
        fit.levy_grid.j,
        fit.levy.q,
        fit.levy.j,
        fit.sk.as_ref().unwrap().j,
        r.model,
        r.j,
        jp
    );
}
