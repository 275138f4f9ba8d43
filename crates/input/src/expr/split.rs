//! Programs split by their dependence on time, with the time-independent part cached per
//! point: loop-invariant code motion over the time steps.
//!
//! Why: the data of a case are evaluated at the same quadrature points at every time step,
//! and most of their instructions do not depend on t: in `0.05*x*y*(1+t) + 0.5*t*max(0,
//! x − 0.6)⁴*(1+y)` and its derivatives the powers of the join, the products in x and y and
//! every `sin`/`cos` of a coordinate are the same at every step. A [`SplitProgram`] is the
//! [`Program`] cut in three:
//!
//! - the **invariant** part: every instruction that does not depend on the time variable,
//!   whose outputs are the *frontier*, the invariant registers that a time-dependent
//!   instruction of the varying part reads or that are outputs themselves (constants and
//!   variables excepted: they cost nothing to recompute);
//! - the **uniform** part: the instructions that depend on time but not on the coordinates
//!   (`1 + t`, `t*(0.3 + 0.2*t)` and their derivatives in t), whose values are the same at
//!   every point: evaluated once per time, on one lane, and handed to the varying part as
//!   columns filled once per call for all its batches. In the data of `zones2d` they are 13
//!   of the 48 time-dependent instructions of f0 and q and 8 of the 28 of the error
//!   integrals (`bench_programs`: f0 and q 17.8 → 14.7 ns per point and time, 8 times per
//!   call, 196 608 points);
//! - the **varying** part: the instructions that depend on time and on the coordinates,
//!   reading the frontier and the uniform values as extra variables after the program's own.
//!
//! Each instruction of the uniform and varying parts is the original instruction on the same
//! operand values, so the outputs are bitwise those of the whole program (evaluated
//! batch-wise, [`super::batch`]).
//!
//! [`SplitProgram::for_batches`] evaluates the invariant part once per set of points and keeps
//! its frontier columns in a cache keyed by the slice of points (its address, length, first and
//! last point); a hit is confirmed by comparing every coordinate, so points that changed in
//! place, or a key collision, cost only an evaluation of the whole program.
//! The caller need not say which points repeat: the finite-element code passes the same
//! quadrature points of a chunk of cells at every step. The cache holds at most the byte
//! budget given at construction; points beyond it are evaluated with the whole program, so
//! the budget bounds memory, never correctness.

use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, RwLock};

use super::batch::Inputs;
use super::compiled::{with_registers, Builder, Instruction, Program, Register};

/// Points per batch of an evaluation: the dispatch on an instruction and the lookup of its
/// operand columns are paid once per batch, and each instruction is a loop of `BATCH / 4`
/// AVX2 operations; the register file of the time-dependent part of a program of about 60
/// instructions (128 × 60 × 8 bytes = 60 KiB) stays in the L2 cache. The values do not depend
/// on the batch: every point gets the operations of the point-by-point evaluation.
///
/// Measured on `zones2d` at 128 cells, k = h, one thread (`bench_harness` and a probe of its
/// run, interleaved with a build of 32 points per batch on a 2-core AMD EPYC of family 26,
/// Zen 5, 48 KiB L1d and 1 MiB L2 per core): data + errors 1.10 / 1.16 s with 32 points per batch,
/// 0.94 / 0.94 s with 128 (data 0.52 / 0.55 → 0.43 / 0.43 s, errors 0.57 / 0.61 → 0.51 /
/// 0.51 s); in probe pairs data 0.53–0.56 s with 32, 0.45–0.52 with 64, 0.39–0.46 with 128,
/// 0.42 with 256. `simulate`'s 128² run is the same with 32 or 128 (1.61–1.67 s fastest in
/// three pairs). Without the AVX2 loop and the evaluation at several times per call, 32 is the
/// faster (data 3.11 s with 128 points per batch, 2.26 s with 32); a separate comparison found
/// 64 within the noise of 32.
pub const BATCH: usize = 128;

