//! The exact fields of a case and every derivative the manufactured data and the error
//! integrals use — u, u̇, ∇u, ∇u̇, ∇²u, ∇²u̇, β, β̇, ∇β, Δβ, ξ, η and g — differentiated
//! symbolically and compiled ONCE per case ([`crate::expr::Tape`]), then evaluated over batches
//! of points on `f64` columns ([`crate::expr::Program::eval_batch`]).
//!
//! Why symbolic differentiation rather than dual numbers in batches: see
//! [`crate::expr::derivative`]. Each consumer gets its own program with only the quantities it
//! reads (dead code removed): f0 (with q, at the same points) needs the second derivatives, the
//! boundary data and the errors only first derivatives, the damage flux only ∇β.

use super::ExactSolution;
use crate::expr::derivative::Value;
use crate::expr::split::BatchOutputs;
use crate::expr::{SplitProgram, Tape};

/// Slot of time in the variables (x, y, z, t).
const TIME: usize = 3;

/// Points per batch of a program evaluation.
pub use crate::expr::split::BATCH;

/// Bytes of time-independent values one program may cache per run
/// ([`crate::expr::SplitProgram`]); points beyond it are evaluated whole. 256 MiB: the
/// finest level of `verify --dim 3` (24³ cells, 1.16 M load quadrature points) would need
/// 325 MB for f0 alone, yet the run took 48.6 s with this budget, 48.6 s with 1 GiB and 55.1 s
/// without a cache (shared 2-core machine).
pub const CACHE_BYTES: usize = 256 << 20;

/// One quantity of the exact solution at a point; `i` indexes components of u or ξ, `j`, `k`
/// spatial directions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// u_i.
    U(usize),
    /// ∂u_i/∂t.
    Rate(usize),
    /// ∂u_i/∂x_j.
    Gradient(usize, usize),
    /// ∂²u_i/∂x_j∂t.
    RateGradient(usize, usize),
    /// ∂²u_i/∂x_j∂x_k.
    Hessian(usize, usize, usize),
    /// ∂³u_i/∂x_j∂x_k∂t.
    RateHessian(usize, usize, usize),
    /// β.
    Damage,
    /// ∂β/∂t.
    DamageRate,
    /// ∂β/∂x_j.
    DamageGradient(usize),
    /// Δβ.
    DamageLaplacian,
    /// ξ_i.
    StickTraction(usize),
    /// η.
    Multiplier,
    /// g.
    Gap,
}

/// A program computing some [`Quantity`]s, and where each one is among its outputs.
///
/// The program is split by its dependence on time ([`SplitProgram`]): what does not depend on t
/// is computed once per quadrature point of a run. A clone shares the compiled code, not the
/// cache (it starts empty), so that each run caches only its own points.
#[derive(Debug, Clone)]
pub struct QuantityProgram<const D: usize> {
    program: SplitProgram,
    /// The output of each quantity, by [`Quantity::index`]; [`NOT_COMPILED`] if none.
    output_of: [u16; QUANTITIES],
}

/// Number of distinct [`Quantity`] values (components up to 3).
const QUANTITIES: usize = 89;

/// Entry of `output_of` for a quantity the program does not compute.
const NOT_COMPILED: u16 = u16::MAX;

impl Quantity {
    /// A dense index in `0..QUANTITIES`.
    fn index(self) -> usize {
        match self {
            Quantity::U(i) => i,
            Quantity::Rate(i) => 3 + i,
            Quantity::Gradient(i, j) => 6 + 3 * i + j,
            Quantity::RateGradient(i, j) => 15 + 3 * i + j,
            Quantity::Hessian(i, j, k) => 24 + 9 * i + 3 * j + k,
            Quantity::RateHessian(i, j, k) => 51 + 9 * i + 3 * j + k,
            Quantity::Damage => 78,
            Quantity::DamageRate => 79,
            Quantity::DamageGradient(j) => 80 + j,
            Quantity::DamageLaplacian => 83,
            Quantity::StickTraction(i) => 84 + i,
            Quantity::Multiplier => 87,
            Quantity::Gap => 88,
        }
    }
}

