//! The decompositions against nalgebra's and against closed forms.
use super::cholesky::*;
use super::envelope::*;
use super::lu::*;
use super::orthonormal::*;
use super::saddle_point::*;
use super::svd::*;
use super::*;
use nalgebra::{DMatrix, DVector};

/// The finiteness test by products with zero: true for finite values of any size and sign (the largest,
/// the smallest subnormal, minus zero), false for one NaN or infinity of either sign at any place, in
/// the four lanes or the remainder, for every length up to nine.
#[test]
fn all_finite_finds_any_nan_or_infinity() {
    let finite = [1.0, -0.0, f64::MAX, -f64::MAX, 5e-324, -3.5, 0.0, 1e-300, 7.0];
    for n in 0..=finite.len() {
        assert!(all_finite(&finite[..n]), "{n} finite values");
        for place in 0..n {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut values = finite[..n].to_vec();
                values[place] = bad;
                assert!(!all_finite(&values), "{bad} at {place} of {n}");
            }
        }
    }
}

/// Gaussian elimination with partial pivoting is one sequence of roundings: the stack LU's solutions
/// are nalgebra's `LU` solutions to the bit, on matrices whose pivots need row exchanges (entries
/// spread over six orders of magnitude), on one with a zero column part-way (passed over, then no
/// solution), on an exactly singular one and on sizes 1, 3 and 6; and they solve the system (residual
/// at round-off).
#[test]
fn small_lu_solves_as_nalgebras_lu_to_the_bit() {
    fn agree<const N: usize>(m: nalgebra::SMatrix<f64, N, N>, b: nalgebra::SVector<f64, N>) {
        let ours = SmallLu::new(&m).solve(&b);
        // nalgebra's on the dynamic size (the same steps as on a fixed one, compared below for six).
        let theirs =
            DMatrix::from_column_slice(N, N, m.as_slice()).lu().solve(&DVector::from_column_slice(b.as_slice()));
        match (ours, theirs) {
            (Some(x), Some(y)) => {
                let bits = |v: &[f64]| v.iter().map(|e| e.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(x.as_slice()), bits(y.as_slice()), "{m}");
                if x.iter().all(|v| v.is_finite()) && m.iter().all(|v| v.is_finite()) {
                    assert!((m * x - b).amax() <= 1e-9 * (m.amax() * x.amax() + b.amax()), "{m} {x}");
                }
            }
            (None, None) => {}
            (x, y) => panic!("{m}: ours {x:?}, nalgebra's {y:?}"),
        }
    }
    let mut next = stream(11);
    for _ in 0..200 {
        let spread = nalgebra::Matrix6::from_fn(|_, _| 10f64.powf(6.0 * next()));
        let (m, b) =
            (nalgebra::Matrix6::from_fn(|r, c| next() * spread[(r, c)]), nalgebra::Vector6::from_fn(|_, _| next()));
        agree(m, b);
        let (x, y) = (SmallLu::new(&m).solve(&b).unwrap(), m.lu().solve(&b).unwrap());
        assert!(x.iter().zip(&y).all(|(x, y)| x.to_bits() == y.to_bits()), "{m}");
        agree(nalgebra::Matrix3::from_fn(|_, _| next()), nalgebra::Vector3::from_fn(|_, _| next()));
        agree(nalgebra::Matrix1::new(next()), nalgebra::Vector1::new(next()));
    }
    let mut zero_column = nalgebra::Matrix6::from_fn(|_, _| next());
    zero_column.column_mut(2).fill(0.0);
    agree(zero_column, nalgebra::Vector6::from_fn(|_, _| next()));
    let mut rank_five = nalgebra::Matrix6::from_fn(|_, _| next());
    let sum = rank_five.column(0) + rank_five.column(1);
    rank_five.set_column(4, &sum);
    agree(rank_five, nalgebra::Vector6::from_fn(|_, _| next()));
    agree(nalgebra::Matrix6::zeros(), nalgebra::Vector6::from_fn(|_, _| next()));
    assert!(SmallLu::new(&zero_column).solve(&nalgebra::Vector6::repeat(1.0)).is_none());
}