/// A [`Program`] split into its time-independent and time-dependent parts, with a cache of the
/// time-independent values per set of points.
#[derive(Debug)]
pub struct SplitProgram {
    /// The whole program: the reference, and the evaluation beyond the cache budget.
    whole: Program,
    /// The instructions that do not depend on time; outputs = the frontier.
    invariant: Program,
    /// The instructions that depend on time only; outputs = the uniform values.
    uniform: Program,
    /// The instructions that depend on time and on the coordinates; variables = those of
    /// `whole`, then the frontier values, then the uniform values.
    varying: Program,
    /// The output columns of `whole` and of `varying` ([`BatchOutputs::get`]).
    whole_columns: Vec<OutputColumn>,
    varying_columns: Vec<OutputColumn>,
    /// Slot of the time variable.
    time: usize,
    cache: PointCache,
}

/// Frontier columns of the points sets seen, by the hash of their coordinates.
#[derive(Debug, Default)]
struct PointCache {
    entries: RwLock<HashMap<u64, Arc<Entry>>>,
    /// Bytes held by `entries`.
    bytes: AtomicUsize,
    /// Most bytes `entries` may hold.
    budget: usize,
}

/// One set of points: its coordinates (to confirm a hit) and, batch after batch of
/// [`BATCH`] points, the frontier columns (`frontier × count` values per batch).
#[derive(Debug)]
struct Entry {
    coordinates: Vec<u8>,
    frontier: Vec<f64>,
}

/// Which program produced the outputs of a batch (see [`BatchOutputs::get`]).
pub struct BatchOutputs<'a> {
    /// Where each output of the program that ran is.
    columns: &'a [OutputColumn],
    registers: &'a [f64],
    count: usize,
    /// The program's input columns: an output that is a variable is read from there (its
    /// register is not written).
    inputs: Inputs<'a>,
}

impl BatchOutputs<'_> {
    /// The `count` values of output `k` at the points of the batch.
    pub fn get(&self, k: usize) -> &[f64] {
        match self.columns[k] {
            OutputColumn::Register(register) => {
                &self.registers[register * self.count..][..self.count]
            }
            OutputColumn::Variable(slot) => self.inputs.column(slot, self.count),
        }
    }

    /// Number of points of the batch.
    pub fn count(&self) -> usize {
        self.count
    }
}

/// Where an output of a program is after a batch evaluation without copies of the variables:
/// in the register file, or in the column of a variable (its register is not written).
#[derive(Debug, Clone, Copy)]
enum OutputColumn {
    Register(usize),
    Variable(usize),
}

/// The [`OutputColumn`] of each output of `program`, in order.
fn output_columns(program: &Program) -> Vec<OutputColumn> {
    program
        .outputs
        .iter()
        .map(|&register| match program.instructions[register as usize] {
            Instruction::Variable(slot) => OutputColumn::Variable(slot),
            _ => OutputColumn::Register(register as usize),
        })
        .collect()
}

/// Per instruction (in dependency order): whether its value depends on a variable whose slot
/// satisfies `reads`.
fn depends_on(instructions: &[Instruction], reads: impl Fn(usize) -> bool) -> Vec<bool> {
    let mut depends = vec![false; instructions.len()];
    for (index, instruction) in instructions.iter().enumerate() {
        depends[index] = matches!(instruction, Instruction::Variable(slot) if reads(*slot))
            || instruction.operands().any(|r| depends[r as usize]);
    }
    depends
}

/// A clone shares the compiled parts, not the cache: it starts empty, with the same budget.
impl Clone for SplitProgram {
    fn clone(&self) -> SplitProgram {
        SplitProgram {
            whole: self.whole.clone(),
            invariant: self.invariant.clone(),
            uniform: self.uniform.clone(),
            varying: self.varying.clone(),
            whole_columns: self.whole_columns.clone(),
            varying_columns: self.varying_columns.clone(),
            time: self.time,
            cache: PointCache {
                budget: self.cache.budget,
                ..PointCache::default()
            },
        }
    }
}

