//! What a leg carries from one pose to the next (warm starts of inverse kinematics and of the loaded
//! equilibrium, buffers), and the loaded offsets a map extrapolates from point to point.

use crate::kinematics::chain::{ChainJacobians, Coordinates};
use crate::kinematics::frame::{Frame, Mat3, Vec3, Vec6};
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

/// Rows of misses a `PlacementTrail` keeps besides the current one: three, for a quadratic extrapolation of
/// the miss across the rows.
const ROWS_BEFORE: usize = 3;

/// Points of a row whose misses are kept: as many as a map's run holds (256, `batch::RUN`, a layer above),
/// beyond which no grid row of a run reaches. A longer row (a compensation's path, one line of thousands
/// of targets) is not kept beyond it: with no rows before it, nothing would read them.
const ROW_POINTS_KEPT: usize = 256;

/// A leg's last placements in a run while its targets keep one orientation: the targets' positions and the
/// actuated and passive coordinates found there. Where the next target lies with them equally spaced on a
/// line (a grid's rows, a sampled path), its placement starts from their polynomial extrapolation instead of
/// the last solution, a step behind.
///
/// On a grid, the extrapolation's miss is itself a smooth function of the row: where the rows before lie
/// equally spaced beside the current one, with the same points, the misses of the same extrapolation at the
/// same index there (m_1 the row before, m_2, m_3) predict this one's, and the start is corrected by
/// 2 m_1 - m_2 or 3 m_1 - 3 m_2 + m_3. On the 3-PUU's bench grid (rows 13 mm apart) that takes the median
/// miss of a coordinate from 3e-3 to 1e-12 (its 90th percentile to 2e-6): the start is then within the
/// inverse kinematics' tolerance, and one polishing step places the leg where an extrapolation alone needed
/// a Newton step and a chord step. The first two points of a row, whose extrapolations along it are the
/// last placement as it is (a row's first point: the far end of the row before), are corrected alike.
#[derive(Clone, Debug, Default)]
pub(super) struct PlacementTrail {
    positions: PositionRing<PLACEMENTS_KEPT>,
    /// Slot k's actuated then passive coordinates at `coordinates[k * n..(k + 1) * n]`, n the coordinates
    /// per placement.
    coordinates: Vec<f64>,
    rotation: Mat3,
    /// The current row (`rows[current]`) and the ones before it (`rows[current - back]`, modulo their
    /// number): `rows_kept` of them hold a row.
    rows: [RowMisses; ROWS_BEFORE + 1],
    current: usize,
    rows_kept: usize,
    /// The extrapolation `predict_into` made for `pending_position` (before any correction) with its count
    /// of terms: the miss `record` measures. One of a single term (the newest placement as it is) is left
    /// for `record` to copy from `coordinates`, where it is read only if it is needed.
    pending: Vec<f64>,
    pending_position: Option<(Vec3, usize)>,
    /// The slot of the newest placement.
    newest_slot: usize,
}

/// One row of a run's placements: where it starts, its step, and at each index the number of terms of the
/// extrapolation along it (0: none made) and its miss, the placement less the extrapolation (n values).
#[derive(Clone, Debug, Default)]
struct RowMisses {
    origin: Vec3,
    step: Vec3,
    last: Vec3,
    points: usize,
    counts: Vec<usize>,
    misses: Vec<f64>,
}

/// Two positions of a grid's arithmetic are the same, to round-off (1e-9) of a spacing whose square is
/// `scale_squared` (squares compared: no root per test).
fn same_position(a: &Vec3, b: &Vec3, scale_squared: f64) -> bool {
    (a - b).norm_squared() <= 1e-18 * scale_squared.max(1e-18)
}

impl RowMisses {
    /// `position` is this row's next point: the row holds one point (the next one fixes the step), or the
    /// position lies one step beyond its last.
    fn continued_by(&self, position: &Vec3) -> bool {
        match self.points {
            0 => false,
            1 => true,
            p => same_position(position, &(self.origin + self.step * p as f64), self.step.norm_squared()),
        }
    }
}

impl PlacementTrail {
    /// Forgets every placement (coordinates set by anything but a placement: a seed, a command).
    pub(super) fn clear(&mut self) {
        self.positions.clear();
        self.rows_kept = 0;
        self.pending_position = None;
    }

    fn row(&self, back: usize) -> &RowMisses {
        &self.rows[(self.current + self.rows.len() - back) % self.rows.len()]
    }

