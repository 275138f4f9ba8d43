//! Closed-form expressions of the case files (manufactured solutions, coefficient laws),
//! evaluated generically on dual numbers so that source terms can be derived by automatic
//! differentiation (`num-dual`, up to third order via nested duals).
//!
//! # Grammar
//! ```text
//! expression := term (("+" | "-") term)*
//! term       := unary (("*" | "/") unary)*
//! unary      := ("-" | "+") unary | power
//! power      := primary ("^" unary)?            right-associative: 2^3^2 = 2^(3^2)
//! primary    := number | name | name "(" arguments ")" | "(" expression ")"
//! number     := 1 | 2.5 | .5 | 1e-3 | 2.5E+2
//! ```
//! `^` binds tighter than unary minus (`-x^2 = -(x^2)`) and its exponent may carry a sign
//! (`2^-1 = 0.5`). Names are the evaluation variables (e.g. `x, y, z, t`), then the constants
//! (`pi`, `e` and the user constants). Functions: `sqrt, exp, ln` (alias `log`)`, sin, cos, tan,
//! tanh, abs` with one argument, `min, max, pow, pospow` with two. There is no implicit
//! multiplication.
//!
//! `pospow(a, p)` is `max(0, a)^p`, the profile `(a)₊^p` of a field of limited smoothness (a
//! stick–slip front, the edge of a contact zone), for a constant exponent `p > 0` that need
//! not be an integer: where `a > 0` it and its derivatives are the classical ones, where
//! `a ≤ 0` they are all zero. Unlike `max(0, a)^p` with a non-integer `p` (whose derivatives at
//! a zero base are `0 · ∞ = NaN`), it can be differentiated everywhere; derivatives of order
//! above `p` grow without bound as `a → 0⁺`, which is the point of the profile.
//!
//! # Evaluation on dual numbers
//! - Exponents that are constant (after folding, e.g. `(y-a)^4`, `x^(1/2)`) are specialized:
//!   an integer exponent (|n| ≤ 1000) uses `powi`, so negative bases are fine and all
//!   derivatives are exact; a non-integer constant exponent uses `powf` (needs a positive base;
//!   at a zero base the dual parts of exponents below 3 are NaN); a variable exponent is
//!   evaluated as `exp(b·ln a)` (needs a positive base), identically for `f64` and duals.
//! - `abs`, `min` and `max` pick a branch by the real part (`abs` takes `+a` at `a = 0`,
//!   `min`/`max` the first argument on ties; a NaN argument is returned as is). Derivatives are
//!   those of the selected branch: exact wherever the join is smooth enough for the order
//!   needed, e.g. `max(0, y-a)^4` is C³, so derivatives up to third order are exact everywhere.
//! - Variable-free subexpressions are folded to constants at parse time; a constant that is
//!   not finite (`1/0`, `ln(0)`, `1e999`) is a parse error. Values at evaluation points are not
//!   checked here (the signature returns a bare number): callers check `is_finite` on results.
//!
//! # Compiled evaluation
//! [`Expr::parse`] also compiles the tree into a [`Program`] (module [`compiled`]): a flat
//! instruction list with common subexpressions shared, run by [`Expr::eval_compiled`] and
//! [`Expr::eval_with`]. [`Expr::eval`] walks the tree; it is the reference the program is
//! tested against. Both apply the same operations in the same order (up to dual-by-`f64`
//! operations for constant operands), so values are bitwise identical and derivatives agree
//! wherever the operands are finite.
//!
//! The harness evaluates the exact fields of a case differently: a [`Tape`] (module
//! [`derivative`]) differentiates the instructions symbolically, once per case, into one
//! program per consumer, and [`Program::eval_batch`] (module [`batch`]) runs it instruction by
//! instruction over columns of `f64` values at a batch of points.

pub mod batch;
pub mod compiled;
pub mod derivative;
mod expression;
mod parser;
pub mod split;
mod token;
mod tree;

pub use compiled::Program;
pub use derivative::Tape;
pub use expression::Expr;
pub use split::SplitProgram;
pub use token::ExprError;

#[cfg(test)]
mod tests {
    use super::tree::{Node, MAX_DEPTH};
    use super::*;
    use nalgebra::{SMatrix, SVector};
    use num_dual::{
        gradient, hessian, third_derivative, Dual2SVec, Dual2SVec64, Dual2Vec, Dual64, DualNum,
        DualSVec64, DualVec,
    };
    use proptest::prelude::*;
    use proptest::test_runner::{TestCaseError, TestCaseResult, TestRunner};
    use std::collections::BTreeMap;
    use std::f64::consts::{E, PI};
    use std::sync::atomic::{AtomicUsize, Ordering};

    const SPACE_TIME: [&str; 4] = ["x", "y", "z", "t"];

    /// A scalar field of (x, y, z, t), written out by hand.
    type Field<D> = fn(D, D, D, D) -> D;
    /// A scalar function of the point [x, y, z, t].
    type PointFunction = fn([f64; 4]) -> f64;

    fn user_constants() -> BTreeMap<String, f64> {
        BTreeMap::from([("a".to_string(), 0.3)])
    }

    fn parse(source: &str) -> Expr {
        Expr::parse(source, &SPACE_TIME, &user_constants())
            .unwrap_or_else(|error| panic!("`{source}` does not parse: {error}"))
    }

    fn parse_error(source: &str) -> ExprError {
        match Expr::parse(source, &SPACE_TIME, &user_constants()) {
            Ok(_) => panic!("`{source}` parsed but should not"),
            Err(error) => error,
        }
    }

    fn close(computed: f64, expected: f64) -> bool {
        (computed - expected).abs() <= 1e-13 * (1.0 + expected.abs())
    }

    fn max_generic<D: DualNum<Primitive = f64> + Copy>(a: D, b: D) -> D {
        if a.re() >= b.re() {
            a
        } else {
            b
        }
    }

    /// The case files' expressions, written out by hand in Rust, generically.
    fn displacement<D: DualNum<Primitive = f64> + Copy>(x: D, y: D, _z: D, t: D) -> D {
        (x * PI).sin() * 0.1 * (t + 1.0).powi(2) * max_generic(D::from(0.0), y - 0.3).powi(4)
    }
    const DISPLACEMENT: &str = "0.1*sin(pi*x)*(1+t)^2*max(0, y-0.3)^4";

    fn mixed<D: DualNum<Primitive = f64> + Copy>(x: D, y: D, z: D, t: D) -> D {
        (-t).exp() * (y * (2.0 * PI)).cos() + x * x * y - z / 3.0 + (x - 0.5).powi(3)
            - (z * z + 1.0).sqrt() * (y + 2.0).ln()
            + (t * 0.3).tan() * (x * z).tanh()
    }
    const MIXED: &str = "exp(-t)*cos(2*pi*y) + x^2*y - z/3 + (x-0.5)^3 \
                         - sqrt(z^2+1)*log(y+2) + tan(0.3*t)*tanh(x*z)";