/// The Cholesky inverse of SPD matrices Q D Q^T (Q orthogonal, condition 1 to 1e8) is exactly symmetric and
/// equals Q D^-1 Q^T to the condition times round-off; an indefinite or singular matrix is refused.
#[test]
fn spd_inverse_is_the_inverse_and_refuses_indefinite_matrices() {
    let mut next = stream(7);
    for spread in [1.0f64, 1e4, 1e8] {
        let q = nalgebra::Matrix6::from_fn(|_, _| next()).qr().q();
        let d = nalgebra::Vector6::from_fn(|i, _| spread.powf(i as f64 / 5.0));
        let a = q * nalgebra::Matrix6::from_diagonal(&d) * q.transpose();
        let exact = q * nalgebra::Matrix6::from_diagonal(&d.map(|v| 1.0 / v)) * q.transpose();
        let inverse = spd_inverse6(&a).unwrap();
        assert_eq!(inverse, inverse.transpose());
        assert!((inverse - exact).amax() < 1e-14 * spread * exact.amax(), "{inverse}\n{exact}");
    }
    let indefinite = nalgebra::Matrix6::from_diagonal(&nalgebra::Vector6::new(1.0, 2.0, -1.0, 3.0, 1.0, 1.0));
    assert!(spd_inverse6(&indefinite).is_none());
    assert!(spd_inverse6(&nalgebra::Matrix6::zeros()).is_none());
    assert!(spd_inverse6(&nalgebra::Matrix6::from_element(f64::NAN)).is_none());
}

/// The complement of k random combinations of r independent six-vectors (scaled 1 to 1e6, plus
/// round-off-sized noise that is not a direction) has 6 - r directions, orthonormal and orthogonal to
/// every vector to round-off: the dimension the SVD's rank decision (`span_basis`) gives. Nothing
/// finite is refused; a NaN is.
#[test]
fn the_orthonormal_complement_has_the_dimension_the_svd_gives() {
    let mut next = stream(11);
    for rank in 0..=6 {
        for count in [rank, rank + 2, 7] {
            let spanning: Vec<nalgebra::Vector6<f64>> =
                (0..rank).map(|k| nalgebra::Vector6::from_fn(|_, _| next()) * 1e3f64.powi(k as i32 % 3)).collect();
            let vectors: Vec<nalgebra::Vector6<f64>> = (0..count)
                .map(|_| {
                    let mixed = spanning.iter().fold(nalgebra::Vector6::zeros(), |s, v| s + v * next());
                    mixed + nalgebra::Vector6::from_fn(|_, _| next() * 1e-14 * mixed.norm())
                })
                .collect();
            let mut set = Orthonormal6::default();
            assert!(set.span(vectors.iter().copied()));
            let complement: Vec<nalgebra::Vector6<f64>> = set.complement().collect();
            let columns = DMatrix::from_fn(6, count, |r, c| vectors[c][r]);
            let svd_rank = span_basis(&columns).unwrap().ncols();
            assert_eq!(complement.len(), 6 - svd_rank, "rank {rank}, {count} vectors");
            assert_eq!(svd_rank, rank.min(count));
            for (i, q) in complement.iter().enumerate() {
                assert!((q.norm() - 1.0).abs() < 1e-14);
                for p in &complement[..i] {
                    assert!(q.dot(p).abs() < 1e-14);
                }
                for v in &vectors {
                    assert!(q.dot(v).abs() < 1e-12 * v.norm().max(1e-300), "rank {rank}: {}", q.dot(v));
                }
            }
        }
    }
    let mut not_finite = [nalgebra::Vector6::repeat(1.0)];
    not_finite[0][3] = f64::NAN;
    assert!(!Orthonormal6::default().span(not_finite));
    assert_eq!(Orthonormal6::default().complement().count(), 6);
}

#[test]
fn solves_like_nalgebra_with_pivoting() {
    let n = 9;
    let m =
        DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 13) % 11) as f64 - 5.0 + if i == (j + 3) % n { 9.0 } else { 0.0 });
    let b = DVector::from_fn(n, |i, _| i as f64 - 2.5);
    let expected = m.clone().lu().solve(&b).unwrap();
    let mut lu = DenseLu::default();
    assert!(lu.factor(m.as_slice(), n));
    let mut x = b.as_slice().to_vec();
    lu.solve_in_place(&mut x);
    for i in 0..n {
        assert!((x[i] - expected[i]).abs() < 1e-12 * expected.amax());
    }
    assert!(!lu.factor(DMatrix::<f64>::zeros(3, 3).as_slice(), 3));
}

