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
//! and condensed onto the end node's six
//! coordinates (eq 17). A singular system (a mechanism with the end held: a redundant passive joint, or a
//! node left free) is reported with its number of free motions and the nodes they move.

pub mod template;

// Tolerances of the reduced system, relative to the sizes they compare (unit twists, row norms, the largest
// pivot or singular value), each well above round-off (~1e-16 per operation) and well below any real size.

/// A motion twist independent of those kept: its residual after projection exceeds this (unit twists).
const MOVING_INDEPENDENCE: f64 = 1e-12;
/// A unit twist completing the complement of the motions: a looser floor, as it only fills the rest.
const COMPLEMENT_INDEPENDENCE: f64 = 1e-9;
/// A constraint row independent of those kept: its residual exceeds this share of its norm.
const ROW_INDEPENDENCE: f64 = 1e-10;
/// A pivot (Cholesky L_ii^2, LU |U_ii|) below this share of the largest marks a mechanism.
const PIVOT_RATIO: f64 = 1e-12;
/// Singular values of a singular system below this share of the largest span its free motions.
const NULL_SHARE: f64 = 1e-11;
/// A null vector whose coordinates are below this is a pattern of multipliers only, not a motion.
const MOTION_FLOOR: f64 = 1e-9;
/// A node moves with a free motion where its twist exceeds this share of the motion's size.
const NODE_MOVES: f64 = 1e-6;

use nalgebra::{DMatrix, DVector};

