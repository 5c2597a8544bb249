//! Values on the command line: lists of numbers, vectors, NAME=VALUE assignments; each finite.

use crate::kinematics::frame::{Vec3, Vec6};

pub(crate) fn parse_assignment(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s.split_once('=').ok_or_else(|| format!("expected NAME=VALUE, got `{s}`"))?;
    let value: f64 = value.trim().parse().map_err(|_| format!("`{}` is not a number", value.trim()))?;
    if !value.is_finite() {
        return Err(format!("`{s}`: the value must be finite"));
    }
    Ok((name.trim().to_string(), value))
}

pub(crate) fn parse_numbers(s: &str, n: usize) -> Result<Vec<f64>, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != n {
        return Err(format!("expected {n} comma-separated numbers, got {} in `{s}`", parts.len()));
    }
    parts
        .iter()
        .map(|t| match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(crate::model::error::not_finite(t)),
            Err(_) => Err(format!("`{t}` is not a number")),
        })
        .collect()
}

pub(crate) fn parse_vec3(s: &str) -> Result<Vec3, String> {
    parse_numbers(s, 3).map(|v| Vec3::from_column_slice(&v))
}

pub(crate) fn parse_vec6(s: &str) -> Result<Vec6, String> {
    parse_numbers(s, 6).map(|v| Vec6::from_column_slice(&v))
}
