//! Numbers in model files: a literal, or a formula over named parameters ("-(L + f_x)", "sqrt(a^2 + b^2)",
//! "pi * d^4 / 64", "deg(120)"), so that each measured number appears once and derived ones show how.

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, Deserializer, Visitor};
use serde::Deserialize;

/// A number as written in a model file.
#[derive(Clone, Debug, PartialEq)]
pub enum ExprSrc {
    /// A literal.
    Number(f64),
    /// A formula over named parameters.
    Formula(String),
}

impl<'de> Deserialize<'de> for ExprSrc {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = ExprSrc;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or a formula in a string")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<ExprSrc, E> {
                Ok(ExprSrc::Number(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<ExprSrc, E> {
                Ok(ExprSrc::Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<ExprSrc, E> {
                Ok(ExprSrc::Number(v as f64))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<ExprSrc, E> {
                Ok(ExprSrc::Formula(v.to_string()))
            }
        }
        d.deserialize_any(V)
    }
}

/// Looks up a parameter's value by name (the model's parameter table).
pub trait Scope {
    /// The value of a name, or why there is none.
    fn lookup(&mut self, name: &str) -> Result<f64, String>;
}

impl Scope for BTreeMap<String, f64> {
    fn lookup(&mut self, name: &str) -> Result<f64, String> {
        self.get(name).copied().ok_or_else(|| format!("unknown parameter `{name}`"))
    }
}

impl ExprSrc {
    /// The value in `scope` (formulas parsed and evaluated).
    pub fn eval(&self, scope: &mut dyn Scope) -> Result<f64, String> {
        match self {
            ExprSrc::Number(v) => Ok(*v),
            ExprSrc::Formula(s) => evaluate(s, scope),
        }
    }

    /// Parses once for evaluation at every pose (see `compile`).
    pub fn compile(&self, resolve: &mut dyn FnMut(&str) -> Result<Expr, String>) -> Result<Expr, String> {
        match self {
            ExprSrc::Number(v) => Ok(Expr::Const(*v)),
            ExprSrc::Formula(s) => compile(s, resolve),
        }
    }
}

/// Evaluates a formula: + - * / ^, parentheses, parameters, `pi`, and the functions sqrt, abs, sin, cos,
/// tan, asin, acos, atan, atan2, deg (degrees to radians).
pub fn evaluate(text: &str, scope: &mut dyn Scope) -> Result<f64, String> {
    let v = compile(text, &mut |name: &str| scope.lookup(name).map(Expr::Const))?.eval(&[]);
    if !v.is_finite() {
        return Err(format!("formula `{text}` is not a finite number"));
    }
    Ok(v)
}

/// A parsed formula, its names resolved: constants folded, per-pose quantities left as slots of a value
/// table, so that formulas evaluated at every pose (MSA geometry) are parsed once.
#[derive(Clone, Debug)]
pub enum Expr {
    /// A number.
    Const(f64),
    /// The value at this index of the table handed to `eval`.
    Slot(usize),
    /// Negation.
    Neg(Box<Expr>),
    /// A binary operation.
    Binary(Op, Box<Expr>, Box<Expr>),
    /// A function of one argument (sqrt, sin, deg, ...).
    Call(fn(f64) -> f64, Box<Expr>),
    /// atan2(y, x).
    Atan2(Box<Expr>, Box<Expr>),
}

/// A binary operator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Op {
    /// a + b
    Add,
    /// a - b
    Sub,
    /// a * b
    Mul,
    /// a / b
    Div,
    /// a ^ b
    Pow,
}

impl Op {
    fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Op::Add => a + b,
            Op::Sub => a - b,
            Op::Mul => a * b,
            Op::Div => a / b,
            Op::Pow => a.powf(b),
        }
    }
}

impl Expr {
    /// The formula's value with `slots` holding the per-pose quantities (may be NaN or infinite: the
    /// caller decides what a non-finite value means).
    pub fn eval(&self, slots: &[f64]) -> f64 {
        match self {
            Expr::Const(v) => *v,
            Expr::Slot(i) => slots[*i],
            Expr::Neg(a) => -a.operand(slots),
            Expr::Binary(op, a, b) => op.apply(a.operand(slots), b.operand(slots)),
            Expr::Call(f, a) => f(a.operand(slots)),
            Expr::Atan2(a, b) => a.operand(slots).atan2(b.operand(slots)),
        }
    }

    /// `eval` of an operand, a number or a slot read in place (half a formula's nodes are such leaves,
    /// and a call per leaf costs more than the leaf).
    #[inline(always)]
    fn operand(&self, slots: &[f64]) -> f64 {
        match self {
            Expr::Const(v) => *v,
            Expr::Slot(i) => slots[*i],
            _ => self.eval(slots),
        }
    }