/// Columns of the quantities at the points of one batch.
pub struct Columns<'a, const D: usize> {
    program: &'a QuantityProgram<D>,
    outputs: &'a BatchOutputs<'a>,
}

impl<const D: usize> Columns<'_, D> {
    /// The values of `quantity` at the points of the batch.
    ///
    /// # Panics
    /// If the program was not compiled with `quantity` (a programming error).
    pub fn get(&self, quantity: Quantity) -> &[f64] {
        match self.program.output_of[quantity.index()] {
            NOT_COMPILED => panic!("{quantity:?} was not compiled"),
            k => self.outputs.get(k as usize),
        }
    }
}

impl<const D: usize> QuantityProgram<D> {
    /// Compiles `quantities` of `exact`.
    pub fn new(exact: &ExactSolution<D>, quantities: &[Quantity]) -> Self {
        let mut tape = Tape::new(4);
        let u: [Value; D] = std::array::from_fn(|i| tape.expression(&exact.displacement[i]));
        let beta = tape.expression(&exact.damage);
        let outputs: Vec<Value> = quantities
            .iter()
            .map(|&q| match q {
                Quantity::U(i) => u[i],
                Quantity::Rate(i) => tape.derivative(u[i], TIME),
                Quantity::Gradient(i, j) => tape.derivative(u[i], j),
                Quantity::RateGradient(i, j) => {
                    let rate = tape.derivative(u[i], TIME);
                    tape.derivative(rate, j)
                }
                Quantity::Hessian(i, j, k) => {
                    let (j, k) = (j.min(k), j.max(k));
                    let first = tape.derivative(u[i], j);
                    tape.derivative(first, k)
                }
                Quantity::RateHessian(i, j, k) => {
                    let (j, k) = (j.min(k), j.max(k));
                    let rate = tape.derivative(u[i], TIME);
                    let first = tape.derivative(rate, j);
                    tape.derivative(first, k)
                }
                Quantity::Damage => beta,
                Quantity::DamageRate => tape.derivative(beta, TIME),
                Quantity::DamageGradient(j) => tape.derivative(beta, j),
                Quantity::DamageLaplacian => {
                    let mut sum = None;
                    for j in 0..D {
                        let first = tape.derivative(beta, j);
                        let second = tape.derivative(first, j);
                        sum = tape.sum(sum, second);
                    }
                    sum
                }
                Quantity::StickTraction(i) => tape.expression(&exact.stick_traction[i]),
                Quantity::Multiplier => tape.expression(&exact.damage_multiplier),
                Quantity::Gap => tape.expression(&exact.gap),
            })
            .collect();
        let mut output_of = [NOT_COMPILED; QUANTITIES];
        for (k, quantity) in quantities.iter().enumerate() {
            output_of[quantity.index()] = k as u16;
        }
        Self {
            program: SplitProgram::new(tape.compile(&outputs), TIME, CACHE_BYTES),
            output_of,
        }
    }

    /// Number of instructions.
    pub fn len(&self) -> usize {
        self.program.whole().len()
    }

    /// Number of time-independent values cached per point.
    pub fn frontier_len(&self) -> usize {
        self.program.frontier_len()
    }

    /// Instructions run per point at each evaluation once the points are cached.
    pub fn varying_len(&self) -> usize {
        self.program.varying_len()
    }

    /// True if the program has no instructions (no quantities).
    pub fn is_empty(&self) -> bool {
        self.program.whole().is_empty()
    }

