//! Symbolic differentiation of compiled expressions: a [`Tape`] holds the SSA instructions of
//! several expressions and of their partial derivatives of any order, all hash-consed together
//! (module [`super::compiled`]), and compiles the wanted ones into one [`Program`].
//!
//! Why symbolic, and not dual numbers evaluated in batches: the manufactured data need up to
//! second derivatives in space of u and u̇ (a third mixed derivative in (x, t)), which nested
//! duals carry as 14 (2D) to 26 (3D) numbers per operation, most of them never used; the
//! derivative programs instead compute exactly the needed f64 quantities, share every common
//! subexpression (`cos(pi*y)` appears once for β, ∂β/∂y, ∂²β/∂y² …, the powers of
//! `max(0, x − a)` once for all derivatives) and run on plain `f64` columns, one instruction
//! over a whole batch of points ([`super::batch`]).
//!
//! The rules are forward-mode differentiation applied to each instruction, i.e. the operations
//! a dual number performs, emitted as instructions: `(a b)' = a' b + a b'`,
//! `(a/b)' = (a' − (a/b) b')/b`, `(aⁿ)' = n aⁿ⁻¹ a'`, `sin' = cos`, …; `abs`, `min` and `max`
//! differentiate the branch selected by the real parts with the same rule as the tree
//! evaluator (so derivatives of the C³ joins `max(0, x − a)⁴` are exact). An identically zero
//! derivative is not emitted (`None`), so ∂/∂z of an expression without z costs nothing.

use std::collections::HashMap;

use super::compiled::{Builder, Instruction, Program, Register};
use super::expression::Expr;
use super::tree::UnaryFunction;

/// A value on a tape: a register, or `None` for an identically zero function.
pub type Value = Option<Register>;

/// Expressions and their symbolic derivatives, hash-consed into one instruction list.
pub struct Tape {
    builder: Builder,
    variables: usize,
    /// ∂(register)/∂(variable), once computed.
    derivatives: HashMap<(Register, usize), Value>,
}

impl Tape {
    /// An empty tape over `variables` variables.
    pub fn new(variables: usize) -> Tape {
        Tape {
            builder: Builder::default(),
            variables,
            derivatives: HashMap::new(),
        }
    }

    /// Records `expression` (parsed over this tape's variables) and returns its value.
    ///
    /// # Panics
    /// If the expression was parsed with another number of variables (a programming error).
    pub fn expression(&mut self, expression: &Expr) -> Value {
        assert_eq!(
            expression.variables().len(),
            self.variables,
            "Tape::expression: `{expression}` has other variables"
        );
        Some(self.builder.lower(&expression.root))
    }

    /// ∂value/∂(variable `variable`), recorded on the tape.
    pub fn derivative(&mut self, value: Value, variable: usize) -> Value {
        assert!(
            variable < self.variables,
            "Tape::derivative: no variable {variable}"
        );
        value.and_then(|register| self.differentiate(register, variable))
    }

    /// The program computing `outputs` in the given order (an identically zero output is the
    /// constant 0), without the instructions none of them needs.
    pub fn compile(mut self, outputs: &[Value]) -> Program {
        let registers = outputs
            .iter()
            .map(|value| value.unwrap_or_else(|| self.constant(0.0)))
            .collect();
        self.builder.finish(registers, self.variables)
    }

    /// a + b, recorded on the tape.
    pub fn sum(&mut self, a: Value, b: Value) -> Value {
        self.add(a, b)
    }

    fn constant(&mut self, value: f64) -> Register {
        self.builder.emit(Instruction::Constant(value.to_bits()))
    }

    fn emit(&mut self, instruction: Instruction) -> Register {
        self.builder.emit(instruction)
    }

    fn negate(&mut self, a: Value) -> Value {
        a.map(|a| self.emit(Instruction::Negate(a)))
    }

    fn add(&mut self, a: Value, b: Value) -> Value {
        match (a, b) {
            (Some(a), Some(b)) => Some(self.emit(Instruction::Add(a, b))),
            (a, None) => a,
            (None, b) => b,
        }
    }

    fn subtract(&mut self, a: Value, b: Value) -> Value {
        match (a, b) {
            (Some(a), Some(b)) => Some(self.emit(Instruction::Subtract(a, b))),
            (a, None) => a,
            (None, b) => self.negate(b),
        }
    }

    fn multiply(&mut self, a: Value, b: Value) -> Value {
        match (a, b) {
            (Some(a), Some(b)) => Some(self.emit(Instruction::Multiply(a, b))),
            _ => None,
        }
    }

    fn scale(&mut self, a: Value, c: f64) -> Value {
        a.map(|a| self.emit(Instruction::MultiplyConstant(a, c.to_bits())))
    }

    fn divide(&mut self, a: Value, b: Register) -> Value {
        a.map(|a| self.emit(Instruction::Divide(a, b)))
    }

    /// The derivative of `select(a, b)` between the branches `x` and `y` (0 for `None`).
    fn select(
        &mut self,
        kind: fn(Register, Register, Register, Register) -> Instruction,
        (a, b): (Register, Register),
        x: Value,
        y: Value,
    ) -> Value {
        if x.is_none() && y.is_none() {
            return None;
        }
        let x = x.unwrap_or_else(|| self.constant(0.0));
        let y = y.unwrap_or_else(|| self.constant(0.0));
        Some(self.emit(kind(a, b, x, y)))
    }

