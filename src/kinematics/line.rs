//! Points equally spaced on a line, and the polynomial extrapolation of a smooth quantity one step along
//! it: the warm starts of a run's placements (`platform`) and loaded equilibria (`study::warm_start`).

use super::frame::Vec3;

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

/// The positions of the last `N` points of a sequence, in a ring whose slots the caller's values share: the
/// slots a next position continues on a line, with their extrapolation weights.
#[derive(Clone, Copy, Debug)]
pub struct PositionRing<const N: usize> {
    positions: [Vec3; N],
    /// Positions held, and the slot of the newest.
    count: usize,
    newest: usize,
}

impl<const N: usize> Default for PositionRing<N> {
    fn default() -> Self {
        Self { positions: [Vec3::zeros(); N], count: 0, newest: 0 }
    }
}

impl<const N: usize> PositionRing<N> {
    /// Forgets every position.
    pub fn clear(&mut self) {
        self.count = 0;
    }

    /// The newest position, where the ring holds one.
    pub fn newest(&self) -> Option<&Vec3> {
        (self.count > 0).then_some(&self.positions[self.newest])
    }

    /// Records `position` as the newest (over the oldest once the ring is full) and returns its slot.
    pub fn push(&mut self, position: Vec3) -> usize {
        self.newest = (self.newest + 1) % N;
        self.count = (self.count + 1).min(N);
        self.positions[self.newest] = position;
        self.newest
    }

    /// How many kept positions lie with `position` equally spaced on a line (`equally_spaced`), and the
    /// extrapolation to it through them: (weight, slot) pairs, newest first (`extrapolation_weights`; the
    /// newest alone, weight 1, where none continues it; none without positions).
    pub fn extrapolation(&self, position: &Vec3) -> (usize, impl Iterator<Item = (f64, usize)> + Clone + '_) {
        let newest_first = (0..self.count).map(|k| (self.newest + N - k) % N);
        let count = equally_spaced(newest_first.clone().map(|k| &self.positions[k]), position);
        (count, extrapolation_weights(count).iter().copied().zip(newest_first))
    }
}
