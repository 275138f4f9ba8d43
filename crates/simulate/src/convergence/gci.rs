//! Solution verification by Richardson extrapolation and the Grid Convergence Index: the
//! three-grid procedure of Celik, Ghia, Roache, Freitas, Coleman & Raad, "Procedure for
//! estimation and reporting of uncertainty due to discretization in CFD applications",
//! ASME J. Fluids Eng. 130 (2008) 078001 (below "Celik"), with the least-squares variant of
//! Eça & Hoekstra for more than three grids.
//!
//! Notation of Celik: grid 1 is the finest, h1 < h2 < h3, φ_i the quantity on grid i,
//! r21 = h2/h1, r32 = h3/h2, ε21 = φ2 − φ1, ε32 = φ3 − φ2, s = sign(ε32/ε21). The observed
//! order p solves (Celik eqs. (3a)–(3c))
//!
//! p = |ln|ε32/ε21| + q(p)| / ln r21,   q(p) = ln((r21^p − s)/(r32^p − s)),
//!
//! by fixed-point iteration from q = 0 (q ≡ 0 when r21 = r32). Then (eqs. (4)–(6))
//! φ_ext21 = (r21^p φ1 − φ2)/(r21^p − 1), e_a21 = |(φ1 − φ2)/φ1|,
//! e_ext21 = |(φ_ext21 − φ1)/φ_ext21| and GCI_fine21 = 1.25 e_a21/(r21^p − 1) (safety factor
//! 1.25 for three or more grids).
//!
//! Classification by R = ε21/ε32: monotone convergence for 0 < R < 1, oscillatory for R < 0,
//! divergent for R ≥ 1; a zero difference (R = 0 or ε32 = 0) leaves the order undetermined.
//! (R does not correct for r21 ≠ r32: with very unequal ratios an exact power law may show
//! R ≥ 1, so the levels of `simulate --convergence` use one ratio.)
//! Only a monotone triplet has an order that means anything: [`Triplet::reported`] gives the
//! estimate for it and nothing otherwise.

use serde::Serialize;

/// The safety factor of the GCI with three or more grids (Celik, eq. (6)).
pub const SAFETY_FACTOR: f64 = 1.25;

/// Tolerance of the fixed-point iteration for p (absolute, on p).
const ORDER_TOLERANCE: f64 = 1e-13;
/// Iterations of the fixed-point iteration before giving up.
const ORDER_ITERATIONS: usize = 500;

/// How a three-grid sequence behaves, from R = ε21/ε32.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Convergence {
    /// 0 < R < 1: the differences shrink without changing sign.
    Monotone,
    /// R < 0: the differences change sign.
    Oscillatory,
    /// R ≥ 1: the differences do not shrink.
    Divergent,
    /// ε21 = 0 or ε32 = 0 (or a value not finite): no order can be determined.
    Undetermined,
}

impl Convergence {
    /// Classifies φ1 (finest), φ2, φ3 (coarsest) by R = ε21/ε32.
    pub fn classify(phi: [f64; 3]) -> Self {
        let e21 = phi[1] - phi[0];
        let e32 = phi[2] - phi[1];
        if !(e21.is_finite() && e32.is_finite()) || e21 == 0.0 || e32 == 0.0 {
            return Convergence::Undetermined;
        }
        let ratio = e21 / e32;
        if ratio < 0.0 {
            Convergence::Oscillatory
        } else if ratio < 1.0 {
            Convergence::Monotone
        } else {
            Convergence::Divergent
        }
    }

    /// Name as written in the reports.
    pub fn name(self) -> &'static str {
        match self {
            Convergence::Monotone => "monotone",
            Convergence::Oscillatory => "oscillatory",
            Convergence::Divergent => "divergent",
            Convergence::Undetermined => "undetermined",
        }
    }
}

/// The Richardson estimate of a triplet (Celik eqs. (3)–(6)), computed with the formulas
/// whatever the classification (Celik prints them for oscillatory triplets too).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// Observed order p.
    pub order: f64,
    /// φ_ext21, the Richardson-extrapolated value.
    pub extrapolated: f64,
    /// e_a21 = |(φ1 − φ2)/φ1|.
    pub approximate_relative_error: f64,
    /// e_ext21 = |(φ_ext21 − φ1)/φ_ext21|.
    pub extrapolated_relative_error: f64,
    /// GCI_fine21 = 1.25 e_a21/(r21^p − 1) (relative).
    pub gci_fine: f64,
    /// GCI_32 = 1.25 |(φ2 − φ3)/φ2|/(r32^p − 1), for the asymptotic-range check.
    pub gci_coarse: f64,
    /// GCI_32 / (r21^p GCI_21): near 1 in the asymptotic range (Roache).
    pub asymptotic_ratio: f64,
}

