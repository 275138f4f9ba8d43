//! Batched evaluation of a [`Program`] on `f64`: instruction-major over structure-of-arrays
//! columns, so that the dispatch on the instruction kind is paid once per instruction and
//! batch, and each instruction is a tight loop over the points of the batch.
//!
//! The register file holds one column of `count` values per instruction (register `i` is
//! `registers[i·count .. (i+1)·count]`); it is the caller's buffer, reused between batches
//! (e.g. a per-thread buffer from [`super::compiled::with_registers`]). Each point gets exactly
//! the operations of [`Program::eval_into`] on `f64`, so the results are bitwise those of the
//! point-by-point evaluation.

use super::compiled::{Instruction, Program};
use super::tree::{maximum, minimum, picks_first, positive_power, UnaryFunction};

impl Program {
    /// Evaluate at `count` points; `inputs[v]` holds the `count` values of variable `v`.
    /// Output `k` is then [`Program::batch_output`]`(registers, count, k)`.
    ///
    /// # Panics
    /// If `inputs` does not have one column of `count` values per variable.
    pub fn eval_batch(&self, inputs: &[&[f64]], count: usize, registers: &mut Vec<f64>) {
        self.eval_batch_with_block(inputs, &[], count, registers)
    }

    /// As [`Program::eval_batch`], with the variables after the first `inputs.len()` taken
    /// from `block`, one column of `count` values after the other (variable
    /// `inputs.len() + k` is `block[k·count .. (k+1)·count]`): the cached frontier of a
    /// [`super::SplitProgram`].
    ///
    /// # Panics
    /// If `inputs` and `block` do not hold one column of `count` values per variable.
    pub fn eval_batch_with_block(
        &self,
        inputs: &[&[f64]],
        block: &[f64],
        count: usize,
        registers: &mut Vec<f64>,
    ) {
        let columns = Inputs::new(inputs, block, count);
        self.eval_batch_columns(&columns, count, registers, true)
    }

    /// [`Program::eval_batch_with_block`] on the variables `inputs`; with
    /// `copy_output_variables` false the registers of outputs that are variables are left
    /// unwritten, for a caller that reads those outputs from their input columns
    /// (`super::split::BatchOutputs`).
    pub(super) fn eval_batch_columns(
        &self,
        inputs: &Inputs<'_>,
        count: usize,
        registers: &mut Vec<f64>,
        copy_output_variables: bool,
    ) {
        let path = batch_path();
        #[cfg(test)]
        tests::LAST_PATH.with(|last| last.set(Some(path)));
        match path {
            // SAFETY: `batch_path` is `Avx2` only where the processor has AVX2.
            #[cfg(target_arch = "x86_64")]
            BatchPath::Avx2 => unsafe {
                self.eval_columns_avx2(inputs, count, registers, copy_output_variables)
            },
            _ => self.eval_columns(inputs, count, registers, copy_output_variables),
        }
    }

