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

use crate::beam::{cantilever_stiffness, frame_along, BeamSection};
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
    let k = r * cantilever_stiffness(section, d.norm()) * r.transpose();
    // A zero length or a modulus at the edge of doubles shows on the diagonal; a non-finite entry off it,
    // if any, is caught downstream: the condensed system's solution is checked, and its null space comes
    // from a checked SVD.
    if !k.diagonal().iter().all(|v| v.is_finite() && *v > 0.0) {
        return None;
    }
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

/// How every node's twist depends on the coordinates: t_v = sum of x z_c over node v's entries (c, x),
/// sorted by column. A node moves only with the coordinates along its forest path, a few of the
/// structure's, so the maps are kept sparse (dense 6 x n_z maps cost most of a pose).
struct NodeMaps {
    entries: Vec<(usize, Vec6)>,
    spans: Vec<std::ops::Range<usize>>,
}

impl NodeMaps {
    fn of(&self, v: usize) -> &[(usize, Vec6)] {
        &self.entries[self.spans[v].clone()]
    }

    /// Node v's twist per unit coordinate, dense over the coordinates (a loop's relative displacement).
    fn dense(&self, v: Option<usize>, nz: usize) -> Vec<Vec6> {
        let mut d = vec![Vec6::zeros(); nz];
        if let Some(v) = v {
            for (c, x) in self.of(v) {
                d[*c] = *x;
            }
        }
        d
    }
}