    /// Records the placement `placed` at `target` as the newest (over the oldest once the trail is full, or
    /// over the newest where it is the newest's target again; the others forgotten where the target
    /// turned), and its miss in its row.
    pub(super) fn record(&mut self, target: &Frame, placed: &Coordinates) {
        let n = placed.actuated.len() + placed.passive.len();
        if target.rot != self.rotation || self.coordinates.len() != PLACEMENTS_KEPT * n {
            self.clear();
            self.rotation = target.rot;
            self.coordinates.resize(PLACEMENTS_KEPT * n, 0.0);
            self.pending.reserve(n);
        }
        // The extrapolation made for this target (none: a zero miss of no terms). Of one term it is the
        // newest placement as it is, which `predict_into` leaves to be read here, before it is overwritten
        // (a pending prediction implies a placement kept: the trail is cleared with it).
        let count = match self.pending_position.take() {
            Some((p, 1)) if p == target.pos => {
                self.pending.clear();
                self.pending.extend_from_slice(&self.coordinates[self.newest_slot * n..(self.newest_slot + 1) * n]);
                1
            }
            Some((p, count)) if p == target.pos && self.pending.len() == n => count,
            _ => 0,
        };
        // A target placed again (a load solved anew at the pose just placed, a path's target commanded
        // anew) replaces its last placement: the same position twice would end every extrapolation
        // through it for the next four targets.
        let slot = match self.positions.newest() {
            Some(newest) if *newest == target.pos => self.newest_slot,
            _ => self.positions.push(target.pos),
        };
        self.newest_slot = slot;
        let values = placed.actuated.iter().chain(&placed.passive);
        for (x, q) in self.coordinates[slot * n..].iter_mut().zip(values.clone()) {
            *x = *q;
        }
        // A target placed again (a load solved at the pose just placed) is not a new point of the row.
        if self.rows_kept > 0 && self.row(0).last == target.pos {
            return;
        }
        if self.rows_kept == 0 || !self.row(0).continued_by(&target.pos) {
            self.current = (self.current + 1) % self.rows.len();
            self.rows_kept = (self.rows_kept + 1).min(self.rows.len());
            let row = &mut self.rows[self.current];
            (row.origin, row.step, row.points) = (target.pos, Vec3::zeros(), 0);
            row.counts.clear();
            row.misses.clear();
            // Room for a whole row at its start: a row's points then allocate nothing.
            row.counts.reserve(ROW_POINTS_KEPT);
            row.misses.reserve(ROW_POINTS_KEPT * n);
        }
        let pending = &self.pending;
        let row = &mut self.rows[self.current];
        if row.points == 1 {
            row.step = target.pos - row.origin;
        }
        row.points += 1;
        row.last = target.pos;
        if row.counts.len() < ROW_POINTS_KEPT {
            row.counts.push(count);
            if count == 0 {
                row.misses.extend(std::iter::repeat_n(0.0, n));
            } else {
                row.misses.extend(values.zip(pending).map(|(q, e)| q - e));
            }
        }
    }

    /// Sets `coords`' actuated and passive coordinates to their extrapolation to `target` (each a sum from
    /// zero, newest term first), corrected by the misses of the rows before where they are known, and
    /// returns true, where at least two kept placements lie with it equally spaced on a line at its
    /// orientation or a correction applies; else leaves them and returns false.
    pub(super) fn predict_into(&mut self, target: &Frame, coords: &mut Coordinates) -> bool {
        self.pending_position = None;
        let n = coords.actuated.len() + coords.passive.len();
        if target.rot != self.rotation || self.coordinates.len() != PLACEMENTS_KEPT * n {
            return false;
        }
        let (count, terms) = self.positions.extrapolation(&target.pos);
        if count == 0 {
            return false;
        }
        self.pending_position = Some((target.pos, count));
        let correction = self.row_correction(&target.pos, count);
        if count < 2 && correction.is_none() {
            return false;
        }
        self.pending.clear();
        self.pending
            .extend((0..n).map(|i| terms.clone().fold(0.0, |sum, (w, k)| sum + w * self.coordinates[k * n + i])));
        let values = coords.actuated.iter_mut().chain(coords.passive.iter_mut());
        match correction {
            // The rows' misses at this index, weighted; a correction within round-off of every
            // extrapolated value (a coordinate the extrapolation along the row already has exactly, such as
            // an actuator moving along the row: the rows' misses are then round-off, amplified by the
            // weights) is left out.
            Some(c) => {
                let misses: [&[f64]; ROWS_BEFORE] = std::array::from_fn(|k| {
                    if k < c.rows_before {
                        &self.row(c.first_back + k).misses[c.index * n..c.index * n + n]
                    } else {
                        &[]
                    }
                });
                let corrections =
                    (0..n).map(|i| (0..c.rows_before).fold(0.0, |sum: f64, k| sum + c.weights[k] * misses[k][i]));
                let noise =
                    corrections.clone().zip(&self.pending).all(|(d, e)| d.abs() <= 16.0 * f64::EPSILON * e.abs());
                if noise && count < 2 {
                    return false;
                }
                for ((q, e), d) in values.zip(&self.pending).zip(corrections) {
                    *q = if noise { *e } else { e + d };
                }
            }
            None => {
                for (q, e) in values.zip(&self.pending) {
                    *q = *e;
                }
            }
        }
        true
    }