/// Several right-hand sides solved together by rows give, bit for bit, what one solve per right-hand
/// side gives (the same operations in the same order), on a system that needs row exchanges.
#[test]
fn solving_by_rows_equals_one_solve_per_right_hand_side() {
    let n = 9;
    let m =
        DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 13) % 11) as f64 - 5.0 + if i == (j + 3) % n { 9.0 } else { 0.0 });
    let mut lu = DenseLu::default();
    assert!(lu.factor(m.as_slice(), n));
    let rhs = |c: usize, i: usize| ((i * 3 + c * 5) % 7) as f64 - 2.5 + if i == c { 1.0 } else { 0.0 };
    let mut rows: Vec<[f64; 3]> = (0..n).map(|i| [rhs(0, i), rhs(1, i), rhs(2, i)]).collect();
    lu.solve_rows(&mut rows);
    for c in 0..3 {
        let mut x: Vec<f64> = (0..n).map(|i| rhs(c, i)).collect();
        lu.solve_in_place(&mut x);
        let by_rows: Vec<f64> = rows.iter().map(|r| r[c]).collect();
        assert_eq!(x, by_rows, "right-hand side {c}");
        let residual = &m * DVector::from_vec(x) - DVector::from_fn(n, |i, _| rhs(c, i));
        assert!(residual.amax() < 1e-12, "right-hand side {c}: residual {}", residual.amax());
    }
}

/// A pseudo-random stream in [-0.5, 0.5) (a linear congruential generator: the tests need no crate).
fn stream(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

/// The branch-free helpers of the factorisations decide as the library's tests do: `larger` is
/// `f64::max` on a running maximum (a NaN argument ignored, an infinite one kept), so pivots and margins
/// do not move; `all_finite` is `all(is_finite)` (one infinity or NaN anywhere refuses the values).
#[test]
fn branch_free_maximum_and_finiteness_decide_as_the_library_does() {
    let mut next = stream(3);
    let specials = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0, f64::MIN_POSITIVE, f64::MAX];
    for trial in 0..200 {
        let values: Vec<f64> = (0..1 + trial % 23)
            .map(|i| if (trial + i) % 9 == 0 { specials[(trial + i) % specials.len()] } else { next() * 1e3 })
            .collect();
        let expected = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let got = values.iter().fold(0.0f64, |m, v| larger(m, v.abs()));
        assert_eq!(got.to_bits(), expected.to_bits(), "trial {trial}: {values:?}");
        assert_eq!(all_finite(&values), values.iter().all(|v| v.is_finite()), "trial {trial}: {values:?}");
    }
    assert!(all_finite(&[]));
}

/// The whole saddle-point matrix [[J, 0], [W, J^T]] of `SaddlePointLu`, dense.
fn saddle_matrix(j: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
    let k = w.nrows();
    let mut m = DMatrix::zeros(k + 6, k + 6);
    m.view_mut((0, 0), (6, k)).copy_from(j);
    m.view_mut((6, 0), (k, k)).copy_from(w);
    m.view_mut((6, k), (k, 6)).copy_from(&j.transpose());
    m
}