/// Three grids, finest first, with the classification and the Richardson estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Triplet {
    /// h1 < h2 < h3.
    pub h: [f64; 3],
    /// φ1, φ2, φ3.
    pub phi: [f64; 3],
    /// r21 = h2/h1.
    pub r21: f64,
    /// r32 = h3/h2.
    pub r32: f64,
    /// See [`Convergence`].
    pub convergence: Convergence,
    /// The formulas of Celik; None when p cannot be computed (a zero difference, or the
    /// fixed-point iteration does not converge).
    pub estimate: Option<Estimate>,
}

impl Triplet {
    /// The estimate if the triplet converges monotonically, else None: an order of an
    /// oscillatory or divergent sequence is never reported.
    pub fn reported(&self) -> Option<Estimate> {
        (self.convergence == Convergence::Monotone)
            .then_some(self.estimate)
            .flatten()
    }
}

/// An error of the input of the procedure.
#[derive(Debug, Clone, PartialEq)]
pub struct GciError(pub String);

impl std::fmt::Display for GciError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for GciError {}

/// Celik's observed order by fixed-point iteration; None if it does not converge.
pub fn observed_order(r21: f64, r32: f64, e21: f64, e32: f64) -> Option<f64> {
    let s = (e32 / e21).signum();
    let log_ratio = (e32 / e21).abs().ln();
    let q = |p: f64| ((r21.powf(p) - s) / (r32.powf(p) - s)).ln();
    let mut p = (log_ratio / r21.ln()).abs();
    for _ in 0..ORDER_ITERATIONS {
        let next = ((log_ratio + q(p)) / r21.ln()).abs();
        if !next.is_finite() {
            return None;
        }
        if (next - p).abs() <= ORDER_TOLERANCE * next.max(1.0) {
            return Some(next);
        }
        p = next;
    }
    None
}

/// The three-grid procedure of Celik on grids `h` (finest first, h1 < h2 < h3) with values
/// `phi`.
pub fn three_grid(h: [f64; 3], phi: [f64; 3]) -> Result<Triplet, GciError> {
    if !(h.iter().all(|x| x.is_finite() && *x > 0.0) && h[0] < h[1] && h[1] < h[2]) {
        return Err(GciError(format!(
            "grid sizes must be positive and increasing from the finest, got {h:?}"
        )));
    }
    if !phi.iter().all(|x| x.is_finite()) {
        return Err(GciError(format!("values must be finite, got {phi:?}")));
    }
    let r21 = h[1] / h[0];
    let r32 = h[2] / h[1];
    let convergence = Convergence::classify(phi);
    let e21 = phi[1] - phi[0];
    let e32 = phi[2] - phi[1];
    let estimate = if e21 == 0.0 || e32 == 0.0 {
        None
    } else {
        observed_order(r21, r32, e21, e32).map(|p| {
            let f21 = r21.powf(p);
            let f32 = r32.powf(p);
            let extrapolated = (f21 * phi[0] - phi[1]) / (f21 - 1.0);
            let approximate_relative_error = ((phi[0] - phi[1]) / phi[0]).abs();
            let gci_fine = SAFETY_FACTOR * approximate_relative_error / (f21 - 1.0);
            let gci_coarse = SAFETY_FACTOR * ((phi[1] - phi[2]) / phi[1]).abs() / (f32 - 1.0);
            Estimate {
                order: p,
                extrapolated,
                approximate_relative_error,
                extrapolated_relative_error: ((extrapolated - phi[0]) / extrapolated).abs(),
                gci_fine,
                gci_coarse,
                asymptotic_ratio: gci_coarse / (f21 * gci_fine),
            }
        })
    };
    Ok(Triplet {
        h,
        phi,
        r21,
        r32,
        convergence,
        estimate,
    })
}

/// The least-squares fit φ ≈ φ0 + α h^p of Eça & Hoekstra over all grids.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LeastSquares {
    /// φ0, the extrapolated value.
    pub extrapolated: f64,
    /// α.
    pub coefficient: f64,
    /// p.
    pub order: f64,
    /// Standard deviation of the fit, √(Σ (φ_i − φ0 − α h_i^p)² / (n − 3)) (0 for n = 3).
    pub standard_deviation: f64,
}

/// Range of orders searched by [`least_squares`].
pub const FIT_ORDERS: (f64, f64) = (0.05, 8.0);