use crate::beam::{cantilever_compliance, frame_along, BeamSection};
use crate::kinematics::frame::{block_rotation, point_shift, Mat3, Mat6, Vec3, Vec6};

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
// A structure holds a few dozen elements, built once per pose; boxing the 12x12 block would add an
// allocation per beam per pose for no saving that matters.
/// An element of an MSA structure (paper 003 s. 2).
#[allow(clippy::large_enum_variant)]
pub enum Element {
    /// A flexible link: the 12x12 stiffness relating the wrenches at nodes i and j to their displacements
    /// (eq 1), base frame.
    Flexible {
        /// First node.
        i: usize,
        /// Second node.
        j: usize,
        /// The blocks [[K_ii, K_ij], [K_ji, K_jj]].
        k: [[Mat6; 2]; 2],
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
#[derive(Clone, Debug, PartialEq)]
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

/// The 12x12 stiffness of a straight beam from `pi` to `pj` (Euler-Bernoulli), built from the clamped-free
/// compliance at j (the same beam the VJM springs use) and rigid-body invariance. The section's y axis is
/// the component of `y_hint` across the beam (default: `frame_along`'s choice, fine for round sections).
pub fn beam_stiffness(section: &BeamSection, pi: &Vec3, pj: &Vec3) -> Option<[[Mat6; 2]; 2]> {
    oriented_beam_stiffness(section, pi, pj, None)
}

/// As `beam_stiffness`, with the section's local y axis given (for sections with Iy != Iz). None where the
/// beam has no finite stiffness (zero length, a length or modulus at the edge of doubles, a y axis along
/// the beam).
pub fn oriented_beam_stiffness(
    section: &BeamSection,
    pi: &Vec3,
    pj: &Vec3,
    y_hint: Option<Vec3>,
) -> Option<[[Mat6; 2]; 2]> {
    let d = pj - pi;
    let frame = match y_hint {
        Some(h) => {
            let x = d.normalize();
            let y = (h - x * x.dot(&h)).normalize();
            Mat3::from_columns(&[x, y, x.cross(&y)])
        }
        None => frame_along(&d),
    };
    let r = block_rotation(&frame);
    let c = r * cantilever_compliance(section, d.norm()) * r.transpose();
    // A non-finite entry off the diagonal, if any, is caught downstream: the condensed system's solution is
    // checked, and its null space comes from a checked SVD.
    let k = c.try_inverse().filter(|k| k.diagonal().iter().all(|v| v.is_finite()))?;
    Some(link_stiffness(&k, pi, pj))
}

/// The 12x12 stiffness of a link from its stiffness at j with i clamped (base frame, at j's point): the
/// rest follows from rigid-body invariance, a rigid motion of both ends loading nothing:
/// K_jj, K_ji = -K_jj A, K_ij = K_ji^T, K_ii = A^T K_jj A, with A carrying a twist at i to j.
pub fn link_stiffness(kjj: &Mat6, pi: &Vec3, pj: &Vec3) -> [[Mat6; 2]; 2] {
    let kjj = (kjj + kjj.transpose()) * 0.5;
    let a = point_shift(&(pj - pi));
    let kji = -(kjj * a);
    [[a.transpose() * kjj * a, kji.transpose()], [kji, kjj]]
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

/// A connection as an edge of the graph: `dt = t_b - A_ab t_a`, a = None for the base.
struct Edge<'a> {
    a: Option<usize>,
    b: usize,
    connection: std::borrow::Cow<'a, Connection>,
}

/// How a node's twist depends on the coordinates: t = T z (6 x n_z).
type Map = DMatrix<f64>;

impl Structure {
    /// The Cartesian stiffness at the end node (eq 17), base frame, at the end node's point.
    pub fn end_stiffness(&self) -> Result<Mat6, MsaFailure> {
        self.condense().map(|a| a.stiffness)
    }

    fn edges(&self) -> Result<Vec<Edge<'_>>, MsaFailure> {
        let n = self.nodes.len();
        let check = |i: usize| if i < n { Ok(i) } else { Err(MsaFailure::BadNode(i)) };
        let mut edges = Vec::new();
        for e in &self.elements {
            match e {
                Element::Flexible { i, j, .. } => {
                    check(*i)?;
                    check(*j)?;
                }
                Element::Rigid { i, j } => edges.push(Edge {
                    a: Some(check(*i)?),
                    b: check(*j)?,
                    connection: std::borrow::Cow::Owned(Connection::rigid()),
                }),
                Element::Joint { i, j, connection } => edges.push(Edge {
                    a: Some(check(*i)?),
                    b: check(*j)?,
                    connection: std::borrow::Cow::Borrowed(connection),
                }),
                Element::Base { node, connection } => {
                    edges.push(Edge { a: None, b: check(*node)?, connection: std::borrow::Cow::Borrowed(connection) })
                }
            }
        }
        check(self.end)?;
        Ok(edges)
    }

    /// The spanning forest: from the base first, then from the end node (whose six coordinates are the
    /// prescribed ones), then from any node still unreached (a free root of six coordinates).
    fn plan(&self) -> Result<Plan<'_>, MsaFailure> {
        let n = self.nodes.len();
        let edges = self.edges()?;
        let mut adjacent: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut from_base = Vec::new();
        for (k, e) in edges.iter().enumerate() {
            adjacent[e.b].push(k);
            match e.a {
                Some(a) => adjacent[a].push(k),
                None => from_base.push(k),
            }
        }
        let mut reached = vec![false; n];
        let mut tree_edge = vec![false; edges.len()];
        // Visiting order: (node, edge it was reached by, or None for a root), roots marked.
        let mut order: Vec<(usize, Option<usize>)> = Vec::new();
        let mut queue = std::collections::VecDeque::new();
        let mut visit = |start_edges: &[usize],
                         root: Option<usize>,
                         reached: &mut Vec<bool>,
                         tree_edge: &mut Vec<bool>,
                         order: &mut Vec<(usize, Option<usize>)>| {
            if let Some(r) = root {
                reached[r] = true;
                order.push((r, None));
                queue.push_back(r);
            }
            for &k in start_edges {
                let b = edges[k].b;
                if !reached[b] {
                    reached[b] = true;
                    tree_edge[k] = true;
                    order.push((b, Some(k)));
                    queue.push_back(b);
                }
            }
            while let Some(v) = queue.pop_front() {
                for &k in &adjacent[v] {
                    if tree_edge[k] {
                        continue;
                    }
                    let e = &edges[k];
                    let other = if e.b == v { e.a } else { Some(e.b) };
                    if let Some(w) = other {
                        if !reached[w] {
                            reached[w] = true;
                            tree_edge[k] = true;
                            order.push((w, Some(k)));
                            queue.push_back(w);
                        }
                    }
                }
            }
        };
        visit(&from_base, None, &mut reached, &mut tree_edge, &mut order);
        let end_is_root = !reached[self.end];
        if end_is_root {
            visit(&[], Some(self.end), &mut reached, &mut tree_edge, &mut order);
        }
        for v in 0..n {
            if !reached[v] {
                visit(&[], Some(v), &mut reached, &mut tree_edge, &mut order);
            }
        }
        // Columns: every coordinate but the end's six, then those six (u).
        let mut n_y = 0;
        let mut first = vec![0usize; order.len()];
        for (slot, (v, via)) in order.iter().enumerate() {
            first[slot] = n_y;
            n_y += match via {
                None if *v == self.end => 0,
                None => 6,
                Some(k) => edges[*k].connection.free.len() + edges[*k].connection.elastic.len(),
            };
        }
        let mut n_constraints = if end_is_root { 0 } else { 6 };
        for (k, e) in edges.iter().enumerate() {
            if !tree_edge[k] {
                n_constraints += 6 - e.connection.free.len() - e.connection.elastic.len();
            }
        }
        Ok(Plan { edges, tree_edge, order, first, n_y, n_constraints, end_is_root })
    }