    fn powers<D: DualNum<Primitive = f64> + Copy>(x: D, y: D, z: D, t: D) -> D {
        (x + 3.0).powf(1.5) + ((y + 2.0).ln() * (t + 1.0)).exp() + (z * z + 1.0).powi(-2) * E
    }
    const POWERS: &str = "pow(x+3, 1.5) + (y+2)^(t+1) + (z^2+1)^-2*e";

    fn points() -> Vec<[f64; 4]> {
        vec![
            [0.25, 0.7, -0.4, 0.5],
            [0.9, 0.1, 0.3, 1.5],
            [-0.3, 0.45, 1.2, 0.0],
        ]
    }

    #[test]
    fn values_match_hand_written_rust() {
        let cases: [(&str, Field<f64>); 3] = [
            (DISPLACEMENT, displacement::<f64>),
            (MIXED, mixed::<f64>),
            (POWERS, powers::<f64>),
        ];
        for (source, reference) in cases {
            let expression = parse(source);
            for [x, y, z, t] in points() {
                let computed = expression.eval_f64(&[x, y, z, t]);
                let expected = reference(x, y, z, t);
                assert!(
                    close(computed, expected),
                    "`{source}` at {:?}: {computed} vs {expected}",
                    [x, y, z, t]
                );
            }
        }
        let more: [(&str, PointFunction); 3] = [
            ("abs(x - 1) + min(y, z)", |[x, y, z, _]: [f64; 4]| {
                (x - 1.0).abs() + y.min(z)
            }),
            ("max(x, y) * -z^2 / (1 + t)", |[x, y, z, t]: [f64; 4]| {
                x.max(y) * -(z * z) / (1.0 + t)
            }),
            ("a * x + 1e-3 * .5 + 2.5E+1", |[x, _, _, _]: [f64; 4]| {
                0.3 * x + 5e-4 + 25.0
            }),
        ];
        for (source, reference) in more {
            let expression = parse(source);
            for point in points() {
                let computed = expression.eval_f64(&point);
                assert!(close(computed, reference(point)), "`{source}` at {point:?}");
            }
        }
    }