    /// [`Program::eval_batch_columns`] compiled for AVX2: the loops over a column take four
    /// values per instruction instead of the two of the x86-64 baseline (SSE2). The same
    /// operations lane by lane (no fused multiply–add: Rust never contracts `a * b + c`), so
    /// bitwise the same values.
    ///
    /// # Safety
    /// The processor must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn eval_columns_avx2(
        &self,
        inputs: &Inputs<'_>,
        count: usize,
        registers: &mut Vec<f64>,
        copy_output_variables: bool,
    ) {
        self.eval_columns(inputs, count, registers, copy_output_variables)
    }

    /// [`Program::eval_batch_columns`] for the target features of its caller.
    #[inline(always)]
    pub(super) fn eval_columns(
        &self,
        inputs: &Inputs<'_>,
        count: usize,
        registers: &mut Vec<f64>,
        copy_output_variables: bool,
    ) {
        assert_eq!(
            inputs.variables(),
            self.variables,
            "Program::eval_batch: variables"
        );
        assert!(
            inputs.direct.iter().all(|column| column.len() == count)
                && inputs.block.len() == inputs.block_columns * count
                && inputs.uniform_stride >= count
                && inputs.uniforms.len() % inputs.uniform_stride == 0,
            "Program::eval_batch: every input column has `count` values"
        );
        // Every register is written before it is read: grow, never clear.
        if registers.len() < self.instructions.len() * count {
            registers.resize(self.instructions.len() * count, 0.0);
        }
        for (index, instruction) in self.instructions.iter().enumerate() {
            let (done, rest) = registers.split_at_mut(index * count);
            let out = &mut rest[..count];
            // A variable's register is read from its input column directly (no copy).
            // Functions rather than closures: a closure is compiled on its own, without the
            // caller's target features, and was not inlined into the AVX2 loop (12% of the
            // evaluation in `bench_programs`).
            let column = |slot: usize| inputs.column(slot, count);
            let instructions = &self.instructions;
            let r = |register: u32| operand_column(instructions, inputs, done, count, register);
            match *instruction {
                Instruction::Constant(bits) => out.fill(f64::from_bits(bits)),
                Instruction::Variable(slot) => {
                    // Copied only where it is an output (read from the registers).
                    if copy_output_variables && self.output_variables[index] {
                        out.copy_from_slice(column(slot))
                    }
                }
                Instruction::Negate(a) => {
                    for (o, &x) in out.iter_mut().zip(r(a)) {
                        *o = -x;
                    }
                }
                Instruction::Add(a, b) => {
                    for ((o, &x), &y) in out.iter_mut().zip(r(a)).zip(r(b)) {
                        *o = x + y;
                    }
                }
                Instruction::Subtract(a, b) => {
                    for ((o, &x), &y) in out.iter_mut().zip(r(a)).zip(r(b)) {
                        *o = x - y;
                    }
                }
                Instruction::Multiply(a, b) => {
                    for ((o, &x), &y) in out.iter_mut().zip(r(a)).zip(r(b)) {
                        *o = x * y;
                    }
                }
                Instruction::Divide(a, b) => {
                    for ((o, &x), &y) in out.iter_mut().zip(r(a)).zip(r(b)) {
                        *o = x / y;
                    }
                }
                Instruction::AddConstant(a, c) => {
                    let c = f64::from_bits(c);
                    for (o, &x) in out.iter_mut().zip(r(a)) {
                        *o = x + c;
                    }
                }
                Instruction::MultiplyConstant(a, c) => {
                    let c = f64::from_bits(c);
                    for (o, &x) in out.iter_mut().zip(r(a)) {
                        *o = x * c;
                    }
                }
                Instruction::SubtractConstant(a, c) => {
                    let c = f64::from_bits(c);
                    for (o, &x) in out.iter_mut().zip(r(a)) {
                        *o = x - c;
                    }
                }
                Instruction::ConstantSubtract(c, a) => {
                    let c = f64::from_bits(c);
                    for (o, &x) in out.iter_mut().zip(r(a)) {
                        *o = -x + c;
                    }
                }
                Instruction::PowerInteger(a, n) => map1(out, r(a), |x| powi(x, n)),
                Instruction::PowerReal(a, bits) => {
                    let p = f64::from_bits(bits);
                    map1(out, r(a), |x| x.powf(p))
                }
                Instruction::PositivePower(a, bits) => {
                    let p = f64::from_bits(bits);
                    map1(out, r(a), |x| positive_power(x, p))
                }
                Instruction::Apply(function, a) => apply(function, out, r(a)),
                Instruction::Min(a, b) => map2(out, r(a), r(b), minimum),
                Instruction::Max(a, b) => map2(out, r(a), r(b), maximum),
                Instruction::MinSelect(a, b, x, y) => {
                    for (p, o) in out.iter_mut().enumerate() {
                        let first = picks_first(r(a)[p], r(b)[p], |a, b| a <= b);
                        *o = if first { r(x)[p] } else { r(y)[p] };
                    }
                }
                Instruction::MaxSelect(a, b, x, y) => {
                    for (p, o) in out.iter_mut().enumerate() {
                        let first = picks_first(r(a)[p], r(b)[p], |a, b| a >= b);
                        *o = if first { r(x)[p] } else { r(y)[p] };
                    }
                }
                Instruction::SignOf(a, x) => {
                    map2(out, r(a), r(x), |a, x| if a < 0.0 { -x } else { x })
                }
            }
        }
    }

    /// The `count` values of output `k` after [`Program::eval_batch`] with the same `count`.
    pub fn batch_output<'r>(&self, registers: &'r [f64], count: usize, k: usize) -> &'r [f64] {
        &registers[self.outputs[k] as usize * count..][..count]
    }
}

/// The loop of [`Program::eval_batch_columns`]: the one compiled for AVX2, or the one for the
/// x86-64 baseline (and every other processor).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum BatchPath {
    /// `Program::eval_columns_avx2`, on x86-64 processors with AVX2 (detected at run time).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    Avx2,
    /// [`Program::eval_columns`] compiled for the target's own features.
    Baseline,
}

/// The loop [`Program::eval_batch_columns`] takes on this processor.
#[inline]
pub(super) fn batch_path() -> BatchPath {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        return BatchPath::Avx2;
    }
    BatchPath::Baseline
}

/// The columns of a program's variables at the points of a batch, in the order of the
/// variables: the direct columns (`count` values each), then the columns of `block` (`count`
/// values each, one after the other: the cached frontier of a [`super::SplitProgram`]), then
/// the uniform columns (`uniform_stride` values each, of which the first `count` are read:
/// the time-only values of a [`super::SplitProgram`], the same at every point).
#[derive(Clone, Copy)]
pub(super) struct Inputs<'c> {
    pub(super) direct: &'c [&'c [f64]],
    pub(super) block: &'c [f64],
    /// Columns in `block`.
    pub(super) block_columns: usize,
    pub(super) uniforms: &'c [f64],
    pub(super) uniform_stride: usize,
}

