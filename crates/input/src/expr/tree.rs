//! The syntax tree of an expression after name resolution, constant folding and exponent
//! specialization, and its evaluation on dual numbers (see the documentation of the `expr`
//! module): the nodes, the functions of one argument, the branch rules of `abs`, `min` and
//! `max`, and the walks over the tree.

use num_dual::DualNum;

/// Largest depth of the syntax tree and of parser recursion (parentheses, unary signs):
/// bounds the stack used by the recursive parser and evaluator.
pub(super) const MAX_DEPTH: usize = 200;

/// Functions of one argument, evaluated elementwise on dual numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum UnaryFunction {
    Sqrt,
    Exp,
    Ln,
    Sin,
    Cos,
    Tan,
    Tanh,
    Abs,
}

/// Syntax tree after name resolution, constant folding and exponent specialization.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Node {
    Constant(f64),
    /// Index into the value slice of [`Expr::eval`](super::Expr::eval).
    Variable(usize),
    Negate(Box<Node>),
    Add(Box<Node>, Box<Node>),
    Subtract(Box<Node>, Box<Node>),
    Multiply(Box<Node>, Box<Node>),
    Divide(Box<Node>, Box<Node>),
    /// `a^n`, constant integer `n`: `powi`.
    PowerInteger(Box<Node>, i32),
    /// `a^p`, constant non-integer `p`: `powf`.
    PowerReal(Box<Node>, f64),
    /// `a^b`, variable `b`: `exp(b ln a)`.
    PowerVariable(Box<Node>, Box<Node>),
    /// `pospow(a, p) = max(0, a)^p`, constant `p`: [`positive_power`].
    PositivePower(Box<Node>, f64),
    Apply(UnaryFunction, Box<Node>),
    Min(Box<Node>, Box<Node>),
    Max(Box<Node>, Box<Node>),
}

/// Recursive evaluation of the tree (depth bounded by [`MAX_DEPTH`]).
pub(super) fn evaluate<T: DualNum<Primitive = f64> + Copy>(node: &Node, values: &[T]) -> T {
    match node {
        Node::Constant(value) => T::from(*value),
        Node::Variable(slot) => values[*slot],
        Node::Negate(operand) => -evaluate(operand, values),
        Node::Add(left, right) => evaluate(left, values) + evaluate(right, values),
        Node::Subtract(left, right) => evaluate(left, values) - evaluate(right, values),
        Node::Multiply(left, right) => evaluate(left, values) * evaluate(right, values),
        Node::Divide(left, right) => evaluate(left, values) / evaluate(right, values),
        Node::PowerInteger(base, exponent) => evaluate(base, values).powi(*exponent),
        Node::PowerReal(base, exponent) => evaluate(base, values).powf(*exponent),
        Node::PowerVariable(base, exponent) => {
            (evaluate(base, values).ln() * evaluate(exponent, values)).exp()
        }
        Node::PositivePower(base, exponent) => positive_power(evaluate(base, values), *exponent),
        Node::Apply(function, argument) => function.apply(evaluate(argument, values)),
        Node::Min(left, right) => minimum(evaluate(left, values), evaluate(right, values)),
        Node::Max(left, right) => maximum(evaluate(left, values), evaluate(right, values)),
    }
}

impl UnaryFunction {
    /// The function applied to a (dual) number; `abs` picks the branch by the real part.
    #[inline]
    pub(super) fn apply<T: DualNum<Primitive = f64> + Copy>(self, argument: T) -> T {
        match self {
            UnaryFunction::Sqrt => argument.sqrt(),
            UnaryFunction::Exp => argument.exp(),
            UnaryFunction::Ln => argument.ln(),
            UnaryFunction::Sin => argument.sin(),
            UnaryFunction::Cos => argument.cos(),
            UnaryFunction::Tan => argument.tan(),
            UnaryFunction::Tanh => argument.tanh(),
            UnaryFunction::Abs => {
                if argument.re() < 0.0 {
                    -argument
                } else {
                    argument
                }
            }
        }
    }
}

