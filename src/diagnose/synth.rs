//! `stiff synth`: measurements with hidden effects, in exactly the format `stiff diagnose` reads, to test
//! the workflow and to plan experiments (which poses and loads separate which effects).

use indicatif::ProgressBar;
use rand::{Rng, SeedableRng};

use super::data::{Dataset, Measurement, Pose, REQUIRED};
use super::error::DiagnoseError;
use super::fit::Problem;
use super::measurement::PoseModel;
use crate::batch::{point_seed, stream, Study, Tally};
use crate::kinematics::frame::{Frame, Vec3, Vec6};
use crate::model::effect::{with_model_effects, Effect, Form, Kind};
use crate::model::grid::{PointSet, PosePoint};
use crate::model::Model;
use crate::output::table::{names, selected_columns, write_row, Column, Record, Row};
use crate::platform::manipulator::{Manipulator, ManipulatorState};

/// What `stiff synth` measures.
pub struct SynthOptions {
    /// The hidden effects.
    pub effects: Vec<Effect>,
    /// Wrenches applied at every pose; empty: each point's own wrench (a plan's rows).
    pub wrenches: Vec<Vec6>,
    /// Standard deviation of the measurement noise, mm (each axis).
    pub noise: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// Rows per pose and wrench (repeated measurements).
    pub repeats: usize,
    /// Predict by the linear response C w (effects all as first-order terms) instead of the loaded
    /// equilibrium of the model with the hidden model-form effects built in.
    pub linear: bool,
    /// The points are a shard's portion of a run: none settling is no error here (the other shards'
    /// may), it is the merged file's.
    pub portion: bool,
}

/// A standard normal draw (Box-Muller).
pub(super) fn normal(rng: &mut impl Rng) -> f64 {
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// Writes the measurements of every pose of `points` to `out` in input order (a pose's id is its name or
/// `p` and its index in the input), solved on `pool`. Each pose's noise is drawn from a generator seeded by
/// the seed and the pose's index, so the bytes depend on neither the thread count nor the other poses.
/// Poses that are unreachable or singular, or have no loaded equilibrium under a wrench, are left out and
/// counted.
pub fn synthesize(
    pool: &rayon::ThreadPool,
    model: &Model,
    points: &mut PointSet,
    o: &SynthOptions,
    out: &mut (dyn std::io::Write + Send),
    progress: &ProgressBar,
) -> anyhow::Result<SynthSummary> {
    // Loaded: the model with the hidden effects that change the robot built in, its loaded equilibrium
    // exact; the measurement terms added. Linear: every effect a first-order term of C w.
    let (robot, terms): (Manipulator, Vec<Effect>) = if o.linear {
        (model.manipulator.clone(), o.effects.clone())
    } else {
        let (changes, terms): (Vec<Effect>, Vec<Effect>) =
            o.effects.iter().cloned().partition(|e| e.kind.form() == Form::Model);
        (with_model_effects(&model.manipulator, &changes), terms)
    };
    let loaded = !o.linear || o.effects.iter().any(|e| e.kind == Kind::LoadedNonlinearity);
    let study = SynthStudy { model, robot, terms, o, loaded };
    let mut summary = stream(pool, &study, points, out, progress)?;
    if let Some(e) = summary.error.take() {
        return Err(e.into());
    }
    if summary.rows == 0 && !o.portion {
        return Err(match summary.first_unsettled.take() {
            Some(e) => SynthError::NoPoseSettles(Box::new(e)),
            None => SynthError::NoReachablePose,
        }
        .into());
    }
    Ok(summary)
}

/// What a synthesis wrote.
#[derive(Clone, Debug, Default)]
pub struct SynthSummary {
    /// Poses measured.
    pub poses: u64,
    /// Rows written.
    pub rows: u64,
    /// Poses left out (unreachable, singular, or without a loaded equilibrium).
    pub skipped: u64,
    /// The first pose left out because its loaded equilibrium was not found, in input order.
    first_unsettled: Option<SynthError>,
    /// The first pose that could not be measured, in input order.
    error: Option<SynthError>,
}

impl Tally for SynthSummary {
    fn merge(&mut self, other: &Self) {
        self.poses += other.poses;
        self.rows += other.rows;
        self.skipped += other.skipped;
        if self.first_unsettled.is_none() {
            self.first_unsettled.clone_from(&other.first_unsettled);
        }
        if self.error.is_none() {
            self.error.clone_from(&other.error);
        }
    }
}

/// Synthesis as a streamed study: one pose's measurements per point.
struct SynthStudy<'a> {
    model: &'a Model,
    /// The robot measured: the model with the hidden model-form effects (loaded synthesis).
    robot: Manipulator,
    /// The hidden effects added as terms of the measurement.
    terms: Vec<Effect>,
    o: &'a SynthOptions,
    /// Some effect needs the loaded equilibrium of every row.
    loaded: bool,
}

