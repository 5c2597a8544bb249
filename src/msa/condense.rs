//! The reduced system of a structure (paper 003 eq 15-17 in the forest's coordinates) and its condensation
//! onto the end node. A structure's graph, spanning forest, coordinates and each node's sparsity depend only
//! on its shape (which elements join which nodes, and how many free and elastic directions each has), not on
//! the pose: a `Condenser` makes them once for a shape and keeps its buffers, so a map of poses only fills
//! numbers (no allocation per pose on the route without loop constraints).

use nalgebra::{DMatrix, DVector};

use super::{Connection, Element, EndAnswer, MsaFailure, Structure};
use crate::kinematics::frame::{Mat6, Vec3, Vec6};
use crate::linalg::EnvelopeCholesky;

// Tolerances of the reduced system, relative to the sizes they compare (row norms, the largest pivot or
// singular value), each well above round-off (~1e-16 per operation) and well below any real size.

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

/// Most starting coordinates tried for the envelope ordering (each costs a pass over the coupling graph).
const ORDERING_STARTS: usize = 64;

/// What the plan needs of an element: its kind, its nodes and its directions' counts (free, elastic).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Shape {
    Flexible(usize, usize),
    Rigid(usize, usize),
    Joint(usize, usize, usize, usize),
    Base(usize, usize, usize),
}

fn shape(e: &Element) -> Shape {
    match e {
        Element::Flexible { i, j, .. } => Shape::Flexible(*i, *j),
        Element::Rigid { i, j } => Shape::Rigid(*i, *j),
        Element::Joint { i, j, connection } => Shape::Joint(*i, *j, connection.free.len(), connection.elastic.len()),
        Element::Base { node, connection } => Shape::Base(*node, connection.free.len(), connection.elastic.len()),
    }
}

/// All six directions rigid: the connection of a rigid link.
fn rigid() -> &'static Connection {
    static RIGID: std::sync::OnceLock<Connection> = std::sync::OnceLock::new();
    RIGID.get_or_init(Connection::rigid)
}

/// A connection as an edge of the graph, `dt = t_b - A_ab t_a` (a = None: the base), made by an element.
#[derive(Clone, Copy, Debug)]
struct Edge {
    element: usize,
    a: Option<usize>,
    b: usize,
    /// Free plus elastic directions: the coordinates the edge adds when it is in the forest.
    moving: usize,
}

impl Edge {
    fn connection<'s>(&self, s: &'s Structure) -> &'s Connection {
        match &s.elements[self.element] {
            Element::Joint { connection, .. } | Element::Base { connection, .. } => connection,
            _ => rigid(),
        }
    }
}

/// The spanning forest and the coordinates of one shape of structure.
#[derive(Clone, Debug)]
struct Plan {
    edges: Vec<Edge>,
    tree_edge: Vec<bool>,
    /// Visiting order: (node, edge it was reached by, or None for a root).
    order: Vec<(usize, Option<usize>)>,
    /// First column of each visited node's coordinates (same indexing as `order`).
    first: Vec<usize>,
    n_y: usize,
    end_is_root: bool,
    /// The reduced system's column of each forest coordinate (an ordering with a small envelope; the
    /// end's six last).
    column: Vec<usize>,
    /// Which entries each node's map has and where each comes from, in these columns.
    layout: Layout,
    /// The reduced stiffness' envelope: per column, the first row of its upper triangle that the assembly
    /// can make non-zero (the factorisation keeps to it).
    envelope: Vec<usize>,
}

/// Where an entry of a node's map comes from: a root's unit twist r, an entry of the parent's map (its
/// index in `Layout::entries`) carried rigidly to the node, or the node's joint's own direction c (free
/// directions first, then elastic ones).
#[derive(Clone, Copy, Debug)]
enum Source {
    Unit(usize),
    Parent(usize),
    Own(usize),
}

/// Each node's map entries as the shape fixes them: (column, source), sorted by column within each node's
/// span; the poses fill in the numbers (`Work::node_maps`).
#[derive(Clone, Debug, Default)]
struct Layout {
    entries: Vec<(usize, Source)>,
    spans: Vec<std::ops::Range<usize>>,
}

