//! Matrix structural analysis (paper 003 s. 2): nodes joined by flexible links (12x12 beam stiffness, eq 1),
//! rigid links (eq 3-5), rigid, passive and elastic joints (eq 6-10) and base connections (eq 11-13),
//! condensed to the Cartesian stiffness at an end node (eq 15-17).
//!
//! Written in the displacement form: the unknowns are the nodes' small displacements (twists at the node
//! points, base frame); links and elastic joints add stiffness, rigid links and the rigid directions of
//! joints and base connections are linear constraints held by Lagrange multipliers (the link wrenches of
//! eq 15). With the end node's displacement prescribed, the stationary point of this system gives the
//! wrench at the end node, so K_C of eq (17) is the matrix of that map. Groundwork for issue 5: the NaVARo
//! models and the leg seam's MSA variant build on it.

use nalgebra::{DMatrix, DVector};

use crate::kinematics::frame::{block_rotation, point_shift, Mat6, Vec3, Vec6};
use crate::vjm::spring::{cantilever_compliance, frame_along, BeamSection};

/// How two nodes (or a node and the base) are connected, by the directions they share.
#[derive(Clone, Debug, PartialEq)]
pub enum Connection {
    /// All six directions rigid (eq 6-7, 11).
    Rigid,
    /// The listed unit twists are free (a revolute joint about axis a at the node: (0, a); a prismatic
    /// joint along a: (a, 0)); the rest rigid (eq 8-9, 12).
    Passive(Vec<Vec6>),
    /// The listed unit twists carry springs of the given stiffness (in those coordinates); the rest rigid
    /// (eq 10, 13).
    Elastic { directions: Vec<Vec6>, stiffness: DMatrix<f64> },
}

#[derive(Clone, Debug, PartialEq)]
pub enum Element {
    /// A flexible link: the 12x12 stiffness relating the wrenches at nodes i and j to their displacements
    /// (eq 1), base frame.
    Flexible { i: usize, j: usize, k: [[Mat6; 2]; 2] },
    /// A rigid link from node i to node j (eq 3-5): the twist of j is the rigid transport of i's.
    Rigid { i: usize, j: usize },
    /// A joint between nodes i and j at the same point.
    Joint { i: usize, j: usize, connection: Connection },
    /// A node's connection to the base.
    Base { node: usize, connection: Connection },
}

/// An MSA structure: node positions (mm, base frame), elements, and the node where K_C is wanted.
#[derive(Clone, Debug, PartialEq)]
pub struct Structure {
    pub nodes: Vec<Vec3>,
    pub elements: Vec<Element>,
    pub end: usize,
}

/// Why a structure gives no stiffness.
#[derive(Clone, Debug, PartialEq)]
pub enum MsaFailure {
    /// The system with the end node held is singular: an internal mechanism (a redundant passive joint, or
    /// nodes left free).
    Mechanism,
}

/// The 12x12 stiffness of a straight beam from `pi` to `pj` (Euler-Bernoulli), built from the clamped-free
/// compliance at j (the same beam the VJM springs use) and rigid-body invariance: K_jj = C^-1 (rotated to
/// the base frame), K_ji = -K_jj A, K_ij = -A^T K_jj, K_ii = A^T K_jj A, with A carrying a twist at i to j.
pub fn beam_stiffness(section: &BeamSection, pi: &Vec3, pj: &Vec3) -> [[Mat6; 2]; 2] {
    let d = pj - pi;
    let r = block_rotation(&frame_along(&d));
    let c = r * cantilever_compliance(section, d.norm()) * r.transpose();
    link_stiffness(&c.try_inverse().expect("a beam's compliance is positive definite"), pi, pj)
}

/// The 12x12 stiffness of a link from its stiffness at j with i clamped (base frame, at j's point): the
/// rest follows from rigid-body invariance, a rigid motion of both ends loading nothing.
pub fn link_stiffness(kjj: &Mat6, pi: &Vec3, pj: &Vec3) -> [[Mat6; 2]; 2] {
    let kjj = (kjj + kjj.transpose()) * 0.5;
    let a = point_shift(&(pj - pi));
    let kji = -(kjj * a);
    [[a.transpose() * kjj * a, kji.transpose()], [kji, kjj]]
}

/// An orthonormal basis of the complement of `free` (the rigid directions of a connection), with the
/// free directions themselves orthonormalised.
fn split_directions(free: &[Vec6]) -> (Vec<Vec6>, Vec<Vec6>) {
    let mut basis: Vec<Vec6> = Vec::new();
    for f in free {
        let mut v = *f;
        for b in &basis {
            v -= b * b.dot(&v);
        }
        if v.norm() > 1e-12 {
            basis.push(v.normalize());
        }
    }
    let n_free = basis.len();
    for k in 0..6 {
        let mut v = Vec6::zeros();
        v[k] = 1.0;
        for b in &basis {
            v -= b * b.dot(&v);
        }
        if v.norm() > 1e-9 {
            basis.push(v.normalize());
        }
    }
    let rigid = basis.split_off(n_free);
    (basis, rigid)
}