impl SynthStudy<'_> {
    /// The pose's rows (each wrench, repeated), predicted with the hidden effects and the description's
    /// own terms, with noise; None where the pose cannot be modelled.
    fn measure(&self, index: u64, p: &PosePoint, out: &mut String) -> Result<usize, SynthError> {
        let (m, o) = (&self.robot, self.o);
        let id = p.name.clone().unwrap_or_else(|| format!("p{index}"));
        let mut pose = Pose { id: id.clone(), position: p.position, rows: Vec::new() };
        let mut data = Dataset { rows: Vec::new(), poses: Vec::new() };
        // Without wrenches for every pose, each point is measured under its own (a plan's rows).
        let own: Vec<Vec6> = p.wrench.into_iter().collect();
        let wrenches = if o.wrenches.is_empty() { &own } else { &o.wrenches };
        if wrenches.is_empty() {
            return Err(SynthError::NoWrench { pose_id: id });
        }
        let per_pose = (wrenches.len() * o.repeats.max(1)) as u64;
        for w in wrenches {
            for _ in 0..o.repeats.max(1) {
                // Measured in input order: the pose's index, then its rows.
                let order = Some((index * per_pose + data.rows.len() as u64) as f64);
                pose.rows.push(data.rows.len());
                data.rows.push(Measurement {
                    pose_id: id.clone(),
                    position: p.position,
                    wrench: *w,
                    displacement: Vec3::zeros(),
                    sigma: Some(o.noise),
                    order,
                    line: 0,
                });
            }
        }
        data.poses.push(pose);
        let weights = vec![1.0; data.rows.len()];
        let terms = &self.model.measurement_terms;
        let loaded_mode = !o.linear;
        let problem = Problem::new(m, terms, &data, weights, loaded_mode, self.loaded).map_err(SynthError::Model)?;
        let rows: Vec<usize> = (0..data.rows.len()).collect();
        let predicted = problem.predict(&self.terms, &rows).map_err(|e| SynthError::Model(e.into()))?;
        let mut rng = rand::rngs::StdRng::seed_from_u64(point_seed(o.seed, index));
        for (row, d) in data.rows.iter().zip(predicted) {
            // What synth writes, diagnose must be able to read: the same bound on every number.
            let readable = |v: &f64| v.is_finite() && v.abs() <= super::data::MAX_MAGNITUDE;
            if !(d.iter().all(readable) && row.wrench.iter().all(readable)) {
                return Err(SynthError::Unreadable { pose_id: row.pose_id.clone() });
            }
            let noisy = d + Vec3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * o.noise;
            // Noise-free data has no sigma (a zero sigma is not a measurement's).
            let sigma = Some(o.noise).filter(|s| *s > 0.0);
            write_row(&MeasurementRow { measurement: row, displacement: noisy, sigma, order: row.order }, &(), out);
        }
        Ok(data.rows.len())
    }
}

/// The columns of a synthesized measurement file, in order.
pub fn synth_table() -> Vec<Column> {
    let blank = Measurement::default();
    let row = MeasurementRow { measurement: &blank, displacement: Vec3::zeros(), sigma: None, order: None };
    selected_columns(&row, &(), None)
}

impl Study for SynthStudy<'_> {
    type Item = PosePoint;
    type State = ManipulatorState;
    type Tally = SynthSummary;

    fn columns(&self) -> Vec<Column> {
        synth_table()
    }

    fn new_state(&self) -> ManipulatorState {
        self.robot.new_state()
    }

    fn solve(
        &self,
        index: u64,
        p: &PosePoint,
        state: &mut ManipulatorState,
        tally: &mut SynthSummary,
        out: &mut String,
    ) {
        if tally.error.is_some() {
            return; // the run stops at its first failure; the command reports it
        }
        if PoseModel::at(&self.robot, &Frame::translation(p.position), state).is_err() {
            tally.skipped += 1;
            return;
        }
        match self.measure(index, p, out) {
            Ok(rows) => {
                tally.poses += 1;
                tally.rows += rows as u64;
            }
            // A pose whose loaded equilibrium is not found (near a singularity, past a limit point) has no
            // measurement to write: left out like an unreachable one.
            Err(e @ SynthError::Model(DiagnoseError::Pose { .. })) => {
                tally.skipped += 1;
                tally.first_unsettled.get_or_insert(e);
            }
            Err(e) => tally.error = Some(e),
        }
    }
}

/// Why synthetic data could not be written.
#[derive(Clone, Debug)]
pub enum SynthError {
    /// The model could not predict a measurement.
    Model(DiagnoseError),
    /// The load or the effects give a displacement `diagnose` could not read (beyond `MAX_MAGNITUDE`).
    Unreadable {
        /// The pose.
        pose_id: String,
    },
    /// No pose of the input is reachable and regular.
    NoReachablePose,
    /// No wrench for every pose was given and this point has none of its own.
    NoWrench {
        /// The pose.
        pose_id: String,
    },
    /// No pose has a loaded equilibrium under the wrenches (with the hidden effects): the first pose's reason.
    NoPoseSettles(Box<SynthError>),
}

impl std::fmt::Display for SynthError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SynthError::Model(e) => write!(f, "{e}"),
            SynthError::Unreadable { pose_id } => write!(
                f,
                "pose {pose_id}: the load or the effects give a displacement beyond {:e} (or not finite): not a \
                 measurement",
                super::data::MAX_MAGNITUDE
            ),
            SynthError::NoReachablePose => f.write_str("no reachable pose to measure"),
            SynthError::NoWrench { pose_id } => write!(
                f,
                "pose {pose_id} has no wrench: give --wrenches, or points with Fx_N..Mz_Nmm columns (a `stiff plan`)"
            ),
            SynthError::NoPoseSettles(first) => write!(
                f,
                "no pose has a loaded equilibrium under the wrenches with the hidden effects, so nothing can be \
                 measured (first: {first}); smaller loads or effects, or --linear"
            ),
        }
    }
}

impl std::error::Error for SynthError {}

/// One written measurement: the row's pose and wrench, the displacement with its noise, and sigma.
struct MeasurementRow<'a> {
    measurement: &'a Measurement,
    displacement: Vec3,
    sigma: Option<f64>,
    order: Option<f64>,
}

impl Row for MeasurementRow<'_> {
    type Layout = ();

    /// The columns `diagnose` reads (`REQUIRED`, then `sigma_mm` and `order`).
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
        r.optional(names::ORDER, self.order);
    }
}
