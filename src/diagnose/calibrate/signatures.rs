//! What measuring at candidate configurations would tell a calibration, to first order: the derivatives a
//! plan (`diagnose::plan::plan_arm`) chooses configurations by.

use nalgebra::DMatrix;

use super::effect::ArmEffect;
use super::options::CalibrationError;
use super::problem::PositionProblem;
use super::synth::Configuration;
use crate::diagnose::positions::{Observed, PositionData, PositionRow};
use crate::kinematics::frame::{Frame, Mat3, Vec3};
use crate::platform::manipulator::Manipulator;

/// What measuring a target's position (and orientation) at each candidate configuration would tell a
/// calibration, to first order about the nominal arm: the derivative of the three coordinates (and three
/// rotations) in every parameter, weighted by 1/noise.
pub struct Signatures {
    /// The candidates with a prediction (the others have no loaded equilibrium), as indices into the
    /// configurations given.
    pub usable: Vec<usize>,
    /// Rows per usable candidate: 3 (a position), or 6 (a position, then an orientation).
    pub rows_per_candidate: usize,
    /// The registration's and the target's columns (9, or 12 with the target's axes): fitted in every
    /// calibration.
    pub nuisance: DMatrix<f64>,
    /// Each effect's label and columns.
    pub effects: Vec<(String, DMatrix<f64>)>,
}

/// The signatures (`Signatures`) of `effects` (where empty: the effects `calibrate` offers by default, play
/// where the candidates load its joint both ways) at `configurations`, one instrument and one target; with
/// `orientation_noise` (rad), the target's orientation measured too. `poses`: a parallel robot's commanded
/// pose for each configuration (its joints empty).
pub fn signatures(
    m: &Manipulator,
    configurations: &[Configuration],
    poses: Option<&[Frame]>,
    effects: &[ArmEffect],
    noise: f64,
    orientation_noise: Option<f64>,
) -> Result<Signatures, CalibrationError> {
    let mut state = m.new_state();
    let mut rows = Vec::with_capacity(configurations.len());
    for (k, (name, joints, wrench)) in configurations.iter().enumerate() {
        // Where the nominal robot puts the target (its tool point, its axes the tool's): the registration's
        // and the target's starts are then the identity, the point about which the first order is taken.
        let pose = poses.map(|p| p[k]);
        let frame = pose.or_else(|| m.pose_at_joints(joints, &mut state));
        let row = |observed: Observed, sigma: f64| PositionRow {
            name: name.clone(),
            line: k + 2,
            joints: joints.clone(),
            pose,
            wrench: *wrench,
            observed,
            sigma: Some(sigma),
            check: false,
            gravity: None,
            configuration: k,
            payload: None,
        };
        let at = frame.map_or(Vec3::zeros(), |f| f.pos);
        rows.push(row(Observed::Position { target: 0, setup: 0, at }, noise));
        if let Some(sigma) = orientation_noise {
            let at = frame.map_or(Mat3::identity(), |f| f.rot);
            rows.push(row(Observed::Orientation { target: 0, setup: 0, at }, sigma));
        }
    }
    let data = PositionData {
        rows,
        targets: vec![String::new()],
        setups: vec![String::new()],
        configurations: configurations.len(),
        unread: Vec::new(),
        orientation_columns: Vec::new(),
        not_used: Vec::new(),
        notes: Vec::new(),
    };
    let problem = PositionProblem::new(m, &data, Some(noise), orientation_noise)?;
    // A configuration is usable where its rows have a prediction (its position and orientation share one
    // equilibrium); the rows of each usable one follow each other.
    let per = if orientation_noise.is_some() { 2 } else { 1 };
    let usable: Vec<usize> =
        (0..configurations.len()).filter(|c| !problem.unusable.iter().any(|(k, _)| k / per == *c)).collect();
    let usable_rows: Vec<usize> = usable.iter().flat_map(|c| per * c..per * c + per).collect();
    let effects = if effects.is_empty() {
        problem.two_sided_play(problem.default_candidates(), &usable_rows).0
    } else {
        effects.to_vec()
    };
    let params = problem.start(&usable_rows, &effects);
    let p = problem.nuisance_count() + effects.iter().map(ArmEffect::size).sum::<usize>();
    let mut all = DMatrix::zeros(3 * usable_rows.len(), p);
    let mut row = DMatrix::zeros(3, p);
    for (i, &r) in usable_rows.iter().enumerate() {
        problem.predict(r, &effects, &params, &mut state, Some(&mut row)).ok_or_else(|| CalibrationError::Row {
            name: data.rows[r].name.clone(),
            line: data.rows[r].line,
            why: "the joint coordinates give no finite pose".into(),
        })?;
        all.view_mut((3 * i, 0), (3, p)).copy_from(&row);
    }
    let nuisance = problem.nuisance_count();
    let mut at = nuisance;
    let effects = effects
        .iter()
        .map(|e| {
            let block = all.columns(at, e.size()).into_owned();
            at += e.size();
            (e.label(&problem.joints), block)
        })
        .collect();
    Ok(Signatures { usable, rows_per_candidate: 3 * per, nuisance: all.columns(0, nuisance).into_owned(), effects })
}
