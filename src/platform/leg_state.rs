//! What a leg carries from one pose to the next (warm starts of inverse kinematics and of the loaded
//! equilibrium, buffers), and the loaded offsets a map extrapolates from point to point.

use crate::kinematics::chain::{ChainJacobians, Coordinates};
use crate::kinematics::frame::{Frame, Vec6};
use crate::kinematics::ik::IkWorkspace;
use crate::vjm::equilibrium::EquilibriumWorkspace;

use super::msa_leg::MsaState;

/// Per-leg state carried from one pose to the next: warm starts of inverse kinematics and of the loaded
/// equilibrium, and buffers.
#[derive(Clone, Debug)]
pub struct LegState {
    /// The leg's coordinates at its last solution.
    pub coords: Coordinates,
    /// True when `coords` holds a solved configuration usable as a warm start.
    pub warm: bool,
    /// Wrench the platform applies to the leg's end at the last equilibrium (N, N mm, at the end point).
    pub end_wrench: Vec6,
    /// The leg-end frame of the last solved equilibrium (or placement), the start of a continuation.
    pub(super) last_target: Frame,
    /// The configuration before a warm-started attempt, restored if that attempt fails.
    pub(super) saved: Coordinates,
    /// The rigid configuration found by `place`.
    pub(super) placed: Coordinates,
    pub(super) ik: IkWorkspace,
    pub(super) jac: ChainJacobians,
    pub(super) equilibrium: EquilibriumWorkspace,
    pub(super) msa: MsaState,
}

/// How a leg's loaded equilibrium departs from its placement: carried from one point of a map to the
/// next, it starts the next equilibrium where the last one ended (neighbouring points load the legs
/// alike), which saves Newton iterations over starting from the unloaded placement.
#[derive(Clone, Debug, Default)]
pub struct LoadedOffsets {
    pub(super) passive: Vec<f64>,
    pub(super) virtual_: Vec<f64>,
    pub(super) wrench: Vec6,
}

impl LoadedOffsets {
    /// The linear extrapolation `2 self - older` (the next of three equally spaced points).
    pub fn extrapolate(&self, older: &LoadedOffsets) -> LoadedOffsets {
        let lin = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| 2.0 * x - y).collect();
        LoadedOffsets {
            passive: lin(&self.passive, &older.passive),
            virtual_: lin(&self.virtual_, &older.virtual_),
            wrench: self.wrench * 2.0 - older.wrench,
        }
    }
}

impl LegState {
    /// After a loaded answer: its departure from the placement.
    pub fn loaded_offsets(&self) -> LoadedOffsets {
        LoadedOffsets {
            passive: self.coords.passive.iter().zip(&self.placed.passive).map(|(a, b)| a - b).collect(),
            virtual_: self.coords.virtual_.clone(),
            wrench: self.end_wrench,
        }
    }

    /// After `place`: start the loaded equilibrium from the placement plus `offsets`.
    pub fn apply_loaded_offsets(&mut self, offsets: &LoadedOffsets) {
        if offsets.passive.len() != self.coords.passive.len() || offsets.virtual_.len() != self.coords.virtual_.len() {
            return;
        }
        for (q, d) in self.coords.passive.iter_mut().zip(&offsets.passive) {
            *q += d;
        }
        self.coords.virtual_.copy_from_slice(&offsets.virtual_);
        self.end_wrench = offsets.wrench;
        self.ik.invalidate();
    }
}