impl Plan {
    /// The spanning forest: from the base first, then from the end node (whose six coordinates are the
    /// prescribed ones), then from any node still unreached (a free root of six coordinates).
    fn new(shapes: &[Shape], n: usize, end: usize) -> Result<Plan, MsaFailure> {
        let check = |i: usize| if i < n { Ok(i) } else { Err(MsaFailure::BadNode(i)) };
        let mut edges = Vec::new();
        for (element, s) in shapes.iter().enumerate() {
            let (a, b, moving) = match *s {
                Shape::Flexible(i, j) => {
                    check(i)?;
                    check(j)?;
                    continue;
                }
                Shape::Rigid(i, j) => (Some(check(i)?), check(j)?, 0),
                Shape::Joint(i, j, free, elastic) => (Some(check(i)?), check(j)?, free + elastic),
                Shape::Base(node, free, elastic) => (None, check(node)?, free + elastic),
            };
            edges.push(Edge { element, a, b, moving });
        }
        check(end)?;
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
        let end_is_root = !reached[end];
        if end_is_root {
            visit(&[], Some(end), &mut reached, &mut tree_edge, &mut order);
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
                None if *v == end => 0,
                None => 6,
                Some(k) => edges[*k].moving,
            };
        }
        let identity: Vec<usize> = (0..n_y + 6).collect();
        let mut plan = Plan {
            edges,
            tree_edge,
            order,
            first,
            n_y,
            end_is_root,
            column: Vec::new(),
            layout: Layout::default(),
            envelope: Vec::new(),
        };
        let coupled = plan.couplings(shapes, &plan.layout(&identity, n, end));
        plan.column = plan.envelope_order(&coupled);
        plan.envelope = (0..n_y + 6).collect();
        for (v, neighbours) in coupled.iter().enumerate() {
            let c = plan.column[v];
            for &u in neighbours {
                plan.envelope[c] = plan.envelope[c].min(plan.column[u]);
            }
        }
        plan.layout = plan.layout(&plan.column, n, end);
        Ok(plan)
    }

    /// Each node's map entries along the forest, the coordinates given the columns `column`: a root's six
    /// unit twists (the end node's are the prescribed coordinates), else the parent's entries carried and
    /// the joint's own directions.
    fn layout(&self, column: &[usize], n: usize, end: usize) -> Layout {
        let mut layout = Layout { entries: Vec::new(), spans: vec![0..0; n] };
        for (slot, &(v, via)) in self.order.iter().enumerate() {
            let (c0, start) = (self.first[slot], layout.entries.len());
            match via {
                None => {
                    let first = if v == end { self.n_y } else { c0 };
                    layout.entries.extend((0..6).map(|r| (column[first + r], Source::Unit(r))));
                }
                Some(k) => {
                    let e = &self.edges[k];
                    let parent = if e.b == v { e.a } else { Some(e.b) };
                    for q in parent.map_or(0..0, |p| layout.spans[p].clone()) {
                        layout.entries.push((layout.entries[q].0, Source::Parent(q)));
                    }
                    layout.entries.extend((0..e.moving).map(|c| (column[c0 + c], Source::Own(c))));
                }
            }
            layout.entries[start..].sort_by_key(|(c, _)| *c);
            layout.spans[v] = start..layout.entries.len();
        }
        layout
    }

    /// Which coordinates share an entry of the reduced stiffness (each one's others, by index), from the
    /// shape alone: a flexible link couples every coordinate moving either end, a spring its own, a loop
    /// its ends'.
    fn couplings(&self, shapes: &[Shape], by_index: &Layout) -> Vec<Vec<usize>> {
        let nz = self.n_y + 6;
        let moved: Vec<Vec<usize>> = by_index
            .spans
            .iter()
            .map(|span| by_index.entries[span.clone()].iter().map(|(c, _)| *c).collect())
            .collect();
        let mut adjacent = vec![vec![false; nz]; nz];
        let mut couple = |cols: &[usize]| {
            for &a in cols {
                for &b in cols {
                    adjacent[a][b] = true;
                }
            }
        };
        for shape in shapes {
            if let Shape::Flexible(i, j) = *shape {
                couple(&[moved[i].as_slice(), moved[j].as_slice()].concat());
            }
        }
        for (slot, &(_, via)) in self.order.iter().enumerate() {
            if let Some(k) = via {
                couple(&(self.first[slot]..self.first[slot] + self.edges[k].moving).collect::<Vec<_>>());
            }
        }
        for (k, e) in self.edges.iter().enumerate() {
            if !self.tree_edge[k] {
                let a = e.a.map(|a| moved[a].clone()).unwrap_or_default();
                couple(&[a.as_slice(), moved[e.b].as_slice()].concat());
            }
        }
        (0..nz).map(|a| (0..nz).filter(|&b| b != a && adjacent[a][b]).collect()).collect()
    }

    /// Columns for the forest's coordinates that keep the reduced stiffness' envelope small (the
    /// Cholesky factorisation costs what the envelope holds), given which coordinates share an entry: the
    /// reverse Cuthill-McKee ordering of that graph from whichever start gives the smallest envelope (or
    /// the forest's own order, if smaller). The end's six coordinates stay last.
    fn envelope_order(&self, coupled: &[Vec<usize>]) -> Vec<usize> {
        let n_y = self.n_y;
        let neighbours: Vec<Vec<usize>> =
            coupled[..n_y].iter().map(|others| others.iter().copied().filter(|&b| b < n_y).collect()).collect();
        // The envelope of an ordering (position -> coordinate): per row, its distance to its first neighbour.
        let envelope = |order: &[usize]| -> usize {
            let mut position = vec![0; n_y];
            for (p, &v) in order.iter().enumerate() {
                position[v] = p;
            }
            (0..n_y)
                .map(|v| position[v] - neighbours[v].iter().map(|&u| position[u]).fold(position[v], usize::min))
                .sum()
        };
        let forest_order: Vec<usize> = (0..n_y).collect();
        let mut best = (envelope(&forest_order), forest_order);
        // Starts of least degree first (the classic choice: a peripheral coordinate), at most
        // `ORDERING_STARTS` of them, so that a structure of thousands of coordinates is ordered in time.
        let mut starts: Vec<usize> = (0..n_y).collect();
        starts.sort_by_key(|&v| (neighbours[v].len(), v));
        starts.truncate(ORDERING_STARTS);
        for start in starts {
            let mut order = Vec::with_capacity(n_y);
            let mut seen = vec![false; n_y];
            let mut next = Some(start);
            while let Some(root) = next {
                seen[root] = true;
                let mut head = order.len();
                order.push(root);
                while head < order.len() {
                    let v = order[head];
                    head += 1;
                    let mut fresh: Vec<usize> = neighbours[v].iter().copied().filter(|&u| !seen[u]).collect();
                    fresh.sort_by_key(|&u| (neighbours[u].len(), u));
                    for u in fresh {
                        seen[u] = true;
                        order.push(u);
                    }
                }
                next = (0..n_y).filter(|&u| !seen[u]).min_by_key(|&u| (neighbours[u].len(), u));
            }
            order.reverse();
            let size = envelope(&order);
            if size < best.0 {
                best = (size, order);
            }
        }
        let mut column: Vec<usize> = (0..n_y + 6).collect();
        for (p, &v) in best.1.iter().enumerate() {
            column[v] = p;
        }
        column
    }
}

