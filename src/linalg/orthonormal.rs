//! Gram-Schmidt in R^6 with SVD-like rank decisions, and the orthogonal complement from its projector.

use super::svd::MAX_ENTRY;
use super::svd::SPAN_SHARE;

/// Orthonormal directions of R^6 grown by Gram-Schmidt: the spans of vectors added, then their orthogonal
/// complement (`complement`). A vector's part outside the directions so far is a new direction when it is
/// above `SPAN_SHARE` of the largest vector added (the rank decision `span_basis` makes with singular
/// values), largest part first; each direction is orthogonalised twice, so the set is orthonormal to
/// round-off even where the vectors are nearly dependent. For a handful of six-vectors this costs a few
/// hundred operations where an SVD costs thousands, and nothing is allocated.
#[derive(Clone, Copy, Debug)]
pub struct Orthonormal6 {
    directions: [nalgebra::Vector6<f64>; 6],
    len: usize,
    largest: f64,
}

impl Default for Orthonormal6 {
    fn default() -> Self {
        Orthonormal6 { directions: [nalgebra::Vector6::zeros(); 6], len: 0, largest: 0.0 }
    }
}

impl Orthonormal6 {
    /// The directions so far.
    pub fn directions(&self) -> &[nalgebra::Vector6<f64>] {
        &self.directions[..self.len]
    }

    /// Adds the span of `vectors`, six at a time. False, leaving the set unusable, where a vector is not
    /// finite or has an entry beyond `MAX_ENTRY`.
    pub fn span(&mut self, vectors: impl IntoIterator<Item = nalgebra::Vector6<f64>>) -> bool {
        let mut part = [nalgebra::Vector6::zeros(); 6];
        let mut count = 0;
        for v in vectors {
            part[count] = v;
            count += 1;
            if count == 6 {
                if !self.span_part(&mut part) {
                    return false;
                }
                count = 0;
            }
        }
        count == 0 || self.span_part(&mut part[..count])
    }

    /// `span` of at most six vectors, which it overwrites.
    fn span_part(&mut self, candidates: &mut [nalgebra::Vector6<f64>]) -> bool {
        if !candidates.iter().flatten().all(|v| v.is_finite() && v.abs() <= MAX_ENTRY) {
            return false;
        }
        self.largest = candidates.iter().map(|v| v.norm_squared()).fold(self.largest, f64::max);
        self.grow(candidates, SPAN_SHARE * SPAN_SHARE * self.largest);
        true
    }

    /// Adds the directions orthogonal to `other` (`complement`: unit vectors, so the rank decision's scale
    /// is at least 1).
    pub fn span_complement_of(&mut self, other: &Orthonormal6) {
        let mut candidates = [nalgebra::Vector6::zeros(); 6];
        let count = other.complement_into(&mut candidates);
        self.largest = self.largest.max(1.0);
        self.grow(&mut candidates[..count], SPAN_SHARE * SPAN_SHARE * self.largest);
    }

    /// An orthonormal basis of the directions orthogonal to the set. The projector P = I - sum q q^T onto
    /// them has the unit vectors' parts outside the set as its columns and their squared norms on its
    /// diagonal; while a direction is missing the largest is at least 1/6 (the trace is the dimension
    /// left), so the largest column, normalised, is a direction, and P loses it.
    pub fn complement(&self) -> impl Iterator<Item = nalgebra::Vector6<f64>> {
        let mut new = [nalgebra::Vector6::zeros(); 6];
        let count = self.complement_into(&mut new);
        new.into_iter().take(count)
    }

    /// `complement` into the first entries of `new`; returns their count.
    fn complement_into(&self, new: &mut [nalgebra::Vector6<f64>; 6]) -> usize {
        // P is not formed: its diagonal is kept, and the one column a direction is taken from is made when
        // it is chosen, each entry reduced by the directions in their order (the same products in the same
        // order as P's, at a fifth of the cost where one or two directions are missing).
        let mut diagonal = [1.0f64; 6];
        for q in self.directions() {
            for (d, v) in diagonal.iter_mut().zip(q.iter()) {
                *d -= v * v;
            }
        }
        // The new directions apart from the set's (which are not copied), each reduced by the set's and
        // then by the new ones before it.
        let missing = 6 - self.len;
        for n in 0..missing {
            let k = (0..6).fold(0, |best, k| if diagonal[k] > diagonal[best] { k } else { best });
            let mut column = nalgebra::Vector6::ith(k, 1.0);
            for q in self.directions() {
                column -= q * q[k];
            }
            for q in &new[..n] {
                column -= q * q[k];
            }
            // Once more against every direction: the column carries round-off of what P removed.
            let mut q = column / diagonal[k].sqrt();
            remove_parts_along(&mut q, self.directions());
            remove_parts_along(&mut q, &new[..n]);
            q /= q.norm();
            for (d, v) in diagonal.iter_mut().zip(q.iter()) {
                *d -= v * v;
            }
            new[n] = q;
        }
        missing
    }

    /// Adds the candidates' parts outside the set, largest first, while its squared norm is above
    /// `threshold` (candidates finite).
    fn grow(&mut self, candidates: &mut [nalgebra::Vector6<f64>], threshold: f64) {
        candidates.iter_mut().for_each(|c| remove_parts_along(c, self.directions()));
        let mut left = candidates.len();
        while self.len < 6 && left > 0 {
            let (i, size) = (0..left).map(|i| (i, candidates[i].norm_squared())).fold((0, -1.0), |best, c| {
                if c.1 > best.1 {
                    c
                } else {
                    best
                }
            });
            if size <= threshold {
                break;
            }
            // Again against the set: the first pass leaves round-off of the size of what it removed.
            let mut q = candidates[i] / size.sqrt();
            candidates.swap(i, left - 1);
            left -= 1;
            remove_parts_along(&mut q, self.directions());
            q /= q.norm();
            candidates[..left].iter_mut().for_each(|c| remove_parts_along(c, &[q]));
            self.directions[self.len] = q;
            self.len += 1;
        }
    }
}

/// Removes from `v` its parts along each of the orthonormal `directions`, one after the other (modified
/// Gram-Schmidt).
pub(super) fn remove_parts_along(v: &mut nalgebra::Vector6<f64>, directions: &[nalgebra::Vector6<f64>]) {
    for q in directions {
        *v -= q * q.dot(v);
    }
}
