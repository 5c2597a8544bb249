//! `stiff synth`: measurements with hidden effects, in exactly the format `stiff diagnose` reads, to test
//! the workflow and to plan experiments (which poses and loads separate which effects).

use rand::{Rng, SeedableRng};

use super::data::{Dataset, Measurement, Pose, REQUIRED};
use super::error::DiagnoseError;
use super::fit::Problem;
use super::measurement::PoseModel;
use crate::kinematics::frame::{Frame, Vec3, Vec6};
use crate::model::effect::{Effect, Kind};
use crate::model::grid::PointSet;
use crate::model::Model;
use crate::output::table::{header, names, write_row, Record, Row};

/// What `stiff synth` measures.
pub struct SynthOptions {
    /// The hidden effects.
    pub effects: Vec<Effect>,
    /// Wrenches applied at every pose.
    pub wrenches: Vec<Vec6>,
    /// Standard deviation of the measurement noise, mm (each axis).
    pub noise: f64,
    /// Seed of the noise.
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

/// Poses measured per block: the data set a block builds (its predictions need every row's model) is
/// bounded by this, so memory does not grow with the grid.
const BLOCK: usize = 256;

/// Writes the measurements of every pose of `points` to `out`, block by block (a pose's id is its name or
/// `p` and its index in the input), and returns the number of poses left out as unreachable or singular.
/// The noise generator is drawn in row order, so the bytes do not depend on the block size.
pub fn synthesize(
    model: &Model,
    points: &mut PointSet,
    o: &SynthOptions,
    out: &mut dyn std::io::Write,
) -> Result<usize, SynthError> {
    let m = &model.manipulator;
    let mut state = m.new_state();
    let mut rng = rand::rngs::StdRng::seed_from_u64(o.seed);
    out.write_all(header(&blank_row(), &()).as_bytes())?;
    let (mut skipped, mut written, mut index) = (0, 0, 0usize);
    let mut block = Vec::with_capacity(BLOCK);
    loop {
        block.clear();
        if points.next_block(BLOCK, &mut block)? == 0 {
            break;
        }
        let mut data = Dataset { rows: Vec::new(), poses: Vec::new() };
        for p in &block {
            let i = index;
            index += 1;
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
            continue;
        }
        let loaded = o.effects.iter().any(|e| e.kind == Kind::LoadedNonlinearity);
        let weights = vec![1.0; data.rows.len()];
        let problem =
            Problem::new(m, &model.measurement_terms, &data, weights, false, loaded).map_err(SynthError::Model)?;
        let rows: Vec<usize> = (0..data.rows.len()).collect();
        let predicted = problem.predict(&o.effects, &rows).map_err(|e| SynthError::Model(e.into()))?;
        let mut text = String::new();
        for (row, d) in data.rows.iter().zip(predicted) {
            // What synth writes, diagnose must be able to read: the same bound on every number.
            let readable = |v: &f64| v.is_finite() && v.abs() <= super::data::MAX_MAGNITUDE;
            if !(d.iter().all(readable) && row.wrench.iter().all(readable)) {
                return Err(SynthError::Unreadable { pose_id: row.pose_id.clone() });
            }
            let noisy = d + Vec3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * o.noise;
            // Noise-free data has no sigma (a zero sigma is not a measurement's).
            let sigma = Some(o.noise).filter(|s| *s > 0.0);
            write_row(&MeasurementRow { measurement: row, displacement: noisy, sigma }, &(), &mut text);
        }
        out.write_all(text.as_bytes())?;
        written += data.rows.len();
    }
    if written == 0 {
        return Err(SynthError::NoReachablePose);
    }
    Ok(skipped)
}

/// Why synthetic data could not be written.
#[derive(Debug)]
pub enum SynthError {
    /// The points file could not be read.
    Input(crate::model::error::InputError),
    /// The model could not predict a measurement.
    Model(DiagnoseError),
    /// The load or the effects give a displacement `diagnose` could not read (beyond `MAX_MAGNITUDE`).
    Unreadable {
        /// The pose.
        pose_id: String,
    },
    /// No pose of the input is reachable and regular.
    NoReachablePose,
    /// Writing the output failed (a closed pipe, a full disk).
    Write(std::io::Error),
}

impl std::fmt::Display for SynthError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SynthError::Input(e) => write!(f, "{e}"),
            SynthError::Model(e) => write!(f, "{e}"),
            SynthError::Unreadable { pose_id } => write!(
                f,
                "pose {pose_id}: the load or the effects give a displacement beyond {:e} (or not finite): not a \
                 measurement",
                super::data::MAX_MAGNITUDE
            ),
            SynthError::NoReachablePose => f.write_str("no reachable pose to measure"),
            SynthError::Write(e) => write!(f, "cannot write the measurements: {e}"),
        }
    }
}

impl std::error::Error for SynthError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SynthError::Write(e) => Some(e),
            _ => None,
        }
    }
}

impl From<std::io::Error> for SynthError {
    fn from(e: std::io::Error) -> Self {
        SynthError::Write(e)
    }
}

impl From<crate::model::error::InputError> for SynthError {
    fn from(e: crate::model::error::InputError) -> Self {
        SynthError::Input(e)
    }
}

/// One written measurement: the row's pose and wrench, the displacement with its noise, and sigma.
struct MeasurementRow<'a> {
    measurement: &'a Measurement,
    displacement: Vec3,
    sigma: Option<f64>,
}

fn blank_row() -> MeasurementRow<'static> {
    static BLANK: std::sync::OnceLock<Measurement> = std::sync::OnceLock::new();
    let measurement = BLANK.get_or_init(|| Measurement {
        pose_id: String::new(),
        position: Vec3::zeros(),
        wrench: Vec6::zeros(),
        displacement: Vec3::zeros(),
        sigma: None,
        line: 0,
    });
    MeasurementRow { measurement, displacement: Vec3::zeros(), sigma: None }
}

impl Row for MeasurementRow<'_> {
    type Layout = ();

    /// The columns `diagnose` reads (`REQUIRED`, then `sigma_mm`).
    fn record(&self, _: &(), r: &mut impl Record) {
        let m = self.measurement;
        r.text(REQUIRED[0], &m.pose_id);
        for k in 0..3 {
            r.number(REQUIRED[1 + k], m.position[k]);
        }
        for k in 0..6 {
            r.number(REQUIRED[4 + k], m.wrench[k]);
        }
        for k in 0..3 {
            r.number(REQUIRED[10 + k], self.displacement[k]);
        }
        r.optional(names::SIGMA, self.sigma);
    }
}