    /// Solves the structure (eq 15-17): the end node's stiffness and the wrench holding it against preloads.
    pub fn condense(&self) -> Result<EndAnswer, MsaFailure> {
        let plan = self.plan()?;
        let (n_y, nz) = (plan.n_y, plan.n_y + 6);
        let mut sys = Reduced {
            kz: DMatrix::zeros(nz, nz),
            f: DVector::zeros(nz),
            constraints: Vec::with_capacity(plan.n_constraints),
        };
        let t = self.node_maps(&plan, &mut sys);
        self.close_loops(&plan, &t, &mut sys);
        if !plan.end_is_root {
            // The end node reached through the forest: its twist must equal the prescribed u.
            for r in 0..6 {
                let mut row = t[self.end].row(r).transpose();
                row[n_y + r] -= 1.0;
                sys.constraints.push(row);
            }
        }
        self.add_flexible_links(&t, &mut sys);
        let n = self.nodes.len();
        let constraints = independent(sys.constraints);
        solve_condensed(&sys.kz, &sys.f, &constraints, n_y).map_err(|null| match null {
            Err(failure) => failure,
            Ok(null) => {
                // Which nodes a free motion moves (the multipliers' part of a null vector is not a motion).
                let mut nodes: Vec<usize> = (0..n)
                    .filter(|&v| null.iter().any(|y| (t[v].columns(0, n_y) * y).norm() > NODE_MOVES * y.norm()))
                    .collect();
                nodes.sort_unstable();
                MsaFailure::Mechanism { free: null.len(), nodes }
            }
        })
    }

    /// Carries a twist at node `from` (the base where None) to node `to`'s point.
    fn shift(&self, from: Option<usize>, to: usize) -> Mat6 {
        match from {
            Some(a) => point_shift(&(self.nodes[to] - self.nodes[a])),
            None => Mat6::identity(),
        }
    }

    /// Each node's twist as a linear map of the reduced coordinates, along the spanning forest; the tree
    /// joints' springs act on their own coordinates (energy 1/2 (s - s0)^T K (s - s0)).
    fn node_maps(&self, plan: &Plan, sys: &mut Reduced) -> Vec<Map> {
        let n = self.nodes.len();
        let (n_y, nz) = (plan.n_y, plan.n_y + 6);
        let mut t: Vec<Map> = vec![Map::zeros(0, 0); n];
        let base = Map::zeros(6, nz);
        for (slot, &(v, via)) in plan.order.iter().enumerate() {
            let c0 = plan.first[slot];
            t[v] = match via {
                None if v == self.end => {
                    let mut m = Map::zeros(6, nz);
                    m.view_mut((0, n_y), (6, 6)).fill_with_identity();
                    m
                }
                None => {
                    let mut m = Map::zeros(6, nz);
                    m.view_mut((0, c0), (6, 6)).fill_with_identity();
                    m
                }
                Some(k) => {
                    let e = &plan.edges[k];
                    let moving = e.connection.free.iter().chain(&e.connection.elastic);
                    let parent_is_a = e.b == v;
                    let parent = if parent_is_a { e.a } else { Some(e.b) };
                    let tp = match parent {
                        Some(p) => &t[p],
                        None => &base,
                    };
                    let mut m = if parent_is_a {
                        // t_b = A_ab t_a + dt
                        to_dmatrix(&self.shift(e.a, e.b)) * tp
                    } else {
                        // t_a = A_ba (t_b - dt)
                        to_dmatrix(&point_shift(&(self.nodes[v] - self.nodes[e.b]))) * tp
                    };
                    let back = point_shift(&(self.nodes[v] - self.nodes[e.b]));
                    for (c, d) in moving.enumerate() {
                        let col = if parent_is_a { *d } else { -(back * d) };
                        m.view_mut((0, c0 + c), (6, 1)).copy_from(&col);
                    }
                    // Elastic coordinates follow the free ones: energy 1/2 (s - s0)^T K (s - s0).
                    let ne = e.connection.elastic.len();
                    if ne > 0 {
                        let s0 = c0 + e.connection.free.len();
                        let mut block = sys.kz.view_mut((s0, s0), (ne, ne));
                        block += &e.connection.stiffness;
                        let mut rows = sys.f.rows_mut(s0, ne);
                        rows += &e.connection.stiffness * &e.connection.preload;
                    }
                    m
                }
            };
        }
        t
    }