    /// Collects the slot indices the formula reads (to order per-pose quantities by dependency).
    pub fn slots(&self, out: &mut Vec<usize>) {
        match self {
            Expr::Const(_) => {}
            Expr::Slot(i) => out.push(*i),
            Expr::Neg(a) | Expr::Call(_, a) => a.slots(out),
            Expr::Binary(_, a, b) | Expr::Atan2(a, b) => {
                a.slots(out);
                b.slots(out);
            }
        }
    }

    fn binary(op: Op, a: Expr, b: Expr) -> Expr {
        match (&a, &b) {
            (Expr::Const(x), Expr::Const(y)) => Expr::Const(op.apply(*x, *y)),
            _ => Expr::Binary(op, Box::new(a), Box::new(b)),
        }
    }

    fn unary(f: fn(f64) -> f64, a: Expr) -> Expr {
        match a {
            Expr::Const(x) => Expr::Const(f(x)),
            a => Expr::Call(f, Box::new(a)),
        }
    }
}

/// Longest formula read: a formula's tree is evaluated recursively at every pose, so its size is bounded
/// (no description needs more than a few hundred characters).
pub const MAX_FORMULA_LENGTH: usize = 10_000;
/// Deepest nesting of parentheses, signs, powers and function calls: the parser recurses per level, and
/// ~10,000 nested parentheses overflowed its stack.
pub const MAX_FORMULA_DEPTH: usize = 100;

/// Parses a formula, resolving each name through `resolve` (a constant or a slot).
pub fn compile(text: &str, resolve: &mut dyn FnMut(&str) -> Result<Expr, String>) -> Result<Expr, String> {
    if text.len() > MAX_FORMULA_LENGTH {
        return Err(format!("a formula may have at most {MAX_FORMULA_LENGTH} characters, this one has {}", text.len()));
    }
    let mut p = Parser { s: text.as_bytes(), i: 0, depth: 0, resolve };
    let v = p.expr()?;
    p.skip_ws();
    if p.i != p.s.len() {
        return Err(format!("unexpected `{}` in formula `{text}`", &text[p.i..]));
    }
    Ok(v)
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    /// Nesting level of the `unary` being parsed (every nesting passes through it).
    depth: usize,
    resolve: &'a mut dyn FnMut(&str) -> Result<Expr, String>,
}

impl Parser<'_> {
    fn skip_ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }
    fn peek(&mut self) -> Option<u8> {
        self.skip_ws();
        self.s.get(self.i).copied()
    }
    fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.i += 1;
            true
        } else {
            false
        }
    }
    fn expr(&mut self) -> Result<Expr, String> {
        let mut v = self.term()?;
        loop {
            if self.eat(b'+') {
                v = Expr::binary(Op::Add, v, self.term()?);
            } else if self.eat(b'-') {
                v = Expr::binary(Op::Sub, v, self.term()?);
            } else {
                return Ok(v);
            }
        }
    }
    fn term(&mut self) -> Result<Expr, String> {
        let mut v = self.unary()?;
        loop {
            if self.eat(b'*') {
                v = Expr::binary(Op::Mul, v, self.unary()?);
            } else if self.eat(b'/') {
                v = Expr::binary(Op::Div, v, self.unary()?);
            } else {
                return Ok(v);
            }
        }
    }
    fn unary(&mut self) -> Result<Expr, String> {
        self.depth += 1;
        if self.depth > MAX_FORMULA_DEPTH {
            return Err(format!("the formula nests more than {MAX_FORMULA_DEPTH} levels deep"));
        }
        let v = self.unary_inner();
        self.depth -= 1;
        v
    }
    fn unary_inner(&mut self) -> Result<Expr, String> {
        if self.eat(b'-') {
            return Ok(match self.unary()? {
                Expr::Const(x) => Expr::Const(-x),
                a => Expr::Neg(Box::new(a)),
            });
        }
        if self.eat(b'+') {
            return self.unary();
        }
        let base = self.primary()?;
        if self.eat(b'^') {
            return Ok(Expr::binary(Op::Pow, base, self.unary()?));
        }
        Ok(base)
    }
    fn primary(&mut self) -> Result<Expr, String> {
        match self.peek() {
            Some(b'(') => {
                self.i += 1;
                let v = self.expr()?;
                if !self.eat(b')') {
                    return Err("missing `)` in formula".into());
                }
                Ok(v)
            }
            Some(c) if c.is_ascii_digit() || c == b'.' => self.number().map(Expr::Const),
            Some(c) if c.is_ascii_alphabetic() || c == b'_' => {
                let start = self.i;
                while self.i < self.s.len() && (self.s[self.i].is_ascii_alphanumeric() || self.s[self.i] == b'_') {
                    self.i += 1;
                }
                let name = std::str::from_utf8(&self.s[start..self.i]).unwrap().to_string();
                if self.eat(b'(') {
                    let mut args = vec![self.expr()?];
                    while self.eat(b',') {
                        args.push(self.expr()?);
                    }
                    if !self.eat(b')') {
                        return Err(format!("missing `)` after the arguments of `{name}`"));
                    }
                    return call(&name, args);
                }
                if name == "pi" {
                    return Ok(Expr::Const(std::f64::consts::PI));
                }
                (self.resolve)(&name)
            }
            Some(c) => Err(format!("unexpected `{}` in formula", c as char)),
            None => Err("formula ends too early".into()),
        }
    }
    fn number(&mut self) -> Result<f64, String> {
        let start = self.i;
        while self.i < self.s.len() && (self.s[self.i].is_ascii_digit() || self.s[self.i] == b'.') {
            self.i += 1;
        }
        if self.i < self.s.len() && (self.s[self.i] == b'e' || self.s[self.i] == b'E') {
            self.i += 1;
            if self.i < self.s.len() && (self.s[self.i] == b'+' || self.s[self.i] == b'-') {
                self.i += 1;
            }
            while self.i < self.s.len() && self.s[self.i].is_ascii_digit() {
                self.i += 1;
            }
        }
        let t = std::str::from_utf8(&self.s[start..self.i]).unwrap();
        t.parse().map_err(|_| format!("`{t}` is not a number"))
    }
}

