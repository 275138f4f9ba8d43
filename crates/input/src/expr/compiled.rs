//! Compiled expressions: the syntax tree of an [`Expr`] turned once into a [`Program`], a flat
//! list of SSA instructions over a register file, which is what is evaluated at every
//! quadrature point.
//!
//! Why: the exact fields of a case are evaluated at every quadrature point of every step.
//! Walking the tree repeats identical subtrees (`max(0, x - x_slip)` in several terms, `1 + t`,
//! `cos(pi*y)`, …) and pays a recursive call per node. The program computes every distinct
//! subexpression once. Besides the node kinds of the tree, three selection instructions
//! (`MinSelect`, `MaxSelect`, `SignOf`) carry the derivatives of `min`, `max` and `abs`.
//!
//! - **Instructions** mirror the node kinds of the tree one to one, with the same semantics
//!   (branch rules of `abs`/`min`/`max` by real part, NaN propagation, `powi`/`powf` for
//!   constant exponents); the variable power `a^b` is lowered to its definition
//!   `exp(ln(a)·b)`, so that `ln a` is shared too. Each operation is the one the tree walk
//!   applies, on the same operands in the same order, except that `a + c`, `a − c`, `c − a`
//!   and `a · c` with a constant `c` use the dual-by-`f64` operations (the tree makes `c` a
//!   dual with zero derivatives): values are bitwise identical, derivatives too as long as
//!   the operands are finite (the tree's extra terms `0 · a` can only turn an infinite `a`
//!   into NaN, and a zero's sign may differ).
//! - **Hash-consing**: an instruction identical to an earlier one (same operation, same
//!   operand registers, same constant bits) is not emitted again; since operands are already
//!   shared, structurally identical subtrees map to one register. Commutative operands are not
//!   reordered (`a*b` and `b*a` stay distinct), because dual products are not bitwise
//!   commutative in their higher derivatives.
//! - **Dead code** (instructions no output depends on) is removed after lowering.
//! - **Several outputs**: [`Program::fuse`] compiles several expressions over the same
//!   variables into one program (e.g. the D components of u), sharing subexpressions across
//!   them.
//! - **Registers**: instruction `i` writes register `i` (SSA); the register file is a `Vec<T>`
//!   the caller provides and that is reused between evaluations, or a per-thread buffer
//!   ([`with_registers`]).
//!
//! Use: point by point on dual numbers, the program measured no faster than the tree walk
//! on the built-in expressions (3.45–3.58 s against 3.24 s task clock on `zones2d`, one
//! thread), which share few subexpressions. What made the harness fast is the combination of
//! symbolic derivatives sharing their subexpressions on one tape ([`super::derivative`]) with
//! batched `f64` evaluation ([`super::batch`]).
//!
//! [`Expr`]: super::Expr

use std::any::Any;
use std::cell::RefCell;
use std::collections::HashMap;

use num_dual::DualNum;

use super::tree::{maximum, minimum, picks_first, positive_power, Node, UnaryFunction};

/// Index of a register (= of the instruction that writes it).
pub(super) type Register = u32;

/// One SSA instruction; its result goes to the register of its own index. Constants are kept
/// as their bit patterns so that instructions can be hashed and compared exactly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum Instruction {
    /// A constant (`f64` bits).
    Constant(u64),
    /// The value of variable `slot`.
    Variable(usize),
    Negate(Register),
    Add(Register, Register),
    Subtract(Register, Register),
    Multiply(Register, Register),
    Divide(Register, Register),
    /// `a + c` (either operand order in the source), constant `c` (`f64` bits).
    AddConstant(Register, u64),
    /// `a · c` (either operand order in the source), constant `c` (`f64` bits).
    MultiplyConstant(Register, u64),
    /// `a − c`, constant `c` (`f64` bits).
    SubtractConstant(Register, u64),
    /// `c − a` as `−a + c`, constant `c` (`f64` bits).
    ConstantSubtract(u64, Register),
    /// `a^n`, constant integer `n`: `powi`.
    PowerInteger(Register, i32),
    /// `a^p`, constant non-integer `p` (`f64` bits): `powf`.
    PowerReal(Register, u64),
    /// `max(0, a)^p`, constant `p` (`f64` bits): see `positive_power` in `super::tree`.
    PositivePower(Register, u64),
    Apply(UnaryFunction, Register),
    Min(Register, Register),
    Max(Register, Register),
    /// The branch rule of `min(a, b)` applied to other registers: `x` where `min(a, b)` picks
    /// `a`, else `y` (`MinSelect(a, b, x, y)`; the derivative of `min`, see [`super::derivative`]).
    MinSelect(Register, Register, Register, Register),
    /// As [`Instruction::MinSelect`] for `max`.
    MaxSelect(Register, Register, Register, Register),
    /// `−x` where `a < 0`, else `x` (`SignOf(a, x)`; the derivative of `abs a` is
    /// `SignOf(a, a')`).
    SignOf(Register, Register),
}