/// How every node's twist depends on the coordinates: t_v = sum of x z_c over node v's entries (c, x),
/// sorted by column. A node moves only with the coordinates along its forest path, a few of the
/// structure's, so the maps are kept sparse (dense 6 x n_z maps cost most of a pose).
#[derive(Clone, Debug, Default)]
struct NodeMaps {
    entries: Vec<(usize, Vec6)>,
    spans: Vec<std::ops::Range<usize>>,
}

impl NodeMaps {
    fn of(&self, v: usize) -> &[(usize, Vec6)] {
        &self.entries[self.spans[v].clone()]
    }
}

/// A twist at one point carried rigidly to a point `d` away: (v + w x d, w), `point_shift(d)` applied.
fn carry(d: &Vec3, x: &Vec6) -> Vec6 {
    let (v, w) = (x.fixed_rows::<3>(0), x.fixed_rows::<3>(3));
    let moved = v + w.cross(d);
    Vec6::new(moved[0], moved[1], moved[2], w[0], w[1], w[2])
}

/// The reduced system being assembled and what solving it needs, kept between poses of one plan.
#[derive(Clone, Debug)]
struct Work {
    maps: NodeMaps,
    /// Stiffness on the forest's coordinates and the end's six (column-major, nz square): its upper
    /// triangle, and only within the plan's envelope, which each pose clears and fills; the rest of the
    /// upper triangle stays as the plan's start made it, zero (the lower triangle is written only as a
    /// mirror of the upper, for the route with loop constraints).
    kz: DMatrix<f64>,
    /// The load on the coordinates.
    f: DVector<f64>,
    /// Loop-closure constraint rows over the nz coordinates, one after another.
    constraints: Vec<f64>,
    /// A connection's relative displacement per coordinate that moves either of its nodes.
    relative: Vec<(usize, Vec6)>,
    link: LinkEnergy,
    cholesky: EnvelopeCholesky,
}

impl Work {
    /// The buffers of a plan's poses, the stiffness all zero.
    fn for_plan(plan: &Plan) -> Work {
        let nz = plan.n_y + 6;
        Work {
            maps: NodeMaps::default(),
            kz: DMatrix::zeros(nz, nz),
            f: DVector::zeros(nz),
            constraints: Vec::new(),
            relative: Vec::new(),
            link: LinkEnergy::default(),
            cholesky: EnvelopeCholesky::new(plan.envelope.clone()),
        }
    }
}