    /// ∂(register)/∂(variable) (recursion depth bounded by the longest dependency chain, i.e.
    /// by the parser's depth limit times the differentiation order).
    fn differentiate(&mut self, register: Register, variable: usize) -> Value {
        if let Some(&known) = self.derivatives.get(&(register, variable)) {
            return known;
        }
        let d = |tape: &mut Tape, operand: Register| tape.differentiate(operand, variable);
        let r = Some(register);
        let instruction = self.builder.instructions[register as usize];
        let result = match instruction {
            Instruction::Constant(_) => None,
            Instruction::Variable(slot) => (slot == variable).then(|| self.constant(1.0)),
            Instruction::Negate(a) => {
                let da = d(self, a);
                self.negate(da)
            }
            Instruction::Add(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                self.add(da, db)
            }
            Instruction::Subtract(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                self.subtract(da, db)
            }
            Instruction::Multiply(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                let first = self.multiply(da, Some(b));
                let second = self.multiply(Some(a), db);
                self.add(first, second)
            }
            Instruction::Divide(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                let quotient_slope = self.multiply(r, db);
                let numerator = self.subtract(da, quotient_slope);
                self.divide(numerator, b)
            }
            Instruction::AddConstant(a, _) | Instruction::SubtractConstant(a, _) => d(self, a),
            Instruction::ConstantSubtract(_, a) => {
                let da = d(self, a);
                self.negate(da)
            }
            Instruction::MultiplyConstant(a, c) => {
                let da = d(self, a);
                self.scale(da, f64::from_bits(c))
            }
            Instruction::PowerInteger(a, n) => {
                let da = d(self, a);
                match n {
                    0 => None,
                    1 => da,
                    _ => {
                        let power = if n == 2 {
                            a
                        } else {
                            self.emit(Instruction::PowerInteger(a, n - 1))
                        };
                        let slope = self.scale(Some(power), f64::from(n));
                        self.multiply(slope, da)
                    }
                }
            }
            Instruction::PowerReal(a, bits) => {
                let da = d(self, a);
                let p = f64::from_bits(bits);
                let power = self.emit(Instruction::PowerReal(a, (p - 1.0).to_bits()));
                let slope = self.scale(Some(power), p);
                self.multiply(slope, da)
            }
            // (max(0, a)^p)' = p max(0, a)^(p−1) a', zero where a ≤ 0
            Instruction::PositivePower(a, bits) => {
                let da = d(self, a);
                let p = f64::from_bits(bits);
                if da.is_none() || p == 0.0 {
                    None
                } else {
                    let power = self.emit(Instruction::PositivePower(a, (p - 1.0).to_bits()));
                    let slope = self.scale(Some(power), p);
                    self.multiply(slope, da)
                }
            }
            Instruction::Apply(function, a) => {
                let da = d(self, a);
                if da.is_none() {
                    None
                } else {
                    self.apply_derivative(function, a, register, da)
                }
            }
            Instruction::Min(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                self.select(Instruction::MinSelect, (a, b), da, db)
            }
            Instruction::Max(a, b) => {
                let (da, db) = (d(self, a), d(self, b));
                self.select(Instruction::MaxSelect, (a, b), da, db)
            }
            Instruction::MinSelect(a, b, x, y) => {
                let (dx, dy) = (d(self, x), d(self, y));
                self.select(Instruction::MinSelect, (a, b), dx, dy)
            }
            Instruction::MaxSelect(a, b, x, y) => {
                let (dx, dy) = (d(self, x), d(self, y));
                self.select(Instruction::MaxSelect, (a, b), dx, dy)
            }
            Instruction::SignOf(a, x) => {
                let dx = d(self, x);
                dx.map(|dx| self.emit(Instruction::SignOf(a, dx)))
            }
        };
        self.derivatives.insert((register, variable), result);
        result
    }

    /// (f(a))' = f'(a) a' for `result` = f(a) and a nonzero `da`.
    fn apply_derivative(
        &mut self,
        function: UnaryFunction,
        a: Register,
        result: Register,
        da: Value,
    ) -> Value {
        let r = Some(result);
        match function {
            // (√a)' = a' / (2√a)
            UnaryFunction::Sqrt => {
                let quotient = self.divide(da, result);
                self.scale(quotient, 0.5)
            }
            UnaryFunction::Exp => self.multiply(da, r),
            UnaryFunction::Ln => self.divide(da, a),
            UnaryFunction::Sin => {
                let cos = self.emit(Instruction::Apply(UnaryFunction::Cos, a));
                self.multiply(da, Some(cos))
            }
            UnaryFunction::Cos => {
                let sin = self.emit(Instruction::Apply(UnaryFunction::Sin, a));
                let product = self.multiply(da, Some(sin));
                self.negate(product)
            }
            // tan' = 1 + tan², tanh' = 1 − tanh²
            UnaryFunction::Tan | UnaryFunction::Tanh => {
                let square = self.emit(Instruction::Multiply(result, result));
                let one = 1.0f64.to_bits();
                let slope = if function == UnaryFunction::Tan {
                    self.emit(Instruction::AddConstant(square, one))
                } else {
                    self.emit(Instruction::ConstantSubtract(one, square))
                };
                self.multiply(da, Some(slope))
            }
            UnaryFunction::Abs => da.map(|da| self.emit(Instruction::SignOf(a, da))),
        }
    }
}