/// The null-space factorisation solves the saddle-point system as a dense LU of the whole matrix does
/// (nalgebra's, to 1e-10 of the solution), for constraint Jacobians with entries of mixed scales (lever
/// arms in mm beside unit columns, as a chain's twist Jacobian has), W non-symmetric and spanning eight
/// orders of magnitude (stiff springs beside soft load terms), no free coordinate, and several
/// right-hand sides solved by rows or one at a time.
#[test]
fn saddle_point_solves_like_a_dense_lu_of_the_whole_matrix() {
    let mut next = stream(11);
    for (case, k) in [6usize, 7, 9, 17, 17, 23].into_iter().enumerate() {
        let j = DMatrix::from_fn(6, k, |r, c| next() * if r < 3 && c % 2 == 0 { 300.0 } else { 1.0 });
        let spread = if case % 2 == 0 { 1.0 } else { 1e8 };
        let w = DMatrix::from_fn(k, k, |r, c| next() + if r == c { spread * (0.5 + next()) } else { 0.0 });
        let dense = saddle_matrix(&j, &w);
        let mut saddle = SaddlePointLu::default();
        let columns = j.column_iter().map(|c| std::array::from_fn(|r| c[r]));
        assert!(saddle.factor(columns, w.as_slice(), k), "k = {k}");
        let rhs = DMatrix::from_fn(k + 6, 3, |_, _| next());
        let expected = dense.clone().lu().solve(&rhs).unwrap();
        let mut rows: Vec<[f64; 3]> = (0..k + 6).map(|r| std::array::from_fn(|c| rhs[(r, c)])).collect();
        saddle.solve_rows(&mut rows);
        for (c, column) in expected.column_iter().enumerate() {
            let error = rows.iter().zip(column.iter()).fold(0.0f64, |e, (row, x)| e.max((row[c] - x).abs()));
            assert!(error <= 1e-10 * column.amax(), "k = {k}, right-hand side {c}: error {error}");
            // One at a time (its own sums, on six-entry arrays): as the dense LU, and as by rows to
            // round-off.
            let mut one: Vec<f64> = rhs.column(c).iter().copied().collect();
            saddle.solve_in_place(&mut one);
            let error = one.iter().zip(column.iter()).fold(0.0f64, |e, (v, x)| e.max((v - x).abs()));
            assert!(error <= 1e-10 * column.amax(), "k = {k}, one at a time {c}: error {error}");
            let apart = one.iter().zip(&rows).fold(0.0f64, |e, (v, row)| e.max((v - row[c]).abs()));
            assert!(apart <= 1e-12 * column.amax(), "k = {k}, one at a time {c} and by rows: {apart}");
        }
    }
}

/// Constraints that cannot all be met (J of rank five: two rows equal) make the system singular, and the
/// factorisation says so rather than dividing by round-off; so do non-finite entries and fewer
/// coordinates than constraints.
#[test]
fn saddle_point_refuses_rank_deficient_constraints() {
    let mut next = stream(5);
    let k = 10;
    let mut j = DMatrix::from_fn(6, k, |_, _| next());
    let row = j.row(1).into_owned();
    j.row_mut(4).copy_from(&row);
    let w = DMatrix::from_fn(k, k, |r, c| next() + if r == c { 3.0 } else { 0.0 });
    let columns = |j: &DMatrix<f64>| j.column_iter().map(|c| std::array::from_fn(|r| c[r])).collect::<Vec<_>>();
    let mut saddle = SaddlePointLu::default();
    assert!(!saddle.factor(columns(&j), w.as_slice(), k));
    j.row_mut(4).copy_from(&DMatrix::from_fn(1, k, |_, _| next()));
    assert!(saddle.factor(columns(&j), w.as_slice(), k));
    let mut not_finite = w.clone();
    not_finite[(3, 2)] = f64::NAN;
    assert!(!saddle.factor(columns(&j), not_finite.as_slice(), k));
    let short = j.columns(0, 5).into_owned();
    assert!(!saddle.factor(columns(&short), DMatrix::<f64>::identity(5, 5).as_slice(), 5));
}

