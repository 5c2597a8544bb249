//! Warm starts of a run's loaded equilibria: each point's Newton method starts from a prediction made from
//! the points solved before it in the same run (paper 000 s. 6: from the previous solution the equilibrium
//! "converges in 1-2 iterations" for small increments).

use crate::kinematics::frame::{apply_twist, Frame, Vec3, Vec6};
use crate::kinematics::line::{equally_spaced, extrapolation_weights, PositionRing};
use crate::platform::leg::{LegState, LoadedOffsets};

/// The degree of the extrapolation through equally spaced values (newest first) that predicts the next
/// best: linear from two values, quadratic from three, and beyond that each degree k whose backward
/// difference the next one shows to be the curve's (|nabla^(k+1)| < |nabla^k|), at most quartic. The
/// degree-k prediction is the sum of the newest value's backward differences up to nabla^k, its error
/// about nabla^(k+1): on a coarse grid the differences fall with each order (along the loaded 3-PUU's rows,
/// 5.7 mm apart, the displacement's third difference is 2e-4 mm, its fifth 3e-6 mm), but on a finely
/// sampled path they reach the solutions' own round-off after the second, and a higher degree would only
/// amplify it (the weights' sizes add up to 2^(d+1) - 1).
pub fn extrapolation_degree(newest_first: &[Vec6]) -> usize {
    let count = newest_first.len().min(6);
    let mut differences: [Vec6; 6] = [Vec6::zeros(); 6];
    differences[..count].copy_from_slice(&newest_first[..count]);
    // sizes[k] = |nabla^k| at the newest value.
    let mut sizes = [0.0; 6];
    for (k, size) in sizes.iter_mut().enumerate().take(count).skip(1) {
        for i in 0..count - k {
            let newer = differences[i + 1];
            differences[i] -= newer;
        }
        *size = differences[0].norm();
    }
    let mut degree = count.saturating_sub(1).min(2);
    while degree + 2 < count && degree < 4 && sizes[degree + 2] < sizes[degree + 1] {
        degree += 1;
    }
    degree
}

/// Values a `Trail` keeps: three, for a quadratic extrapolation (on a finely sampled path a higher degree
/// would only amplify the values' round-off, see `extrapolation_degree`).
const TRAIL_KEPT: usize = 3;

/// A quantity's values at the last positions of a sequence, and its extrapolation to the next position, at
/// most quadratic.
#[derive(Clone, Debug, Default)]
pub struct Trail {
    positions: PositionRing<TRAIL_KEPT>,
    /// The value at each slot of `positions`.
    values: [Vec6; TRAIL_KEPT],
}

impl Trail {
    /// Records the value at `position` as the newest (the oldest dropped once the trail is full).
    pub fn record(&mut self, position: Vec3, value: Vec6) {
        let slot = self.positions.push(position);
        self.values[slot] = value;
    }

    /// The value extrapolated to `position` (`extrapolation_weights` through the values whose positions lie
    /// with it equally spaced on a line, else the newest value); None without values.
    pub fn predict(&self, position: &Vec3) -> Option<Vec6> {
        let (count, terms) = self.positions.extrapolation(position);
        (count > 0).then(|| terms.map(|(w, k)| self.values[k] * w).sum())
    }

    /// Forgets every value.
    pub fn clear(&mut self) {
        self.positions.clear();
    }
}

/// One loaded solution: commanded position, platform displacement, each leg's departure from its placement.
#[derive(Clone, Debug, Default)]
struct Solution {
    position: Vec3,
    displacement: Vec6,
    offsets: Vec<LoadedOffsets>,
}

impl Solution {
    /// Overwrites the solution (its buffers reused): the platform's displacement and the legs' departures
    /// from their placement.
    fn set(&mut self, position: Vec3, displacement: Vec6, legs: &[LegState]) {
        self.position = position;
        self.displacement = displacement;
        self.offsets.resize_with(legs.len(), LoadedOffsets::default);
        for (o, leg) in self.offsets.iter_mut().zip(legs) {
            leg.loaded_offsets_into(o);
        }
    }
}