/// The solver of structures of one shape: the forest and coordinates made at the first structure and
/// kept while later ones have the same shape (remade otherwise), with its buffers.
#[derive(Clone, Debug, Default)]
pub struct Condenser {
    shapes: Vec<Shape>,
    nodes: usize,
    end: usize,
    /// The plan of the current shape and the buffers of its poses, made together.
    solver: Option<(Plan, Work)>,
}

impl Condenser {
    /// Solves the structure (eq 15-17): the end node's stiffness and the wrench holding it against preloads.
    pub fn condense(&mut self, s: &Structure) -> Result<EndAnswer, MsaFailure> {
        let fits = self.solver.is_some()
            && self.nodes == s.nodes.len()
            && self.end == s.end
            && self.shapes.len() == s.elements.len()
            && self.shapes.iter().zip(&s.elements).all(|(a, e)| *a == shape(e));
        if !fits {
            self.solver = None;
            self.shapes.clear();
            self.shapes.extend(s.elements.iter().map(shape));
            self.nodes = s.nodes.len();
            self.end = s.end;
            let plan = Plan::new(&self.shapes, self.nodes, self.end)?;
            let work = Work::for_plan(&plan);
            self.solver = Some((plan, work));
        }
        let (plan, work) = self.solver.as_mut().expect("made above");
        work.solve(plan, s)
    }
}

impl Work {
    fn solve(&mut self, plan: &Plan, s: &Structure) -> Result<EndAnswer, MsaFailure> {
        let (n_y, nz) = (plan.n_y, plan.n_y + 6);
        self.assemble(plan, s);
        let answer = if self.constraints.is_empty() && n_y > 0 {
            self.condense_by_cholesky(n_y).ok_or_else(|| {
                // Not positive definite: a mechanism, whose free motions are K_yy's null space. The
                // elimination has overwritten K_yy, so it is assembled again (this route is rare).
                self.assemble(plan, s);
                null_space(&DMatrix::from_fn(n_y, n_y, |r, c| self.kz[(r.min(c), r.max(c))]), n_y)
            })
        } else {
            for c in 0..nz {
                for r in 0..c {
                    self.kz[(c, r)] = self.kz[(r, c)];
                }
            }
            let constraints = independent(&self.constraints, nz);
            solve_condensed(&self.kz, &self.f, &constraints, n_y)
        };
        answer.map_err(|null| match null {
            Err(failure) => failure,
            Ok(null) => {
                // Which nodes a free motion moves (the multipliers' part of a null vector is not a motion).
                let moves = |v: usize, y: &DVector<f64>| {
                    let twist: Vec6 = self.maps.of(v).iter().filter(|(c, _)| *c < n_y).map(|(c, x)| x * y[*c]).sum();
                    twist.norm() > NODE_MOVES * y.norm()
                };
                let nodes: Vec<usize> = (0..s.nodes.len()).filter(|&v| null.iter().any(|y| moves(v, y))).collect();
                MsaFailure::Mechanism { free: null.len(), nodes }
            }
        })
    }

    /// The reduced system at this pose: the stiffness' envelope cleared and filled (its upper triangle),
    /// the load, and the constraint rows.
    fn assemble(&mut self, plan: &Plan, s: &Structure) {
        let nz = plan.n_y + 6;
        let k = self.kz.as_mut_slice();
        for (c, &first) in plan.envelope.iter().enumerate() {
            k[c * nz + first..=c * nz + c].fill(0.0);
        }
        self.f.fill(0.0);
        self.constraints.clear();
        self.node_maps(plan, s);
        self.close_loops(plan, s);
        if !plan.end_is_root {
            // The end node reached through the forest: its twist must equal the prescribed u.
            for r in 0..6 {
                let start = self.constraints.len();
                self.constraints.resize(start + nz, 0.0);
                let row = &mut self.constraints[start..];
                for (c, x) in self.maps.of(s.end) {
                    row[*c] = x[r];
                }
                row[plan.n_y + r] -= 1.0;
            }
        }
        self.add_flexible_links(s);
        debug_assert!(
            (0..nz).all(|c| self.kz.as_slice()[c * nz..c * nz + plan.envelope[c]].iter().all(|v| *v == 0.0)),
            "the assembly keeps to the plan's envelope"
        );
    }