impl Instruction {
    /// The registers read.
    pub(super) fn operands(&self) -> impl Iterator<Item = Register> {
        let (first, second) = match *self {
            Instruction::MinSelect(a, b, x, y) | Instruction::MaxSelect(a, b, x, y) => {
                return [Some(a), Some(b), Some(x), Some(y)].into_iter().flatten();
            }
            Instruction::SignOf(a, x) => (Some(a), Some(x)),
            Instruction::Constant(_) | Instruction::Variable(_) => (None, None),
            Instruction::Negate(a)
            | Instruction::PowerInteger(a, _)
            | Instruction::PowerReal(a, _)
            | Instruction::PositivePower(a, _)
            | Instruction::AddConstant(a, _)
            | Instruction::MultiplyConstant(a, _)
            | Instruction::SubtractConstant(a, _)
            | Instruction::ConstantSubtract(_, a)
            | Instruction::Apply(_, a) => (Some(a), None),
            Instruction::Add(a, b)
            | Instruction::Subtract(a, b)
            | Instruction::Multiply(a, b)
            | Instruction::Divide(a, b)
            | Instruction::Min(a, b)
            | Instruction::Max(a, b) => (Some(a), Some(b)),
        };
        [first, second, None, None].into_iter().flatten()
    }

    /// The same instruction reading `map[operand]` instead of each operand.
    fn renumbered(self, map: &[Register]) -> Instruction {
        let m = |register: Register| map[register as usize];
        match self {
            Instruction::Constant(_) | Instruction::Variable(_) => self,
            Instruction::Negate(a) => Instruction::Negate(m(a)),
            Instruction::Add(a, b) => Instruction::Add(m(a), m(b)),
            Instruction::Subtract(a, b) => Instruction::Subtract(m(a), m(b)),
            Instruction::Multiply(a, b) => Instruction::Multiply(m(a), m(b)),
            Instruction::Divide(a, b) => Instruction::Divide(m(a), m(b)),
            Instruction::AddConstant(a, c) => Instruction::AddConstant(m(a), c),
            Instruction::MultiplyConstant(a, c) => Instruction::MultiplyConstant(m(a), c),
            Instruction::SubtractConstant(a, c) => Instruction::SubtractConstant(m(a), c),
            Instruction::ConstantSubtract(c, a) => Instruction::ConstantSubtract(c, m(a)),
            Instruction::PowerInteger(a, n) => Instruction::PowerInteger(m(a), n),
            Instruction::PowerReal(a, p) => Instruction::PowerReal(m(a), p),
            Instruction::PositivePower(a, p) => Instruction::PositivePower(m(a), p),
            Instruction::Apply(function, a) => Instruction::Apply(function, m(a)),
            Instruction::Min(a, b) => Instruction::Min(m(a), m(b)),
            Instruction::Max(a, b) => Instruction::Max(m(a), m(b)),
            Instruction::MinSelect(a, b, x, y) => Instruction::MinSelect(m(a), m(b), m(x), m(y)),
            Instruction::MaxSelect(a, b, x, y) => Instruction::MaxSelect(m(a), m(b), m(x), m(y)),
            Instruction::SignOf(a, x) => Instruction::SignOf(m(a), m(x)),
        }
    }
}