impl<'c> Inputs<'c> {
    /// The direct columns and the block of `count`-value columns after them; no uniforms.
    pub(super) fn new(direct: &'c [&'c [f64]], block: &'c [f64], count: usize) -> Inputs<'c> {
        Inputs {
            direct,
            block,
            block_columns: block.len().checked_div(count).unwrap_or(0),
            uniforms: &[],
            uniform_stride: count.max(1),
        }
    }

    /// These columns followed by the uniform columns `uniforms`, `stride` values each.
    pub(super) fn with_uniforms(self, uniforms: &'c [f64], stride: usize) -> Inputs<'c> {
        Inputs {
            uniforms,
            uniform_stride: stride,
            ..self
        }
    }

    /// Number of variables the columns hold.
    fn variables(&self) -> usize {
        self.direct.len() + self.block_columns + self.uniforms.len() / self.uniform_stride
    }

    /// The column of variable `slot`.
    #[inline(always)]
    pub(super) fn column(&self, slot: usize, count: usize) -> &'c [f64] {
        let Some(k) = slot.checked_sub(self.direct.len()) else {
            return self.direct[slot];
        };
        match k.checked_sub(self.block_columns) {
            None => &self.block[k * count..][..count],
            Some(u) => &self.uniforms[u * self.uniform_stride..][..count],
        }
    }
}

/// The column of `register`: its input column if it is a variable, else its register.
#[inline(always)]
fn operand_column<'c>(
    instructions: &[Instruction],
    inputs: &Inputs<'c>,
    done: &'c [f64],
    count: usize,
    register: u32,
) -> &'c [f64] {
    match instructions[register as usize] {
        Instruction::Variable(slot) => inputs.column(slot, count),
        _ => &done[register as usize * count..][..count],
    }
}

/// `out[p] = f(a[p])`.
#[inline]
fn map1(out: &mut [f64], a: &[f64], f: impl Fn(f64) -> f64) {
    for (o, &x) in out.iter_mut().zip(a) {
        *o = f(x);
    }
}

/// `out[p] = f(a[p], b[p])`.
#[inline]
fn map2(out: &mut [f64], a: &[f64], b: &[f64], f: impl Fn(f64, f64) -> f64) {
    for ((o, &x), &y) in out.iter_mut().zip(a).zip(b) {
        *o = f(x, y);
    }
}

/// A function of one argument over a column, one loop per function (no dispatch per point).
fn apply(function: UnaryFunction, out: &mut [f64], a: &[f64]) {
    match function {
        UnaryFunction::Sqrt => map1(out, a, f64::sqrt),
        UnaryFunction::Exp => map1(out, a, f64::exp),
        UnaryFunction::Ln => map1(out, a, f64::ln),
        UnaryFunction::Sin => map1(out, a, f64::sin),
        UnaryFunction::Cos => map1(out, a, f64::cos),
        UnaryFunction::Tan => map1(out, a, f64::tan),
        UnaryFunction::Tanh => map1(out, a, f64::tanh),
        UnaryFunction::Abs => map1(out, a, |x| function.apply(x)),
    }
}

/// `a^n` by binary powering, the algorithm of `f64::powi` at run time (compiler-rt's
/// `__powidf2`), inlined so that the loop over a column needs no call per point: bitwise the
/// tree evaluator's `powi`.
#[inline]
fn powi(a: f64, n: i32) -> f64 {
    let reciprocal = n < 0;
    let mut base = a;
    let mut exponent = n;
    let mut result = 1.0;
    loop {
        if exponent & 1 != 0 {
            result *= base;
        }
        exponent /= 2;
        if exponent == 0 {
            break;
        }
        base *= base;
    }
    if reciprocal {
        1.0 / result
    } else {
        result
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::{powi, BatchPath};
    use std::cell::Cell;

    thread_local! {
        /// The loop the last [`super::Program::eval_batch_columns`] of this thread took.
        pub(in super::super) static LAST_PATH: Cell<Option<BatchPath>> = const { Cell::new(None) };
    }

    #[test]
    fn inlined_powers_are_bitwise_those_of_powi() {
        for n in -12..=12 {
            for a in [
                0.0,
                -0.0,
                0.3,
                -1.7,
                2.5,
                1e-3,
                123.456,
                f64::INFINITY,
                f64::NAN,
            ] {
                let (ours, std) = (powi(a, n), a.powi(std::hint::black_box(n)));
                assert!(
                    ours.to_bits() == std.to_bits() || (ours.is_nan() && std.is_nan()),
                    "{a}^{n}: {ours} vs {std}"
                );
            }
        }
    }
}