    /// Each node's twist as a linear map of the reduced coordinates, along the spanning forest; the tree
    /// joints' springs act on their own coordinates (energy 1/2 (s - s0)^T K (s - s0)).
    fn node_maps(&mut self, plan: &Plan, s: &Structure) {
        let layout = &plan.layout;
        let t = &mut self.maps;
        t.entries.resize(layout.entries.len(), (0, Vec6::zeros()));
        t.spans.clone_from(&layout.spans);
        for (slot, &(v, via)) in plan.order.iter().enumerate() {
            let span = layout.spans[v].clone();
            let Some(k) = via else {
                // A root: the end node's six prescribed coordinates, or a free root's own six.
                for i in span {
                    let (c, Source::Unit(r)) = layout.entries[i] else {
                        unreachable!("a root's entries are unit twists")
                    };
                    t.entries[i] = (c, Vec6::from_fn(|k, _| if k == r { 1.0 } else { 0.0 }));
                }
                continue;
            };
            let e = &plan.edges[k];
            let connection = e.connection(s);
            let parent_is_a = e.b == v;
            let parent = if parent_is_a { e.a } else { Some(e.b) };
            // t_b = A_ab t_a + dt, or t_a = A_ba (t_b - dt): the parent's map carried to v.
            let d = parent.map_or(Vec3::zeros(), |p| s.nodes[v] - s.nodes[p]);
            let back = s.nodes[v] - s.nodes[e.b];
            let n_free = connection.free.len();
            for i in span {
                let (c, source) = layout.entries[i];
                let x = match source {
                    Source::Parent(q) => carry(&d, &t.entries[q].1),
                    Source::Own(j) => {
                        let direction = if j < n_free { &connection.free[j] } else { &connection.elastic[j - n_free] };
                        if parent_is_a {
                            *direction
                        } else {
                            -carry(&back, direction)
                        }
                    }
                    Source::Unit(_) => unreachable!("a joint's entries are carried or its own"),
                };
                t.entries[i] = (c, x);
            }
            // Elastic coordinates follow the free ones: energy 1/2 (s - s0)^T K (s - s0).
            let c0 = plan.first[slot];
            let ne = connection.elastic.len();
            let s0 = c0 + n_free;
            let (k, preload) = (&connection.stiffness, &connection.preload);
            for c in 0..ne {
                for r in 0..ne {
                    let (row, col) = (plan.column[s0 + r], plan.column[s0 + c]);
                    if row <= col {
                        self.kz[(row, col)] += 0.5 * (k[(r, c)] + k[(c, r)]);
                    }
                    self.f[row] += k[(r, c)] * preload[c];
                }
            }
        }
        debug_assert!(t.entries.iter().all(|(c, _)| *c < plan.n_y + 6));
    }

    /// Connections outside the forest close loops: their rigid directions become constraints, their
    /// elastic ones springs on the relative displacement dt.
    fn close_loops(&mut self, plan: &Plan, s: &Structure) {
        let nz = plan.n_y + 6;
        for (k, e) in plan.edges.iter().enumerate() {
            if plan.tree_edge[k] {
                continue;
            }
            let d = e.a.map_or(Vec3::zeros(), |a| s.nodes[e.b] - s.nodes[a]);
            relative_displacement(&self.maps, e.a, e.b, &d, &mut self.relative);
            let connection = e.connection(s);
            let (_, rigid) = connection.moving_and_rigid();
            for direction in &rigid {
                let start = self.constraints.len();
                self.constraints.resize(start + nz, 0.0);
                for (c, x) in &self.relative {
                    self.constraints[start + c] = x.dot(direction);
                }
            }
            // Springs on the relative displacement: energy 1/2 (B z - s0)^T K (B z - s0), B = elastic^T dt,
            // as a link's energy with K (its symmetric part) and B's columns padded to six.
            let (elastic, stiffness, preload) = (&connection.elastic, &connection.stiffness, &connection.preload);
            let ne = elastic.len();
            if ne > 0 {
                let inside = |r: usize, c: usize| r < ne && c < ne;
                let spring =
                    Mat6::from_fn(
                        |r, c| if inside(r, c) { 0.5 * (stiffness[(r, c)] + stiffness[(c, r)]) } else { 0.0 },
                    );
                let held = Vec6::from_fn(|r, _| {
                    (0..ne).map(|c| if inside(r, c) { stiffness[(r, c)] * preload[c] } else { 0.0 }).sum()
                });
                for (c, dt) in &mut self.relative {
                    *dt = Vec6::from_fn(|r, _| if r < ne { elastic[r].dot(dt) } else { 0.0 });
                    self.f[*c] += dt.dot(&held);
                }
                self.link.add(&self.relative, &spring, self.kz.as_mut_slice(), nz);
            }
        }
    }