/// A twist at one point carried rigidly to a point `d` away: (v + w x d, w), `point_shift(d)` applied.
fn carry(d: &Vec3, x: &Vec6) -> Vec6 {
    let (v, w) = (x.fixed_rows::<3>(0), x.fixed_rows::<3>(3));
    let moved = v + w.cross(d);
    Vec6::new(moved[0], moved[1], moved[2], w[0], w[1], w[2])
}

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
                let mut row = DVector::zeros(nz);
                for (c, x) in t.of(self.end) {
                    row[*c] = x[r];
                }
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
                let moves = |v: usize, y: &DVector<f64>| {
                    let twist: Vec6 = t.of(v).iter().filter(|(c, _)| *c < n_y).map(|(c, x)| x * y[*c]).sum();
                    twist.norm() > NODE_MOVES * y.norm()
                };
                let mut nodes: Vec<usize> = (0..n).filter(|&v| null.iter().any(|y| moves(v, y))).collect();
                nodes.sort_unstable();
                MsaFailure::Mechanism { free: null.len(), nodes }
            }
        })
    }

    /// Each node's twist as a linear map of the reduced coordinates, along the spanning forest; the tree
    /// joints' springs act on their own coordinates (energy 1/2 (s - s0)^T K (s - s0)).
    fn node_maps(&self, plan: &Plan, sys: &mut Reduced) -> NodeMaps {
        let n = self.nodes.len();
        let n_y = plan.n_y;
        let mut t = NodeMaps { entries: Vec::new(), spans: vec![0..0; n] };
        for (slot, &(v, via)) in plan.order.iter().enumerate() {
            let c0 = plan.first[slot];
            let start = t.entries.len();
            match via {
                None => {
                    // A root: the end node's six prescribed coordinates, or a free root's own six.
                    let first = if v == self.end { n_y } else { c0 };
                    t.entries.extend((0..6).map(|r| (first + r, Vec6::from_fn(|k, _| if k == r { 1.0 } else { 0.0 }))));
                }
                Some(k) => {
                    let e = &plan.edges[k];
                    let parent_is_a = e.b == v;
                    let parent = if parent_is_a { e.a } else { Some(e.b) };
                    if let Some(p) = parent {
                        // t_b = A_ab t_a + dt, or t_a = A_ba (t_b - dt): the parent's map carried to v.
                        let d = self.nodes[v] - self.nodes[p];
                        for q in t.spans[p].clone() {
                            let (c, x) = t.entries[q];
                            t.entries.push((c, carry(&d, &x)));
                        }
                    }
                    let back = self.nodes[v] - self.nodes[e.b];
                    let moving = e.connection.free.iter().chain(&e.connection.elastic);
                    for (c, d) in moving.enumerate() {
                        let col = if parent_is_a { *d } else { -carry(&back, d) };
                        t.entries.push((c0 + c, col));
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
                }
            }
            t.entries[start..].sort_by_key(|(c, _)| *c);
            t.spans[v] = start..t.entries.len();
        }
        t
    }

    /// Connections outside the forest close loops: their rigid directions become constraints, their
    /// elastic ones springs on the relative displacement dt.
    fn close_loops(&self, plan: &Plan, t: &NodeMaps, sys: &mut Reduced) {
        let nz = plan.n_y + 6;
        for (k, e) in plan.edges.iter().enumerate() {
            if plan.tree_edge[k] {
                continue;
            }
            // dt = t_b - A_ab t_a, per coordinate.
            let mut dt = t.dense(Some(e.b), nz);
            if let Some(a) = e.a {
                let d = self.nodes[e.b] - self.nodes[a];
                for (c, x) in t.of(a) {
                    dt[*c] -= carry(&d, x);
                }
            }
            let (_, rigid) = e.connection.moving_and_rigid();
            for d in &rigid {
                sys.constraints.push(DVector::from_iterator(nz, dt.iter().map(|x| x.dot(d))));
            }
            let ne = e.connection.elastic.len();
            if ne > 0 {
                let b = DMatrix::from_fn(ne, nz, |r, c| e.connection.elastic[r].dot(&dt[c]));
                let kb = &e.connection.stiffness * &b;
                sys.kz += b.transpose() * &kb;
                sys.f += b.transpose() * (&e.connection.stiffness * &e.connection.preload);
            }
        }
    }

    /// Flexible links (eq 1): energy 1/2 [t_i; t_j]^T K [t_i; t_j], over the few coordinates that move
    /// nodes i and j (those along their forest paths), not all of them.
    fn add_flexible_links(&self, t: &NodeMaps, sys: &mut Reduced) {
        // Per coordinate moving i or j: its twists at i and j, and K times them (the link's wrenches).
        let mut cols: Vec<(usize, Vec6, Vec6)> = Vec::new();
        let mut loads: Vec<(Vec6, Vec6)> = Vec::new();
        for e in &self.elements {
            let Element::Flexible { i, j, k } = e else { continue };
            cols.clear();
            let (ti, tj) = (t.of(*i), t.of(*j));
            let (mut p, mut q) = (0, 0);
            while p < ti.len() || q < tj.len() {
                let (ci, cj) = (ti.get(p).map_or(usize::MAX, |x| x.0), tj.get(q).map_or(usize::MAX, |x| x.0));
                let c = ci.min(cj);
                let xi = if ci == c {
                    p += 1;
                    ti[p - 1].1
                } else {
                    Vec6::zeros()
                };
                let xj = if cj == c {
                    q += 1;
                    tj[q - 1].1
                } else {
                    Vec6::zeros()
                };
                cols.push((c, xi, xj));
            }
            loads.clear();
            loads.extend(cols.iter().map(|(_, xi, xj)| (k[0][0] * xi + k[0][1] * xj, k[1][0] * xi + k[1][1] * xj)));
            // The link's energy is symmetric in the coordinates: the upper triangle, mirrored.
            let nz = sys.kz.nrows();
            let kz = sys.kz.as_mut_slice();
            for (a, (ca, xi, xj)) in cols.iter().enumerate() {
                for ((cb, _, _), (wi, wj)) in cols[a..].iter().zip(&loads[a..]) {
                    let v = xi.dot(wi) + xj.dot(wj);
                    kz[cb * nz + ca] += v;
                    if cb != ca {
                        kz[ca * nz + cb] += v;
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

/// Condenses min 1/2 z^T K z - f^T z subject to C z = 0 onto the last six coordinates u (eq 17): returns the
/// end stiffness and the holding wrench at u = 0, or the null space (as vectors over y) of a mechanism.
fn solve_condensed(
    kz: &DMatrix<f64>,
    f: &DVector<f64>,
    constraints: &[DVector<f64>],
    n_y: usize,
) -> Result<EndAnswer, Result<Vec<DVector<f64>>, MsaFailure>> {
    let m = constraints.len();
    if m == 0 && n_y > 0 {
        return condense_by_cholesky(kz, f, n_y);
    }
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
        let solved = {
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

/// `solve_condensed` where no loop closes: the reduced stiffness K_yy is symmetric positive definite
/// unless the structure is a mechanism, and with K_yy = L L^T, W = L^-1 K_yu and g = L^-1 f_y the end's
/// stiffness is K_uu - W^T W and its holding wrench W^T g - f_u (eq 17, as a Schur complement).
fn condense_by_cholesky(
    kz: &DMatrix<f64>,
    f: &DVector<f64>,
    n_y: usize,
) -> Result<EndAnswer, Result<Vec<DVector<f64>>, MsaFailure>> {
    let nz = kz.nrows();
    let k = kz.as_slice();
    let mut yy = vec![0.0; n_y * n_y];
    for c in 0..n_y {
        yy[c * n_y..(c + 1) * n_y].copy_from_slice(&k[c * nz..c * nz + n_y]);
    }
    let mut cholesky = crate::linalg::DenseCholesky::default();
    match cholesky.factor(&yy, n_y) {
        Some((lo, hi)) if lo > PIVOT_RATIO * hi => {}
        _ => return Err(null_space(&DMatrix::from_column_slice(n_y, n_y, &yy), n_y)),
    }
    // Columns of W (K_yu's six, then f_y), each L^-1 applied.
    let mut w = vec![0.0; 7 * n_y];
    for c in 0..6 {
        w[c * n_y..(c + 1) * n_y].copy_from_slice(&k[(n_y + c) * nz..(n_y + c) * nz + n_y]);
    }
    w[6 * n_y..].copy_from_slice(&f.as_slice()[..n_y]);
    for c in 0..7 {
        cholesky.forward_in_place(&mut w[c * n_y..(c + 1) * n_y]);
    }
    if !w.iter().all(|v| v.is_finite()) {
        return Err(null_space(&DMatrix::from_column_slice(n_y, n_y, &yy), n_y));
    }
    let column = |c: usize| &w[c * n_y..(c + 1) * n_y];
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut stiffness = Mat6::zeros();
    let mut holding = Vec6::zeros();
    for r in 0..6 {
        for c in r..6 {
            // K_uu is symmetric to round-off: its mean, as the general route symmetrises its result.
            let kuu = 0.5 * (kz[(n_y + r, n_y + c)] + kz[(n_y + c, n_y + r)]);
            let v = kuu - dot(column(r), column(c));
            stiffness[(r, c)] = v;
            stiffness[(c, r)] = v;
        }
        holding[r] = dot(column(r), column(6)) - f[n_y + r];
    }
    Ok(EndAnswer { stiffness, holding_wrench: holding })
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
