//! `stiff synth`: measurements with hidden effects, in exactly the format `stiff diagnose` reads, to test
//! the workflow and to plan experiments (which poses and loads separate which effects).

use rand::{Rng, SeedableRng};

use super::data::{Dataset, Measurement, Pose, REQUIRED};
use super::effects::{Effect, Kind, PoseModel};
use super::fit::Problem;
use crate::kinematics::frame::{Frame, Vec3, Vec6};
use crate::model::grid::PosePoint;
use crate::output::table::{push_number, push_text};
use crate::platform::manipulator::Manipulator;

pub struct SynthOptions {
    pub effects: Vec<Effect>,
    pub wrenches: Vec<Vec6>,
    /// Standard deviation of the measurement noise, mm (each axis).
    pub noise: f64,
    pub seed: u64,
    /// Rows per pose and wrench (repeated measurements).
    pub repeats: usize,
}

/// A standard normal draw (Box-Muller).
fn normal(rng: &mut impl Rng) -> f64 {
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// The CSV text and the number of poses left out as unreachable or singular.
pub fn synthesize(m: &Manipulator, points: &[PosePoint], o: &SynthOptions) -> Result<(String, usize), String> {
    let mut state = m.new_state();
    let mut data = Dataset { rows: Vec::new(), poses: Vec::new() };
    let mut skipped = 0;
    for (i, p) in points.iter().enumerate() {
        if PoseModel::at(m, &Frame::translation(p.position), &mut state).is_err() {
            skipped += 1;
            continue;
        }
        let id = p.name.clone().unwrap_or_else(|| format!("p{i}"));
        let mut pose = Pose { id: id.clone(), position: p.position, rows: Vec::new() };
        for w in &o.wrenches {
            for _ in 0..o.repeats.max(1) {
                pose.rows.push(data.rows.len());
                data.rows.push(Measurement {
                    pose_id: id.clone(),
                    position: p.position,
                    wrench: *w,
                    displacement: Vec3::zeros(),
                    sigma: Some(o.noise),
                    line: 0,
                });
            }
        }
        data.poses.push(pose);
    }
    if data.rows.is_empty() {
        return Err("no reachable pose to measure".into());
    }
    let loaded = o.effects.iter().any(|e| e.kind == Kind::LoadedNonlinearity);
    let weights = vec![1.0; data.rows.len()];
    let problem =
        Problem::new(m, &data, weights, false, loaded).map_err(|b| format!("pose {}: {}", b.pose_id, b.why))?;
    let rows: Vec<usize> = (0..data.rows.len()).collect();
    let predicted = problem.predict(&o.effects, &rows)?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(o.seed);
    let mut text = REQUIRED.join(",") + ",sigma_mm\n";
    for (row, d) in data.rows.iter().zip(predicted) {
        push_text(&mut text, &row.pose_id);
        let noisy = d + Vec3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * o.noise;
        for v in row.position.iter().chain(row.wrench.iter()).chain(noisy.iter()) {
            text.push(',');
            push_number(&mut text, *v);
        }
        // Noise-free data has no sigma (a zero sigma is not a measurement's).
        text.push(',');
        if o.noise > 0.0 {
            push_number(&mut text, o.noise);
        }
        text.push('\n');
    }
    Ok((text, skipped))
}