fn call(name: &str, mut a: Vec<Expr>) -> Result<Expr, String> {
    let f: fn(f64) -> f64 = match name {
        "sqrt" => f64::sqrt,
        "abs" => f64::abs,
        "sin" => f64::sin,
        "cos" => f64::cos,
        "tan" => f64::tan,
        "asin" => f64::asin,
        "acos" => f64::acos,
        "atan" => f64::atan,
        "deg" => f64::to_radians,
        "atan2" if a.len() == 2 => {
            let x = a.pop().expect("two arguments");
            let y = a.pop().expect("two arguments");
            return Ok(match (&y, &x) {
                (Expr::Const(y), Expr::Const(x)) => Expr::Const(y.atan2(*x)),
                _ => Expr::Atan2(Box::new(y), Box::new(x)),
            });
        }
        "atan2" => return Err("`atan2` takes two arguments".into()),
        _ => return Err(format!("unknown function `{name}`")),
    };
    if a.len() != 1 {
        return Err(format!("`{name}` takes one argument, got {}", a.len()));
    }
    Ok(Expr::unary(f, a.pop().expect("one argument")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: ~10,000 nested parentheses overflowed the parser's stack (an abort, not an error).
    #[test]
    fn deeply_nested_formulas_are_refused_not_overflowing() {
        let mut p = std::collections::BTreeMap::<String, f64>::new();
        let deep = format!("{}1{}", "(".repeat(10_000), ")".repeat(10_000));
        assert!(evaluate(&deep, &mut p).unwrap_err().contains("characters"));
        let deep = format!("{}1{}", "(".repeat(2_000), ")".repeat(2_000));
        assert!(evaluate(&deep, &mut p).unwrap_err().contains("levels deep"));
        let signs = format!("{}1", "-".repeat(5_000));
        assert!(evaluate(&signs, &mut p).is_err());
        assert_eq!(evaluate(&format!("{}1{}", "(".repeat(50), ")".repeat(50)), &mut p).unwrap(), 1.0);
    }

    #[test]
    fn formulas_follow_usual_precedence() {
        let mut p: BTreeMap<String, f64> = [("L".to_string(), 2.0), ("f_x".to_string(), 3.0)].into();
        assert_eq!(evaluate("-(L + f_x) * 2", &mut p).unwrap(), -10.0);
        assert_eq!(evaluate("L^3 / 4 - -1", &mut p).unwrap(), 3.0);
        assert_eq!(evaluate("-L^2", &mut p).unwrap(), -4.0);
        assert_eq!(evaluate("sqrt(f_x^2 + 4^2)", &mut p).unwrap(), 5.0);
        assert_eq!(evaluate("1.5e3", &mut p).unwrap(), 1500.0);
        assert!((evaluate("deg(180)", &mut p).unwrap() - std::f64::consts::PI).abs() < 1e-15);
        assert!(evaluate("L +", &mut p).is_err());
        assert!(evaluate("nope * 2", &mut p).unwrap_err().contains("nope"));
        assert!(evaluate("1 / 0", &mut p).is_err());
    }
}