/// A compiled expression (or several fused ones): straight-line SSA code with common
/// subexpressions shared and no dead code, evaluated on any dual number type.
#[derive(Debug, Clone)]
pub struct Program {
    /// In dependency order: every operand register is smaller than the instruction's own.
    pub(super) instructions: Vec<Instruction>,
    /// The register of each output, in the order the expressions were given.
    pub(super) outputs: Vec<Register>,
    /// Number of values the evaluation takes.
    pub(super) variables: usize,
    /// Per instruction: a variable that is also an output (its register is then written by a
    /// batch evaluation, which otherwise reads variables from their input columns).
    pub(super) output_variables: Vec<bool>,
}

/// Lowering of trees into hash-consed instructions (constant operands of `+`, `−`, `·` are
/// folded into the instruction; the constant instruction then becomes dead code).
#[derive(Default)]
pub(super) struct Builder {
    pub(super) instructions: Vec<Instruction>,
    known: HashMap<Instruction, Register>,
}

impl Builder {
    /// A builder holding `instructions` (in dependency order) as they are, for
    /// [`Builder::finish`]; nothing is hash-consed.
    pub(super) fn from_instructions(instructions: Vec<Instruction>) -> Builder {
        Builder {
            instructions,
            known: HashMap::new(),
        }
    }

    /// The register of `instruction`: an existing identical one, or a new one.
    pub(super) fn emit(&mut self, instruction: Instruction) -> Register {
        *self.known.entry(instruction).or_insert_with(|| {
            self.instructions.push(instruction);
            Register::try_from(self.instructions.len() - 1)
                .expect("program has fewer than 2^32 instructions")
        })
    }

    /// The bits of the constant in `register`, if it holds one.
    pub(super) fn constant(&self, register: Register) -> Option<u64> {
        match self.instructions[register as usize] {
            Instruction::Constant(bits) => Some(bits),
            _ => None,
        }
    }

    /// Lower `node` (recursion depth bounded by the tree depth limit of the parser).
    pub(super) fn lower(&mut self, node: &Node) -> Register {
        let instruction = match node {
            Node::Constant(value) => Instruction::Constant(value.to_bits()),
            Node::Variable(slot) => Instruction::Variable(*slot),
            Node::Negate(a) => Instruction::Negate(self.lower(a)),
            Node::Add(a, b) => {
                let (a, b) = (self.lower(a), self.lower(b));
                match (self.constant(a), self.constant(b)) {
                    (Some(c), _) => Instruction::AddConstant(b, c),
                    (_, Some(c)) => Instruction::AddConstant(a, c),
                    _ => Instruction::Add(a, b),
                }
            }
            Node::Subtract(a, b) => {
                let (a, b) = (self.lower(a), self.lower(b));
                match (self.constant(a), self.constant(b)) {
                    (Some(c), _) => Instruction::ConstantSubtract(c, b),
                    (_, Some(c)) => Instruction::SubtractConstant(a, c),
                    _ => Instruction::Subtract(a, b),
                }
            }
            Node::Multiply(a, b) => {
                let (a, b) = (self.lower(a), self.lower(b));
                match (self.constant(a), self.constant(b)) {
                    (Some(c), _) => Instruction::MultiplyConstant(b, c),
                    (_, Some(c)) => Instruction::MultiplyConstant(a, c),
                    _ => Instruction::Multiply(a, b),
                }
            }
            Node::Divide(a, b) => Instruction::Divide(self.lower(a), self.lower(b)),
            Node::PowerInteger(a, n) => Instruction::PowerInteger(self.lower(a), *n),
            Node::PowerReal(a, p) => Instruction::PowerReal(self.lower(a), p.to_bits()),
            Node::PositivePower(a, p) => Instruction::PositivePower(self.lower(a), p.to_bits()),
            Node::PowerVariable(a, b) => {
                // exp(ln(a)·b), as the tree evaluates it.
                let base = self.lower(a);
                let exponent = self.lower(b);
                let logarithm = self.emit(Instruction::Apply(UnaryFunction::Ln, base));
                let product = self.emit(Instruction::Multiply(logarithm, exponent));
                Instruction::Apply(UnaryFunction::Exp, product)
            }
            Node::Apply(function, a) => Instruction::Apply(*function, self.lower(a)),
            Node::Min(a, b) => Instruction::Min(self.lower(a), self.lower(b)),
            Node::Max(a, b) => Instruction::Max(self.lower(a), self.lower(b)),
        };
        self.emit(instruction)
    }

