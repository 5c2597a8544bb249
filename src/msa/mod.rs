//! Matrix structural analysis (paper 003 s. 2): nodes joined by flexible links (12x12 beam stiffness, eq 1),
//! rigid links (eq 3-5), rigid, passive and elastic joints (eq 6-10) and base connections (eq 11-13),
//! condensed to the Cartesian stiffness at an end node (eq 15-17).
//!
//! The paper aggregates every node's wrench and displacement into one rectangular system and inverts it by
//! a pseudo-inverse. Here the same equations are solved in reduced coordinates, which is exact and much
//! smaller: the connections (joints, rigid links, base connections) form a graph; along a spanning forest of
//! it each node's small displacement is a linear function of the forest's coordinates (a root's six, and
//! each joint's free and elastic motions: t_j = A_ij t_i + F dq), as in a serial VJM chain. Connections
//! outside the forest close loops: their rigid directions become constraints held by Lagrange multipliers
//! (the internal wrenches of eq 15), their elastic directions springs on the relative displacement. The
//! remaining system, symmetric and of the size of the structure's joint coordinates plus its loop
//! constraints, is factorised once per pose (Cholesky where no loop closes, else LU with partial pivoting)
//! and condensed onto the end node's six coordinates (eq 17); `condense.rs` holds that solver, made once
//! per shape of structure and reused pose after pose. A singular system (a mechanism with the end held: a
//! redundant passive joint, or a node left free) is reported with its number of free motions and the nodes
//! they move.

mod condense;
pub mod template;

pub use condense::Condenser;

// Tolerances of the reduced system, relative to the sizes they compare (unit twists, row norms, the largest
// pivot or singular value), each well above round-off (~1e-16 per operation) and well below any real size.

/// A motion twist independent of those kept: its residual after projection exceeds this (unit twists).
const MOVING_INDEPENDENCE: f64 = 1e-12;
/// A unit twist completing the complement of the motions: a looser floor, as it only fills the rest.
const COMPLEMENT_INDEPENDENCE: f64 = 1e-9;

use nalgebra::{DMatrix, DVector};

use crate::beam::{frame_along, turned_cantilever_stiffness, BeamSection};
use crate::kinematics::frame::{Mat3, Mat6, Vec3, Vec6};

/// How two nodes (or a node and the base) are joined, at the second node's point: the relative small
/// displacement `dt = t_j - A_ij t_i` (`A_ij` carries i's twist to j's point, so for coincident nodes
/// `dt = t_j - t_i`) is zero in the rigid directions, free in the passive ones (the Lambda^p rows of eq 8-9)
/// and resisted by springs in the elastic ones (eq 10, 13). Rigid directions are the complement of the others.
#[derive(Clone, Debug, PartialEq)]
pub struct Connection {
    /// Unit twists that move freely (a revolute joint about axis a: (0, a); a prismatic one along a: (a, 0)).
    pub free: Vec<Vec6>,
    /// Orthonormal unit twists carrying springs.
    pub elastic: Vec<Vec6>,
    /// Spring stiffness in the elastic directions' coordinates (elastic.len() square).
    pub stiffness: DMatrix<f64>,
    /// Rest values of the elastic coordinates (preload, eq 10): the spring's force is K (s - s0).
    pub preload: DVector<f64>,
}

impl Connection {
    /// All six directions rigid (eq 6-7, 11).
    pub fn rigid() -> Connection {
        Connection::passive(Vec::new())
    }

    /// The listed directions free, the rest rigid (eq 8-9, 12).
    pub fn passive(free: Vec<Vec6>) -> Connection {
        Connection { free, elastic: Vec::new(), stiffness: DMatrix::zeros(0, 0), preload: DVector::zeros(0) }
    }

    /// Springs of the given stiffness (and zero preload) in the listed orthonormal directions, the rest rigid.
    pub fn elastic(elastic: Vec<Vec6>, stiffness: DMatrix<f64>) -> Connection {
        let preload = DVector::zeros(elastic.len());
        Connection { free: Vec::new(), elastic, stiffness, preload }
    }

    /// The directions that move (free, then elastic) and the rigid ones, an orthonormal basis of the rest.
    fn moving_and_rigid(&self) -> (Vec<Vec6>, Vec<Vec6>) {
        let moving: Vec<Vec6> = self.free.iter().chain(&self.elastic).copied().collect();
        let rigid = complement(&moving);
        (moving, rigid)
    }
}

#[derive(Clone, Debug, PartialEq)]
// A structure holds a few dozen elements, filled in place at every pose; boxing the 6x6 block would add
// an indirection per beam for no saving that matters.
/// An element of an MSA structure (paper 003 s. 2).
#[allow(clippy::large_enum_variant)]
pub enum Element {
    /// A flexible link: the 12x12 stiffness relating the wrenches at nodes i and j to their displacements
    /// (eq 1), base frame, given by its K_jj block.
    Flexible {
        /// First node.
        i: usize,
        /// Second node.
        j: usize,
        /// Its stiffness at j with i clamped (base frame, at j's point): K_jj of eq 1, whose other blocks
        /// follow by rigid-body invariance (K_ji = -K_jj A, K_ii = A^T K_jj A, A carrying a twist at i to j).
        kjj: Mat6,
    },
    /// A rigid link from node i to node j (eq 3-5): the twist of j is the rigid transport of i's.
    Rigid {
        /// The node carried from.
        i: usize,
        /// The node carried.
        j: usize,
    },
    /// A joint between nodes i and j, sitting at j's point (j's side rigidly carried by i elsewhere).
    Joint {
        /// First node.
        i: usize,
        /// Second node (where the joint sits).
        j: usize,
        /// Its free, elastic and rigid directions.
        connection: Connection,
    },
    /// A node's connection to the base.
    Base {
        /// The node.
        node: usize,
        /// Its free, elastic and rigid directions relative to the base.
        connection: Connection,
    },
}

