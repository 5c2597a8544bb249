//! Warm starts of a run's loaded equilibria: each point's Newton method starts from a prediction made from
//! the points solved before it in the same run (paper 000 s. 6: from the previous solution the equilibrium
//! "converges in 1-2 iterations" for small increments).

use crate::kinematics::frame::{apply_twist, Frame, Vec3, Vec6};
use crate::platform::leg::{LegState, LoadedOffsets};

/// How many of the last points (`newest_first`) lie with `position` equally spaced on a line: 0 without
/// points, else at least 1.
pub fn equally_spaced<'a>(mut newest_first: impl Iterator<Item = &'a Vec3>, position: &Vec3) -> usize {
    let Some(mut newer) = newest_first.next() else { return 0 };
    let step = position - newer;
    let mut count = 1;
    for older in newest_first {
        if ((newer - older) - step).norm() > 1e-9 * step.norm().max(1e-9) {
            break;
        }
        count += 1;
        newer = older;
    }
    count
}

/// The weights, newest first, of the polynomial extrapolation one step beyond `count` equally spaced
/// values (at least 1): the value itself, linear (2, -1), quadratic (3, -3, 1), cubic (4, -6, 4, -1), and
/// quartic (5, -10, 10, -5, 1) from five or more: (-1)^i C(d + 1, i + 1) for degree d, whose prediction is
/// O(h^(d+1)) from a smooth function of the position.
pub fn extrapolation_weights(count: usize) -> &'static [f64] {
    match count {
        0 | 1 => &[1.0],
        2 => &[2.0, -1.0],
        3 => &[3.0, -3.0, 1.0],
        4 => &[4.0, -6.0, 4.0, -1.0],
        _ => &[5.0, -10.0, 10.0, -5.0, 1.0],
    }
}

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

/// A quantity's values at the last positions of a sequence (oldest first), and its extrapolation to the
/// next position, at most quadratic.
#[derive(Clone, Debug, Default)]
pub struct Trail {
    last: Vec<(Vec3, Vec6)>,
}

impl Trail {
    /// Records the value at `position` as the newest (the oldest dropped once the trail is full).
    pub fn record(&mut self, position: Vec3, value: Vec6) {
        if self.last.len() == TRAIL_KEPT {
            self.last.remove(0);
        }
        self.last.push((position, value));
    }

    /// The value extrapolated to `position` (`extrapolation_weights` through the values whose positions lie
    /// with it equally spaced on a line, else the newest value); None without values.
    pub fn predict(&self, position: &Vec3) -> Option<Vec6> {
        let count = equally_spaced(self.last.iter().rev().map(|(p, _)| p), position);
        let weights = extrapolation_weights(count).iter().zip(self.last.iter().rev());
        (count > 0).then(|| weights.map(|(w, (_, v))| v * *w).sum())
    }

    /// Forgets every value.
    pub fn clear(&mut self) {
        self.last.clear();
    }
}

/// One loaded solution: commanded position, platform displacement, each leg's departure from its placement.
#[derive(Clone, Debug, Default)]
struct Solution {
    position: Vec3,
    displacement: Vec6,
    offsets: Vec<LoadedOffsets>,
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
        let prediction = Prediction { solutions: &self.solutions, weights };
        Some(prediction)
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
        let newest = self.make_room();
        newest.position = position;
        newest.displacement = displacement;
        newest.offsets.resize_with(legs.len(), LoadedOffsets::default);
        for (o, leg) in newest.offsets.iter_mut().zip(legs) {
            leg.loaded_offsets_into(o);
        }
    }

    fn distance(&self, position: &Vec3) -> f64 {
        self.solutions.last().map_or(f64::INFINITY, |s| (position - s.position).norm())
    }
}

/// An extrapolation: the newest solutions (the last `weights.len()` of `solutions`, oldest first) and
/// their weights, newest first.
struct Prediction<'a> {
    solutions: &'a [Solution],
    weights: &'static [f64],
}

impl Prediction<'_> {
    /// The solutions used, newest first, with their weights.
    fn terms(&self) -> impl Iterator<Item = (f64, &Solution)> + Clone {
        self.solutions.iter().rev().zip(self.weights).map(|(s, w)| (*w, s))
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

/// A run's loaded solutions: the last points, and the first points of the last lines (the starts of a
/// grid's rows), so a point that begins a line starts from the lines before it rather than from the far
/// end of the previous row.
#[derive(Clone, Debug, Default)]
pub struct LoadedHistory {
    recent: Sequence,
    line_starts: Sequence,
    /// The current line (three equally spaced points) has its first point among `line_starts`.
    line_recorded: bool,
}

impl LoadedHistory {
    /// The extrapolation to `position` from the solutions before.
    fn predict(&self, position: &Vec3) -> Option<Prediction<'_>> {
        let continues_line = self.recent.equally_spaced(position) >= 2;
        if !continues_line && self.line_starts.distance(position) < self.recent.distance(position) {
            return self.line_starts.predict(position);
        }
        self.recent.predict(position)
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