    /// Connections outside the forest close loops: their rigid directions become constraints, their
    /// elastic ones springs on the relative displacement dt.
    fn close_loops(&self, plan: &Plan, t: &[Map], sys: &mut Reduced) {
        let base = Map::zeros(6, plan.n_y + 6);
        for (k, e) in plan.edges.iter().enumerate() {
            if plan.tree_edge[k] {
                continue;
            }
            let ta = match e.a {
                Some(a) => &t[a],
                None => &base,
            };
            let dt: Map = &t[e.b] - to_dmatrix(&self.shift(e.a, e.b)) * ta;
            let (_, rigid) = e.connection.moving_and_rigid();
            for d in &rigid {
                sys.constraints.push(dt.tr_mul(&DVector::from_column_slice(d.as_slice())));
            }
            let ne = e.connection.elastic.len();
            if ne > 0 {
                let l = DMatrix::from_fn(ne, 6, |r, c| e.connection.elastic[r][c]);
                let b = l * &dt;
                let kb = &e.connection.stiffness * &b;
                sys.kz += b.transpose() * &kb;
                sys.f += b.transpose() * (&e.connection.stiffness * &e.connection.preload);
            }
        }
    }

    /// Flexible links (eq 1): energy 1/2 [t_i; t_j]^T K [t_i; t_j], over the few coordinates that move
    /// nodes i and j (those along their forest paths), not all of them.
    fn add_flexible_links(&self, t: &[Map], sys: &mut Reduced) {
        let nz = sys.f.len();
        let used: Vec<Vec<usize>> =
            t.iter().map(|m| (0..nz).filter(|&c| m.column(c).iter().any(|v| *v != 0.0)).collect()).collect();
        for e in &self.elements {
            if let Element::Flexible { i, j, k } = e {
                let mut cols: Vec<usize> = used[*i].iter().chain(&used[*j]).copied().collect();
                cols.sort_unstable();
                cols.dedup();
                let tij =
                    DMatrix::from_fn(
                        12,
                        cols.len(),
                        |r, c| if r < 6 { t[*i][(r, cols[c])] } else { t[*j][(r - 6, cols[c])] },
                    );
                let k12 = DMatrix::from_fn(12, 12, |r, c| k[r / 6][c / 6][(r % 6, c % 6)]);
                let kc = tij.transpose() * (k12 * &tij);
                for (a, &ca) in cols.iter().enumerate() {
                    for (b, &cb) in cols.iter().enumerate() {
                        sys.kz[(ca, cb)] += kc[(a, b)];
                    }
                }
            }
        }
    }
}

/// The reduced system being assembled: stiffness and load on the forest's coordinates and the end's six,
/// and the loop-closure constraint rows.
struct Reduced {
    kz: DMatrix<f64>,
    f: DVector<f64>,
    constraints: Vec<DVector<f64>>,
}

struct Plan<'a> {
    edges: Vec<Edge<'a>>,
    tree_edge: Vec<bool>,
    order: Vec<(usize, Option<usize>)>,
    /// First column of each visited node's coordinates (same indexing as `order`).
    first: Vec<usize>,
    n_y: usize,
    n_constraints: usize,
    end_is_root: bool,
}

/// Drops constraint rows that repeat others (a loop of joints closed exactly, as in an over-constrained
/// mechanism written with consistent geometry): they carry no information, and kept they make the
/// system singular although the structure is not a mechanism.
fn independent(rows: Vec<DVector<f64>>) -> Vec<DVector<f64>> {
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let mut kept = Vec::new();
    for row in rows {
        let mut v = row.clone();
        for _ in 0..2 {
            for b in &basis {
                let d = b.dot(&v);
                v.axpy(-d, b, 1.0);
            }
        }
        let n = v.norm();
        if n > ROW_INDEPENDENCE * row.norm() {
            basis.push(v / n);
            kept.push(row);
        }
    }
    kept
}