    /// Where the rows before hold misses for `position`'s index in its row, made by an extrapolation of
    /// `count` terms, in rows equally spaced beside its own with the same step: which rows, with which
    /// weights across them (2, -1 or 3, -3, 1: at least two rows, whose shift checks the spacing).
    fn row_correction(&self, position: &Vec3, count: usize) -> Option<RowCorrection> {
        // At least two rows before a new one, three with the current one continued (a path, one long
        // row, never gets past this).
        if self.rows_kept < 2 {
            return None;
        }
        let current = self.row(0);
        if current.last == *position {
            return None;
        }
        // The position's row: the current one continued, or a new row beside it (index 0), whose rows
        // before then start with the current one.
        let (origin, index, step, first_back) = if current.continued_by(position) {
            let step = if current.points == 1 { position - current.origin } else { current.step };
            (current.origin, current.points, step, 1)
        } else {
            (*position, 0, current.step, 0)
        };
        let step_squared = step.norm_squared();
        let mut rows_before = 0;
        let (mut shift, mut shift_squared) = (Vec3::zeros(), 0.0);
        let mut newer_origin = origin;
        for k in 0..ROWS_BEFORE {
            let back = first_back + k;
            if back >= self.rows_kept {
                break;
            }
            let row = self.row(back);
            let row_shift = newer_origin - row.origin;
            if k == 0 {
                (shift, shift_squared) = (row_shift, row_shift.norm_squared());
            }
            // A row's first miss is measured from the last point of the row before it: that row must be
            // alike too (one more row, of as many points).
            let before_alike = index > 0
                || (back + 1 < self.rows_kept && {
                    let before = self.row(back + 1);
                    before.points == row.points
                        && same_position(&before.step, &step, step_squared)
                        && same_position(&(row.origin - before.origin), &shift, shift_squared)
                });
            let alike = shift_squared > 0.0
                && same_position(&row_shift, &shift, shift_squared)
                && same_position(&row.step, &step, step_squared)
                && row.counts.get(index) == Some(&count)
                && before_alike;
            if !alike {
                break;
            }
            newer_origin = row.origin;
            rows_before = k + 1;
        }
        let weights = match rows_before {
            2 => [2.0, -1.0, 0.0],
            3 => [3.0, -3.0, 1.0],
            _ => return None,
        };
        Some(RowCorrection { weights, first_back, rows_before, index })
    }
}

/// The correction of a placement's start by the misses of the rows before (`PlacementTrail`): rows
/// `first_back..first_back + rows_before` back, their misses at `index` weighted by `weights`.
#[derive(Clone, Copy, Debug)]
struct RowCorrection {
    weights: [f64; ROWS_BEFORE],
    first_back: usize,
    rows_before: usize,
    index: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A placement in `run`: x, y, the coordinates placed, and the start the trail gave (None: none).
    type Placed = (f64, f64, [f64; 2], Option<[f64; 2]>);

    /// Placements of a smooth function over a grid's rows (x along a row, rows y apart), each predicted
    /// before it is recorded: the start the trail gives at each point, and what it would be without the
    /// rows before (the extrapolation along the row alone).
    fn run(rows: &[f64], xs: &[f64], q: impl Fn(f64, f64) -> [f64; 2]) -> Vec<Placed> {
        let mut trail = PlacementTrail::default();
        let mut coords = Coordinates { actuated: vec![0.0], passive: vec![0.0], virtual_: vec![] };
        let mut out = Vec::new();
        for &y in rows {
            for &x in xs {
                let target = Frame::translation(Vec3::new(x, y, 0.0));
                let start = trail.predict_into(&target, &mut coords).then(|| [coords.actuated[0], coords.passive[0]]);
                let [a, p] = q(x, y);
                (coords.actuated[0], coords.passive[0]) = (a, p);
                trail.record(&target, &coords);
                out.push((x, y, [a, p], start));
            }
        }
        out
    }

