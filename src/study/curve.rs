//! `stiff curve`: a force-deflection curve at one pose, under force control (a wrench growing along a
//! direction) or displacement control (a displacement growing along a direction), with the smallest
//! eigenvalue of the tangent stiffness and stability at every step. Force control continues through a
//! bifurcation (the equilibrium path goes on, flagged unstable) and switches to displacement control where
//! it cannot pass a limit point.

use anyhow::{anyhow, bail, Result};

use crate::kinematics::frame::{Frame, Vec6};
use crate::output::table::push_number;
use crate::platform::leg::apply_twist;
use crate::platform::loaded::{eigenvalue_range, positive_definite};
use crate::platform::manipulator::Manipulator;

#[derive(Clone, Copy, Debug)]
pub enum Control {
    /// The wrench is `load_factor * W`.
    Force(Vec6),
    /// The displacement is `load_factor * D` (mm, rad).
    Displacement(Vec6),
}

#[derive(Clone, Debug, PartialEq)]
pub struct CurveRow {
    pub step: usize,
    /// "force" or "displacement".
    pub control: &'static str,
    pub load_factor: f64,
    /// External wrench holding the platform (N, N mm).
    pub wrench: Vec6,
    /// Platform displacement from the commanded pose (mm, rad).
    pub displacement: Vec6,
    /// Smallest eigenvalue of the symmetric part of the tangent stiffness, rotations weighted by the
    /// length scale (N/mm).
    pub min_eigenvalue: f64,
    pub stable: bool,
    pub iterations: usize,
    /// "", "buckling" (the tangent stiffness stops being positive definite at this step), "limit_point"
    /// (force control could not go on; displacement control from here), "restabilised".
    pub event: &'static str,
}

pub const CURVE_HEADER: &str = "step,control,load_factor,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,dx_mm,dy_mm,dz_mm,rx_rad,ry_rad,rz_rad,min_eigenvalue_N_per_mm,stable,iterations,event\n";

pub fn push_curve_row(out: &mut String, r: &CurveRow) {
    out.push_str(&format!("{},{},", r.step, r.control));
    push_number(out, r.load_factor);
    for v in r.wrench.iter().chain(r.displacement.iter()) {
        out.push(',');
        push_number(out, *v);
    }
    out.push(',');
    push_number(out, r.min_eigenvalue);
    out.push_str(&format!(",{},{},{}\n", r.stable, r.iterations, r.event));
}

/// The load factor at which the smallest eigenvalue crosses zero, interpolated linearly between the two
/// steps that bracket it (the first crossing).
pub fn critical_load_factor(rows: &[CurveRow]) -> Option<f64> {
    rows.windows(2).find(|w| w[0].min_eigenvalue > 0.0 && w[1].min_eigenvalue <= 0.0).map(|w| {
        let (a, b) = (&w[0], &w[1]);
        a.load_factor + (b.load_factor - a.load_factor) * a.min_eigenvalue / (a.min_eigenvalue - b.min_eigenvalue)
    })
}

pub fn run_curve(m: &Manipulator, at: &Frame, control: Control, max: f64, steps: usize) -> Result<Vec<CurveRow>> {
    if steps == 0 {
        bail!("--steps must be at least 1");
    }
    if !max.is_finite() || max <= 0.0 {
        bail!("--max must be a positive number, got {max}");
    }
    let leg_error = |e: crate::platform::manipulator::PoseFailure| anyhow!("leg {}: {:?}", e.leg + 1, e.failure);
    let mut state = m.new_state();
    m.place(at, &mut state).map_err(|e| anyhow!("the pose cannot be reached: {}", leg_error(e)))?;
    let mut rows: Vec<CurveRow> = Vec::with_capacity(steps + 1);
    let mut t = *at;
    let mut was_pd = true;
    // After a limit point under force control: (step of the switch, displacement before it, increment).
    let mut continuation: Option<(usize, Vec6, Vec6)> = None;
    for step in 0..=steps {
        let lambda = max * step as f64 / steps as f64;
        let mut event = "";
        let held_at = |pose: Frame, state: &mut _| m.hold(&pose, state).map(|h| (pose, h)).map_err(leg_error);
        let (pose, held, iterations, factor, by_force) = match control {
            Control::Displacement(d) => {
                let (pose, h) = held_at(apply_twist(at, &(d * lambda)), &mut state)?;
                (pose, h, h.iterations, lambda, false)
            }
            Control::Force(w) => {
                let attempt = match continuation {
                    None => m.deflect(at, &(w * lambda), Some(&t), &mut state).ok(),
                    Some(_) => None,
                };
                match attempt {
                    Some(d) => (d.pose, d.held, d.iterations, lambda, true),
                    None => {
                        if continuation.is_none() {
                            let n = rows.len();
                            if n < 2 {
                                bail!("force control failed at step {step}: no equilibrium under this load");
                            }
                            let increment = rows[n - 1].displacement - rows[n - 2].displacement;
                            continuation = Some((step, rows[n - 1].displacement, increment));
                            event = "limit_point";
                        }
                        let (k0, base, increment) = continuation.expect("set just above");
                        let target = base + increment * (step + 1 - k0) as f64;
                        let (pose, h) = held_at(apply_twist(at, &target), &mut state)?;
                        (pose, h, h.iterations, project(&h.force, &w), false)
                    }
                }
            }
        };
        t = pose;
        let (lo, _) = eigenvalue_range(&held.stiffness, m.length_scale);
        let pd = positive_definite(&held.stiffness, m.length_scale);
        if event.is_empty() {
            event = match (was_pd, pd) {
                (true, false) => "buckling",
                (false, true) => "restabilised",
                _ => "",
            };
        }
        was_pd = pd;
        rows.push(CurveRow {
            step,
            control: if by_force { "force" } else { "displacement" },
            load_factor: factor,
            wrench: held.force,
            displacement: at.error_to(&pose),
            min_eigenvalue: lo,
            stable: pd && held.legs_stable,
            iterations,
            event,
        });
    }
    Ok(rows)
}

/// The load factor of a wrench along a direction: (F . W) / (W . W).
fn project(f: &Vec6, w: &Vec6) -> f64 {
    f.dot(w) / w.dot(w)
}