    /// Evaluates the quantities at `points` and time `t` in batches of [`BATCH`] points, calling
    /// `each(offset, columns)` for the batch starting at `points[offset]` (in order).
    pub fn for_batches(
        &self,
        points: &[[f64; D]],
        t: f64,
        mut each: impl FnMut(usize, &Columns<'_, D>),
    ) {
        self.program.for_batches(points, t, |offset, outputs| {
            each(
                offset,
                &Columns {
                    program: self,
                    outputs,
                },
            )
        });
    }
    /// As [`QuantityProgram::for_batches`] at several times: for each batch in order, the
    /// quantities at `times[0]`, `times[1]`, … in turn, `each(offset, time_index, columns)`
    /// ([`SplitProgram::for_batches_at_times`]: bitwise the values at each time alone, the
    /// time-independent values read once for all the times).
    pub fn for_batches_at_times(
        &self,
        points: &[[f64; D]],
        times: &[f64],
        mut each: impl FnMut(usize, usize, &Columns<'_, D>),
    ) {
        self.program
            .for_batches_at_times(points, times, |offset, time_index, outputs| {
                each(
                    offset,
                    time_index,
                    &Columns {
                        program: self,
                        outputs,
                    },
                )
            });
    }
}

/// The quantities of the body force f0 = −Div σ (chain rule through the laws).
pub fn body_force_quantities<const D: usize>() -> Vec<Quantity> {
    let mut q = gradients::<D>();
    for i in 0..D {
        for j in 0..D {
            for k in 0..D {
                q.push(Quantity::Hessian(i, j, k));
                q.push(Quantity::RateHessian(i, j, k));
            }
        }
    }
    q.push(Quantity::Damage);
    q.extend((0..D).map(Quantity::DamageGradient));
    q
}

/// The quantities of the tractions σν (f2) and f3 on Γ3.
pub fn boundary_quantities<const D: usize>() -> Vec<Quantity> {
    let mut q = gradients::<D>();
    q.extend((0..D).map(Quantity::U));
    q.extend((0..D).map(Quantity::Rate));
    q.extend((0..D).map(Quantity::StickTraction));
    q.extend([Quantity::Damage, Quantity::Gap]);
    q
}

/// The quantities of the damage supply q = β̇ − κΔβ + η − φ(ε(u), β).
pub fn supply_quantities<const D: usize>() -> Vec<Quantity> {
    let mut q: Vec<Quantity> = (0..D)
        .flat_map(|i| (0..D).map(move |j| Quantity::Gradient(i, j)))
        .collect();
    q.extend([
        Quantity::Damage,
        Quantity::DamageRate,
        Quantity::DamageLaplacian,
        Quantity::Multiplier,
    ]);
    q
}

/// The quantities of f0 and q together ([`body_force_quantities`] and
/// [`supply_quantities`]): the solver evaluates both at the same points, one after the other.
pub fn bulk_quantities<const D: usize>() -> Vec<Quantity> {
    let mut q = body_force_quantities::<D>();
    q.extend([
        Quantity::DamageRate,
        Quantity::DamageLaplacian,
        Quantity::Multiplier,
    ]);
    q
}

/// The quantities of the damage flux κ∇β·ν.
pub fn flux_quantities<const D: usize>() -> Vec<Quantity> {
    (0..D).map(Quantity::DamageGradient).collect()
}

/// The quantities of the error integrals: ∇u, ∇u̇, β, ∇β.
pub fn error_quantities<const D: usize>() -> Vec<Quantity> {
    let mut q = gradients::<D>();
    q.push(Quantity::Damage);
    q.extend((0..D).map(Quantity::DamageGradient));
    q
}

/// ∇u and ∇u̇.
fn gradients<const D: usize>() -> Vec<Quantity> {
    let mut q = Vec::new();
    for i in 0..D {
        for j in 0..D {
            q.push(Quantity::Gradient(i, j));
            q.push(Quantity::RateGradient(i, j));
        }
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantity_indices_are_dense_and_distinct() {
        let mut all = Vec::new();
        for i in 0..3 {
            all.extend([
                Quantity::U(i),
                Quantity::Rate(i),
                Quantity::DamageGradient(i),
                Quantity::StickTraction(i),
            ]);
            for j in 0..3 {
                all.extend([Quantity::Gradient(i, j), Quantity::RateGradient(i, j)]);
                for k in 0..3 {
                    all.extend([Quantity::Hessian(i, j, k), Quantity::RateHessian(i, j, k)]);
                }
            }
        }
        all.extend([
            Quantity::Damage,
            Quantity::DamageRate,
            Quantity::DamageLaplacian,
            Quantity::Multiplier,
            Quantity::Gap,
        ]);
        let mut indices: Vec<usize> = all.iter().map(|q| q.index()).collect();
        indices.sort_unstable();
        assert_eq!(indices, (0..QUANTITIES).collect::<Vec<_>>());
    }
}