    /// The cubic extrapolation along a row misses x^4 g(y) by a multiple of g(y) (its fourth difference),
    /// and with g quadratic across the rows, the misses of the three rows before predict this row's
    /// exactly (3 m_1 - 3 m_2 + m_3): from the fourth row on, every start is the placement itself to
    /// round-off (a row's second point too, whose extrapolation along the row is the last placement as it
    /// is; its first from the fifth row), where the extrapolation alone misses by about 1e-2.
    #[test]
    fn the_rows_before_correct_a_placement_start_to_round_off() {
        let xs: Vec<f64> = (0..10).map(|i| -60.0 + 13.0 * i as f64).collect();
        let rows: Vec<f64> = (0..6).map(|j| -40.0 + 11.0 * j as f64).collect();
        let g = |y: f64| 1.0 + y / 100.0 + (y / 100.0).powi(2);
        let q = |x: f64, y: f64| [(x / 30.0).powi(4) * g(y), 0.5 * (x / 30.0).powi(4) * g(y) + 0.1];
        let starts = run(&rows, &xs, q);
        let mut plain_misses = 0.0f64;
        for (k, (x, y, placed, start)) in starts.iter().enumerate() {
            let (row, index) = (k / xs.len(), k % xs.len());
            // From the third point of a row on, the extrapolation along it; before, only the rows' correction.
            let Some(start) = start else {
                assert!(index < 2 && row < 3, "a start at ({x}, {y})");
                continue;
            };
            let miss = (placed[0] - start[0]).abs().max((placed[1] - start[1]).abs());
            // A row's first point is corrected by the rows' first misses, each measured from the end of the
            // row before: three of them from the fifth row.
            if row >= if index == 0 { 4 } else { 3 } {
                assert!(miss <= 1e-12, "row {row}, index {index}: start {miss:e} from the placement");
            }
            if row < 2 && index >= 4 {
                plain_misses = plain_misses.max(miss);
            }
        }
        assert!(plain_misses > 1e-3, "the extrapolation along a row alone misses: {plain_misses:e}");
    }

    /// Rows that are not equally spaced (a grid's rows at 0, 10 and 25) have no smooth miss across them:
    /// no correction is made, and the starts are the extrapolation along the row.
    #[test]
    fn rows_not_equally_spaced_leave_the_extrapolation_along_the_row() {
        let xs: Vec<f64> = (0..6).map(|i| 5.0 * i as f64).collect();
        let q = |x: f64, y: f64| [(x / 10.0).powi(4) + y, 0.0];
        let uneven = run(&[0.0, 10.0, 25.0, 45.0], &xs, q);
        // The extrapolation along the row alone, by hand: cubic from the fourth point on.
        for (k, (_, _, placed, start)) in uneven.iter().enumerate().skip(3 * xs.len()) {
            let index = k % xs.len();
            if index >= 4 {
                let p = |back: usize| uneven[k - back].2[0];
                let cubic = 4.0 * p(1) - 6.0 * p(2) + 4.0 * p(3) - p(4);
                assert_eq!(start.expect("an extrapolation")[0], cubic, "index {index}");
                assert!((placed[0] - cubic).abs() > 1e-3);
            }
        }
    }
    /// A target placed a second time (a path's target commanded anew while a compensation iterates)
    /// replaces its placement in the trail: the next target's start is still the cubic extrapolation
    /// through the last four targets, exact for coordinates cubic along the line, where two entries at one
    /// position would have ended it (the start then the last placement, a step's change away).
    #[test]
    fn a_target_placed_again_keeps_the_extrapolation_through_it() {
        let q = |x: f64| [(x / 10.0).powi(3), 2.0 - x / 10.0];
        let mut trail = PlacementTrail::default();
        let mut coords = Coordinates { actuated: vec![0.0], passive: vec![0.0], virtual_: vec![] };
        let mut place = |x: f64, coords: &mut Coordinates| {
            let target = Frame::translation(Vec3::new(x, 1.0, 2.0));
            let start = trail.predict_into(&target, coords).then(|| [coords.actuated[0], coords.passive[0]]);
            [coords.actuated[0], coords.passive[0]] = q(x);
            trail.record(&target, coords);
            start
        };
        for x in [0.0, 3.0, 6.0, 9.0] {
            place(x, &mut coords);
        }
        // Placed again at its own target, first from elsewhere (its start the last placement as it is).
        [coords.actuated[0], coords.passive[0]] = [0.5, 0.5];
        place(9.0, &mut coords);
        let start = place(12.0, &mut coords).expect("an extrapolation");
        let exact = q(12.0);
        assert!((start[0] - exact[0]).abs() <= 1e-12 && (start[1] - exact[1]).abs() <= 1e-12, "{start:?} vs {exact:?}");
    }
}