/// An MSA structure: node positions (mm, base frame), elements, and the node where K_C is wanted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Structure {
    /// Node positions, mm, base frame.
    pub nodes: Vec<Vec3>,
    /// Its elements.
    pub elements: Vec<Element>,
    /// The end node, whose stiffness is wanted.
    pub end: usize,
}

/// Why a structure gives no stiffness.
#[derive(Clone, Debug, PartialEq)]
pub enum MsaFailure {
    /// With the end node held the structure still moves: `free` independent motions (a redundant passive
    /// joint, or nodes left free), moving the listed nodes.
    Mechanism {
        /// Number of independent free motions.
        free: usize,
        /// The nodes they move.
        nodes: Vec<usize>,
    },
    /// An element names a node that does not exist.
    BadNode(usize),
    /// The system has non-finite entries, or its decomposition did not converge (extreme values).
    NotFinite,
}

/// The end node's answer (eq 17): its Cartesian stiffness, and the wrench that holds it in place against
/// the springs' preloads, both at the end node's point, base frame.
#[derive(Clone, Debug, PartialEq)]
pub struct EndAnswer {
    /// Cartesian stiffness at the end node (base frame, at its point).
    pub stiffness: Mat6,
    /// Wrench applied to the end node from outside to keep its displacement zero (N, N mm).
    pub holding_wrench: Vec6,
}

/// The stiffness at `pj` of a straight beam from `pi` to `pj` clamped at `pi` (Euler-Bernoulli, base frame):
/// the K_jj block of eq 1, the inverse of the clamped-free compliance the VJM springs use. The section's
/// y axis is the component of `y_hint` across the beam (default: `frame_along`'s choice, fine for round
/// sections).
pub fn beam_stiffness(section: &BeamSection, pi: &Vec3, pj: &Vec3) -> Option<Mat6> {
    oriented_beam_stiffness(section, pi, pj, None)
}

/// As `beam_stiffness`, with the section's local y axis given (for sections with Iy != Iz). None where the
/// beam has no finite stiffness (zero length, a length or modulus at the edge of doubles, a y axis along
/// the beam).
pub fn oriented_beam_stiffness(section: &BeamSection, pi: &Vec3, pj: &Vec3, y_hint: Option<Vec3>) -> Option<Mat6> {
    let d = pj - pi;
    let frame = match y_hint {
        Some(h) => {
            let x = d.normalize();
            let y = (h - x * x.dot(&h)).normalize();
            Mat3::from_columns(&[x, y, x.cross(&y)])
        }
        None => frame_along(&d),
    };
    let k = turned_cantilever_stiffness(section, d.norm(), &frame);
    // A zero length or a modulus at the edge of doubles shows on the diagonal; a non-finite entry off it,
    // if any, is caught downstream: the condensed system's solution is checked, and its null space comes
    // from a checked SVD.
    if !k.diagonal().iter().all(|v| v.is_finite() && *v > 0.0) {
        return None;
    }
    Some(k)
}

/// An orthonormal basis of the complement of span(`moving`).
fn complement(moving: &[Vec6]) -> Vec<Vec6> {
    let mut basis: Vec<Vec6> = Vec::new();
    let add = |v: Vec6, tol: f64, basis: &mut Vec<Vec6>| {
        let mut v = v;
        for _ in 0..2 {
            for b in basis.iter() {
                v -= b * b.dot(&v);
            }
        }
        if v.norm() > tol {
            basis.push(v.normalize());
            true
        } else {
            false
        }
    };
    for m in moving {
        add(*m, MOVING_INDEPENDENCE, &mut basis);
    }
    let n_moving = basis.len();
    for k in 0..6 {
        add(Vec6::from_fn(|r, _| if r == k { 1.0 } else { 0.0 }), COMPLEMENT_INDEPENDENCE, &mut basis);
    }
    basis.split_off(n_moving)
}

impl Structure {
    /// The Cartesian stiffness at the end node (eq 17), base frame, at the end node's point.
    pub fn end_stiffness(&self) -> Result<Mat6, MsaFailure> {
        self.condense().map(|a| a.stiffness)
    }

    /// Solves the structure (eq 15-17): the end node's stiffness and the wrench holding it against preloads.
    /// A map of poses keeps a `Condenser` instead, which makes the forest once and reuses its buffers.
    pub fn condense(&self) -> Result<EndAnswer, MsaFailure> {
        Condenser::default().condense(self)
    }
}