    /// The program computing `outputs`, without the instructions none of them depends on.
    pub(super) fn finish(self, outputs: Vec<Register>, variables: usize) -> Program {
        let mut live = vec![false; self.instructions.len()];
        for &output in &outputs {
            live[output as usize] = true;
        }
        for index in (0..self.instructions.len()).rev() {
            if live[index] {
                for operand in self.instructions[index].operands() {
                    live[operand as usize] = true;
                }
            }
        }
        let mut map = vec![Register::MAX; self.instructions.len()];
        let mut instructions = Vec::with_capacity(live.iter().filter(|l| **l).count());
        for (index, instruction) in self.instructions.into_iter().enumerate() {
            if live[index] {
                map[index] = instructions.len() as Register;
                instructions.push(instruction.renumbered(&map));
            }
        }
        let outputs: Vec<Register> = outputs.iter().map(|&o| map[o as usize]).collect();
        let mut output_variables = vec![false; instructions.len()];
        for &output in &outputs {
            output_variables[output as usize] =
                matches!(instructions[output as usize], Instruction::Variable(_));
        }
        Program {
            instructions,
            outputs,
            variables,
            output_variables,
        }
    }
}

impl Program {
    /// Compile the trees `roots` over `variables` values into one program with one output per
    /// root.
    pub(super) fn compile(roots: &[&Node], variables: usize) -> Program {
        let mut builder = Builder::default();
        let outputs = roots.iter().map(|root| builder.lower(root)).collect();
        builder.finish(outputs, variables)
    }

    /// Number of instructions (= registers used by an evaluation).
    pub fn len(&self) -> usize {
        self.instructions.len()
    }

    /// True for a program without instructions (only the fusion of no expressions).
    pub fn is_empty(&self) -> bool {
        self.instructions.is_empty()
    }

    /// Number of outputs.
    pub fn output_count(&self) -> usize {
        self.outputs.len()
    }

    /// Number of values an evaluation takes.
    pub fn variable_count(&self) -> usize {
        self.variables
    }

    /// Run the instructions at `values`, leaving register `i` in `registers[i]`.
    fn run<T: DualNum<Primitive = f64> + Copy>(&self, values: &[T], registers: &mut Vec<T>) {
        assert_eq!(
            values.len(),
            self.variables,
            "Program evaluation: {} values for {} variables",
            values.len(),
            self.variables
        );
        registers.clear();
        registers.reserve(self.instructions.len());
        for instruction in &self.instructions {
            let r = |register: Register| registers[register as usize];
            let value = match *instruction {
                Instruction::Constant(bits) => T::from(f64::from_bits(bits)),
                Instruction::Variable(slot) => values[slot],
                Instruction::Negate(a) => -r(a),
                Instruction::Add(a, b) => r(a) + r(b),
                Instruction::Subtract(a, b) => r(a) - r(b),
                Instruction::Multiply(a, b) => r(a) * r(b),
                Instruction::Divide(a, b) => r(a) / r(b),
                Instruction::AddConstant(a, c) => r(a) + f64::from_bits(c),
                Instruction::MultiplyConstant(a, c) => r(a) * f64::from_bits(c),
                Instruction::SubtractConstant(a, c) => r(a) - f64::from_bits(c),
                Instruction::ConstantSubtract(c, a) => -r(a) + f64::from_bits(c),
                Instruction::PowerInteger(a, n) => r(a).powi(n),
                Instruction::PowerReal(a, bits) => r(a).powf(f64::from_bits(bits)),
                Instruction::PositivePower(a, bits) => positive_power(r(a), f64::from_bits(bits)),
                Instruction::Apply(function, a) => function.apply(r(a)),
                Instruction::Min(a, b) => minimum(r(a), r(b)),
                Instruction::Max(a, b) => maximum(r(a), r(b)),
                Instruction::MinSelect(a, b, x, y) => {
                    if picks_first(r(a).re(), r(b).re(), |a, b| a <= b) {
                        r(x)
                    } else {
                        r(y)
                    }
                }
                Instruction::MaxSelect(a, b, x, y) => {
                    if picks_first(r(a).re(), r(b).re(), |a, b| a >= b) {
                        r(x)
                    } else {
                        r(y)
                    }
                }
                Instruction::SignOf(a, x) => {
                    if r(a).re() < 0.0 {
                        -r(x)
                    } else {
                        r(x)
                    }
                }
            };
            registers.push(value);
        }
    }