/// The definiteness test against an independent route: the eigenvalues of N^T H N, N an orthonormal basis
/// of J's null space from the eigenvectors of J^T J, H = -sym(W). W = -(H + A) with H symmetric of random spectrum shifted
/// so that some cases are definite on the null space and others not, and A antisymmetric (a
/// non-conservative part, which the test must ignore). Cases within 1e-6 of the boundary are skipped.
#[test]
fn saddle_point_definiteness_follows_the_null_space_eigenvalues() {
    let mut next = stream(23);
    let (mut definite, mut indefinite) = (0, 0);
    for case in 0..60 {
        // f = k - 6 from 2 to 13: sizes `with_known_size!` names and one past them.
        let k = 8 + case % 12;
        let j = DMatrix::from_fn(6, k, |_, _| next());
        let m = DMatrix::from_fn(k, k, |_, _| next());
        let shift = 0.6 * (case % 5) as f64 / 4.0 * k as f64 / 8.0;
        let h = &m * m.transpose() - DMatrix::identity(k, k) * shift;
        let a = DMatrix::from_fn(k, k, |_, _| next());
        let w = -(&h + (&a - a.transpose()));
        // J^T J's eigenvectors of eigenvalue zero span J's null space (J has full row rank).
        let gram = (j.transpose() * &j).symmetric_eigen();
        let top = gram.eigenvalues.amax();
        let kept: Vec<usize> = (0..k).filter(|&i| gram.eigenvalues[i] < 1e-10 * top).collect();
        assert_eq!(kept.len(), k - 6);
        let null = gram.eigenvectors.select_columns(&kept);
        let smallest = (null.transpose() * &h * &null).symmetric_eigen().eigenvalues.min();
        if smallest.abs() < 1e-6 * h.amax() {
            continue;
        }
        let mut saddle = SaddlePointLu::default();
        assert!(saddle.factor(j.column_iter().map(|c| std::array::from_fn(|r| c[r])), w.as_slice(), k));
        assert_eq!(saddle.reduced_negative_definite(), smallest > 0.0, "case {case}: smallest {smallest}");
        if smallest > 0.0 {
            definite += 1;
        } else {
            indefinite += 1;
        }
    }
    assert!(definite >= 10 && indefinite >= 10, "both kinds tested: {definite} and {indefinite}");
}

/// The envelope of a symmetric matrix from its numbers: each column's first non-zero above the diagonal.
fn envelope_of(m: &DMatrix<f64>) -> EnvelopeCholesky {
    EnvelopeCholesky::new((0..m.ncols()).map(|j| (0..j).find(|&i| m[(i, j)] != 0.0).unwrap_or(j)).collect())
}

/// A symmetric positive definite system solved as nalgebra's Cholesky solves it, dense and with an
/// envelope (a banded block with zeros inside the band and a stray far entry), factorised in a larger
/// buffer whose strict lower triangle is left as it was; U is nalgebra's L transposed, the pivots are the
/// squares of its diagonal; an indefinite matrix is refused.
#[test]
fn envelope_cholesky_solves_like_nalgebra() {
    let n = 11;
    let dense = DMatrix::from_fn(n, n, |i, j| ((i * 5 + j * 3) % 7) as f64 - 3.0 + if i == j { 4.0 } else { 0.0 });
    let banded = DMatrix::from_fn(n, n, |i, j| {
        let near = i.abs_diff(j) <= 2 && (i + j) % 5 != 1;
        if i == j {
            3.0
        } else if near || (i, j) == (9, 1) || (i, j) == (1, 9) {
            0.3 + 0.05 * (i + j) as f64
        } else {
            0.0
        }
    });
    for g in [dense, banded] {
        let m = &g * g.transpose();
        let b = DVector::from_fn(n, |i, _| 1.5 - i as f64);
        let expected = m.clone().cholesky().unwrap();
        let stride = n + 3;
        let mut buffer = DMatrix::from_fn(stride, n + 1, |i, j| if i < n && j < n { m[(i, j)] } else { 7.0 });
        let lower_before: Vec<f64> = (0..n).flat_map(|j| (j + 1..n).map(move |i| (i, j))).map(|p| buffer[p]).collect();
        let mut c = envelope_of(&m);
        let (lo, hi) = c.factor(buffer.as_mut_slice(), stride).unwrap();
        let lower_after: Vec<f64> = (0..n).flat_map(|j| (j + 1..n).map(move |i| (i, j))).map(|p| buffer[p]).collect();
        assert_eq!(lower_before, lower_after);
        let l = expected.l();
        for j in 0..n {
            for i in j..n {
                assert!((buffer[(j, i)] - l[(i, j)]).abs() < 1e-12 * l.amax(), "U[{j},{i}]");
            }
        }
        let squares: Vec<f64> = (0..n).map(|i| l[(i, i)] * l[(i, i)]).collect();
        assert!((lo - squares.iter().cloned().fold(f64::MAX, f64::min)).abs() < 1e-12 * hi);
        assert!((hi - squares.iter().cloned().fold(0.0, f64::max)).abs() < 1e-12 * hi);
        let mut x = b.as_slice().to_vec();
        c.solve_in_place(buffer.as_slice(), stride, &mut x);
        let x_expected = expected.solve(&b);
        for i in 0..n {
            assert!((x[i] - x_expected[i]).abs() < 1e-12 * x_expected.amax());
        }
    }
    let mut indefinite = DMatrix::<f64>::identity(3, 3);
    indefinite[(1, 1)] = -1.0;
    assert!(envelope_of(&indefinite).factor(indefinite.as_mut_slice(), 3).is_none());
}