impl SplitProgram {
    /// Splits `program` by its dependence on variable `time`; the cache of time-independent
    /// values holds at most `cache_bytes` bytes.
    ///
    /// # Panics
    /// If `time` is not a variable of the program (a programming error).
    pub fn new(program: Program, time: usize, cache_bytes: usize) -> SplitProgram {
        assert!(time < program.variables, "SplitProgram::new: time slot");
        let instructions = &program.instructions;
        let count = instructions.len();
        let varies = depends_on(instructions, |slot| slot == time);
        // Depends on a coordinate (a variable other than time).
        let spatial = depends_on(instructions, |slot| slot != time);
        let per_point = |r: usize| varies[r] && spatial[r];
        // What the varying part reads from the other two, or gives out as it is.
        let mut needed = vec![false; count];
        for (index, instruction) in instructions.iter().enumerate() {
            if per_point(index) {
                for operand in instruction.operands() {
                    needed[operand as usize] |= !per_point(operand as usize);
                }
            }
        }
        for &output in &program.outputs {
            needed[output as usize] |= !per_point(output as usize);
        }
        // Constants and variables (time among them) are recomputed or read where they are.
        let handed_over = |r: Register| {
            needed[r as usize]
                && !matches!(
                    instructions[r as usize],
                    Instruction::Constant(_) | Instruction::Variable(_)
                )
        };
        let frontier: Vec<Register> = (0..count as Register)
            .filter(|&r| handed_over(r) && !varies[r as usize])
            .collect();
        let uniforms: Vec<Register> = (0..count as Register)
            .filter(|&r| handed_over(r) && varies[r as usize])
            .collect();
        let invariant = Builder::from_instructions(instructions.clone())
            .finish(frontier.clone(), program.variables);
        let uniform = Builder::from_instructions(instructions.clone())
            .finish(uniforms.clone(), program.variables);
        // Same positions, frontier and uniform registers replaced by variables: no
        // renumbering needed before dead-code removal.
        let mut varying = instructions.clone();
        for (k, &register) in frontier.iter().chain(&uniforms).enumerate() {
            varying[register as usize] = Instruction::Variable(program.variables + k);
        }
        let varying = Builder::from_instructions(varying).finish(
            program.outputs.clone(),
            program.variables + frontier.len() + uniforms.len(),
        );
        SplitProgram {
            whole_columns: output_columns(&program),
            varying_columns: output_columns(&varying),
            whole: program,
            invariant,
            uniform,
            varying,
            time,
            cache: PointCache {
                budget: cache_bytes,
                ..PointCache::default()
            },
        }
    }

    /// The whole program.
    pub fn whole(&self) -> &Program {
        &self.whole
    }

    /// Number of time-independent values kept per point.
    pub fn frontier_len(&self) -> usize {
        self.invariant.outputs.len()
    }

    /// Instructions of the time-dependent part run at every point (at every evaluation).
    pub fn varying_len(&self) -> usize {
        self.varying.len()
    }

    /// Values that depend on time only, computed once per time of an evaluation.
    pub fn uniform_len(&self) -> usize {
        self.uniform.outputs.len()
    }

    /// Bytes held by the cache.
    pub fn cached_bytes(&self) -> usize {
        self.cache.bytes.load(Ordering::Relaxed)
    }