    #[test]
    fn first_and_second_derivatives_match_num_dual_on_rust_closures() {
        let cases: [(&str, Field<DualSVec64<4>>, Field<Dual2SVec64<4>>); 3] = [
            (DISPLACEMENT, displacement, displacement),
            (MIXED, mixed, mixed),
            (POWERS, powers, powers),
        ];
        for (source, first_order, second_order) in cases {
            let expression = parse(source);
            for point in points() {
                let at = SVector::<f64, 4>::from(point);
                let (value, grad) = gradient(
                    |v: SVector<DualSVec64<4>, 4>| expression.eval(v.as_slice()),
                    &at,
                );
                let (value_ref, grad_ref) = gradient(
                    |v: SVector<DualSVec64<4>, 4>| first_order(v[0], v[1], v[2], v[3]),
                    &at,
                );
                assert!(close(value, value_ref), "`{source}` value at {point:?}");
                for i in 0..4 {
                    assert!(
                        close(grad[i], grad_ref[i]),
                        "`{source}` gradient {i} at {point:?}: {} vs {}",
                        grad[i],
                        grad_ref[i]
                    );
                }
                let (_, _, hess) = hessian(
                    |v: SVector<Dual2SVec64<4>, 4>| expression.eval(v.as_slice()),
                    &at,
                );
                let (_, _, hess_ref): (f64, SVector<f64, 4>, SMatrix<f64, 4, 4>) = hessian(
                    |v: SVector<Dual2SVec64<4>, 4>| second_order(v[0], v[1], v[2], v[3]),
                    &at,
                );
                for i in 0..4 {
                    for j in 0..4 {
                        assert!(
                            close(hess[(i, j)], hess_ref[(i, j)]),
                            "`{source}` hessian ({i},{j}) at {point:?}: {} vs {}",
                            hess[(i, j)],
                            hess_ref[(i, j)]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn smooth_join_and_negative_base_derivatives_are_exact() {
        let expression = parse("max(0, y-a)^4 + (x-0.5)^3");
        // Below the join: only the cubic contributes, 3 (x-0.5)^2 with x - 0.5 < 0 (powi).
        let at = SVector::<f64, 4>::from([0.2, 0.1, 0.0, 0.0]);
        let (_, grad) = gradient(
            |v: SVector<DualSVec64<4>, 4>| expression.eval(v.as_slice()),
            &at,
        );
        assert!(close(grad[0], 3.0 * 0.09) && grad[1] == 0.0, "{grad:?}");
        // Above the join: 4 (y - a)^3.
        let at = SVector::<f64, 4>::from([0.2, 0.5, 0.0, 0.0]);
        let (_, grad, hess) = hessian(
            |v: SVector<Dual2SVec64<4>, 4>| expression.eval(v.as_slice()),
            &at,
        );
        assert!(close(grad[1], 4.0 * 0.2f64.powi(3)), "{grad:?}");
        assert!(close(hess[(1, 1)], 12.0 * 0.04), "{hess:?}");
        assert!(close(hess[(0, 0)], 6.0 * (0.2 - 0.5)), "{hess:?}");
        assert_eq!(hess[(0, 1)], 0.0);
    }

    #[test]
    fn pospow_is_the_power_of_the_positive_part_with_zero_derivatives_where_it_vanishes() {
        // (x − 0.3)₊^2.5 (1 + t): value, ∂x, ∂x², ∂x∂t by the symbolic tape and by nested duals
        let expression = parse("pospow(x - 0.3, 2.5)*(1 + t)");
        let mut tape = Tape::new(4);
        let value = tape.expression(&expression);
        let dx = tape.derivative(value, 0);
        let dxx = tape.derivative(dx, 0);
        let dxt = tape.derivative(dx, 3);
        let program = tape.compile(&[value, dx, dxx, dxt]);
        for x in [-1.0, 0.2, 0.3, 0.300_000_001, 0.7, 1.3] {
            let t = 0.4;
            let d: f64 = x - 0.3;
            let expected = if d > 0.0 {
                [
                    d.powf(2.5) * (1.0 + t),
                    2.5 * d.powf(1.5) * (1.0 + t),
                    3.75 * d.powf(0.5) * (1.0 + t),
                    2.5 * d.powf(1.5),
                ]
            } else {
                [0.0; 4]
            };
            let out: [f64; 4] = program.eval_array(&[x, 0.0, 0.0, t], &mut Vec::new());
            for (computed, expected) in out.iter().zip(expected) {
                assert!(
                    computed.is_finite() && close(*computed, expected),
                    "x = {x}: {out:?} against {expected:?}"
                );
            }
            let at = SVector::<f64, 4>::from([x, 0.0, 0.0, t]);
            let (dual_value, grad, hess) = hessian(
                |v: SVector<Dual2SVec64<4>, 4>| expression.eval(v.as_slice()),
                &at,
            );
            assert!(close(dual_value, expected[0]), "x = {x}: {dual_value}");
            assert!(close(grad[0], expected[1]), "x = {x}: {grad:?}");
            assert!(close(hess[(0, 0)], expected[2]), "x = {x}: {hess:?}");
            assert!(close(hess[(0, 3)], expected[3]), "x = {x}: {hess:?}");
        }
        // the exponent is a positive constant
        for (source, message) in [
            ("pospow(x, y)", "must be a constant"),
            ("pospow(x, 0)", "must be positive"),
            ("pospow(x, -1.5)", "must be positive"),
            ("pospow(x)", "takes 2 arguments"),
        ] {
            let error = parse_error(source).to_string();
            assert!(error.contains(message), "{source}: {error}");
        }
        // folded when the argument is constant, like every function
        assert_eq!(
            parse("pospow(-2, 0.5) + pospow(4, 0.5)").eval(&[0.0; 4]),
            2.0
        );
    }

    #[test]
    fn third_derivatives_are_exact() {
        let expression = Expr::parse("x^4 + sin(2*x)", &["x"], &BTreeMap::new()).unwrap();
        for x in [-0.7, 0.0, 0.4, 1.3] {
            let (value, first, second, third) = third_derivative(|v| expression.eval(&[v]), x);
            assert!(close(value, x.powi(4) + (2.0 * x).sin()));
            assert!(close(first, 4.0 * x.powi(3) + 2.0 * (2.0 * x).cos()));
            assert!(close(second, 12.0 * x * x - 4.0 * (2.0 * x).sin()));
            assert!(close(third, 24.0 * x - 8.0 * (2.0 * x).cos()));
        }
    }

    #[test]
    fn nested_duals_give_the_gradient_of_the_laplacian() {
        // u = sin(pi x) y^3: Δu = sin(pi x) (6 y - pi^2 y^3).
        let expression = Expr::parse("sin(pi*x)*y^3", &["x", "y"], &BTreeMap::new()).unwrap();
        let laplacian = |v: SVector<DualSVec64<2>, 2>| {
            let (_, _, hess) = hessian(
                |w: SVector<Dual2SVec<DualVec<f64, nalgebra::Const<2>>, 2>, 2>| {
                    expression.eval(w.as_slice())
                },
                &v,
            );
            hess[(0, 0)] + hess[(1, 1)]
        };
        let (x, y) = (0.3, 0.8);
        let (value, grad) = gradient(laplacian, &SVector::from([x, y]));
        let (s, c) = (PI * x).sin_cos();
        assert!(close(value, s * (6.0 * y - PI * PI * y.powi(3))));
        assert!(close(grad[0], PI * c * (6.0 * y - PI * PI * y.powi(3))));
        assert!(close(grad[1], s * (6.0 - 3.0 * PI * PI * y * y)));
    }

    #[test]
    fn precedence_and_associativity() {
        let cases = [
            ("-x^2", -9.0),
            ("-2^2", -4.0),
            ("(-2)^2", 4.0),
            ("2^3^2", 512.0),
            ("2^-1", 0.5),
            ("2^-1^2", 0.5),
            ("2*3+4", 10.0),
            ("2+3*4", 14.0),
            ("2-3-4", -5.0),
            ("16/4/2", 2.0),
            ("2*x^2", 18.0),
            ("--x", 3.0),
            ("+x", 3.0),
            ("x - -1", 4.0),
            ("2 * -x", -6.0),
            ("-x*2", -6.0),
            ("x^2/x", 3.0),
            ("(1+2)*(3+4)", 21.0),
            ("pow(2, 3)^2", 64.0),
            ("max(1,2)*min(3,4)", 6.0),
            ("abs(-x)", 3.0),
            (".5e1 + 1.", 6.0),
        ];
        for (source, expected) in cases {
            let value = parse(source).eval_f64(&[3.0, 0.0, 0.0, 0.0]);
            assert_eq!(value, expected, "`{source}`");
        }
    }

    #[test]
    fn constant_exponents_are_specialized() {
        let root = |source: &str| parse(source).root;
        assert!(matches!(root("x^(1+1)"), Node::PowerInteger(_, 2)));
        assert!(matches!(root("pow(x, -3)"), Node::PowerInteger(_, -3)));
        assert!(matches!(root("x^(1/2)"), Node::PowerReal(_, p) if p == 0.5));
        assert!(matches!(root("x^y"), Node::PowerVariable(_, _)));
        assert!(matches!(root("x^1e9"), Node::PowerReal(_, _)));
        assert_eq!(root("2*pi - sin(0)"), Node::Constant(2.0 * PI));
    }

    #[test]
    fn used_variables_lists_occurring_names_in_declaration_order() {
        assert_eq!(parse("t*y + sin(y)").used_variables(), vec!["y", "t"]);
        assert!(parse("pi*a").used_variables().is_empty());
        let expression = parse(DISPLACEMENT);
        assert_eq!(expression.used_variables(), vec!["x", "y", "t"]);
        assert_eq!(expression.variables(), SPACE_TIME);
        assert_eq!(expression.to_string(), DISPLACEMENT);
    }

    #[test]
    fn other_variable_sets_bind_in_their_order() {
        let expression = Expr::parse(
            "beta * tr_eps + 2 * eps_eps",
            &["beta", "tr_eps", "eps_eps"],
            &BTreeMap::new(),
        )
        .unwrap();
        assert_eq!(expression.eval_f64(&[0.5, 2.0, 3.0]), 7.0);
    }

    #[test]
    fn errors_name_the_column_and_the_problem() {
        let cases = [
            ("x + #", 5, "unexpected character `#`"),
            ("x \u{2212} 1", 3, "ASCII minus"),
            ("(x + 1", 1, "unbalanced parentheses"),
            ("x + 1)", 6, "unbalanced parentheses"),
            ("max(1, 2", 4, "unbalanced parentheses"),
            ("foo(x)", 1, "unknown function `foo`"),
            ("x(2)", 1, "unknown function `x`"),
            ("max(x)", 1, "function `max` takes 2 arguments, found 1"),
            ("sin(x, y)", 1, "function `sin` takes 1 argument, found 2"),
            ("pow()", 1, "function `pow` takes 2 arguments, found 0"),
            ("sin x", 1, "needs its arguments"),
            ("x y", 3, "unexpected `y` after a complete expression"),
            ("2x", 2, "implicit multiplication"),
            ("x, y", 2, "unexpected `,`"),
            ("", 1, "empty expression"),
            ("   ", 1, "empty expression"),
            ("x +", 4, "found end of input"),
            ("2 * (x + )", 10, "found `)`"),
            ("min(1 2)", 7, "expected `,` or `)`"),
            ("1e999 * x", 1, "out of the range"),
            (
                "x + ln(0)",
                5,
                "constant subexpression `ln(0)` evaluates to -inf",
            ),
            ("x / (1 - 1)^-1", 5, "not finite"),
        ];
        for (source, column, fragment) in cases {
            let error = parse_error(source);
            assert_eq!(error.column, column, "`{source}`: {error}");
            assert!(
                error.message.contains(fragment),
                "`{source}`: `{}` lacks `{fragment}`",
                error.message
            );
        }
        assert_eq!(
            parse_error("x + w").to_string(),
            "column 5: unknown variable `w` (known: x, y, z, t; constants: pi, e, a)"
        );
    }

    #[test]
    fn conflicting_names_are_errors() {
        let constants = BTreeMap::from([("x".to_string(), 1.0), ("e".to_string(), 2.0)]);
        let error = Expr::parse("2*x", &SPACE_TIME, &constants).unwrap_err();
        assert_eq!(error.column, 3);
        assert!(error.message.contains("ambiguous"), "{error}");
        let error = Expr::parse("y + e", &SPACE_TIME, &constants).unwrap_err();
        assert_eq!(error.column, 5);
        assert!(error.message.contains("redefines the built-in"), "{error}");
        let constants = BTreeMap::from([("c".to_string(), f64::NAN)]);
        let error = Expr::parse("y + c", &SPACE_TIME, &constants).unwrap_err();
        assert!(error.message.contains("not finite"), "{error}");
    }

    #[test]
    fn deep_nesting_is_an_error_not_a_stack_overflow() {
        let deep = format!("{}x{}", "(".repeat(100_000), ")".repeat(100_000));
        assert!(parse_error(&deep).message.contains("nested too deeply"));
        let signs = format!("{}x", "-".repeat(100_000));
        assert!(parse_error(&signs).message.contains("nested too deeply"));
        let long_sum = vec!["x"; 100_000].join("+");
        let error = parse_error(&long_sum);
        assert!(
            error.message.contains("terms or factors in one chain"),
            "{error}"
        );
        assert_eq!(error.column, 2 * MAX_DEPTH + 1, "{error}");
        // grouped in parentheses, the same terms parse
        let group = vec!["x"; 150].join("+");
        let grouped = format!("({group}) + ({group})");
        assert_eq!(parse(&grouped).eval_f64(&[1.0; 4]), 300.0);
        // Long constant sums fold to one constant and are fine.
        let constant_sum = vec!["1"; 10_000].join("+");
        assert_eq!(parse(&constant_sum).eval_f64(&[0.0; 4]), 10_000.0);
    }

    // ---- property tests ----------------------------------------------------------------

    /// Independent syntax tree for the printer/re-parser property test.
    #[derive(Debug, Clone)]
    enum Tree {
        Literal(String),
        Variable(usize),
        Named(&'static str, f64),
        Negate(Box<Tree>),
        Positive(Box<Tree>),
        Binary(char, Box<Tree>, Box<Tree>),
        Power(Box<Tree>, Box<Tree>),
        Call(&'static str, Vec<Tree>),
        Group(Box<Tree>),
    }

    fn precedence(tree: &Tree) -> u8 {
        match tree {
            Tree::Binary('+' | '-', _, _) => 1,
            Tree::Binary(_, _, _) => 2,
            Tree::Negate(_) | Tree::Positive(_) => 3,
            Tree::Power(_, _) => 4,
            _ => 5,
        }
    }

    /// Print with the parentheses the grammar requires (plus the tree's own `Group`s).
    fn print(tree: &Tree, minimum: u8) -> String {
        let text = match tree {
            Tree::Literal(text) => text.clone(),
            Tree::Variable(slot) => SPACE_TIME[*slot].to_string(),
            Tree::Named(name, _) => name.to_string(),
            Tree::Negate(operand) => format!("-{}", print(operand, 3)),
            Tree::Positive(operand) => format!("+{}", print(operand, 3)),
            Tree::Binary(operator, left, right) => {
                let level = precedence(tree);
                format!(
                    "{} {operator} {}",
                    print(left, level),
                    print(right, level + 1)
                )
            }
            Tree::Power(base, exponent) => format!("{}^{}", print(base, 5), print(exponent, 3)),
            Tree::Call(name, arguments) => {
                let arguments: Vec<String> = arguments
                    .iter()
                    .map(|argument| print(argument, 0))
                    .collect();
                format!("{name}({})", arguments.join(", "))
            }
            Tree::Group(inner) => format!("({})", print(inner, 0)),
        };
        if precedence(tree) < minimum {
            format!("({text})")
        } else {
            text
        }
    }

    /// Reference evaluation mirroring the documented semantics (folding, exponent
    /// specialization, branch selection). Returns (value, is constant, has a non-finite
    /// constant subexpression).
    fn reference(tree: &Tree, values: &[f64; 4]) -> (f64, bool, bool) {
        let pick = |a: f64, b: f64, keep_first: bool| {
            if a.is_nan() || (!b.is_nan() && keep_first) {
                a
            } else {
                b
            }
        };
        let (value, constant, invalid) = match tree {
            Tree::Literal(text) => (text.parse().unwrap(), true, false),
            Tree::Variable(slot) => (values[*slot], false, false),
            Tree::Named(_, value) => (*value, true, false),
            Tree::Negate(operand) => {
                let (value, constant, invalid) = reference(operand, values);
                (-value, constant, invalid)
            }
            Tree::Positive(operand) | Tree::Group(operand) => reference(operand, values),
            Tree::Binary(operator, left, right) => {
                let (a, a_constant, a_invalid) = reference(left, values);
                let (b, b_constant, b_invalid) = reference(right, values);
                let value = match operator {
                    '+' => a + b,
                    '-' => a - b,
                    '*' => a * b,
                    _ => a / b,
                };
                (value, a_constant && b_constant, a_invalid || b_invalid)
            }
            Tree::Power(base, exponent) => power_reference(base, exponent, values),
            Tree::Call(name, arguments) => {
                if *name == "pow" {
                    power_reference(&arguments[0], &arguments[1], values)
                } else if *name == "pospow" {
                    let (a, constant, invalid) = reference(&arguments[0], values);
                    let (p, _, _) = reference(&arguments[1], values);
                    let value = if a > 0.0 {
                        a.powf(p)
                    } else if a.is_nan() {
                        a
                    } else {
                        0.0
                    };
                    (value, constant, invalid)
                } else {
                    let evaluated: Vec<_> = arguments
                        .iter()
                        .map(|argument| reference(argument, values))
                        .collect();
                    let constant = evaluated.iter().all(|(_, constant, _)| *constant);
                    let invalid = evaluated.iter().any(|(_, _, invalid)| *invalid);
                    let a = evaluated[0].0;
                    let value = match *name {
                        "sqrt" => a.sqrt(),
                        "exp" => a.exp(),
                        "ln" | "log" => a.ln(),
                        "sin" => a.sin(),
                        "cos" => a.cos(),
                        "tan" => a.tan(),
                        "tanh" => a.tanh(),
                        "abs" => {
                            if a < 0.0 {
                                -a
                            } else {
                                a
                            }
                        }
                        "min" => pick(a, evaluated[1].0, a <= evaluated[1].0),
                        "max" => pick(a, evaluated[1].0, a >= evaluated[1].0),
                        other => unreachable!("no function {other} is generated"),
                    };
                    (value, constant, invalid)
                }
            }
        };
        (value, constant, invalid || (constant && !value.is_finite()))
    }

    fn power_reference(base: &Tree, exponent: &Tree, values: &[f64; 4]) -> (f64, bool, bool) {
        let (a, a_constant, a_invalid) = reference(base, values);
        let (b, b_constant, b_invalid) = reference(exponent, values);
        let value = if b_constant && b == b.trunc() && b.abs() <= 1000.0 {
            a.powi(b as i32)
        } else if b_constant {
            a.powf(b)
        } else {
            (a.ln() * b).exp()
        };
        (value, a_constant && b_constant, a_invalid || b_invalid)
    }

    fn tree_strategy() -> impl Strategy<Value = Tree> {
        let literal = prop_oneof![
            (0u32..20).prop_map(|n| n.to_string()),
            (0u32..1000).prop_map(|n| format!("{}.{:02}", n / 100, n % 100)),
            (1u32..10, -3i32..3).prop_map(|(m, e)| format!("{m}e{e}")),
            (1u32..10).prop_map(|d| format!(".{d}")),
        ]
        .prop_map(Tree::Literal);
        let leaf = prop_oneof![
            3 => literal,
            4 => (0usize..4).prop_map(Tree::Variable),
            1 => prop_oneof![
                Just(Tree::Named("pi", PI)),
                Just(Tree::Named("e", E)),
                Just(Tree::Named("a", 0.3)),
            ],
        ];
        leaf.prop_recursive(5, 40, 2, |inner| {
            let unary_names = prop_oneof![
                Just("sqrt"),
                Just("exp"),
                Just("ln"),
                Just("log"),
                Just("sin"),
                Just("cos"),
                Just("tan"),
                Just("tanh"),
                Just("abs"),
            ];
            let binary_names = prop_oneof![Just("min"), Just("max"), Just("pow")];
            prop_oneof![
                inner.clone().prop_map(|t| Tree::Negate(Box::new(t))),
                inner.clone().prop_map(|t| Tree::Positive(Box::new(t))),
                inner.clone().prop_map(|t| Tree::Group(Box::new(t))),
                (
                    prop_oneof![Just('+'), Just('-'), Just('*'), Just('/')],
                    inner.clone(),
                    inner.clone()
                )
                    .prop_map(|(op, l, r)| Tree::Binary(
                        op,
                        Box::new(l),
                        Box::new(r)
                    )),
                (inner.clone(), inner.clone())
                    .prop_map(|(b, e)| Tree::Power(Box::new(b), Box::new(e))),
                (unary_names, inner.clone()).prop_map(|(name, t)| Tree::Call(name, vec![t])),
                (binary_names, inner.clone(), inner.clone())
                    .prop_map(|(name, a, b)| Tree::Call(name, vec![a, b])),
                (inner, 1u32..40).prop_map(|(a, quarters)| Tree::Call(
                    "pospow",
                    vec![a, Tree::Literal(format!("{}", f64::from(quarters) / 4.0))]
                )),
            ]
        })
    }

    /// Equal to 1e-13 relative, or both NaN, or the same infinity (the compiled program and
    /// the tree walk apply the same operations, so in fact the bits agree).
    fn agree(computed: f64, expected: f64) -> bool {
        computed.to_bits() == expected.to_bits()
            || (computed.is_nan() && expected.is_nan())
            || (computed - expected).abs() <= 1e-13 * expected.abs()
    }

    /// Derivative parts: as [`agree`] where the tree's is finite (where it is not, the
    /// compiled program may be finite: it skips the tree's `0 · a` terms of constant
    /// operands, see [`compiled`]).
    fn derivatives_agree(computed: f64, expected: f64) -> bool {
        !expected.is_finite() || agree(computed, expected)
    }

    /// Value and gradient in (x, y, z, t) on first-order duals through `evaluate`.
    fn gradient_of(
        expression: &Expr,
        values: &[f64; 4],
        evaluate: fn(&Expr, &[DualSVec64<4>]) -> DualSVec64<4>,
    ) -> (f64, SVector<f64, 4>) {
        gradient(
            |v: SVector<DualSVec64<4>, 4>| evaluate(expression, v.as_slice()),
            &SVector::from(*values),
        )
    }

    /// The value of `expression` on `tape`, its time derivative, and (∂j, ∂j∂t) for j = x, y, z.
    fn first_derivatives(tape: &mut Tape, expression: &Expr) -> Vec<derivative::Value> {
        let value = tape.expression(expression);
        let rate = tape.derivative(value, 3);
        let mut outputs = vec![value, rate];
        for j in 0..3 {
            outputs.push(tape.derivative(value, j));
            outputs.push(tape.derivative(rate, j));
        }
        outputs
    }

    /// Every derivative the manufactured data use: value, ∂t, ∂j, ∂j∂t (as
    /// [`first_derivatives`]), then ∂j∂k and ∂j∂k∂t for j ≤ k.
    fn manufactured_derivatives(tape: &mut Tape, expression: &Expr) -> Vec<derivative::Value> {
        let mut outputs = first_derivatives(tape, expression);
        let (value, rate) = (outputs[0], outputs[1]);
        for j in 0..3 {
            for k in j..3 {
                let first = tape.derivative(value, j);
                outputs.push(tape.derivative(first, k));
                let first_rate = tape.derivative(rate, j);
                outputs.push(tape.derivative(first_rate, k));
            }
        }
        outputs
    }

    /// The expression printed from `tree` (None when it does not parse) with the program of
    /// every derivative the manufactured data use.
    fn compiled_manufactured(tree: &Tree) -> Option<(String, Expr, Program)> {
        let source = print(tree, 0);
        let expression = Expr::parse(&source, &SPACE_TIME, &user_constants()).ok()?;
        let mut tape = Tape::new(4);
        let outputs = manufactured_derivatives(&mut tape, &expression);
        let program = tape.compile(&outputs);
        Some((source, expression, program))
    }

    /// One column per variable (x, y, z, t) of the first `count` points.
    fn point_columns(points: &[[f64; 4]], count: usize) -> Vec<Vec<f64>> {
        (0..4)
            .map(|v| points.iter().take(count).map(|p| p[v]).collect())
            .collect()
    }

    /// Cases each random-expression test below runs to the end: values of its strategy whose
    /// printed expression parses. The others (a constant subexpression that is not finite,
    /// e.g. `ln(0)` or `1/0`) are rejected with `prop_assume!` and do not count.
    const ACCEPTED_CASES: u32 = 256;

    /// Cases accepted and rejected by one run of [`run_accepted`].
    struct Counts {
        accepted: usize,
        rejected: usize,
    }

    /// Runs `test` on values of `strategy` as `proptest!` does (its configuration, failure
    /// persistence and shrinking) until [`ACCEPTED_CASES`] values were accepted, counting the
    /// cases `test` accepts and rejects (`prop_assume!`); asserts that that many were accepted.
    fn run_accepted<S: Strategy>(
        name: &'static str,
        strategy: S,
        test: impl Fn(S::Value) -> TestCaseResult,
    ) -> Counts {
        let accepted = AtomicUsize::new(0);
        let rejected = AtomicUsize::new(0);
        let mut config =
            proptest::test_runner::contextualize_config(ProptestConfig::with_cases(ACCEPTED_CASES));
        config.test_name = Some(name);
        config.source_file = Some(file!());
        let cases = config.cases as usize;
        let mut runner = TestRunner::new(config);
        let result = runner.run(&strategy, |value| {
            let result = test(value);
            match result {
                Ok(()) => _ = accepted.fetch_add(1, Ordering::Relaxed),
                Err(TestCaseError::Reject(_)) => _ = rejected.fetch_add(1, Ordering::Relaxed),
                Err(TestCaseError::Fail(_)) => {}
            }
            result
        });
        if let Err(error) = result {
            panic!("{name}: {error}\n{runner}");
        }
        let counts = Counts {
            accepted: accepted.into_inner(),
            rejected: rejected.into_inner(),
        };
        eprintln!(
            "{name}: {} cases accepted, {} rejected (expression does not parse)",
            counts.accepted, counts.rejected
        );
        assert!(
            counts.accepted >= cases,
            "{name}: {} cases accepted, {cases} wanted",
            counts.accepted
        );
        counts
    }

    /// The expression printed from `tree`, parsed; rejects the case when it does not parse.
    fn parsed(tree: &Tree) -> Result<(String, Expr), TestCaseError> {
        let source = print(tree, 0);
        let parsed = Expr::parse(&source, &SPACE_TIME, &user_constants());
        prop_assume!(parsed.is_ok(), "`{}` does not parse", source);
        Ok((source, parsed.unwrap()))
    }

    /// At most this fraction of the generated trees may fail to parse. Observed: 0 to 17
    /// rejected per 256 accepted (at most 6.2%, mean 2.2%) in 2500 runs of the four tests; a
    /// larger fraction would mean the generator drifted towards invalid expressions.
    const MAX_REJECTED_FRACTION: f64 = 0.1;

    /// Asserts that at most [`MAX_REJECTED_FRACTION`] of the cases of `counts` were rejected.
    fn assert_few_rejected(name: &str, counts: &Counts) {
        let fraction = counts.rejected as f64 / (counts.accepted + counts.rejected) as f64;
        assert!(
            fraction <= MAX_REJECTED_FRACTION,
            "{name}: {fraction:.3} of the cases rejected"
        );
    }

    #[test]
    fn compiled_programs_agree_with_the_tree_on_random_expressions() {
        let name = "compiled_programs_agree_with_the_tree_on_random_expressions";
        let strategy = (tree_strategy(), proptest::array::uniform4(-2.0f64..2.0));
        let counts = run_accepted(name, strategy, |(tree, values)| {
            let (source, expression) = parsed(&tree)?;
            // Plain numbers.
            let compiled = expression.eval_compiled(&values);
            let walked = expression.eval(&values);
            prop_assert!(
                agree(compiled, walked),
                "`{source}` at {values:?}: {compiled} vs {walked}"
            );
            // Nested duals as in `manufactured::jet`: value, gradient and Hessian in space
            // (3D), each with its time derivative.
            let point = SVector::<Dual64, 3>::from_fn(|i, _| Dual64::from(values[i]));
            let ((value, gradient, hess), (value_ref, gradient_ref, hess_ref)) = hessian(
                |p: SVector<Dual2Vec<Dual64, nalgebra::Const<3>>, 3>| {
                    let time = Dual2Vec::from_re(Dual64::new(values[3], 1.0));
                    let vars = [p[0], p[1], p[2], time];
                    (expression.eval_compiled(&vars), expression.eval(&vars))
                },
                &point,
            );
            let mut pairs = vec![(value, value_ref)];
            pairs.extend(gradient.iter().copied().zip(gradient_ref.iter().copied()));
            pairs.extend(hess.iter().copied().zip(hess_ref.iter().copied()));
            prop_assert!(agree(value.re, value_ref.re), "`{source}` at {values:?}");
            for (computed, expected) in pairs {
                prop_assert!(
                    derivatives_agree(computed.re, expected.re)
                        && derivatives_agree(computed.eps, expected.eps),
                    "`{source}` at {values:?}: {computed} vs {expected}"
                );
            }
            // First-order duals as in `manufactured::value_gradient`.
            let (value, gradient) = gradient_of(&expression, &values, Expr::eval_compiled);
            let (value_ref, gradient_ref) = gradient_of(&expression, &values, Expr::eval);
            prop_assert!(agree(value, value_ref), "`{source}` at {values:?}");
            for i in 0..4 {
                prop_assert!(
                    derivatives_agree(gradient[i], gradient_ref[i]),
                    "`{source}` at {values:?}"
                );
            }
            Ok(())
        });
        assert_few_rejected(name, &counts);
    }

    /// The batch evaluation compiled for AVX2 and the baseline one give bitwise the same
    /// registers, on full batches of [`split::BATCH`] points and partial ones, with every
    /// derivative the manufactured data use. Both loops are called directly; on a processor
    /// without AVX2 (where only the baseline loop can run) the test says so and compares
    /// nothing, and [`batch_dispatch_takes_the_avx2_loop_exactly_where_the_processor_has_it`]
    /// checks that the baseline loop is the one taken there.
    #[test]
    fn batch_evaluation_with_and_without_avx2_is_bitwise_the_same() {
        let name = "batch_evaluation_with_and_without_avx2_is_bitwise_the_same";
        #[cfg(not(target_arch = "x86_64"))]
        {
            eprintln!("{name}: not run: not an x86-64 processor, there is no AVX2 loop");
        }
        #[cfg(target_arch = "x86_64")]
        {
            if !std::arch::is_x86_feature_detected!("avx2") {
                eprintln!("{name}: not run: no AVX2 on this machine");
                return;
            }
            if cfg!(target_feature = "avx2") {
                // The baseline loop is compiled for the target's features: with AVX2 among
                // them both loops are the same code.
                eprintln!("{name}: not run: the baseline loop is itself compiled with AVX2");
                return;
            }
            let strategy = (
                tree_strategy(),
                proptest::collection::vec(
                    proptest::array::uniform4(-2.0f64..2.0),
                    1..split::BATCH + 40,
                ),
            );
            let counts = run_accepted(name, strategy, |(tree, points)| {
                let compiled = compiled_manufactured(&tree);
                prop_assume!(compiled.is_some(), "`{}` does not parse", print(&tree, 0));
                let (source, _, program) = compiled.unwrap();
                for count in [points.len(), split::BATCH.min(points.len())] {
                    let columns = point_columns(&points, count);
                    let inputs: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
                    let inputs = batch::Inputs::new(&inputs, &[], count);
                    let mut baseline = vec![0.0; program.len() * count];
                    program.eval_columns(&inputs, count, &mut baseline, true);
                    let mut avx2 = vec![0.0; program.len() * count];
                    // SAFETY: the processor has AVX2 (checked above).
                    unsafe { program.eval_columns_avx2(&inputs, count, &mut avx2, true) };
                    // NaN as one value: which operand's NaN payload (or sign) a product of two
                    // NaNs keeps depends on the instruction's operand order, which the
                    // compiler may swap; every other value bit for bit.
                    let bits = |registers: &[f64]| -> Vec<u64> {
                        registers
                            .iter()
                            .map(|r| {
                                if r.is_nan() {
                                    f64::NAN.to_bits()
                                } else {
                                    r.to_bits()
                                }
                            })
                            .collect()
                    };
                    prop_assert_eq!(bits(&baseline), bits(&avx2), "`{}`", source);
                }
                Ok(())
            });
            assert_few_rejected(name, &counts);
        }
    }

    /// The batch evaluation takes the AVX2 loop where the processor has AVX2 and the baseline
    /// loop everywhere else (where the comparison of the two loops above cannot run).
    #[test]
    fn batch_dispatch_takes_the_avx2_loop_exactly_where_the_processor_has_it() {
        #[cfg(target_arch = "x86_64")]
        let has_avx2 = std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let has_avx2 = false;
        let expression = parse("x * y + sin(z) - t");
        let mut tape = Tape::new(4);
        let value = tape.expression(&expression);
        let program = tape.compile(&[value]);
        let columns = point_columns(&[[0.1, 0.2, 0.3, 0.4], [1.0, 2.0, 3.0, 4.0]], 2);
        let inputs: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
        batch::tests::LAST_PATH.with(|last| last.set(None));
        let mut registers = Vec::new();
        program.eval_batch(&inputs, 2, &mut registers);
        let taken = batch::tests::LAST_PATH.with(|last| last.get());
        let expected = if has_avx2 {
            batch::BatchPath::Avx2
        } else {
            batch::BatchPath::Baseline
        };
        assert_eq!(taken, Some(expected), "AVX2 detected: {has_avx2}");
        eprintln!("AVX2 detected: {has_avx2}; the batch evaluation took the {expected:?} loop");
        assert_eq!(
            program.batch_output(&registers, 2, 0)[1],
            expression.eval_f64(&[1.0, 2.0, 3.0, 4.0])
        );
    }

    /// Relative moves of the point (in pairs ±s) for the noise estimate of the test below.
    const NOISE_STEPS: [f64; 4] = [1e-9, -1e-9, 2e-9, -2e-9];

    /// The order of each output of [`manufactured_derivatives`]: value, ∂t, (∂j, ∂j∂t) × 3,
    /// (∂j∂k, ∂j∂k∂t) × 6.
    const JET_ORDERS: [usize; 20] = [0, 1, 1, 2, 1, 2, 1, 2, 2, 3, 2, 3, 2, 3, 2, 3, 2, 3, 2, 3];

    /// The outputs of [`manufactured_derivatives`] at `values` by the tree walk on nested duals
    /// as in `manufactured::jet` (the reference of the symbolic derivatives).
    fn dual_jet(expression: &Expr, values: &[f64; 4]) -> Vec<f64> {
        let point = SVector::<Dual64, 3>::from_fn(|i, _| Dual64::from(values[i]));
        let (v, g, h) = hessian(
            |x: SVector<Dual2Vec<Dual64, nalgebra::Const<3>>, 3>| {
                let time = Dual2Vec::from_re(Dual64::new(values[3], 1.0));
                expression.eval(&[x[0], x[1], x[2], time])
            },
            &point,
        );
        let mut jet = vec![v.re, v.eps];
        for j in 0..3 {
            jet.extend([g[j].re, g[j].eps]);
        }
        for j in 0..3 {
            for k in j..3 {
                jet.extend([h[(j, k)].re, h[(j, k)].eps]);
            }
        }
        jet
    }

    /// At most this fraction of the points where the field is defined may be skipped by the
    /// test below (the dual reference is no 1e-13 reference there, or the point is
    /// ill-conditioned). Observed: 0.095 to 0.284 (mean 0.183, standard deviation 0.025) in
    /// 5000 runs of 256 cases, with 429 to 619 points compared in each. Nearly all skipped
    /// points (96 %) have an intermediate value above 100, mostly from `pospow` of a large base
    /// or exponent. 0.40 is 8.7 standard deviations above the mean, and a run that skips it
    /// still compares more than half of its points.
    const MAX_SKIPPED_FRACTION: f64 = 0.40;

    #[test]
    fn symbolic_derivatives_in_batches_agree_with_nested_duals_on_random_expressions() {
        let name = "symbolic_derivatives_in_batches_agree_with_nested_duals_on_random_expressions";
        let points_compared = AtomicUsize::new(0);
        let points_undefined = AtomicUsize::new(0);
        let points_skipped = AtomicUsize::new(0);
        let strategy = (
            tree_strategy(),
            proptest::collection::vec(proptest::array::uniform4(-2.0f64..2.0), 1..6),
        );
        let counts = run_accepted(name, strategy, |(tree, points)| {
            let compiled = compiled_manufactured(&tree);
            prop_assume!(compiled.is_some(), "`{}` does not parse", print(&tree, 0));
            let (source, expression, program) = compiled.unwrap();
            let count = points.len();
            let columns = point_columns(&points, count);
            let inputs: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
            let mut registers = Vec::new();
            program.eval_batch(&inputs, count, &mut registers);
            // Every point scaled by 1 + s for s in NOISE_STEPS: the moved points and the
            // registers of the symbolic program there.
            let moved: Vec<(Vec<[f64; 4]>, Vec<f64>)> = NOISE_STEPS
                .iter()
                .map(|step| {
                    let moved: Vec<[f64; 4]> =
                        points.iter().map(|p| p.map(|x| x * (1.0 + step))).collect();
                    let columns = point_columns(&moved, count);
                    let inputs: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
                    let mut registers = Vec::new();
                    program.eval_batch(&inputs, count, &mut registers);
                    (moved, registers)
                })
                .collect();
            for (p, values) in points.iter().enumerate() {
                let jet = dual_jet(&expression, values);
                // The value on plain numbers (nested duals may turn e.g. 0^pi into NaN).
                let plain = expression.eval(values);
                if !plain.is_finite() {
                    // The field is undefined at the point (`ln` of a negative number, ...):
                    // its value is compared, its derivatives are not.
                    let computed = program.batch_output(&registers, count, 0)[p];
                    prop_assert!(
                        agree(computed, plain),
                        "`{source}` at {values:?}: {computed} vs {plain}"
                    );
                    points_undefined.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                // The dual reference computes powers as x^(n−3)·x·x·x (num-dual), which rounds
                // differently from `powi`; where that alone moves its value by more than 1e-14
                // (e.g. `sin((10 + x)^4)`: sin of a large argument), or makes it NaN (0^pi), its
                // derivatives are not a 1e-13 reference and the point is skipped (and counted).
                let dual_value_agrees = (jet[0] - plain).abs() <= 1e-14 * plain.abs().max(1.0);
                if !dual_value_agrees {
                    points_skipped.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                let mut expected = jet;
                expected[0] = plain;
                // Well-conditioned points only: every intermediate value of the derivative
                // program finite and at most 100 in magnitude. Elsewhere both evaluations are
                // dominated by their own rounding (sin of a large argument, cancellations of
                // large terms in third derivatives) or by conventions for ∞·0 at exact
                // singularities (ln 0, 0^b, underflow to 0 under a square root); such points
                // are skipped (and counted).
                let intermediate = (0..program.len())
                    .map(|i| registers[i * count + p].abs())
                    .fold(
                        0.0f64,
                        |m, r| if r.is_nan() { f64::INFINITY } else { m.max(r) },
                    );
                if intermediate > 100.0 {
                    points_skipped.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                // 1e-13 relative to the jet up to the output's order and to the largest
                // intermediate value of the evaluation: a derivative that vanishes analytically
                // (∂²y/∂y² of `1/(1/y)`, tanh' where tanh = 1) is a rounding residue of terms of
                // that size, in either evaluation.
                let scale = |output: usize| {
                    expected
                        .iter()
                        .zip(JET_ORDERS)
                        .filter(|(e, o)| *o <= JET_ORDERS[output] && e.is_finite())
                        .fold(intermediate, |m, (e, _)| m.max(e.abs()))
                };
                // Both evaluations can cancel terms far larger than the intermediate values of
                // the symbolic program (seen: `sin(x) / -x` and `x / min(0, tan(x))` near
                // x = 0, ∂x∂x off by 4.7e-12 and 2.2e-11 in the symbolic program; the reference's
                // `(x / x)^1`, ∂x∂x = −2/x² + 2x/x³, −1.5e-11 at x = −0.0048 against 0).
                // Their rounding error is estimated from the noise of each evaluation (Moré &
                // Wild's ECnoise): the second difference f(p(1 + s)) + f(p(1 − s)) − 2 f(p) at
                // s = 1e-9 and 2e-9, where the jet itself changes by about s² |p|² |∇²f| but the
                // rounding of every intermediate value changes. Where that noise exceeds 1e-14 of
                // the output's scale for either evaluation, the point is ill-conditioned for a
                // 1e-13 comparison and is skipped (and counted).
                let noisy = (0..NOISE_STEPS.len() / 2).any(|pair| {
                    let (up, down) = (&moved[2 * pair], &moved[2 * pair + 1]);
                    let (reference_up, reference_down) = (
                        dual_jet(&expression, &up.0[p]),
                        dual_jet(&expression, &down.0[p]),
                    );
                    (1..expected.len()).any(|o| {
                        let symbolic =
                            |registers: &[f64]| program.batch_output(registers, count, o)[p];
                        let reference_noise =
                            reference_up[o] + reference_down[o] - 2.0 * expected[o];
                        let symbolic_noise =
                            symbolic(&up.1) + symbolic(&down.1) - 2.0 * symbolic(&registers);
                        reference_noise.abs().max(symbolic_noise.abs()) > 1e-14 * scale(o)
                    })
                });
                if noisy {
                    points_skipped.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                points_compared.fetch_add(1, Ordering::Relaxed);
                for (output, &wanted) in expected.iter().enumerate() {
                    let computed = program.batch_output(&registers, count, output)[p];
                    let close = (computed - wanted).abs() <= 1e-13 * scale(output);
                    prop_assert!(
                        if output == 0 {
                            agree(computed, wanted)
                        } else {
                            !wanted.is_finite() || close || agree(computed, wanted)
                        },
                        "`{source}` at {values:?}, output {output}: {computed} vs {wanted}"
                    );
                }
            }
            Ok(())
        });
        assert_few_rejected(name, &counts);
        let compared = points_compared.into_inner();
        let undefined = points_undefined.into_inner();
        let skipped = points_skipped.into_inner();
        let fraction = skipped as f64 / (compared + skipped) as f64;
        eprintln!(
            "{name}: derivatives compared at {compared} points, skipped at {skipped} \
             ({fraction:.3} of the points where the field is defined); value only at {undefined} \
             points where it is not"
        );
        assert!(
            fraction <= MAX_SKIPPED_FRACTION,
            "{name}: skipped at {skipped} of {} points",
            compared + skipped
        );
    }

    #[test]
    fn split_programs_are_bitwise_the_whole_program_on_random_expressions() {
        let name = "split_programs_are_bitwise_the_whole_program_on_random_expressions";
        let strategy = (
            tree_strategy(),
            proptest::collection::vec(
                proptest::array::uniform3(-2.0f64..2.0),
                1..2 * split::BATCH + 20,
            ),
            proptest::collection::vec(-2.0f64..2.0, 1..4),
        );
        let counts = run_accepted(name, strategy, |(tree, points, times)| {
            let (source, expression) = parsed(&tree)?;
            let mut tape = Tape::new(4);
            let outputs = first_derivatives(&mut tape, &expression);
            let program = tape.compile(&outputs);
            let split = split::SplitProgram::new(program.clone(), 3, 1 << 24);
            let count = points.len();
            let mut registers = Vec::new();
            for &t in &times {
                let columns: Vec<Vec<f64>> = (0..3)
                    .map(|v| points.iter().map(|p| p[v]).collect())
                    .chain([vec![t; count]])
                    .collect();
                let inputs: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
                program.eval_batch(&inputs, count, &mut registers);
                // The first time fills the cache, later times read it.
                split.for_batches(&points, t, |offset, batch| {
                    for k in 0..program.output_count() {
                        let whole =
                            &program.batch_output(&registers, count, k)[offset..][..batch.count()];
                        for (p, (a, b)) in batch.get(k).iter().zip(whole).enumerate() {
                            assert!(
                                a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                                "`{source}` output {k} at {:?}, t = {t}: {a} vs {b}",
                                points[offset + p]
                            );
                        }
                    }
                });
            }
            prop_assert!(split.cached_bytes() > 0 || split.frontier_len() == 0);
            Ok(())
        });
        assert_few_rejected(name, &counts);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn printed_random_trees_reparse_to_the_same_value(
            tree in tree_strategy(),
            values in proptest::array::uniform4(-2.0f64..2.0),
        ) {
            let source = print(&tree, 0);
            let (expected, _, invalid_constant) = reference(&tree, &values);
            match Expr::parse(&source, &SPACE_TIME, &user_constants()) {
                Ok(expression) => {
                    prop_assert!(!invalid_constant, "`{source}` should fail (non-finite constant)");
                    let value = expression.eval_f64(&values);
                    prop_assert!(
                        value.to_bits() == expected.to_bits() || (value.is_nan() && expected.is_nan()),
                        "`{source}` at {values:?}: parsed {value} vs reference {expected}"
                    );
                }
                Err(error) => {
                    prop_assert!(invalid_constant, "`{source}` failed: {error}");
                    prop_assert!(error.message.contains("not finite"), "`{source}`: {error}");
                }
            }
        }

        #[test]
        fn garbage_never_panics(source in "[-+*/^(),.0-9a-z_ eE#]{0,40}") {
            if let Ok(expression) = Expr::parse(&source, &SPACE_TIME, &user_constants()) {
                let _ = expression.eval_f64(&[0.1, 0.2, 0.3, 0.4]);
                let _ = expression.used_variables();
            }
        }

        #[test]
        fn arbitrary_unicode_never_panics(source in any::<String>()) {
            if let Ok(expression) = Expr::parse(&source, &SPACE_TIME, &user_constants()) {
                let _ = expression.eval_f64(&[0.1, 0.2, 0.3, 0.4]);
            }
        }
    }
}
