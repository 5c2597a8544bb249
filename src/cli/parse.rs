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

/// Wrenches `Fx,Fy,Fz,Mx,My,Mz` separated by `;` (`--wrenches`, `--loads`); none where the flag is absent.
pub(crate) fn parse_wrench_list(text: Option<&str>) -> Result<Vec<Vec6>, String> {
    text.map_or(Ok(Vec::new()), |t| t.split(';').map(|w| parse_vec6(w.trim())).collect())
}

/// `NAME=FROM:TO:COUNT` (or `NAME=FROM:TO` for a sampled sweep): a parameter's range.
pub(crate) fn parse_parameter_range(s: &str) -> Result<crate::study::sweep::ParameterRange, String> {
    let usage = || format!("expected NAME=FROM:TO:COUNT (e.g. k_act=10000:40000:7), got `{s}`");
    let (name, range) = s.split_once('=').ok_or_else(usage)?;
    let parts: Vec<&str> = range.split(':').map(str::trim).collect();
    if !(2..=3).contains(&parts.len()) || name.trim().is_empty() {
        return Err(usage());
    }
    let number = |t: &str| match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(crate::model::error::not_finite(t)),
        Err(_) => Err(format!("`{t}` is not a number ({})", usage())),
    };
    let count = match parts.get(2) {
        None => None,
        Some(t) => match t.parse::<u64>() {
            Ok(n) if n >= 1 => Some(n),
            _ => return Err(format!("COUNT `{t}` must be a whole number >= 1 ({})", usage())),
        },
    };
    let (from, to) = (number(parts[0])?, number(parts[1])?);
    if count == Some(1) && from != to {
        return Err(format!("`{s}`: one value needs FROM equal to TO"));
    }
    Ok(crate::study::sweep::ParameterRange { name: name.trim().to_string(), from, to, count })
}

/// `lhs:N`: a Latin hypercube of N designs.
pub(crate) fn parse_sample(s: &str) -> Result<u64, String> {
    let n =
        s.strip_prefix("lhs:").ok_or_else(|| format!("expected lhs:N (a Latin hypercube of N designs), got `{s}`"))?;
    n.trim().parse::<u64>().ok().filter(|&n| n >= 1).ok_or_else(|| format!("`{s}`: N must be a whole number >= 1"))
}