    /// Flexible links (eq 1): energy 1/2 dt^T K_jj dt over the relative displacement dt = t_j - A_ij t_i
    /// (the 12x12 form [t_i; t_j]^T K [t_i; t_j] of eq 1 with K_ji = -K_jj A_ij, K_ii = A_ij^T K_jj A_ij
    /// by rigid-body invariance, written as one square), over the few coordinates that move nodes i and j
    /// (those along their forest paths), not all of them.
    fn add_flexible_links(&mut self, s: &Structure) {
        let nz = self.kz.nrows();
        for e in &s.elements {
            let Element::Flexible { i, j, kjj } = e else { continue };
            let k = (kjj + kjj.transpose()) * 0.5;
            relative_displacement(&self.maps, Some(*i), *j, &(s.nodes[*j] - s.nodes[*i]), &mut self.relative);
            self.link.add(&self.relative, &k, self.kz.as_mut_slice(), nz);
        }
    }

    /// The solution where no loop closes: the reduced stiffness K_yy is symmetric positive definite unless
    /// the structure is a mechanism, and with K_yy = U^T U, W = U^-T K_yu and g = U^-T f_y the end's
    /// stiffness is the Schur complement K_uu - W^T W and its holding wrench W^T g - f_u (eq 17). One
    /// elimination of the y coordinates, in place where the system was assembled, leaves U, W beside it
    /// and the Schur complement in the trailing block. None where K_yy is not positive definite (or the
    /// numbers not finite): a mechanism.
    fn condense_by_cholesky(&mut self, n_y: usize) -> Option<EndAnswer> {
        let nz = self.kz.nrows();
        let (k, f) = (self.kz.as_mut_slice(), self.f.as_mut_slice());
        match self.cholesky.eliminate(k, nz, n_y) {
            Some((lo, hi)) if lo > PIVOT_RATIO * hi => {}
            _ => return None,
        }
        // Without preloads on the eliminated coordinates g is zero: no solve (an unloaded leg's, as in a map).
        let preloaded = f[..n_y].iter().any(|v| *v != 0.0);
        if preloaded {
            self.cholesky.forward_in_place(k, nz, &mut f[..n_y]);
        }
        let first = self.cholesky.first();
        let finite = |v: &f64| v.is_finite();
        if !(f[..n_y].iter().all(finite) && (n_y..nz).all(|c| k[c * nz + first[c]..=c * nz + c].iter().all(finite))) {
            return None;
        }
        let mut stiffness = Mat6::zeros();
        let mut holding = Vec6::zeros();
        for c in 0..6 {
            let column = &k[(n_y + c) * nz..(n_y + c + 1) * nz];
            for r in 0..=c {
                stiffness[(r, c)] = column[n_y + r];
                stiffness[(c, r)] = column[n_y + r];
            }
            // W's column c, above the trailing block.
            let start = if preloaded { first[n_y + c].min(n_y) } else { n_y };
            let wg: f64 = column[start..n_y].iter().zip(&f[start..n_y]).map(|(w, g)| w * g).sum();
            holding[c] = wg - f[n_y + c];
        }
        Some(EndAnswer { stiffness, holding_wrench: holding })
    }
}

/// The relative displacement dt = t_j - A_ij t_i across a connection or link from node i (None: the base)
/// to node j, `d` from i's point to j's, for each coordinate that moves either node: their maps merged, in
/// column order.
fn relative_displacement(maps: &NodeMaps, i: Option<usize>, j: usize, d: &Vec3, out: &mut Vec<(usize, Vec6)>) {
    let (ti, tj) = (i.map_or(&[][..], |i| maps.of(i)), maps.of(j));
    out.clear();
    let (mut p, mut q) = (0, 0);
    while p < ti.len() || q < tj.len() {
        let (ci, cj) = (ti.get(p).map_or(usize::MAX, |x| x.0), tj.get(q).map_or(usize::MAX, |x| x.0));
        let c = ci.min(cj);
        let mut dt = Vec6::zeros();
        if cj == c {
            dt = tj[q].1;
            q += 1;
        }
        if ci == c {
            dt -= carry(d, &ti[p].1);
            p += 1;
        }
        out.push((c, dt));
    }
}

/// A link's energy over the coordinates that move either of its ends, with its buffers: the coordinates
/// whose relative displacement dt is a signed unit twist (+-e_r: a root's own coordinates, and the
/// translations carried from one, about half of a pantograph beam's) and the others, dense.
#[derive(Clone, Debug, Default)]
struct LinkEnergy {
    /// (column, dt, K dt), in increasing column order.
    dense: Vec<(usize, Vec6, Vec6)>,
    /// (column, r, sign): dt = sign e_r.
    units: Vec<(usize, usize, f64)>,
}