/// `max(0, a)^p` for a constant exponent `p`: `powf` where the real part of `a` is positive, and
/// zero with every derivative where it is not (the function vanishes identically for `a ≤ 0`,
/// so its one-sided derivatives from there are zero); a NaN argument is returned as is.
///
/// Where `a > 0` the derivatives are the classical ones, `p a^(p−1) a'`, …; those of order
/// above `p` grow without bound as `a → 0⁺` (the point of the function: a profile of limited
/// smoothness), and at `a = 0` the zero of the left side is taken.
#[inline]
pub(crate) fn positive_power<T: DualNum<Primitive = f64> + Copy>(argument: T, exponent: f64) -> T {
    let real = argument.re();
    if real > 0.0 {
        argument.powf(exponent)
    } else if real.is_nan() {
        argument
    } else {
        T::from(0.0)
    }
}

/// `min(a, b)`: by real part, the first on ties, a NaN argument wins.
#[inline]
pub(super) fn minimum<T: DualNum<Primitive = f64> + Copy>(first: T, second: T) -> T {
    select_by_real_part(first, second, |a, b| a <= b)
}

/// `max(a, b)`: by real part, the first on ties, a NaN argument wins.
#[inline]
pub(super) fn maximum<T: DualNum<Primitive = f64> + Copy>(first: T, second: T) -> T {
    select_by_real_part(first, second, |a, b| a >= b)
}

/// `first` if `keep_first(re first, re second)`, else `second`; a NaN argument wins, so that
/// `min`/`max` never hide a NaN.
#[inline]
fn select_by_real_part<T: DualNum<Primitive = f64> + Copy>(
    first: T,
    second: T,
    keep_first: impl Fn(f64, f64) -> bool,
) -> T {
    if picks_first(first.re(), second.re(), keep_first) {
        first
    } else {
        second
    }
}

/// The branch rule of `min`/`max` on real parts `a`, `b`: the first if `keep_first(a, b)`, and
/// a NaN wins.
#[inline]
pub(super) fn picks_first(a: f64, b: f64, keep_first: impl Fn(f64, f64) -> bool) -> bool {
    a.is_nan() || (!b.is_nan() && keep_first(a, b))
}

pub(super) fn mark_variables(node: &Node, used: &mut [bool]) {
    match node {
        Node::Constant(_) => {}
        Node::Variable(slot) => used[*slot] = true,
        Node::Negate(operand)
        | Node::PowerInteger(operand, _)
        | Node::PowerReal(operand, _)
        | Node::PositivePower(operand, _)
        | Node::Apply(_, operand) => mark_variables(operand, used),
        Node::Add(left, right)
        | Node::Subtract(left, right)
        | Node::Multiply(left, right)
        | Node::Divide(left, right)
        | Node::PowerVariable(left, right)
        | Node::Min(left, right)
        | Node::Max(left, right) => {
            mark_variables(left, used);
            mark_variables(right, used);
        }
    }
}

/// True if every direct child is a constant (children are folded first, so the whole
/// subtree is then variable-free). Leaves return false: they need no folding.
pub(super) fn children_are_constant(node: &Node) -> bool {
    let is_constant = |child: &Node| matches!(child, Node::Constant(_));
    match node {
        Node::Constant(_) | Node::Variable(_) => false,
        Node::Negate(operand)
        | Node::PowerInteger(operand, _)
        | Node::PowerReal(operand, _)
        | Node::PositivePower(operand, _)
        | Node::Apply(_, operand) => is_constant(operand),
        Node::Add(left, right)
        | Node::Subtract(left, right)
        | Node::Multiply(left, right)
        | Node::Divide(left, right)
        | Node::PowerVariable(left, right)
        | Node::Min(left, right)
        | Node::Max(left, right) => is_constant(left) && is_constant(right),
    }
}