/// The last few solutions of a sequence of points, oldest first, and the prediction they make for the next.
#[derive(Clone, Debug, Default)]
struct Sequence {
    solutions: Vec<Solution>,
}

/// Solutions a sequence keeps: six, for a quartic extrapolation whose last difference is judged by the
/// next (`extrapolation_degree`).
const KEPT: usize = 6;

impl Sequence {
    /// The polynomial extrapolation to `position` through the last solutions that lie with `position`
    /// equally spaced on a line, of the degree their displacements' differences support
    /// (`extrapolation_degree`), else the last solution as it is: along a grid's rows the start is up to
    /// O(h^5) from the equilibrium, and Newton's method confirms it with fewer chord steps.
    fn predict(&self, position: &Vec3) -> Option<Prediction<'_>> {
        self.solutions.last()?;
        let count = self.equally_spaced(position);
        let mut displacements = [Vec6::zeros(); KEPT];
        for (d, s) in displacements.iter_mut().zip(self.solutions.iter().rev().take(count)) {
            *d = s.displacement;
        }
        let weights = extrapolation_weights(extrapolation_degree(&displacements[..count]) + 1);
        Some(Prediction::along(&self.solutions, weights))
    }

    /// How many of the last solutions lie with `position` equally spaced on a line (at least 1).
    fn equally_spaced(&self, position: &Vec3) -> usize {
        equally_spaced(self.solutions.iter().rev().map(|s| &s.position), position)
    }

    /// The slot of a new newest solution: the oldest one's buffers once the sequence is full (no
    /// allocation), to be overwritten.
    fn make_room(&mut self) -> &mut Solution {
        if self.solutions.len() == KEPT {
            self.solutions.rotate_left(1);
        } else {
            self.solutions.push(Solution::default());
        }
        self.solutions.last_mut().expect("a solution was just made room for")
    }

    /// Records a solution: the platform's displacement and the legs' departures from their placement.
    fn record(&mut self, position: Vec3, displacement: Vec6, legs: &[LegState]) {
        self.make_room().set(position, displacement, legs);
    }

    fn distance(&self, position: &Vec3) -> f64 {
        self.solutions.last().map_or(f64::INFINITY, |s| (position - s.position).norm())
    }
}

/// Terms a prediction combines at most: an extrapolation along the row (up to five solutions) and its
/// error measured in each of the three rows before (the same extrapolation there, and the solution it
/// predicted).
const MAX_TERMS: usize = 4 * (KEPT + 1);