impl LinkEnergy {
    /// Adds dt_a . (K dt_b) for every pair of coordinates of `relative` (column, dt; in column order) to the
    /// upper triangle of `kz` (column-major, `nz` square), K symmetric: a pair with a unit +-e_r reads
    /// +-(K dt)_r, two units +-K_rs, where the others take a dot product.
    fn add(&mut self, relative: &[(usize, Vec6)], k: &Mat6, kz: &mut [f64], nz: usize) {
        // Room for every coordinate in either list: which are units can change from pose to pose (a carried
        // rotation meets an axis), and a map of poses allocates nothing once it has its size.
        self.dense.clear();
        self.dense.reserve(relative.len());
        self.units.clear();
        self.units.reserve(relative.len());
        for (c, dt) in relative {
            match signed_unit(dt) {
                Some((r, sign)) => self.units.push((*c, r, sign)),
                None => self.dense.push((*c, *dt, k * dt)),
            }
        }
        add_link_energy(&self.dense, kz, nz);
        let mut add = |a: usize, b: usize, v: f64| kz[a.max(b) * nz + a.min(b)] += v;
        for (u, &(cu, ru, su)) in self.units.iter().enumerate() {
            for (cd, _, load) in &self.dense {
                add(cu, *cd, su * load[ru]);
            }
            for &(cv, rv, sv) in &self.units[u..] {
                add(cu, cv, su * sv * k[(ru, rv)]);
            }
        }
    }
}

/// (r, sign) where `x` is sign e_r exactly (sign +-1), as a root's unit twists and the translations
/// carried from them are.
fn signed_unit(x: &Vec6) -> Option<(usize, f64)> {
    let mut unit = None;
    for (r, &v) in x.iter().enumerate() {
        if v == 0.0 {
            continue;
        }
        if unit.is_some() || v.abs() != 1.0 {
            return None;
        }
        unit = Some((r, v));
    }
    unit
}

/// A link's energy dt_a . (K dt_b) for every pair of its coordinates (`link`: column, dt, K dt, in
/// increasing column order), added to the upper triangle of `kz` (column-major, `nz` square). Against each
/// b, coordinates a and a + 1 are taken together, their two sums side by side (which the compiler keeps
/// in one vector register), each summed in the order of `dot6`, so the sums are those of one pair at a
/// time to the bit.
fn add_link_energy(link: &[(usize, Vec6, Vec6)], kz: &mut [f64], nz: usize) {
    debug_assert!(link.windows(2).all(|w| w[0].0 < w[1].0), "a link's coordinates in column order");
    for (b, (cb, _, load)) in link.iter().enumerate() {
        let column = &mut kz[cb * nz..cb * nz + cb + 1];
        let mut pairs = link[..=b].chunks_exact(2);
        for pair in &mut pairs {
            let ((ca, dta, _), (cn, dtn, _)) = (&pair[0], &pair[1]);
            let mut sum = [0.0f64; 2];
            for k in 0..6 {
                sum[0] += dta[k] * load[k];
                sum[1] += dtn[k] * load[k];
            }
            column[*ca] += sum[0];
            column[*cn] += sum[1];
        }
        for (ca, dta, _) in pairs.remainder() {
            column[*ca] += dot6(dta, load);
        }
    }
}

/// x . y summed from +0 in index order, as nalgebra's `dot` of two 6-vectors sums it.
fn dot6(x: &Vec6, y: &Vec6) -> f64 {
    let mut sum = 0.0;
    for k in 0..6 {
        sum += x[k] * y[k];
    }
    sum
}

