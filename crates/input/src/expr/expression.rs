//! A parsed expression, [`Expr`]: parsing, evaluation by the tree walk or the compiled program,
//! and the fusion of several expressions into one [`Program`].

use std::collections::BTreeMap;
use std::fmt;

use num_dual::DualNum;

use super::compiled::{self, Program};
use super::parser;
use super::token::ExprError;
use super::tree::{evaluate, mark_variables, Node};

/// A parsed expression: syntax tree with variables resolved to slots of the value slice
/// passed to [`Expr::eval`].
#[derive(Debug, Clone)]
pub struct Expr {
    source: String,
    variables: Vec<String>,
    pub(super) root: Node,
    /// The tree compiled once at parse time; what [`Expr::eval`] runs.
    program: Program,
}

impl Expr {
    /// Parse `source`.
    ///
    /// `variables` are the names bound at evaluation, in the order of the value slice of
    /// [`Expr::eval`] (e.g. `["x", "y", "z", "t"]` or `["beta", "tr_eps", "eps_eps"]`);
    /// `constants` are named values (`pi` and `e` are always available; the case file's
    /// constants are added here). A name that is both a variable and a constant, or a user
    /// constant `pi`/`e` with another value, is an error where it is used.
    pub fn parse(
        source: &str,
        variables: &[&str],
        constants: &BTreeMap<String, f64>,
    ) -> Result<Expr, ExprError> {
        let root = parser::parse(source, variables, constants)?;
        let program = Program::compile(&[&root], variables.len());
        Ok(Expr {
            source: source.to_string(),
            variables: variables.iter().map(|name| name.to_string()).collect(),
            root,
            program,
        })
    }

    /// Evaluate at `values` (one per variable, in the order given to [`Expr::parse`]) on any
    /// dual number type with `f64` real parts, or on `f64` itself.
    ///
    /// Walks the syntax tree: the reference semantics, and for now the faster path on the
    /// built-in cases (see [`compiled`]).
    ///
    /// # Panics
    /// If `values.len()` differs from the number of variables given to [`Expr::parse`]
    /// (a programming error: the variable list is fixed by the caller's code).
    pub fn eval<T: DualNum<Primitive = f64> + Copy>(&self, values: &[T]) -> T {
        self.check_arity(values.len());
        evaluate(&self.root, values)
    }

    /// Evaluate by running the compiled [`Program`] in a per-thread register buffer (no
    /// allocation once the buffer of the type `T` has grown on the calling thread). Same
    /// result as [`Expr::eval`] (see the documentation of the module [`crate::expr`]); same
    /// panics.
    pub fn eval_compiled<T: DualNum<Primitive = f64> + Copy>(&self, values: &[T]) -> T {
        self.check_arity(values.len());
        compiled::with_registers(|registers| self.program.eval_scalar(values, registers))
    }

    /// Evaluate like [`Expr::eval_compiled`] in the caller's register buffer `registers` (its
    /// previous content is overwritten; it grows to [`Program::len`] entries).
    ///
    /// # Panics
    /// As [`Expr::eval`].
    pub fn eval_with<T: DualNum<Primitive = f64> + Copy>(
        &self,
        values: &[T],
        registers: &mut Vec<T>,
    ) -> T {
        self.check_arity(values.len());
        self.program.eval_scalar(values, registers)
    }

    /// The compiled program of this expression (one output).
    pub fn program(&self) -> &Program {
        &self.program
    }

    fn check_arity(&self, count: usize) {
        assert_eq!(
            count,
            self.variables.len(),
            "Expr::eval of `{}`: {} values for the {} variables {:?}",
            self.source,
            count,
            self.variables.len(),
            self.variables
        );
    }

    /// Evaluate on plain floating-point numbers (same panics as [`Expr::eval`]).
    pub fn eval_f64(&self, values: &[f64]) -> f64 {
        self.eval(values)
    }

    /// Names of the variables that actually occur, in the order given to [`Expr::parse`].
    /// Variables that occur only inside folded constants cannot exist (a variable is never
    /// constant), so this is exactly the dependence of the expression.
    pub fn used_variables(&self) -> Vec<String> {
        let mut used = vec![false; self.variables.len()];
        mark_variables(&self.root, &mut used);
        self.variables
            .iter()
            .zip(used)
            .filter(|(_, is_used)| *is_used)
            .map(|(name, _)| name.clone())
            .collect()
    }

    /// All variable names, in the order of the value slice of [`Expr::eval`].
    pub fn variables(&self) -> &[String] {
        &self.variables
    }

    /// The source text the expression was parsed from.
    pub fn source(&self) -> &str {
        &self.source
    }
}

impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.source)
    }
}

impl Program {
    /// One program computing all `expressions` (outputs in the given order), sharing their
    /// common subexpressions.
    ///
    /// # Panics
    /// If the expressions were not parsed with the same variable list (a programming error).
    pub fn fuse(expressions: &[&Expr]) -> Program {
        let variables = expressions.first().map_or(&[][..], |e| e.variables());
        for expression in expressions {
            assert_eq!(
                expression.variables(),
                variables,
                "Program::fuse: `{expression}` has other variables"
            );
        }
        let roots: Vec<&Node> = expressions.iter().map(|e| &e.root).collect();
        Program::compile(&roots, variables.len())
    }
}
