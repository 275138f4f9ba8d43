//! The recursive-descent parser of the expression grammar (see the documentation of the `expr`
//! module): tokens to a syntax tree, with names resolved, variable-free subexpressions folded
//! and constant exponents specialized.

use std::collections::BTreeMap;

use super::token::{tokenize, ExprError, Token, TokenKind};
use super::tree::{children_are_constant, evaluate, Node, UnaryFunction, MAX_DEPTH};

/// Largest |n| for which `a^n` with a constant integer `n` is evaluated by `powi`
/// (num-dual computes n(n−1)(n−2) in `i32` for third derivatives).
const MAX_INTEGER_EXPONENT: f64 = 1000.0;

/// Tokenize and parse `source` into its syntax tree (see [`Expr::parse`]).
///
/// [`Expr::parse`]: super::Expr::parse
pub(super) fn parse(
    source: &str,
    variables: &[&str],
    constants: &BTreeMap<String, f64>,
) -> Result<Node, ExprError> {
    let tokens = tokenize(source)?;
    let mut parser = Parser {
        tokens,
        position: 0,
        source: source.chars().collect(),
        variables,
        constants,
        nesting: 0,
    };
    Ok(parser.parse_top()?.node)
}

/// Functions known to the parser (with their argument counts).
#[derive(Debug, Clone, Copy)]
enum Function {
    Unary(UnaryFunction),
    Min,
    Max,
    Pow,
    PositivePower,
}

const FUNCTION_NAMES: &str = "sqrt, exp, ln, log, sin, cos, tan, tanh, abs, min, max, pow, pospow";

fn lookup_function(name: &str) -> Option<Function> {
    Some(match name {
        "sqrt" => Function::Unary(UnaryFunction::Sqrt),
        "exp" => Function::Unary(UnaryFunction::Exp),
        "ln" | "log" => Function::Unary(UnaryFunction::Ln),
        "sin" => Function::Unary(UnaryFunction::Sin),
        "cos" => Function::Unary(UnaryFunction::Cos),
        "tan" => Function::Unary(UnaryFunction::Tan),
        "tanh" => Function::Unary(UnaryFunction::Tanh),
        "abs" => Function::Unary(UnaryFunction::Abs),
        "min" => Function::Min,
        "max" => Function::Max,
        "pow" => Function::Pow,
        "pospow" => Function::PositivePower,
        _ => return None,
    })
}

/// Built-in constants, always available.
const BUILTIN_CONSTANTS: [(&str, f64); 2] =
    [("pi", std::f64::consts::PI), ("e", std::f64::consts::E)];

/// A parsed subexpression with its source span (0-based character indices) and tree depth.
struct Parsed {
    node: Node,
    start: usize,
    end: usize,
    depth: usize,
}

struct Parser<'a> {
    tokens: Vec<Token>,
    position: usize,
    source: Vec<char>,
    variables: &'a [&'a str],
    constants: &'a BTreeMap<String, f64>,
    /// Current recursion depth through parentheses and unary signs.
    nesting: usize,
}