    /// Evaluate at `values` into `outputs` (one per output), using `registers` as the
    /// register file (overwritten, grown to [`Program::len`]; reuse it to avoid allocation).
    ///
    /// # Panics
    /// If `values` or `outputs` have the wrong length.
    pub fn eval_into<T: DualNum<Primitive = f64> + Copy>(
        &self,
        values: &[T],
        registers: &mut Vec<T>,
        outputs: &mut [T],
    ) {
        assert_eq!(outputs.len(), self.outputs.len(), "Program outputs");
        self.run(values, registers);
        for (output, &register) in outputs.iter_mut().zip(&self.outputs) {
            *output = registers[register as usize];
        }
    }

    /// Evaluate a program with `N` outputs at `values` (see [`Program::eval_into`]).
    pub fn eval_array<T: DualNum<Primitive = f64> + Copy, const N: usize>(
        &self,
        values: &[T],
        registers: &mut Vec<T>,
    ) -> [T; N] {
        assert_eq!(N, self.outputs.len(), "Program outputs");
        self.run(values, registers);
        std::array::from_fn(|k| registers[self.outputs[k] as usize])
    }

    /// Evaluate a one-output program at `values` (see [`Program::eval_into`]).
    pub fn eval_scalar<T: DualNum<Primitive = f64> + Copy>(
        &self,
        values: &[T],
        registers: &mut Vec<T>,
    ) -> T {
        let [value] = self.eval_array(values, registers);
        value
    }
}

thread_local! {
    /// One register buffer per number type used on this thread.
    static REGISTERS: RefCell<Vec<Box<dyn Any>>> = const { RefCell::new(Vec::new()) };
}