/// An extrapolation: solutions and their weights (the first `count` of `terms`).
struct Prediction<'a> {
    terms: [(f64, &'a Solution); MAX_TERMS],
    count: usize,
}

impl<'a> Prediction<'a> {
    /// The polynomial extrapolation of `weights` (newest first) through the newest of `solutions` (oldest
    /// first, at least one).
    fn along(solutions: &'a [Solution], weights: &[f64]) -> Self {
        let newest = solutions.last().expect("an extrapolation through at least one solution");
        // Slots past `count` are never read; they hold the newest solution only to be initialised.
        let mut p = Prediction { terms: [(0.0, newest); MAX_TERMS], count: 0 };
        for (w, s) in weights.iter().zip(solutions.iter().rev()) {
            p.add(*w, s);
        }
        p
    }

    fn add(&mut self, weight: f64, solution: &'a Solution) {
        self.terms[self.count] = (weight, solution);
        self.count += 1;
    }

    /// The solutions used with their weights.
    fn terms(&self) -> impl Iterator<Item = (f64, &Solution)> + Clone {
        self.terms[..self.count].iter().map(|(w, s)| (*w, *s))
    }

    /// The platform's displacement predicted.
    fn displacement(&self) -> Vec6 {
        self.terms().map(|(w, s)| s.displacement * w).sum()
    }

    /// Each leg placed in `legs` moved by its predicted offsets (`LegState::apply_combined_offsets`).
    fn apply(&self, legs: &mut [LegState]) {
        for (k, leg) in legs.iter_mut().enumerate() {
            if self.terms().all(|(_, s)| k < s.offsets.len()) {
                leg.apply_combined_offsets(self.terms().map(|(w, s)| (w, &s.offsets[k])));
            }
        }
    }
}

/// The solutions of one row of a grid (points equally spaced on a line, in order), in buffers kept from
/// row to row: the first `len` of `solutions`, of the row's `points` so far (all of them up to
/// `ROW_POINTS_KEPT`).
#[derive(Clone, Debug, Default)]
struct Row {
    solutions: Vec<Solution>,
    len: usize,
    points: usize,
}

/// Points of a row whose solutions are kept: a map's run (`batch::RUN`), beyond which no grid row of a run
/// reaches. A longer row (a compensation's path, one line of thousands of targets) is not kept beyond it:
/// with no rows before it, nothing would read them.
const ROW_POINTS_KEPT: usize = crate::batch::RUN;

impl Row {
    fn solved(&self) -> &[Solution] {
        &self.solutions[..self.len]
    }

    /// The row's solution at `index`, where it was solved at `position` (to round-off of the grid's
    /// arithmetic, relative to the row's `spacing`).
    fn at(&self, index: usize, position: &Vec3, spacing: f64) -> Option<&Solution> {
        let s = self.solved().get(index)?;
        ((s.position - position).norm() <= 1e-9 * spacing).then_some(s)
    }

    fn record(&mut self, position: Vec3, displacement: Vec6, legs: &[LegState]) {
        self.points += 1;
        if self.len == ROW_POINTS_KEPT {
            return;
        }
        if self.len == self.solutions.len() {
            self.solutions.push(Solution::default());
        }
        self.solutions[self.len].set(position, displacement, legs);
        self.len += 1;
    }

    fn clear(&mut self) {
        self.len = 0;
        self.points = 0;
    }
}

/// Rows whose solutions a run keeps: the current one and the three before it.
const ROWS_KEPT: usize = 4;

/// A run's loaded solutions: the last points, the first points of the last lines (the starts of a grid's
/// rows), so a point that begins a line starts from the lines before it rather than from the far end of the
/// previous row, and the last rows (up to `ROW_POINTS_KEPT` points each), so that the error of the
/// extrapolation along a row is measured on the rows before it and taken off.
#[derive(Clone, Debug, Default)]
pub struct LoadedHistory {
    recent: Sequence,
    line_starts: Sequence,
    /// The current line (three equally spaced points) has its first point among `line_starts`.
    line_recorded: bool,
    /// The current row (`rows[current]`) and the three before it (`rows[current - 1]`, ..., modulo
    /// `ROWS_KEPT`): `rows_kept` of them hold a row.
    rows: [Row; ROWS_KEPT],
    current: usize,
    rows_kept: usize,
}

impl LoadedHistory {
    /// The extrapolation to `position` from the solutions before.
    fn predict(&self, position: &Vec3) -> Option<Prediction<'_>> {
        if self.begins_line(position) {
            return self.line_starts.predict(position);
        }
        let mut prediction = self.recent.predict(position)?;
        if self.continues_row(position) {
            self.correct_from_rows_before(position, &mut prediction);
        }
        Some(prediction)
    }

    /// `position` begins a new line beside the last line's start, nearer to it than to the last point solved:
    /// its start is predicted from the lines' starts, and the last solve's factorisations, made at the far
    /// end of the last line, are of no use to it.
    pub fn begins_line(&self, position: &Vec3) -> bool {
        let continues_line = self.recent.equally_spaced(position) >= 2;
        !continues_line && self.line_starts.distance(position) < self.recent.distance(position)
    }

    fn row(&self, back: usize) -> &Row {
        &self.rows[(self.current + ROWS_KEPT - back) % ROWS_KEPT]
    }

    /// `position` is the next point of the current row: the row holds one point (the next fixes its
    /// spacing), or it lies equally spaced after the row's last two.
    fn continues_row(&self, position: &Vec3) -> bool {
        match self.row(0).points {
            0 => false,
            1 => true,
            // The row's last two points are the last two solved.
            _ => self.recent.equally_spaced(position) >= 2,
        }
    }

    /// Takes off an extrapolation's error along the current row as the rows before it show it: for a point
    /// at index i of the row, the same extrapolation through the points of each earlier row at the same
    /// indices misses that row's own solution at i by e_1 (the row before), e_2, e_3; the error varies
    /// smoothly from row to row, so the prediction gains its extrapolation across the equally spaced rows:
    /// 3 e_1 - 3 e_2 + e_3, or 2 e_1 - e_2, or e_1 where fewer rows are known. Along a short row the
    /// extrapolation is of low degree near its start (a constant at its second point), and the correction
    /// leaves only the mixed differences across rows. Nothing is added where the earlier rows do not hold
    /// the same points shifted by the same step between rows.
    fn correct_from_rows_before<'a>(&'a self, position: &Vec3, prediction: &mut Prediction<'a>) {
        let current = self.row(0).solved();
        // The point's index in the row (the row holds at least one point: it continues it), where the row's
        // points are all kept.
        let index = self.row(0).points;
        if index > current.len() {
            return;
        }
        let along = prediction.count;
        // The along-row terms are the row's last `along` solutions (`Sequence::predict` took them from the
        // recent points, which the row's last points are: it continues the row).
        if along > current.len() || along == 0 {
            return;
        }
        let spacing = (position - current[index - 1].position).norm();
        let mut shifts = [Vec3::zeros(); 3];
        let mut rows_before = 0;
        for back in 1..=3.min(self.rows_kept.saturating_sub(1)) {
            let (row, newer) = (self.row(back).solved(), self.row(back - 1).solved());
            let (Some(first), Some(newer_first)) = (row.first(), newer.first()) else { break };
            let shift = newer_first.position - first.position;
            // Equally spaced rows: the shift between earlier rows is the first's.
            if back >= 2 && (shift - shifts[0]).norm() > 1e-9 * shift.norm().max(1e-9) {
                break;
            }
            shifts[back - 1] = shift;
            rows_before = back;
        }
        let weights: [f64; 3] = match rows_before {
            1 => [1.0, 0.0, 0.0],
            2 => [2.0, -1.0, 0.0],
            3 => [3.0, -3.0, 1.0],
            _ => return,
        };
        // Each earlier row's point at `index`, and at the indices of the along-row terms.
        let mut found: [[Option<&Solution>; KEPT + 1]; 3] = [[None; KEPT + 1]; 3];
        for back in 1..=rows_before {
            let offset: Vec3 = shifts[..back].iter().sum();
            let row = self.row(back);
            found[back - 1][0] = row.at(index, &(position - offset), spacing);
            for k in 0..along {
                let j = index - 1 - k;
                found[back - 1][k + 1] = row.at(j, &(current[j].position - offset), spacing);
            }
            if found[back - 1][..=along].iter().any(Option::is_none) {
                return;
            }
        }
        let along_weights: [f64; KEPT] = std::array::from_fn(|k| if k < along { prediction.terms[k].0 } else { 0.0 });
        for (back, row_weight) in weights.iter().enumerate().take(rows_before) {
            let solutions = &found[back];
            prediction.add(*row_weight, solutions[0].expect("checked above"));
            for (k, w) in along_weights.iter().enumerate().take(along) {
                prediction.add(-row_weight * w, solutions[k + 1].expect("checked above"));
            }
        }
    }

    /// The start of the equilibrium at `position` (the key the solutions were recorded by), where the run
    /// has solutions: the legs, placed in `legs`, moved by their predicted departures from the placement,
    /// and the platform pose `from` moved by the predicted displacement. None, `legs` untouched, without.
    pub fn start(&self, position: &Vec3, from: &Frame, legs: &mut [LegState]) -> Option<Frame> {
        let prediction = self.predict(position)?;
        prediction.apply(legs);
        Some(apply_twist(from, &prediction.displacement()))
    }

    /// Records the solution at `position`: the platform's displacement and the legs' departures from their
    /// placement (`LegState::loaded_offsets`).
    pub fn push(&mut self, position: Vec3, displacement: Vec6, legs: &[LegState]) {
        let continues_line = self.recent.equally_spaced(&position) >= 2;
        if !continues_line {
            self.line_recorded = false;
        }
        if !self.continues_row(&position) {
            self.current = (self.current + 1) % ROWS_KEPT;
            self.rows[self.current].clear();
            self.rows_kept = (self.rows_kept + 1).min(ROWS_KEPT);
        }
        self.rows[self.current].record(position, displacement, legs);
        self.recent.record(position, displacement, legs);
        // Three equally spaced points make a line: its first is the oldest of them.
        if continues_line && !self.line_recorded {
            self.line_starts.make_room().clone_from(&self.recent.solutions[self.recent.solutions.len() - 3]);
            self.line_recorded = true;
        }
    }

    /// Records the solution at `position` in place of the newest where that was solved at the same
    /// position (another command tried for one target of a compensation): a line's points stay equally
    /// spaced, and the latest solve, the one the next starts nearest to, is the one kept.
    pub fn supersede(&mut self, position: Vec3, displacement: Vec6, legs: &[LegState]) {
        if self.recent.solutions.last().is_some_and(|s| s.position == position) {
            self.recent.solutions.pop();
            let row = &mut self.rows[self.current];
            row.points = row.points.saturating_sub(1);
            row.len = row.len.min(row.points);
        }
        self.push(position, displacement, legs);
    }

    /// No solution recorded (a run's start, or after a failure).
    pub fn is_empty(&self) -> bool {
        self.recent.solutions.is_empty()
    }

    /// Forgets every solution (after a point that failed: its neighbours' starts are no longer trusted).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A displacement quadratic in the position along a line is predicted exactly by the quadratic
    /// extrapolation through three equally spaced points. Compensation solves a target more than once (a
    /// command tried, then a better one): the second solution at the newest position must replace the
    /// first, not stand beside it at zero spacing, which would break the line and leave only the last value
    /// as the next prediction.
    /// Along a grid's rows the extrapolation through a row's last points misses a displacement cubic along
    /// the row by 6 h^3 times the cubic's coefficient. Where that coefficient varies linearly across the
    /// rows, the misses of the same extrapolation on the rows before (at the same points) predict this
    /// row's miss exactly: the start is then exact, where the row's own points alone leave the miss.
    #[test]
    fn the_rows_before_correct_the_extrapolation_along_a_row() {
        let displacement = |x: f64, y: f64| Vec6::new((1.0 + 0.5 * y) * x * x * x + x * y, 0.0, 0.0, 0.0, 0.0, 0.0);
        let position = |x: f64, y: f64| Vec3::new(x, y, 0.0);
        let mut history = LoadedHistory::default();
        for y in 0..3 {
            for x in 0..6 {
                history.push(position(x as f64, y as f64), displacement(x as f64, y as f64), &[]);
            }
        }
        let mut row_alone = LoadedHistory::default();
        for x in 0..3 {
            history.push(position(x as f64, 3.0), displacement(x as f64, 3.0), &[]);
            row_alone.push(position(x as f64, 3.0), displacement(x as f64, 3.0), &[]);
        }
        let exact = displacement(3.0, 3.0);
        let corrected = history.predict(&position(3.0, 3.0)).unwrap().displacement();
        let alone = row_alone.predict(&position(3.0, 3.0)).unwrap().displacement();
        assert!((corrected - exact).norm() < 1e-12, "corrected {corrected} vs {exact}");
        assert!((alone - exact).norm() > 1.0, "the row alone misses by 6 (1 + 0.5 * 3): {alone} vs {exact}");
        // Rows shifted along the row by the same amount each (a sheared grid) hold the same points along the
        // shear: the correction is exact there too.
        let mut sheared = LoadedHistory::default();
        for y in 0..4 {
            for x in 0..if y < 3 { 6 } else { 3 } {
                let x = x as f64 + 0.5 * y as f64;
                sheared.push(position(x, y as f64), displacement(x, y as f64), &[]);
            }
        }
        let predicted = sheared.predict(&position(4.5, 3.0)).unwrap().displacement();
        assert!((predicted - displacement(4.5, 3.0)).norm() < 1e-12, "sheared {predicted}");
        // Rows spaced unlike the current one do not hold its points: the row's own extrapolation stays.
        let mut finer = LoadedHistory::default();
        for y in 0..3 {
            for x in 0..6 {
                finer.push(position(x as f64, y as f64), displacement(x as f64, y as f64), &[]);
            }
        }
        for x in 0..3 {
            finer.push(position(0.5 * x as f64, 3.0), displacement(0.5 * x as f64, 3.0), &[]);
        }
        let predicted = finer.predict(&position(1.5, 3.0)).unwrap().displacement();
        let along: Vec6 = [3.0, -3.0, 1.0].iter().zip([1.0, 0.5, 0.0]).map(|(w, x)| displacement(x, 3.0) * *w).sum();
        assert_eq!(predicted, along);
    }

    /// A compensation's path is one line of thousands of targets: its row is kept only up to a map's run
    /// (nothing reads it, as no row lies before it), so the history neither grows with the path nor
    /// allocates per target; the extrapolation along the line is the one the recent points make.
    #[test]
    fn a_long_line_keeps_a_bounded_row() {
        let position = |x: f64| Vec3::new(x, 0.5 * x, 0.0);
        let displacement = |x: f64| Vec6::new(x * x, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut history = LoadedHistory::default();
        for i in 0..1000 {
            history.push(position(i as f64), displacement(i as f64), &[]);
        }
        let row = history.row(0);
        assert_eq!((row.points, row.len, row.solutions.len()), (1000, ROW_POINTS_KEPT, ROW_POINTS_KEPT));
        let predicted = history.predict(&position(1000.0)).unwrap().displacement();
        assert!((predicted - displacement(1000.0)).norm() < 1e-6, "{predicted}");
    }

    /// A loaded map's point that begins a grid's line beside the last line's start lies a row's length
    /// from the last point solved, whose factorisations chord steps would reuse: they contract by how far
    /// the matrices have moved since, and stall there. Such a point, and only such a point, begins a line.
    #[test]
    fn only_the_first_point_of_a_new_line_begins_a_line() {
        let mut history = LoadedHistory::default();
        let mut begun = Vec::new();
        for y in 0..3 {
            for x in 0..6 {
                let position = Vec3::new(x as f64, y as f64, 0.0);
                if history.begins_line(&position) {
                    begun.push((x, y));
                }
                history.push(position, Vec6::repeat(x as f64 * y as f64), &[]);
            }
        }
        // The first line has no line before it to begin beside; the later lines begin at x = 0.
        assert_eq!(begun, [(0, 1), (0, 2)]);
    }

    #[test]
    fn a_second_solution_at_one_position_replaces_the_first() {
        let position = |x: f64| Vec3::new(x, 2.0 * x, -x);
        let displacement = |x: f64| Vec6::new(x * x, 1.0 - x, 0.5 * x * x, 0.0, 0.0, 0.0);
        let mut history = LoadedHistory::default();
        history.supersede(position(0.0), displacement(0.0), &[]);
        history.supersede(position(1.0), displacement(1.0), &[]);
        history.supersede(position(2.0), Vec6::repeat(7.0), &[]);
        history.supersede(position(2.0), displacement(2.0), &[]);
        let predicted = history.predict(&position(3.0)).unwrap().displacement();
        assert!((predicted - displacement(3.0)).norm() < 1e-12, "{predicted} vs {}", displacement(3.0));
    }
}