    /// Evaluates the outputs at `points` (their coordinates fill the first `D` variables, the
    /// other variables but time are 0) and time `t`, in batches of [`BATCH`] points, calling
    /// `each(offset, outputs)` for the batch starting at `points[offset]`, in order.
    ///
    /// # Panics
    /// If the program has fewer than `D + 1` variables, or more than 4.
    pub fn for_batches<const D: usize>(
        &self,
        points: &[[f64; D]],
        t: f64,
        mut each: impl FnMut(usize, &BatchOutputs<'_>),
    ) {
        self.for_batches_at_times(points, &[t], |offset, _, outputs| each(offset, outputs))
    }

    /// As [`SplitProgram::for_batches`] at several times: for each batch of points in order,
    /// the outputs at `times[0]`, `times[1]`, … in turn, `each(offset, time_index, outputs)`.
    /// The outputs at each time are bitwise those of [`SplitProgram::for_batches`] at that
    /// time; the time-independent values of a batch are read from memory once for all the
    /// times (they stay in the L1 or L2 cache between them).
    ///
    /// # Panics
    /// If the program has fewer than `D + 1` variables, or more than 4.
    pub fn for_batches_at_times<const D: usize>(
        &self,
        points: &[[f64; D]],
        times: &[f64],
        mut each: impl FnMut(usize, usize, &BatchOutputs<'_>),
    ) {
        let variables = self.whole.variables;
        assert!(D < variables && variables <= 4, "SplitProgram: variables");
        let entry = self.cached(points);
        let frontier = self.frontier_len();
        // With the cache: the uniform values at each time, each as a column of BATCH copies,
        // time after time.
        let uniform_columns = match entry {
            Some(_) => self.uniform_columns(times),
            None => Vec::new(),
        };
        let uniforms = self.uniform_len() * BATCH;
        with_registers(|registers: &mut Vec<f64>| {
            let mut inputs = [[0.0; BATCH]; 4];
            for (batch, chunk) in points.chunks(BATCH).enumerate() {
                let count = chunk.len();
                fill_coordinates(&mut inputs, chunk);
                let offset = batch * BATCH;
                // Outputs that are variables are read from their columns, not copied.
                let (program, output_columns, block) = match &entry {
                    Some(entry) => {
                        let cached = &entry.frontier[offset * frontier..][..count * frontier];
                        (&self.varying, &self.varying_columns, cached)
                    }
                    None => (&self.whole, &self.whole_columns, &[][..]),
                };
                for (time_index, &t) in times.iter().enumerate() {
                    inputs[self.time] = [t; BATCH];
                    let direct: [&[f64]; 4] = std::array::from_fn(|v| &inputs[v][..count]);
                    let mut columns = Inputs::new(&direct[..variables], block, count);
                    if entry.is_some() {
                        columns = columns.with_uniforms(
                            &uniform_columns[time_index * uniforms..][..uniforms],
                            BATCH,
                        );
                    }
                    program.eval_batch_columns(&columns, count, registers, false);
                    each(
                        offset,
                        time_index,
                        &BatchOutputs {
                            columns: output_columns,
                            registers,
                            count,
                            inputs: columns,
                        },
                    );
                }
            }
        });
    }

    /// The uniform values at each of `times`, each as a column of [`BATCH`] copies (the
    /// uniform part evaluated on one lane per time, the coordinates 0: it reads none).
    fn uniform_columns(&self, times: &[f64]) -> Vec<f64> {
        let uniforms = self.uniform_len();
        let mut columns = Vec::with_capacity(times.len() * uniforms * BATCH);
        if uniforms == 0 {
            return columns;
        }
        with_registers(|registers: &mut Vec<f64>| {
            for &t in times {
                let mut lane = [[0.0]; 4];
                lane[self.time] = [t];
                let direct: [&[f64]; 4] = std::array::from_fn(|v| &lane[v][..]);
                self.uniform
                    .eval_batch(&direct[..self.whole.variables], 1, registers);
                for k in 0..uniforms {
                    let value = self.uniform.batch_output(registers, 1, k)[0];
                    columns.extend(std::iter::repeat_n(value, BATCH));
                }
            }
        });
        columns
    }

    /// The cached frontier of `points`, computed now if they are new and the budget allows;
    /// None beyond the budget.
    fn cached<const D: usize>(&self, points: &[[f64; D]]) -> Option<Arc<Entry>> {
        // The coordinates as bytes: a hit is confirmed bit for bit (one memcmp).
        let coordinates: &[u8] = bytemuck::cast_slice(points);
        // The key names the slice (address, length, first and last point): the finite-element
        // code passes the same slices of its quadrature points at every step.
        let mut hasher = rustc_hash::FxHasher::default();
        (points.as_ptr() as usize, points.len()).hash(&mut hasher);
        for x in points.first().into_iter().chain(points.last()).flatten() {
            x.to_bits().hash(&mut hasher);
        }
        let key = hasher.finish();
        let same = |entry: &Entry| entry.coordinates == coordinates;
        if let Some(entry) = self.cache.entries.read().ok()?.get(&key) {
            return same(entry).then(|| entry.clone());
        }
        let frontier = self.frontier_len();
        let bytes = points.len() * (frontier + D) * std::mem::size_of::<f64>();
        let held = self.cache.bytes.fetch_add(bytes, Ordering::Relaxed);
        if held + bytes > self.cache.budget {
            self.cache.bytes.fetch_sub(bytes, Ordering::Relaxed);
            return None;
        }
        let mut values = Vec::with_capacity(points.len() * frontier);
        with_registers(|registers: &mut Vec<f64>| {
            let mut inputs = [[0.0; BATCH]; 4];
            for chunk in points.chunks(BATCH) {
                let count = chunk.len();
                fill_coordinates(&mut inputs, chunk);
                let columns: [&[f64]; 4] = std::array::from_fn(|v| &inputs[v][..count]);
                self.invariant
                    .eval_batch(&columns[..self.whole.variables], count, registers);
                for k in 0..frontier {
                    values.extend_from_slice(self.invariant.batch_output(registers, count, k));
                }
            }
        });
        let entry = Arc::new(Entry {
            coordinates: coordinates.to_vec(),
            frontier: values,
        });
        let mut entries = self.cache.entries.write().ok()?;
        match entries.get(&key) {
            // Another thread was first (or a collision): keep the first, give back the bytes.
            Some(first) => {
                self.cache.bytes.fetch_sub(bytes, Ordering::Relaxed);
                same(first).then(|| first.clone())
            }
            None => {
                entries.insert(key, entry.clone());
                Some(entry)
            }
        }
    }
}

/// The coordinates of `chunk` into the first `D` input columns.
fn fill_coordinates<const D: usize>(inputs: &mut [[f64; BATCH]; 4], chunk: &[[f64; D]]) {
    for (p, x) in chunk.iter().enumerate() {
        for (j, &xj) in x.iter().enumerate() {
            inputs[j][p] = xj;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Expr;

    fn program(sources: &[&str]) -> Program {
        let parsed: Vec<Expr> = sources
            .iter()
            .map(|s| Expr::parse(s, &["x", "y", "z", "t"], &Default::default()).unwrap())
            .collect();
        Program::fuse(&parsed.iter().collect::<Vec<_>>())
    }

    fn points(count: usize) -> Vec<[f64; 2]> {
        (0..count)
            .map(|p| [0.013 * p as f64, 1.0 - 0.007 * p as f64])
            .collect()
    }

    /// All outputs at `points` and `t`, output-major.
    fn outputs(split: &SplitProgram, points: &[[f64; 2]], t: f64) -> Vec<Vec<u64>> {
        let mut values = vec![Vec::new(); split.whole().output_count()];
        split.for_batches(points, t, |_, batch| {
            for (k, column) in values.iter_mut().enumerate() {
                column.extend(batch.get(k).iter().map(|v| v.to_bits()));
            }
        });
        values
    }

    #[test]
    fn only_time_dependent_instructions_run_at_each_step() {
        let split = SplitProgram::new(
            program(&["sin(pi*x)*cos(pi*y)*(1 + t)", "max(0, x - 0.6)^4*t^2"]),
            3,
            1 << 20,
        );
        // sin(πx)·cos(πy) and max(0, x − 0.6)⁴ are the frontier.
        assert_eq!(split.frontier_len(), 2);
        assert!(split.varying_len() < split.whole().len());
        assert!(!split
            .varying
            .instructions
            .iter()
            .any(|i| matches!(i, Instruction::Apply(..) | Instruction::Max(..))));
    }

    #[test]
    fn time_only_values_are_computed_once_per_time() {
        let split = SplitProgram::new(
            program(&["sin(pi*x)*(1 + t)", "max(0, x - 0.6)^4*t^2", "exp(-t)"]),
            3,
            1 << 20,
        );
        // 1 + t, t² and the output exp(−t): uniform values, not instructions per point.
        assert_eq!(split.uniform_len(), 3);
        // Per point, only the two products of a frontier value and a uniform one.
        let computed = |program: &Program| {
            program
                .instructions
                .iter()
                .filter(|i| !matches!(i, Instruction::Variable(_) | Instruction::Constant(_)))
                .count()
        };
        assert_eq!(computed(&split.varying), 2);
        assert_eq!(computed(&split.uniform), 4);
    }

    #[test]
    fn cached_evaluation_is_bitwise_the_whole_program() {
        let sources = [
            "sin(pi*x)*cos(pi*y)*(1 + t)",
            "0.05*x*y*(1+t) + 0.5*t*max(0, x - 0.6)^4*(1+y)",
            "x^2 + y",
            "exp(-t)",
            "3",
        ];
        let split = SplitProgram::new(program(&sources), 3, 1 << 20);
        let whole = SplitProgram::new(program(&sources), 3, 0);
        // Two full batches and a partial one.
        let points = points(2 * BATCH + 44);
        for t in [0.0, 0.25, 1.0] {
            // First call fills the cache, the second reads it; the budget-0 one never caches.
            for _ in 0..2 {
                assert_eq!(outputs(&split, &points, t), outputs(&whole, &points, t));
            }
        }
        assert!(split.cached_bytes() > 0);
        assert_eq!(whole.cached_bytes(), 0);
    }

    #[test]
    fn several_times_at_once_are_bitwise_each_time_alone() {
        let sources = [
            "sin(pi*x)*cos(pi*y)*(1 + t)",
            "0.05*x*y*(1+t) + 0.5*t*max(0, x - 0.6)^4*(1+y)",
            "exp(-t)*x",
        ];
        let times = [0.0, 0.125, 0.25, 1.0];
        // Three full batches and a partial one; cached and uncached.
        let points = points(3 * BATCH + 4);
        for budget in [1 << 20, 0] {
            let split = SplitProgram::new(program(&sources), 3, budget);
            let mut at_times = vec![vec![Vec::new(); split.whole().output_count()]; times.len()];
            let mut seen = Vec::new();
            split.for_batches_at_times(&points, &times, |offset, at, batch| {
                seen.push((offset, at));
                for (k, column) in at_times[at].iter_mut().enumerate() {
                    column.extend(batch.get(k).iter().map(|v| v.to_bits()));
                }
            });
            // Batch after batch, the times in order within each batch.
            let expected: Vec<(usize, usize)> = (0..4)
                .flat_map(|batch| (0..times.len()).map(move |at| (batch * BATCH, at)))
                .collect();
            assert_eq!(seen, expected);
            for (at, &t) in times.iter().enumerate() {
                assert_eq!(at_times[at], outputs(&split, &points, t), "t = {t}");
            }
        }
    }

    #[test]
    fn other_points_with_the_same_count_are_not_mistaken_for_cached_ones() {
        let split = SplitProgram::new(program(&["sin(pi*x)*(1 + t)"]), 3, 1 << 20);
        let first = points(50);
        let mut second = first.clone();
        second[17][0] += 1e-9;
        let a = outputs(&split, &first, 0.5);
        let b = outputs(&split, &second, 0.5);
        assert_ne!(a[0][17], b[0][17]);
        assert_eq!(a[0][16], b[0][16]);
    }

    #[test]
    fn the_budget_bounds_the_cache() {
        let split = SplitProgram::new(program(&["sin(pi*x)*(1 + t)"]), 3, 3000);
        // 100 points × (1 frontier + 2 coordinates) × 8 bytes = 2400 bytes: one set fits.
        outputs(&split, &points(100), 0.5);
        assert_eq!(split.cached_bytes(), 2400);
        let more: Vec<[f64; 2]> = points(100).iter().map(|x| [x[0], x[1] + 1.0]).collect();
        let reference = SplitProgram::new(program(&["sin(pi*x)*(1 + t)"]), 3, 0);
        assert_eq!(outputs(&split, &more, 0.5), outputs(&reference, &more, 0.5));
        assert_eq!(split.cached_bytes(), 2400);
    }
}