impl Structure {
    /// The Cartesian stiffness at the end node (eq 17), base frame, at the end node's point.
    pub fn end_stiffness(&self) -> Result<Mat6, MsaFailure> {
        let n = self.nodes.len();
        let dof = 6 * n;
        let mut k = DMatrix::<f64>::zeros(dof, dof);
        let mut constraints: Vec<DVector<f64>> = Vec::new();
        let add_block = |k: &mut DMatrix<f64>, a: usize, b: usize, m: &Mat6| {
            let mut v = k.view_mut((6 * a, 6 * b), (6, 6));
            v += m;
        };
        for e in &self.elements {
            match e {
                Element::Flexible { i, j, k: kk } => {
                    add_block(&mut k, *i, *i, &kk[0][0]);
                    add_block(&mut k, *i, *j, &kk[0][1]);
                    add_block(&mut k, *j, *i, &kk[1][0]);
                    add_block(&mut k, *j, *j, &kk[1][1]);
                }
                Element::Rigid { i, j } => {
                    // t_j = A t_i: six constraints.
                    let a = point_shift(&(self.nodes[*j] - self.nodes[*i]));
                    for r in 0..6 {
                        let mut row = DVector::zeros(dof);
                        row[6 * j + r] = 1.0;
                        for c in 0..6 {
                            row[6 * i + c] = -a[(r, c)];
                        }
                        constraints.push(row);
                    }
                }
                Element::Joint { i, j, connection } => connect(Some(*i), *j, connection, &mut k, &mut constraints),
                Element::Base { node, connection } => connect(None, *node, connection, &mut k, &mut constraints),
            }
        }
        // Unknowns: every node but the end one, then the multipliers; the end node's twist is prescribed.
        let others: Vec<usize> = (0..dof).filter(|d| d / 6 != self.end).collect();
        let ends: Vec<usize> = (0..6).map(|c| 6 * self.end + c).collect();
        let (no, nc) = (others.len(), constraints.len());
        let size = no + nc;
        let mut a = DMatrix::<f64>::zeros(size, size);
        let mut rhs = DMatrix::<f64>::zeros(size, 6);
        for (r, &gr) in others.iter().enumerate() {
            for (c, &gc) in others.iter().enumerate() {
                a[(r, c)] = k[(gr, gc)];
            }
            for (c, &ge) in ends.iter().enumerate() {
                rhs[(r, c)] = -k[(gr, ge)];
            }
        }
        for (m, row) in constraints.iter().enumerate() {
            for (c, &gc) in others.iter().enumerate() {
                a[(no + m, c)] = row[gc];
                a[(c, no + m)] = row[gc];
            }
            for (c, &ge) in ends.iter().enumerate() {
                rhs[(no + m, c)] = -row[ge];
            }
        }
        // Scale the multiplier rows and columns to the stiffness' size, for a balanced factorisation.
        let scale = k.amax().max(1.0);
        for m in 0..nc {
            for c in 0..size {
                a[(no + m, c)] *= scale;
                a[(c, no + m)] *= scale;
            }
            for c in 0..6 {
                rhs[(no + m, c)] *= scale;
            }
        }
        let lu = a.lu();
        let x = lu.solve(&rhs).ok_or(MsaFailure::Mechanism)?;
        if !x.iter().all(|v| v.is_finite()) {
            return Err(MsaFailure::Mechanism);
        }
        // Wrench at the end node: K_eo x + K_ee u + C_e^T lambda (lambda = scale * multipliers).
        let mut out = Mat6::zeros();
        for (r, &ger) in ends.iter().enumerate() {
            for col in 0..6 {
                let mut w = k[(ger, ends[col])];
                for (c, &gc) in others.iter().enumerate() {
                    w += k[(ger, gc)] * x[(c, col)];
                }
                for (m, row) in constraints.iter().enumerate() {
                    w += row[ger] * scale * x[(no + m, col)];
                }
                out[(r, col)] = w;
            }
        }
        Ok((out + out.transpose()) * 0.5)
    }
}

/// A constraint row `dir . (t_j - t_i)` (or `dir . t_j` against the base) over all `dof` displacements.
fn relative_row(dof: usize, i: Option<usize>, j: usize, dir: &Vec6) -> DVector<f64> {
    let mut row = DVector::zeros(dof);
    for c in 0..6 {
        row[6 * j + c] = dir[c];
        if let Some(i) = i {
            row[6 * i + c] = -dir[c];
        }
    }
    row
}

/// Adds a connection between node i (or the base) and node j: constraints on its rigid directions, and
/// the stiffness of its elastic ones.
fn connect(
    i: Option<usize>,
    j: usize,
    connection: &Connection,
    k: &mut DMatrix<f64>,
    constraints: &mut Vec<DVector<f64>>,
) {
    match connection {
        Connection::Rigid => {
            for r in 0..6 {
                let mut d = Vec6::zeros();
                d[r] = 1.0;
                constraints.push(relative_row(k.nrows(), i, j, &d));
            }
        }
        Connection::Passive(free) => {
            let (_, rigid) = split_directions(free);
            for d in &rigid {
                constraints.push(relative_row(k.nrows(), i, j, d));
            }
        }
        Connection::Elastic { directions, stiffness } => {
            let (_, rigid) = split_directions(directions);
            for d in &rigid {
                constraints.push(relative_row(k.nrows(), i, j, d));
            }
            // Energy 1/2 (L dt)^T K_e (L dt) with L's rows the elastic directions (as given: the
            // stiffness is expressed in them), dt = t_j - t_i.
            let l = DMatrix::from_fn(directions.len(), 6, |r, c| directions[r][c]);
            let ke = l.transpose() * stiffness * &l;
            let ke = Mat6::from_fn(|r, c| ke[(r, c)]);
            let mut add = |a: usize, b: usize, m: Mat6| {
                let mut v = k.view_mut((6 * a, 6 * b), (6, 6));
                v += m;
            };
            add(j, j, ke);
            if let Some(i) = i {
                add(i, i, ke);
                add(i, j, -ke);
                add(j, i, -ke);
            }
        }
    }
}