/// Eça–Hoekstra fit φ ≈ φ0 + α h^p minimizing Σ (φ_i − φ0 − α h_i^p)²: for each p, φ0 and α
/// are a linear least-squares problem, and p minimizes the residual over [`FIT_ORDERS`] (a
/// scan, then golden-section refinement). None for fewer than three grids or when the
/// minimum lies on the boundary of the range (no order in it fits).
pub fn least_squares(h: &[f64], phi: &[f64]) -> Option<LeastSquares> {
    if h.len() < 3 || h.len() != phi.len() {
        return None;
    }
    let n = h.len() as f64;
    let linear = |p: f64| -> (f64, f64, f64) {
        let x: Vec<f64> = h.iter().map(|h| h.powf(p)).collect();
        let mean_x = x.iter().sum::<f64>() / n;
        let mean_y = phi.iter().sum::<f64>() / n;
        let sxx: f64 = x.iter().map(|x| (x - mean_x).powi(2)).sum();
        let sxy: f64 = x
            .iter()
            .zip(phi)
            .map(|(x, y)| (x - mean_x) * (y - mean_y))
            .sum();
        let alpha = sxy / sxx;
        let phi0 = mean_y - alpha * mean_x;
        let residual: f64 = x
            .iter()
            .zip(phi)
            .map(|(x, y)| (y - phi0 - alpha * x).powi(2))
            .sum();
        (phi0, alpha, residual)
    };
    let (low, high) = FIT_ORDERS;
    let samples = 400;
    let at = |i: usize| low + (high - low) * i as f64 / samples as f64;
    let best = (0..=samples).min_by(|&a, &b| linear(at(a)).2.total_cmp(&linear(at(b)).2))?;
    if best == 0 || best == samples {
        return None;
    }
    let (mut a, mut b) = (at(best - 1), at(best + 1));
    let golden = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..200 {
        let c = b - golden * (b - a);
        let d = a + golden * (b - a);
        if linear(c).2 < linear(d).2 {
            b = d;
        } else {
            a = c;
        }
        if b - a < 1e-14 {
            break;
        }
    }
    let order = 0.5 * (a + b);
    let (extrapolated, coefficient, residual) = linear(order);
    let standard_deviation = if h.len() > 3 {
        (residual / (n - 3.0)).sqrt()
    } else {
        0.0
    };
    Some(LeastSquares {
        extrapolated,
        coefficient,
        order,
        standard_deviation,
    })
}