/// Run `f` with this thread's register buffer for the number type `T` (created empty on first
/// use, kept for later calls, so repeated evaluations do not allocate). Re-entrant: a nested
/// call for the same type gets a fresh buffer.
pub fn with_registers<T: 'static, R>(f: impl FnOnce(&mut Vec<T>) -> R) -> R {
    let taken = REGISTERS.with(|pool| {
        let mut pool = pool.borrow_mut();
        let position = pool.iter().position(|buffer| buffer.is::<Vec<T>>());
        position.map(|position| pool.swap_remove(position))
    });
    let mut buffer = taken.unwrap_or_else(|| Box::new(Vec::<T>::new()));
    let result = f(buffer
        .downcast_mut::<Vec<T>>()
        .expect("the buffer was found by its type"));
    REGISTERS.with(|pool| pool.borrow_mut().push(buffer));
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Expr;
    use std::collections::BTreeMap;

    fn parse(source: &str) -> Expr {
        let constants = BTreeMap::from([("x_slip".to_string(), 0.6)]);
        Expr::parse(source, &["x", "y", "z", "t"], &constants).unwrap()
    }

    fn count(program: &Program, wanted: impl Fn(&Instruction) -> bool) -> usize {
        program.instructions.iter().filter(|i| wanted(i)).count()
    }

    #[test]
    fn common_subexpressions_are_computed_once() {
        let program = parse("sin(x)*sin(x) + sin(x)").program().clone();
        let sines = count(&program, |i| {
            matches!(i, Instruction::Apply(UnaryFunction::Sin, _))
        });
        assert_eq!(sines, 1);
        // x, sin x, sin x · sin x, + sin x.
        assert_eq!(program.len(), 4);
    }

    #[test]
    fn repeated_joins_share_one_max() {
        let program = parse(
            "max(0, x - x_slip)^4*(1+y) + t*max(0, x - x_slip)^3 + max(0, x - x_slip)^4*(1+t)",
        )
        .program()
        .clone();
        assert_eq!(count(&program, |i| matches!(i, Instruction::Max(..))), 1);
        assert_eq!(
            count(&program, |i| matches!(i, Instruction::SubtractConstant(..))),
            1
        );
        // One `^4`, shared by the first and last terms.
        assert_eq!(
            count(&program, |i| matches!(i, Instruction::PowerInteger(_, 4))),
            1
        );
        // Only the 0 of `max` stays a constant register (0.6 and 1 are folded into
        // `SubtractConstant`/`AddConstant`, their constant instructions removed as dead code).
        assert_eq!(
            count(&program, |i| matches!(i, Instruction::Constant(_))),
            1
        );
        assert_eq!(
            count(&program, |i| matches!(i, Instruction::AddConstant(..))),
            2
        );
    }

    #[test]
    fn variable_powers_share_the_logarithm() {
        let program = parse("x^y + ln(x) + x^y").program().clone();
        let logarithms = count(&program, |i| {
            matches!(i, Instruction::Apply(UnaryFunction::Ln, _))
        });
        assert_eq!(logarithms, 1);
        assert_eq!(
            count(&program, |i| matches!(
                i,
                Instruction::Apply(UnaryFunction::Exp, _)
            )),
            1
        );
    }

    #[test]
    fn commutative_operands_are_not_reordered() {
        let program = parse("x*y + y*x").program().clone();
        assert_eq!(
            count(&program, |i| matches!(i, Instruction::Multiply(..))),
            2
        );
    }

    #[test]
    fn dead_code_is_removed() {
        let mut builder = Builder::default();
        let x = builder.emit(Instruction::Variable(0));
        let y = builder.emit(Instruction::Variable(1));
        let unused = builder.emit(Instruction::Apply(UnaryFunction::Sin, y));
        let _ = builder.emit(Instruction::Multiply(unused, x));
        let output = builder.emit(Instruction::Negate(x));
        let program = builder.finish(vec![output], 2);
        assert_eq!(
            program.instructions,
            vec![Instruction::Variable(0), Instruction::Negate(0)]
        );
        assert_eq!(program.eval_scalar(&[3.0, 1.0], &mut Vec::new()), -3.0);
    }

    #[test]
    fn fused_programs_share_across_outputs_and_keep_their_order() {
        let u = [
            parse("0.05*x*y*(1+t) + 0.5*t*max(0, x - x_slip)^4*(1+y)"),
            parse("-(0.1 + 0.1*t)*x^2*(1+y)"),
        ];
        let fused = Program::fuse(&[&u[0], &u[1]]);
        assert_eq!(fused.output_count(), 2);
        assert!(fused.len() < u[0].program().len() + u[1].program().len());
        let point: [f64; 4] = [0.8, 0.3, 0.0, 0.5];
        let mut registers = Vec::new();
        let [first, second] = fused.eval_array(&point, &mut registers);
        assert_eq!(first.to_bits(), u[0].eval(&point).to_bits());
        assert_eq!(second.to_bits(), u[1].eval(&point).to_bits());
        let mut outputs = [0.0; 2];
        fused.eval_into(&point, &mut registers, &mut outputs);
        assert_eq!(outputs, [first, second]);
    }

    #[test]
    fn thread_buffers_are_reused_and_reentrant() {
        let expression = parse("x + y");
        let capacity = with_registers(|registers: &mut Vec<f64>| {
            expression.eval_with(&[1.0, 2.0, 0.0, 0.0], registers);
            // A nested evaluation of the same type gets its own buffer.
            assert_eq!(expression.eval_compiled(&[1.0, 2.0, 0.0, 0.0]), 3.0);
            registers.capacity()
        });
        assert!(capacity >= 3);
        let again = with_registers(|registers: &mut Vec<f64>| registers.capacity());
        assert!(again >= 3);
    }
}
