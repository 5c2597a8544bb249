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