/// Drops constraint rows that repeat others (a loop of joints closed exactly, as in an over-constrained
/// mechanism written with consistent geometry): they carry no information, and kept they make the
/// system singular although the structure is not a mechanism.
fn independent(rows: &[f64], nz: usize) -> Vec<DVector<f64>> {
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let mut kept = Vec::new();
    for row in rows.chunks_exact(nz) {
        let row = DVector::from_column_slice(row);
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

/// The flexible links' assembly against eq 1 as the paper writes it.
#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::frame::point_shift;

    /// The 12x12 stiffness of eq 1 from K_jj by rigid-body invariance (a rigid motion of both ends loads
    /// nothing): K_ji = -K_jj A, K_ij = K_ji^T, K_ii = A^T K_jj A, A carrying a twist at i to j.
    fn twelve_by_twelve(kjj: &Mat6, pi: &Vec3, pj: &Vec3) -> [[Mat6; 2]; 2] {
        let a = point_shift(&(pj - pi));
        let kji = -(kjj * a);
        [[a.transpose() * kjj * a, kji.transpose()], [kji, *kjj]]
    }

    /// The link energy as one square over the relative displacement equals eq 1's 12x12 quadratic form.
    #[test]
    fn relative_displacement_energy_equals_the_twelve_by_twelve_form() {
        let g = Mat6::from_fn(|r, c| ((r * 7 + c * 3) % 5) as f64 - 2.0 + if r == c { 6.0 } else { 0.0 });
        let kjj = g * g.transpose();
        let (pi, pj) = (Vec3::new(1.0, -2.0, 0.5), Vec3::new(40.0, 12.0, -7.0));
        let k = twelve_by_twelve(&kjj, &pi, &pj);
        let ti = Vec6::new(0.3, -0.1, 0.7, 0.02, -0.05, 0.01);
        let tj = Vec6::new(-0.2, 0.4, 0.1, -0.03, 0.06, 0.02);
        let full = ti.dot(&(k[0][0] * ti + k[0][1] * tj)) + tj.dot(&(k[1][0] * ti + k[1][1] * tj));
        let dt = tj - carry(&(pj - pi), &ti);
        let square = dt.dot(&(kjj * dt));
        assert!((full - square).abs() < 1e-12 * full.abs(), "{full} vs {square}");
    }

    /// A link's energy with some coordinates' relative displacements signed unit twists (+-e_r, read
    /// rather than summed) equals the plain sums dt_a . (K dt_b) over every pair, in the upper triangle;
    /// a vector next to a unit (1 + 1e-15, or a unit with a stray 1e-300) is summed as a dense one.
    #[test]
    fn unit_displacements_read_from_k_equal_the_dot_products() {
        let nz = 12;
        let g = Mat6::from_fn(|r, c| ((r * 5 + c * 3) % 7) as f64 - 3.0 + if r == c { 9.0 } else { 0.0 });
        let k = g * g.transpose();
        let unit = |r: usize, sign: f64| Vec6::from_fn(|i, _| if i == r { sign } else { 0.0 });
        let mut stray = unit(2, 1.0);
        stray[4] = 1e-300;
        let relative: Vec<(usize, Vec6)> = vec![
            (0, unit(3, 1.0)),
            (2, Vec6::new(0.3, -1.2, 0.5, 0.01, 0.2, -0.7)),
            (3, unit(0, -1.0)),
            (5, unit(1, 1.0 + 1e-15)),
            (6, stray),
            (8, Vec6::new(-0.4, 0.1, 0.9, -0.3, 0.05, 0.6)),
            (11, unit(5, -1.0)),
        ];
        let mut expected = vec![0.0; nz * nz];
        for (b, (cb, dtb)) in relative.iter().enumerate() {
            for (ca, dta) in &relative[..=b] {
                expected[cb * nz + ca] += dta.dot(&(k * dtb));
            }
        }
        let mut link = LinkEnergy::default();
        let mut kz = vec![0.0; nz * nz];
        link.add(&relative, &k, &mut kz, nz);
        assert_eq!(link.units.len(), 3, "the three exact signed units");
        for (i, (got, want)) in kz.iter().zip(&expected).enumerate() {
            assert!((got - want).abs() <= 1e-13 * k.amax(), "entry {i}: {got} vs {want}");
        }
    }

    /// A link's energy is the same number however its coordinate pairs are grouped: the paired lanes of
    /// `add_link_energy` give, to the bit, the sums of one pair at a time with nalgebra's `dot`, in the
    /// upper triangle only, for odd and even counts, columns with gaps, and a signed zero.
    #[test]
    fn paired_link_energies_equal_one_pair_at_a_time_to_the_bit() {
        let value = |i: usize| ((i * 37 % 101) as f64 - 50.0) / 7.0 + (i as f64).sqrt() * 1e-9;
        for count in [0, 1, 2, 5, 8] {
            let nz = 11;
            let columns = [0, 1, 2, 4, 6, 7, 9, 10];
            let mut link: Vec<(usize, Vec6, Vec6)> = (0..count)
                .map(|a| {
                    let dt = Vec6::from_fn(|r, _| value(a * 12 + r));
                    (columns[a], dt, Vec6::from_fn(|r, _| value(a * 12 + 6 + r)))
                })
                .collect();
            if count > 1 {
                // (1, 1)'s products are all -0: summed from +0 they give +0, which the -0 in kz keeps.
                link[1].1 = Vec6::from_element(-0.0);
                link[1].2 = Vec6::from_element(2.0);
            }
            let mut expected = vec![-0.0; nz * nz];
            for (b, (cb, _, load)) in link.iter().enumerate() {
                for (ca, dta, _) in &link[..=b] {
                    expected[cb * nz + ca] += dta.dot(load);
                }
            }
            let mut kz = vec![-0.0; nz * nz];
            add_link_energy(&link, &mut kz, nz);
            let bits = |m: &[f64]| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&kz), bits(&expected), "{count} coordinates");
            assert!((0..nz).all(|c| (c + 1..nz).all(|r| kz[c * nz + r].to_bits() == (-0.0f64).to_bits())), "lower");
        }
    }
}