fn to_dmatrix(m: &Mat6) -> DMatrix<f64> {
    DMatrix::from_column_slice(6, 6, m.as_slice())
}

/// Condenses min 1/2 z^T K z - f^T z subject to C z = 0 onto the last six coordinates u (eq 17): returns the
/// end stiffness and the holding wrench at u = 0, or the null space (as vectors over y) of a mechanism.
fn solve_condensed(
    kz: &DMatrix<f64>,
    f: &DVector<f64>,
    constraints: &[DVector<f64>],
    n_y: usize,
) -> Result<EndAnswer, Result<Vec<DVector<f64>>, MsaFailure>> {
    let m = constraints.len();
    let size = n_y + m;
    // Constraint rows scaled to the stiffness' size, for a balanced factorisation.
    let scale = (0..kz.nrows()).map(|i| kz[(i, i)].abs()).fold(1.0, f64::max);
    let mut a = DMatrix::<f64>::zeros(size, size);
    a.view_mut((0, 0), (n_y, n_y)).copy_from(&kz.view((0, 0), (n_y, n_y)));
    let mut rhs = DMatrix::<f64>::zeros(size, 7);
    for c in 0..6 {
        for r in 0..n_y {
            rhs[(r, c)] = -kz[(r, n_y + c)];
        }
    }
    for r in 0..n_y {
        rhs[(r, 6)] = f[r];
    }
    for (row, g) in constraints.iter().enumerate() {
        for c in 0..n_y {
            a[(n_y + row, c)] = scale * g[c];
            a[(c, n_y + row)] = scale * g[c];
        }
        for c in 0..6 {
            rhs[(n_y + row, c)] = -scale * g[n_y + c];
        }
    }
    let x = if size == 0 {
        DMatrix::zeros(0, 7)
    } else {
        let solved = if m == 0 {
            // No loop closes: the reduced stiffness is symmetric positive definite unless a mechanism.
            a.clone().cholesky().and_then(|c| {
                let l = c.l_dirty();
                let diag = (0..size).map(|i| l[(i, i)] * l[(i, i)]);
                let (lo, hi) = diag.fold((f64::INFINITY, 0.0f64), |(lo, hi), p| (lo.min(p), hi.max(p)));
                (lo > PIVOT_RATIO * hi).then(|| c.solve(&rhs))
            })
        } else {
            let lu = a.clone().lu();
            let u = lu.u();
            let pivots = (0..size).map(|i| u[(i, i)].abs());
            let (lo, hi) = pivots.fold((f64::INFINITY, 0.0f64), |(lo, hi), p| (lo.min(p), hi.max(p)));
            if lo > PIVOT_RATIO * hi {
                lu.solve(&rhs)
            } else {
                None
            }
        };
        match solved {
            Some(x) if x.iter().all(|v| v.is_finite()) => x,
            _ => return Err(null_space(&a, n_y)),
        }
    };
    // Wrench at the end: dE/du = K_uy y + K_uu u + C_u^T lambda - f_u, lambda = scale * multipliers.
    let mut stiffness = Mat6::zeros();
    let mut holding = Vec6::zeros();
    for r in 0..6 {
        let ur = n_y + r;
        for col in 0..7 {
            let mut w = if col < 6 { kz[(ur, n_y + col)] } else { -f[ur] };
            for c in 0..n_y {
                w += kz[(ur, c)] * x[(c, col)];
            }
            for (row, g) in constraints.iter().enumerate() {
                w += g[ur] * scale * x[(n_y + row, col)];
            }
            if col < 6 {
                stiffness[(r, col)] = w;
            } else {
                holding[r] = w;
            }
        }
    }
    Ok(EndAnswer { stiffness: (stiffness + stiffness.transpose()) * 0.5, holding_wrench: holding })
}

/// The null space of a singular reduced system, restricted to the coordinates y (the free motions).
fn null_space(a: &DMatrix<f64>, n_y: usize) -> Result<Vec<DVector<f64>>, MsaFailure> {
    let svd = crate::linalg::capped_svd(a.clone(), false, true).ok_or(MsaFailure::NotFinite)?;
    let v_t = svd.v_t.expect("asked for V^T");
    let top = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    Ok(svd
        .singular_values
        .iter()
        .enumerate()
        .filter(|(_, s)| **s <= NULL_SHARE * top)
        .map(|(k, _)| v_t.row(k).columns(0, n_y).transpose())
        .filter(|y| y.norm() > MOTION_FLOOR)
        .collect())
}
