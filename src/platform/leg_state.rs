//! What a leg carries from one pose to the next (warm starts of inverse kinematics and of the loaded
//! equilibrium, buffers), and the loaded offsets a map extrapolates from point to point.

use crate::kinematics::chain::{ChainJacobians, Coordinates};
use crate::kinematics::frame::{Frame, Mat3, Vec6};
use crate::kinematics::ik::IkWorkspace;
use crate::kinematics::line::PositionRing;
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
    /// The configuration and end wrench kept by `checkpoint` for `rollback`.
    pub(super) checkpoint: (Coordinates, Vec6),
    /// The rigid configuration found by `place`.
    pub(super) placed: Coordinates,
    /// The last placements of the run, the start of the next one.
    pub(super) placements: PlacementTrail,
    pub(super) ik: IkWorkspace,
    pub(super) jac: ChainJacobians,
    pub(super) equilibrium: EquilibriumWorkspace,
    pub(super) msa: MsaState,
    /// Scratch of `apply_combined_offsets`: the passive coordinates' combined offsets.
    pub(super) offset_sums: Vec<f64>,
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

impl LegState {
    /// Keeps what a loaded Newton attempt changes (configuration, end wrench), for `rollback` (no
    /// allocation once the buffers have their size, unlike a clone of the whole state).
    pub fn checkpoint(&mut self) {
        self.checkpoint.0.clone_from(&self.coords);
        self.checkpoint.1 = self.end_wrench;
    }

    /// Back to the last `checkpoint`.
    pub fn rollback(&mut self) {
        self.coords.clone_from(&self.checkpoint.0);
        self.end_wrench = self.checkpoint.1;
        self.ik.invalidate();
    }

    /// After a loaded answer: its departure from the placement, into `offsets` (its buffers reused).
    pub fn loaded_offsets_into(&self, offsets: &mut LoadedOffsets) {
        offsets.passive.clear();
        offsets.passive.extend(self.coords.passive.iter().zip(&self.placed.passive).map(|(a, b)| a - b));
        offsets.virtual_.clone_from(&self.coords.virtual_);
        offsets.wrench = self.end_wrench;
    }

    /// After `place`: start the loaded equilibrium from the placement plus the weighted sum `sum w_k o_k`
    /// of offsets at earlier points (with the weights of a polynomial extrapolation, `2, -1` linear,
    /// `3, -3, 1` quadratic, the prediction at the next of equally spaced points), each entry summed from
    /// zero in the terms' order. Offsets of another shape (another leg) are ignored.
    pub fn apply_combined_offsets<'a>(&mut self, terms: impl Iterator<Item = (f64, &'a LoadedOffsets)> + Clone) {
        let (n, m) = (self.coords.passive.len(), self.coords.virtual_.len());
        if !terms.clone().all(|(_, o)| o.passive.len() == n && o.virtual_.len() == m) {
            return;
        }
        // Term by term over contiguous entries (each entry's sum still from zero in the terms' order: the
        // same bits as one sum per entry, without walking the terms once per entry).
        let sums = &mut self.offset_sums;
        sums.clear();
        sums.resize(n, 0.0);
        self.coords.virtual_.iter_mut().for_each(|theta| *theta = 0.0);
        let mut wrench = Vec6::zeros();
        for (w, o) in terms {
            for (sum, d) in sums.iter_mut().zip(&o.passive) {
                *sum += w * d;
            }
            for (theta, d) in self.coords.virtual_.iter_mut().zip(&o.virtual_) {
                *theta += w * d;
            }
            wrench += o.wrench * w;
        }
        for (q, sum) in self.coords.passive.iter_mut().zip(sums.iter()) {
            *q += sum;
        }
        self.end_wrench = wrench;
        self.ik.invalidate();
    }
}

/// Placements a `PlacementTrail` keeps: four, for a cubic extrapolation, whose miss falls as h^4. Along a
/// 3-PUU map's rows 13 mm apart it starts the inverse kinematics about 5e-4 mm from the pose (two
/// Gauss-Newton steps, the second to round-off; from the last placement, 13 mm away, three), along rows
/// 2.4 mm apart about 1e-7 mm (one step). A quadratic's start (3e-2 mm on the coarse rows) needs the same
/// two steps there and two instead of one on the fine rows (12% more instructions per point there); a
/// quartic's saves no step and costs more to keep.
const PLACEMENTS_KEPT: usize = 4;

/// A leg's last placements in a run while its targets keep one orientation: the targets' positions and the
/// actuated and passive coordinates found there. Where the next target lies with them equally spaced on a
/// line (a grid's rows, a sampled path), its placement starts from their polynomial extrapolation instead of
/// the last solution, a step behind.
#[derive(Clone, Debug, Default)]
pub(super) struct PlacementTrail {
    positions: PositionRing<PLACEMENTS_KEPT>,
    /// Slot k's actuated then passive coordinates at `coordinates[k * n..(k + 1) * n]`, n the coordinates
    /// per placement.
    coordinates: Vec<f64>,
    rotation: Mat3,
}

impl PlacementTrail {
    /// Forgets every placement (coordinates set by anything but a placement: a seed, a command).
    pub(super) fn clear(&mut self) {
        self.positions.clear();
    }

    /// Records the placement `placed` at `target` as the newest (over the oldest once the trail is full;
    /// the others forgotten where the target turned).
    pub(super) fn record(&mut self, target: &Frame, placed: &Coordinates) {
        let n = placed.actuated.len() + placed.passive.len();
        if target.rot != self.rotation || self.coordinates.len() != PLACEMENTS_KEPT * n {
            self.positions.clear();
            self.rotation = target.rot;
            self.coordinates.resize(PLACEMENTS_KEPT * n, 0.0);
        }
        let slot = self.positions.push(target.pos);
        for (x, q) in self.coordinates[slot * n..].iter_mut().zip(placed.actuated.iter().chain(&placed.passive)) {
            *x = *q;
        }
    }

    /// Sets `coords`' actuated and passive coordinates to their extrapolation to `target` (each a sum from
    /// zero, newest term first) and returns true, where at least two kept placements lie with it equally
    /// spaced on a line at its orientation; else leaves them and returns false.
    pub(super) fn predict_into(&self, target: &Frame, coords: &mut Coordinates) -> bool {
        let n = coords.actuated.len() + coords.passive.len();
        if target.rot != self.rotation || self.coordinates.len() != PLACEMENTS_KEPT * n {
            return false;
        }
        let (count, terms) = self.positions.extrapolation(&target.pos);
        if count < 2 {
            return false;
        }
        for (i, q) in coords.actuated.iter_mut().chain(coords.passive.iter_mut()).enumerate() {
            *q = terms.clone().fold(0.0, |sum, (w, k)| sum + w * self.coordinates[k * n + i]);
        }
        true
    }
}
