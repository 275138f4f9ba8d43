//! The exact fields of a case and every derivative the manufactured data and the error
//! integrals use — u, u̇, ∇u, ∇u̇, ∇²u, ∇²u̇, β, β̇, ∇β, Δβ, ξ, η and g — differentiated
//! symbolically and compiled ONCE per case ([`crate::expr::Tape`]), then evaluated over batches
//! of points on `f64` columns ([`crate::expr::Program::eval_batch`]).
//!
//! Why symbolic differentiation rather than dual numbers in batches: see
//! [`crate::expr::derivative`]. Each consumer gets its own program with only the quantities it
//! reads (dead code removed): f0 needs the second derivatives, the boundary data and the errors
//! only first derivatives, the damage flux only ∇β.

use super::ExactSolution;
use crate::expr::compiled::with_registers;
use crate::expr::derivative::Value;
use crate::expr::{Program, Tape};

/// Slot of time in the variables (x, y, z, t).
const TIME: usize = 3;

/// Points per batch of a program evaluation (the register file of a program of a few hundred
/// instructions then stays in the L2 cache).
pub const BATCH: usize = 128;

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
#[derive(Debug, Clone)]
pub struct QuantityProgram<const D: usize> {
    program: Program,
    quantities: Vec<Quantity>,
}

/// Columns of the quantities at the points of one batch.
pub struct Columns<'a, const D: usize> {
    program: &'a QuantityProgram<D>,
    registers: &'a [f64],
    count: usize,
}

impl<const D: usize> Columns<'_, D> {
    /// The values of `quantity` at the points of the batch.
    ///
    /// # Panics
    /// If the program was not compiled with `quantity` (a programming error).
    pub fn get(&self, quantity: Quantity) -> &[f64] {
        let k = self
            .program
            .quantities
            .iter()
            .position(|&q| q == quantity)
            .unwrap_or_else(|| panic!("{quantity:?} was not compiled"));
        self.program
            .program
            .batch_output(self.registers, self.count, k)
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
        Self {
            program: tape.compile(&outputs),
            quantities: quantities.to_vec(),
        }
    }

    /// Number of instructions.
    pub fn len(&self) -> usize {
        self.program.len()
    }

    /// True if the program has no instructions (no quantities).
    pub fn is_empty(&self) -> bool {
        self.program.is_empty()
    }

    /// Evaluates the quantities at `points` and time `t` in batches of [`BATCH`] points, calling
    /// `each(offset, columns)` for the batch starting at `points[offset]` (in order).
    pub fn for_batches(
        &self,
        points: &[[f64; D]],
        t: f64,
        mut each: impl FnMut(usize, &Columns<'_, D>),
    ) {
        with_registers(|registers: &mut Vec<f64>| {
            let mut inputs = [[0.0; BATCH]; 4];
            inputs[TIME] = [t; BATCH];
            for (batch, chunk) in points.chunks(BATCH).enumerate() {
                let count = chunk.len();
                for (p, x) in chunk.iter().enumerate() {
                    for (j, &xj) in x.iter().enumerate() {
                        inputs[j][p] = xj;
                    }
                }
                let columns: [&[f64]; 4] = std::array::from_fn(|v| &inputs[v][..count]);
                self.program.eval_batch(&columns, count, registers);
                each(
                    batch * BATCH,
                    &Columns {
                        program: self,
                        registers,
                        count,
                    },
                );
            }
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