/// Eliminating the first m coordinates of a matrix with an envelope (a band in the eliminated block,
/// trailing rows that reach only part of it) leaves the Schur complement A_uu - A_uy A_yy^-1 A_yu
/// (computed here with nalgebra's inverse) in the trailing block's upper triangle, and U^-T A_yu
/// (= (A_uy L^-T)^T, L nalgebra's factor of A_yy) above it.
#[test]
fn elimination_leaves_the_schur_complement() {
    let (n, m) = (10, 7);
    let g = DMatrix::from_fn(n, n, |i, j| {
        if i.abs_diff(j) <= 2 || (i >= m && j >= 3) || (j >= m && i >= 3) {
            ((i * 3 + j * 5) % 7) as f64 - 3.0 + if i == j { 5.0 } else { 0.0 }
        } else {
            0.0
        }
    });
    let a = &g * g.transpose();
    assert!(envelope_of(&a).first()[m] > 0, "the trailing rows reach only part of the eliminated block");
    check_schur_complement(&a, m);
}

/// Trailing columns whose envelope starts below the eliminated block (coupled only among themselves,
/// two of them side by side), and nothing eliminated at all, condense as the explicit formula says.
#[test]
fn trailing_columns_outside_the_eliminated_block_condense_too() {
    let n = 10;
    let g = DMatrix::from_fn(n, n, |i, j| {
        let coupled = if i < 6 && j < 6 { i.abs_diff(j) <= 2 } else { i >= 6 && j >= 6 };
        if coupled {
            ((i * 3 + j * 5) % 7) as f64 - 3.0 + if i == j { 6.0 } else { 0.0 }
        } else {
            0.0
        }
    });
    let a = &g * g.transpose();
    assert!(envelope_of(&a).first()[6] >= 6 && envelope_of(&a).first()[7] >= 6, "columns 6 and 7 start below m");
    check_schur_complement(&a, 4);
    check_schur_complement(&a, 6);
    let mut untouched = a.clone();
    envelope_of(&a).eliminate(untouched.as_mut_slice(), n, 0).unwrap();
    assert!((untouched - &a).upper_triangle().amax() == 0.0, "nothing eliminated leaves the matrix as it is");
}

/// `eliminate(m)` against the Schur complement A_uu - A_uy A_yy^-1 A_yu and U^-T A_yu computed with
/// nalgebra's inverse and Cholesky.
fn check_schur_complement(a: &DMatrix<f64>, m: usize) {
    let n = a.nrows();
    let (ayy, ayu, auu) = (a.view((0, 0), (m, m)), a.view((0, m), (m, n - m)), a.view((m, m), (n - m, n - m)));
    let schur = auu - ayu.transpose() * ayy.clone_owned().try_inverse().unwrap() * ayu;
    let l = ayy.clone_owned().cholesky().unwrap().l();
    let below = ayu.transpose() * l.transpose().try_inverse().unwrap();
    let mut buffer = a.clone();
    envelope_of(a).eliminate(buffer.as_mut_slice(), n, m).unwrap();
    for j in 0..n - m {
        for i in 0..=j {
            assert!((buffer[(m + i, m + j)] - schur[(i, j)]).abs() <= 1e-10 * schur.amax(), "S[{i},{j}], m = {m}");
        }
        for k in 0..m {
            assert!((buffer[(k, m + j)] - below[(j, k)]).abs() <= 1e-10 * below.amax(), "W[{j},{k}], m = {m}");
        }
    }
}
