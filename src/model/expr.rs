//! Numbers in model files: a literal, or a formula over named parameters ("-(L + f_x)", "sqrt(a^2 + b^2)",
//! "pi * d^4 / 64", "deg(120)"), so that each measured number appears once and derived ones show how.

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, Deserializer, Visitor};
use serde::Deserialize;

/// A number as written in a model file.
#[derive(Clone, Debug, PartialEq)]
pub enum ExprSrc {
    Number(f64),
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
    fn lookup(&mut self, name: &str) -> Result<f64, String>;
}

impl Scope for BTreeMap<String, f64> {
    fn lookup(&mut self, name: &str) -> Result<f64, String> {
        self.get(name).copied().ok_or_else(|| format!("unknown parameter `{name}`"))
    }
}

impl ExprSrc {
    pub fn eval(&self, scope: &mut dyn Scope) -> Result<f64, String> {
        match self {
            ExprSrc::Number(v) => Ok(*v),
            ExprSrc::Formula(s) => evaluate(s, scope),
        }
    }
}

/// Evaluates a formula: + - * / ^, parentheses, parameters, `pi`, and the functions sqrt, abs, sin, cos,
/// tan, asin, acos, atan, atan2, deg (degrees to radians).
pub fn evaluate(text: &str, scope: &mut dyn Scope) -> Result<f64, String> {
    let mut p = Parser { s: text.as_bytes(), i: 0, scope };
    let v = p.expr()?;
    p.skip_ws();
    if p.i != p.s.len() {
        return Err(format!("unexpected `{}` in formula `{text}`", &text[p.i..]));
    }
    if !v.is_finite() {
        return Err(format!("formula `{text}` is not a finite number"));
    }
    Ok(v)
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    scope: &'a mut dyn Scope,
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
    fn expr(&mut self) -> Result<f64, String> {
        let mut v = self.term()?;
        loop {
            if self.eat(b'+') {
                v += self.term()?;
            } else if self.eat(b'-') {
                v -= self.term()?;
            } else {
                return Ok(v);
            }
        }
    }
    fn term(&mut self) -> Result<f64, String> {
        let mut v = self.unary()?;
        loop {
            if self.eat(b'*') {
                v *= self.unary()?;
            } else if self.eat(b'/') {
                v /= self.unary()?;
            } else {
                return Ok(v);
            }
        }
    }
    fn unary(&mut self) -> Result<f64, String> {
        if self.eat(b'-') {
            return Ok(-self.unary()?);
        }
        if self.eat(b'+') {
            return self.unary();
        }
        let base = self.primary()?;
        if self.eat(b'^') {
            return Ok(base.powf(self.unary()?));
        }
        Ok(base)
    }
    fn primary(&mut self) -> Result<f64, String> {
        match self.peek() {
            Some(b'(') => {
                self.i += 1;
                let v = self.expr()?;
                if !self.eat(b')') {
                    return Err("missing `)` in formula".into());
                }
                Ok(v)
            }
            Some(c) if c.is_ascii_digit() || c == b'.' => self.number(),
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
                    return call(&name, &args);
                }
                if name == "pi" {
                    return Ok(std::f64::consts::PI);
                }
                self.scope.lookup(&name)
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

fn call(name: &str, a: &[f64]) -> Result<f64, String> {
    let one = |f: fn(f64) -> f64| {
        if a.len() == 1 {
            Ok(f(a[0]))
        } else {
            Err(format!("`{name}` takes one argument, got {}", a.len()))
        }
    };
    match name {
        "sqrt" => one(f64::sqrt),
        "abs" => one(f64::abs),
        "sin" => one(f64::sin),
        "cos" => one(f64::cos),
        "tan" => one(f64::tan),
        "asin" => one(f64::asin),
        "acos" => one(f64::acos),
        "atan" => one(f64::atan),
        "deg" => one(f64::to_radians),
        "atan2" if a.len() == 2 => Ok(a[0].atan2(a[1])),
        "atan2" => Err("`atan2` takes two arguments".into()),
        _ => Err(format!("unknown function `{name}`")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