impl Parser<'_> {
    fn peek(&self) -> &Token {
        &self.tokens[self.position]
    }

    fn advance(&mut self) -> Token {
        let token = self.tokens[self.position].clone();
        if token.kind != TokenKind::End {
            self.position += 1;
        }
        token
    }

    /// How a token is named in messages: "end of input", "number `2.5`", "`x`", "`)`".
    fn describe(&self, token: &Token) -> String {
        let text: String = self.source[token.start..token.end].iter().collect();
        match token.kind {
            TokenKind::End => "end of input".to_string(),
            TokenKind::Number(_) => format!("number `{text}`"),
            _ => format!("`{text}`"),
        }
    }

    fn error(column: usize, message: impl Into<String>) -> ExprError {
        ExprError {
            column,
            message: message.into(),
        }
    }

    /// Enter one level of parser recursion (a parenthesis or a unary sign at `column`).
    fn enter(&mut self, column: usize) -> Result<(), ExprError> {
        self.nesting += 1;
        if self.nesting > MAX_DEPTH {
            return Err(Self::error(
                column,
                format!("expression nested too deeply (more than {MAX_DEPTH} levels)"),
            ));
        }
        Ok(())
    }

    fn leave(&mut self) {
        self.nesting -= 1;
    }

    fn parse_top(&mut self) -> Result<Parsed, ExprError> {
        if self.peek().kind == TokenKind::End {
            return Err(Self::error(1, "empty expression"));
        }
        let parsed = self.parse_expression()?;
        let token = self.peek().clone();
        match token.kind {
            TokenKind::End => Ok(parsed),
            TokenKind::CloseParen => Err(Self::error(
                token.column(),
                "unbalanced parentheses: `)` without a matching `(`",
            )),
            TokenKind::Number(_) | TokenKind::Name(_) | TokenKind::OpenParen => Err(Self::error(
                token.column(),
                format!(
                    "unexpected {} after a complete expression (implicit multiplication is not \
                     supported: write `*`)",
                    self.describe(&token)
                ),
            )),
            _ => Err(Self::error(
                token.column(),
                format!(
                    "unexpected {} after a complete expression",
                    self.describe(&token)
                ),
            )),
        }
    }

    fn parse_expression(&mut self) -> Result<Parsed, ExprError> {
        let mut left = self.parse_term()?;
        loop {
            let kind = self.peek().kind.clone();
            let make: fn(Box<Node>, Box<Node>) -> Node = match kind {
                TokenKind::Plus => Node::Add,
                TokenKind::Minus => Node::Subtract,
                _ => return Ok(left),
            };
            self.advance();
            let right = self.parse_term()?;
            left = self.binary(make, left, right)?;
        }
    }

    fn parse_term(&mut self) -> Result<Parsed, ExprError> {
        let mut left = self.parse_unary()?;
        loop {
            let kind = self.peek().kind.clone();
            let make: fn(Box<Node>, Box<Node>) -> Node = match kind {
                TokenKind::Star => Node::Multiply,
                TokenKind::Slash => Node::Divide,
                _ => return Ok(left),
            };
            self.advance();
            let right = self.parse_unary()?;
            left = self.binary(make, left, right)?;
        }
    }

    fn parse_unary(&mut self) -> Result<Parsed, ExprError> {
        let token = self.peek().clone();
        let negate = match token.kind {
            TokenKind::Minus => true,
            TokenKind::Plus => false,
            _ => return self.parse_power(),
        };
        self.advance();
        self.enter(token.column())?;
        let operand = self.parse_unary()?;
        self.leave();
        if negate {
            self.finish(
                Node::Negate(Box::new(operand.node)),
                token.start,
                operand.end,
                operand.depth + 1,
            )
        } else {
            Ok(Parsed {
                start: token.start,
                ..operand
            })
        }
    }

    fn parse_power(&mut self) -> Result<Parsed, ExprError> {
        let base = self.parse_primary()?;
        if self.peek().kind != TokenKind::Caret {
            return Ok(base);
        }
        let caret = self.advance();
        self.enter(caret.column())?;
        let exponent = self.parse_unary()?;
        self.leave();
        self.power(base, exponent)
    }

    fn parse_primary(&mut self) -> Result<Parsed, ExprError> {
        let token = self.advance();
        match &token.kind {
            TokenKind::Number(value) => Ok(Parsed {
                node: Node::Constant(*value),
                start: token.start,
                end: token.end,
                depth: 1,
            }),
            TokenKind::Name(name) => {
                if self.peek().kind == TokenKind::OpenParen {
                    self.parse_call(name, &token)
                } else {
                    let node = self.resolve_name(name, &token)?;
                    Ok(Parsed {
                        node,
                        start: token.start,
                        end: token.end,
                        depth: 1,
                    })
                }
            }
            TokenKind::OpenParen => {
                self.enter(token.column())?;
                let inner = self.parse_expression()?;
                self.leave();
                let close = self.advance();
                match close.kind {
                    TokenKind::CloseParen => Ok(Parsed {
                        start: token.start,
                        end: close.end,
                        ..inner
                    }),
                    TokenKind::End => Err(Self::error(
                        token.column(),
                        "unbalanced parentheses: this `(` is never closed",
                    )),
                    _ => Err(Self::error(
                        close.column(),
                        format!(
                            "expected an operator or `)` closing the `(` at column {}, found {}",
                            token.column(),
                            self.describe(&close)
                        ),
                    )),
                }
            }
            _ => Err(Self::error(
                token.column(),
                format!(
                    "expected a number, variable, function call or `(`, found {}",
                    self.describe(&token)
                ),
            )),
        }
    }

    /// Parse `name(arguments)`; the current token is the `(`.
    fn parse_call(&mut self, name: &str, name_token: &Token) -> Result<Parsed, ExprError> {
        let Some(function) = lookup_function(name) else {
            let hint = if self.variables.contains(&name) || self.constant_value(name).is_some() {
                format!(" (`{name}` is a variable or constant; write `{name}*(...)` to multiply)")
            } else {
                format!(" (known functions: {FUNCTION_NAMES})")
            };
            return Err(Self::error(
                name_token.column(),
                format!("unknown function `{name}`{hint}"),
            ));
        };
        let open = self.advance();
        self.enter(open.column())?;
        let mut arguments = Vec::new();
        let close = if self.peek().kind == TokenKind::CloseParen {
            self.advance()
        } else {
            loop {
                arguments.push(self.parse_expression()?);
                let separator = self.advance();
                match separator.kind {
                    TokenKind::Comma => continue,
                    TokenKind::CloseParen => break separator,
                    TokenKind::End => {
                        return Err(Self::error(
                            open.column(),
                            format!("unbalanced parentheses: the `(` of `{name}(` is never closed"),
                        ))
                    }
                    _ => {
                        return Err(Self::error(
                            separator.column(),
                            format!(
                                "expected `,` or `)` in the arguments of `{name}`, found {}",
                                self.describe(&separator)
                            ),
                        ))
                    }
                }
            }
        };
        self.leave();
        let expected = match function {
            Function::Unary(_) => 1,
            Function::Min | Function::Max | Function::Pow | Function::PositivePower => 2,
        };
        if arguments.len() != expected {
            let plural = if expected == 1 { "" } else { "s" };
            return Err(Self::error(
                name_token.column(),
                format!(
                    "function `{name}` takes {expected} argument{plural}, found {}",
                    arguments.len()
                ),
            ));
        }
        let mut arguments = arguments.into_iter();
        let first = arguments.next().expect("argument count checked");
        let second = arguments.next();
        let (start, end) = (name_token.start, close.end);
        match (function, second) {
            (Function::Unary(unary), None) => {
                let depth = first.depth + 1;
                self.finish(Node::Apply(unary, Box::new(first.node)), start, end, depth)
            }
            (Function::Min, Some(second)) => {
                let depth = first.depth.max(second.depth) + 1;
                let node = Node::Min(Box::new(first.node), Box::new(second.node));
                self.finish(node, start, end, depth)
            }
            (Function::Max, Some(second)) => {
                let depth = first.depth.max(second.depth) + 1;
                let node = Node::Max(Box::new(first.node), Box::new(second.node));
                self.finish(node, start, end, depth)
            }
            (Function::Pow, Some(second)) => {
                let parsed = self.power(first, second)?;
                Ok(Parsed {
                    start,
                    end,
                    ..parsed
                })
            }
            (Function::PositivePower, Some(second)) => match second.node {
                Node::Constant(exponent) if exponent.is_finite() && exponent > 0.0 => {
                    let depth = first.depth + 1;
                    let node = Node::PositivePower(Box::new(first.node), exponent);
                    self.finish(node, start, end, depth)
                }
                Node::Constant(exponent) => Err(Self::error(
                    name_token.column(),
                    format!("the exponent of `pospow` must be positive, found {exponent}"),
                )),
                _ => Err(Self::error(
                    name_token.column(),
                    "the exponent of `pospow` must be a constant (a number or a named constant)"
                        .to_string(),
                )),
            },
            _ => unreachable!("argument count checked against the function"),
        }
    }

    /// Value of a constant (user constants, then `pi`, `e`), if `name` is one.
    fn constant_value(&self, name: &str) -> Option<f64> {
        self.constants.get(name).copied().or_else(|| {
            BUILTIN_CONSTANTS
                .iter()
                .find(|(builtin, _)| *builtin == name)
                .map(|(_, value)| *value)
        })
    }

    fn resolve_name(&self, name: &str, token: &Token) -> Result<Node, ExprError> {
        let slot = self.variables.iter().position(|variable| *variable == name);
        let constant = self.constant_value(name);
        match (slot, constant) {
            (Some(_), Some(_)) => Err(Self::error(
                token.column(),
                format!("ambiguous name `{name}`: it is both a variable and a constant"),
            )),
            (Some(slot), None) => Ok(Node::Variable(slot)),
            (None, Some(value)) => {
                if let Some((_, builtin)) = BUILTIN_CONSTANTS.iter().find(|(b, _)| *b == name) {
                    if value != *builtin {
                        return Err(Self::error(
                            token.column(),
                            format!(
                                "constant `{name}` = {value} redefines the built-in `{name}` = \
                                 {builtin}"
                            ),
                        ));
                    }
                }
                if !value.is_finite() {
                    return Err(Self::error(
                        token.column(),
                        format!("constant `{name}` = {value} is not finite"),
                    ));
                }
                Ok(Node::Constant(value))
            }
            (None, None) => {
                let message = if lookup_function(name).is_some() {
                    format!("function `{name}` needs its arguments in parentheses: `{name}(...)`")
                } else {
                    let mut constants: Vec<&str> =
                        BUILTIN_CONSTANTS.iter().map(|(name, _)| *name).collect();
                    for key in self.constants.keys() {
                        if !constants.contains(&key.as_str()) {
                            constants.push(key);
                        }
                    }
                    format!(
                        "unknown variable `{name}` (known: {}; constants: {})",
                        if self.variables.is_empty() {
                            "none".to_string()
                        } else {
                            self.variables.join(", ")
                        },
                        constants.join(", ")
                    )
                };
                Err(Self::error(token.column(), message))
            }
        }
    }

    fn binary(
        &self,
        make: fn(Box<Node>, Box<Node>) -> Node,
        left: Parsed,
        right: Parsed,
    ) -> Result<Parsed, ExprError> {
        let depth = left.depth.max(right.depth) + 1;
        if depth > MAX_DEPTH && left.depth >= right.depth {
            // a left-leaning chain `a + b + c + …` is as deep as it is long
            return Err(Self::error(
                right.start + 1,
                format!(
                    "more than {MAX_DEPTH} terms or factors in one chain (the expression tree is \
                     limited to depth {MAX_DEPTH}); group them in parentheses, e.g. \
                     `(a + b + …) + (c + d + …)`"
                ),
            ));
        }
        self.finish(
            make(Box::new(left.node), Box::new(right.node)),
            left.start,
            right.end,
            depth,
        )
    }

    /// `base ^ exponent`, specialized on a constant exponent (see the documentation of the `expr`
    /// module).
    fn power(&self, base: Parsed, exponent: Parsed) -> Result<Parsed, ExprError> {
        let depth = base.depth.max(exponent.depth) + 1;
        let node = match exponent.node {
            Node::Constant(value)
                if value == value.trunc() && value.abs() <= MAX_INTEGER_EXPONENT =>
            {
                // Exact: |value| ≤ 1000 is an integer representable in i32.
                Node::PowerInteger(Box::new(base.node), value as i32)
            }
            Node::Constant(value) => Node::PowerReal(Box::new(base.node), value),
            variable => Node::PowerVariable(Box::new(base.node), Box::new(variable)),
        };
        self.finish(node, base.start, exponent.end, depth)
    }

    /// Check the depth of a new node and fold it to a constant if its children are constant.
    fn finish(
        &self,
        node: Node,
        start: usize,
        end: usize,
        depth: usize,
    ) -> Result<Parsed, ExprError> {
        let (node, depth) = if children_are_constant(&node) {
            let value = evaluate::<f64>(&node, &[]);
            if !value.is_finite() {
                let text: String = self.source[start..end].iter().collect();
                return Err(Self::error(
                    start + 1,
                    format!("constant subexpression `{text}` evaluates to {value}, not finite"),
                ));
            }
            (Node::Constant(value), 1)
        } else if depth > MAX_DEPTH {
            return Err(Self::error(
                start + 1,
                format!("expression nested too deeply (tree depth above {MAX_DEPTH})"),
            ));
        } else {
            (node, depth)
        };
        Ok(Parsed {
            node,
            start,
            end,
            depth,
        })
    }
}