/// Every consecutive triplet of a sequence of grids given finest first.
pub fn triplets(h: &[f64], phi: &[f64]) -> Result<Vec<Triplet>, GciError> {
    if h.len() < 3 || h.len() != phi.len() {
        return Err(GciError(format!(
            "need at least three grids with one value each, got {} sizes and {} values",
            h.len(),
            phi.len()
        )));
    }
    (0..h.len() - 2)
        .map(|i| three_grid([h[i], h[i + 1], h[i + 2]], [phi[i], phi[i + 1], phi[i + 2]]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Celik et al. (2008), Table 1 ("Sample calculations of discretization error"): three 2D
    /// grids of N1 = 18000, N2 = 8000, N3 = 4500 cells, h = (1/N)^(1/2) up to a common factor,
    /// so r21 = 1.5 and r32 = 4/3 (non-constant: the fixed-point iteration for p is needed).
    /// Column 1 (the reattachment length): φ = 6.063, 5.972, 5.863 and the printed
    /// p = 1.53, φ_ext21 = 6.1685, e_a21 = 1.5 %, e_ext21 = 1.7 %, GCI_fine21 = 2.2 %. The same
    /// φ are the input of the GCI.m example of the KTH course page found in the `pages` corpus
    /// (canvas.kth.se/courses/35445, "example how to calculate the GCI", citing Celik).
    const CELIK_COLUMN_1: [f64; 3] = [6.063, 5.972, 5.863];
    /// Columns 2 and 3 of the same table (velocities): column 2 converges monotonically,
    /// column 3 oscillates (φ3 > φ1 > φ2), with e_a21 = 0.6 % and 0.7 %.
    const CELIK_COLUMNS_2_3: [([f64; 3], f64); 2] = [
        ([10.7880, 10.7250, 10.6050], 0.6),
        ([6.0042, 5.9624, 6.0909], 0.7),
    ];

    fn rounded(value: f64, decimals: i32) -> f64 {
        let scale = 10f64.powi(decimals);
        (value * scale).round() / scale
    }

    #[test]
    fn celik_2008_table_1_to_the_printed_digits() {
        let h = [18000f64, 8000.0, 4500.0].map(|n| (1.0 / n).sqrt());
        let triplet = three_grid(h, CELIK_COLUMN_1).unwrap();
        assert_eq!(rounded(triplet.r21, 3), 1.5);
        assert_eq!(rounded(triplet.r32, 3), 1.333);
        assert_eq!(triplet.convergence, Convergence::Monotone);
        let estimate = triplet.reported().unwrap();
        assert_eq!(rounded(estimate.order, 2), 1.53, "{estimate:?}");
        assert_eq!(rounded(estimate.extrapolated, 4), 6.1685, "{estimate:?}");
        assert_eq!(rounded(100.0 * estimate.approximate_relative_error, 1), 1.5);
        assert_eq!(
            rounded(100.0 * estimate.extrapolated_relative_error, 1),
            1.7
        );
        assert_eq!(rounded(100.0 * estimate.gci_fine, 1), 2.2);
        let kinds: Vec<Convergence> = CELIK_COLUMNS_2_3
            .iter()
            .map(|(phi, e_a)| {
                let triplet = three_grid(h, *phi).unwrap();
                let estimate = triplet.estimate.unwrap();
                assert_eq!(
                    rounded(100.0 * estimate.approximate_relative_error, 1),
                    *e_a
                );
                triplet.convergence
            })
            .collect();
        assert_eq!(kinds, [Convergence::Monotone, Convergence::Oscillatory]);
        assert!(three_grid(h, CELIK_COLUMNS_2_3[1].0)
            .unwrap()
            .reported()
            .is_none());
    }

    #[test]
    fn synthetic_power_law_recovers_order_and_limit() {
        let (phi0, c, p) = (1.25, -0.8, 1.7);
        for h in [[0.025, 0.05, 0.1], [0.04, 0.06, 0.1], [0.03, 0.05, 0.08]] {
            let phi = h.map(|h: f64| phi0 + c * h.powf(p));
            let triplet = three_grid(h, phi).unwrap();
            assert_eq!(triplet.convergence, Convergence::Monotone);
            let estimate = triplet.reported().unwrap();
            assert!((estimate.order - p).abs() < 1e-10, "{estimate:?}");
            assert!((estimate.extrapolated - phi0).abs() < 1e-10, "{estimate:?}");
            // exact power law: GCI_32 = r21^p GCI_21 up to the relative scaling by φ2 and φ1
            let ratio = phi[0] / phi[1];
            assert!(
                (estimate.asymptotic_ratio - ratio).abs() < 1e-10,
                "{estimate:?}"
            );
            let error = ((phi[0] - phi0) / phi0).abs();
            assert!((estimate.extrapolated_relative_error - error).abs() < 1e-10);
            assert!(estimate.gci_fine > error);
        }
        let h = [0.025, 0.035, 0.05, 0.07, 0.1];
        let phi: Vec<f64> = h.iter().map(|h: &f64| phi0 + c * h.powf(p)).collect();
        let fit = least_squares(&h, &phi).unwrap();
        assert!((fit.order - p).abs() < 1e-6, "{fit:?}");
        assert!((fit.extrapolated - phi0).abs() < 1e-8, "{fit:?}");
        assert!((fit.coefficient - c).abs() < 1e-6, "{fit:?}");
    }

    #[test]
    fn synthetic_sequences_are_classified() {
        let h = [0.25, 0.5, 1.0];
        use Convergence::*;
        let cases = [
            ([1.01, 1.04, 1.16], Monotone),
            ([0.99, 0.96, 0.84], Monotone),
            ([1.01, 0.97, 1.10], Oscillatory),
            ([1.0, 1.1, 1.15], Divergent),
            ([1.0, 1.1, 1.2], Divergent),
            ([1.0, 1.0, 1.2], Undetermined),
            ([1.0, 1.2, 1.2], Undetermined),
        ];
        for (phi, kind) in cases {
            let triplet = three_grid(h, phi).unwrap();
            assert_eq!(triplet.convergence, kind, "{phi:?}");
            assert_eq!(triplet.reported().is_some(), kind == Monotone, "{phi:?}");
        }
    }

    #[test]
    fn bad_grids_are_refused() {
        assert!(three_grid([0.5, 0.25, 1.0], [1.0, 2.0, 3.0]).is_err());
        assert!(three_grid([0.25, 0.5, 1.0], [1.0, f64::NAN, 3.0]).is_err());
        assert!(triplets(&[0.1, 0.2], &[1.0, 2.0]).is_err());
        assert_eq!(
            triplets(&[0.1, 0.2, 0.4, 0.8], &[1.0, 1.1, 1.3, 1.7])
                .unwrap()
                .len(),
            2
        );
    }
}
