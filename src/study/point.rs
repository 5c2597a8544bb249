//! One pose of a study: the manipulator's unloaded stiffness there and what follows from it.

use crate::kinematics::frame::{Mat6, Vec6};
use crate::model::grid::PosePoint;
use crate::platform::compliance::{analyse, principal, Analysis, PrincipalCompliance};
use crate::platform::leg::LegFailure;
use crate::platform::manipulator::{Manipulator, ManipulatorState};

/// The outcome of one point, as the map reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Ok,
    /// Inverse kinematics found no configuration of some leg.
    Unreachable,
    /// The sum over legs has rank below 6.
    Singular,
    /// A leg's springs do not restrain what its passive joints leave free.
    SingularLeg,
    /// The loaded equilibrium was not found.
    NotConverged,
}

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Unreachable => "unreachable",
            Status::Singular => "singular",
            Status::SingularLeg => "singular_leg",
            Status::NotConverged => "not_converged",
        }
    }
}

#[derive(Clone, Debug)]
pub struct PointResult {
    pub status: Status,
    /// Rank of the stiffness matrix (0 where it could not be computed).
    pub rank: usize,
    pub stiffness: Option<Mat6>,
    pub compliance: Option<Mat6>,
    pub principal: Option<PrincipalCompliance>,
    /// Linear deflection C w under the point's reference wrench.
    pub deflection: Option<Vec6>,
    /// Free directions of a singular manipulator.
    pub free: Vec<Vec6>,
}

impl PointResult {
    fn failed(status: Status) -> Self {
        Self { status, rank: 0, stiffness: None, compliance: None, principal: None, deflection: None, free: Vec::new() }
    }
}

pub fn unloaded_point(m: &Manipulator, p: &PosePoint, state: &mut ManipulatorState) -> PointResult {
    let agg = match m.unloaded(&p.frame(), state) {
        Ok(a) => a,
        Err(e) => {
            return PointResult::failed(match e.failure {
                LegFailure::Unreachable(_) => Status::Unreachable,
                LegFailure::SingularChain => Status::SingularLeg,
                LegFailure::NotConverged { .. } => Status::NotConverged,
            })
        }
    };
    match analyse(&agg.stiffness, m.length_scale) {
        Analysis::Regular { compliance } => PointResult {
            status: Status::Ok,
            rank: 6,
            stiffness: Some(agg.stiffness),
            compliance: Some(compliance),
            principal: Some(principal(&compliance)),
            deflection: p.wrench.map(|w| compliance * w),
            free: Vec::new(),
        },
        Analysis::Singular { rank, free } => PointResult {
            status: Status::Singular,
            rank,
            stiffness: Some(agg.stiffness),
            compliance: None,
            principal: None,
            deflection: None,
            free,
        },
    }
}
