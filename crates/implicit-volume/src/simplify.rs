//! Quadric-error edge-collapse simplification (Garland and Heckbert, *Surface Simplification
//! Using Quadric Error Metrics*, SIGGRAPH 1997) that keeps a closed mesh a watertight,
//! consistently oriented 2-manifold.
//!
//! Every vertex carries the sum of the area-weighted plane quadrics of its triangles; an edge
//! `(u, v)` collapses to the best of its endpoints, its midpoint and the quadric minimiser,
//! cheapest edge first. A collapse is refused when it would
//! * break the link condition (the two end vertices share neighbours other than the two
//!   vertices opposite the edge): this is what keeps the surface a 2-manifold;
//! * leave a vertex with fewer than three neighbours (a tetrahedron collapsing flat) or more
//!   than 16;
//! * turn a triangle by more than about 80 degrees or make it degenerate (fold-overs).
//!
//! The collapses run in passes: the costs of all edges are computed in parallel and sorted
//! (ties broken by vertex index), then the cheaper half is collapsed in that order, skipping
//! the edges of vertices already merged in this pass (their queued cost is stale) until the
//! budget is met; the next pass re-plans the edges of the merged mesh. A pass replaces the
//! millions of heap updates of a one-edge-at-a-time queue by one parallel sort, and the
//! result does not depend on the thread count.
//!
//! [`simplify_with_progress`] asks its [`Progress`] whether to stop before every pass and every
//! 4096 queued edges of a pass, and then ends with [`Error::Stopped`] (no mesh); a
//! run that is not stopped gives the same mesh as [`simplify`].

use rayon::prelude::*;
use relief_heightfield::Progress;

use crate::error::{Error, Result};
use crate::mesh::Mesh;

/// Largest valence a collapse may create (keeps triangles well shaped and the cost of the
/// neighbourhood scans bounded on flat regions).
const MAX_VALENCE: usize = 16;

/// Queued edges (collapse attempts) between two asks of [`Progress::stopped`]: a small slice
/// of a pass (which goes through up to half the edges), so a stop is honoured quickly while the
/// asks cost nothing next to the collapses.
const POLL_EVERY: usize = 4096;

/// What [`simplify`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimplifyReport {
    /// Triangles before.
    pub triangles_in: usize,
    /// Triangles after.
    pub triangles_out: usize,
    /// Edge collapses refused by the topology and fold-over checks.
    pub refused: usize,
    /// Passes (parallel re-plannings of every edge).
    pub passes: usize,
}

type Quadric = [f64; 10];
type P = [f64; 3];

fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: P, b: P) -> P {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: P, b: P) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn plane_quadric(a: P, b: P, c: P) -> Quadric {
    let n = cross(sub(b, a), sub(c, a));
    let len = dot(n, n).sqrt();
    if len == 0.0 {
        return [0.0; 10];
    }
    let area = 0.5 * len;
    let n = [n[0] / len, n[1] / len, n[2] / len];
    let d = -dot(n, a);
    let (x, y, z) = (n[0], n[1], n[2]);
    [
        x * x * area,
        x * y * area,
        x * z * area,
        x * d * area,
        y * y * area,
        y * z * area,
        y * d * area,
        z * z * area,
        z * d * area,
        d * d * area,
    ]
}

fn q_add(a: &Quadric, b: &Quadric) -> Quadric {
    let mut r = *a;
    for (x, y) in r.iter_mut().zip(b) {
        *x += y;
    }
    r
}

fn q_eval(q: &Quadric, p: P) -> f64 {
    let (x, y, z) = (p[0], p[1], p[2]);
    q[0] * x * x
        + 2.0 * q[1] * x * y
        + 2.0 * q[2] * x * z
        + 2.0 * q[3] * x
        + q[4] * y * y
        + 2.0 * q[5] * y * z
        + 2.0 * q[6] * y
        + q[7] * z * z
        + 2.0 * q[8] * z
        + q[9]
}

/// Minimiser of the quadric when its 3x3 part is well conditioned.
fn q_optimum(q: &Quadric) -> Option<P> {
    let m = [[q[0], q[1], q[2]], [q[1], q[4], q[5]], [q[2], q[5], q[7]]];
    let b = [-q[3], -q[6], -q[8]];
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let scale = (q[0] + q[4] + q[7]).powi(3);
    if det.is_nan() || det.abs() <= 1e-9 * scale.max(1e-300) {
        return None;
    }
    let solve = |k: usize| {
        let mut mm = m;
        for r in 0..3 {
            mm[r][k] = b[r];
        }
        (mm[0][0] * (mm[1][1] * mm[2][2] - mm[1][2] * mm[2][1])
            - mm[0][1] * (mm[1][0] * mm[2][2] - mm[1][2] * mm[2][0])
            + mm[0][2] * (mm[1][0] * mm[2][1] - mm[1][1] * mm[2][0]))
            / det
    };
    Some([solve(0), solve(1), solve(2)])
}

struct State {
    pos: Vec<P>,
    tris: Vec<[u32; 3]>,
    alive: Vec<bool>,
    vtris: Vec<Vec<u32>>,
    quad: Vec<Quadric>,
}

impl State {
    /// Sorted distinct neighbours of `v` into `n`.
    fn neighbours_into(&self, v: u32, n: &mut Vec<u32>) {
        n.clear();
        for &t in &self.vtris[v as usize] {
            for &w in &self.tris[t as usize] {
                if w != v {
                    n.push(w);
                }
            }
        }
        n.sort_unstable();
        n.dedup();
    }

    /// Best target position and cost of collapsing edge `(u, v)`.
    fn plan(&self, u: u32, v: u32) -> (f64, P) {
        let q = q_add(&self.quad[u as usize], &self.quad[v as usize]);
        let (a, b) = (self.pos[u as usize], self.pos[v as usize]);
        let mid = [
            0.5 * (a[0] + b[0]),
            0.5 * (a[1] + b[1]),
            0.5 * (a[2] + b[2]),
        ];
        let len2 = dot(sub(a, b), sub(a, b));
        // A tiny length term orders the (zero-cost) collapses of flat regions shortest first,
        // so they coarsen evenly instead of around one vertex.
        let tie = 1e-6 * len2 * len2;
        let mut best = (q_eval(&q, mid), mid);
        for p in [Some(a), Some(b), q_optimum(&q)].into_iter().flatten() {
            // The minimiser may fly far off on nearly flat patches: keep it near the edge.
            if dot(sub(p, mid), sub(p, mid)) > len2 {
                continue;
            }
            let c = q_eval(&q, p);
            if c < best.0 {
                best = (c, p);
            }
        }
        (best.0.max(0.0) + tie, best.1)
    }

    /// Whether moving vertex `w` (one end of the edge, the other being `o`) to `p` keeps
    /// every triangle of `w` not on the edge turned by less than ~80 degrees and non-degenerate.
    fn keeps_orientation(&self, w: u32, o: u32, p: P) -> bool {
        for &t in &self.vtris[w as usize] {
            let tri = self.tris[t as usize];
            if tri.contains(&o) {
                continue;
            }
            let pts = tri.map(|x| self.pos[x as usize]);
            let moved = tri.map(|x| if x == w { p } else { self.pos[x as usize] });
            let n0 = cross(sub(pts[1], pts[0]), sub(pts[2], pts[0]));
            let n1 = cross(sub(moved[1], moved[0]), sub(moved[2], moved[0]));
            let (l0, l1) = (dot(n0, n0).sqrt(), dot(n1, n1).sqrt());
            if l1 <= 1e-12 * l0.max(1e-300) || dot(n0, n1) < 0.17 * l0 * l1 {
                return false;
            }
        }
        true
    }
}

/// Outcome of [`State::try_collapse`].
enum Collapse {
    Done,
    Refused,
    NotAnEdge,
}

impl State {
    /// Collapses `u` into `v` at the planned position when the checks of the module docs pass.
    fn try_collapse(&mut self, u: u32, v: u32, nu: &mut Vec<u32>, nv: &mut Vec<u32>) -> Collapse {
        // The edge must be shared by exactly two triangles (interior of a closed surface).
        let mut on_edge = [0u32; 2];
        let mut count = 0;
        for &t in &self.vtris[u as usize] {
            if self.tris[t as usize].contains(&v) {
                if count == 2 {
                    return Collapse::NotAnEdge;
                }
                on_edge[count] = t;
                count += 1;
            }
        }
        if count != 2 {
            return Collapse::NotAnEdge;
        }
        self.neighbours_into(u, nu);
        self.neighbours_into(v, nv);
        let common = nu.iter().filter(|x| nv.binary_search(x).is_ok()).count();
        let valence = nu.len() + nv.len() - 2 - common;
        let opposite_shared = on_edge.iter().all(|&t| {
            self.tris[t as usize]
                .iter()
                .find(|&&x| x != u && x != v)
                .is_some_and(|o| nu.binary_search(o).is_ok() && nv.binary_search(o).is_ok())
        });
        if common != 2 || !opposite_shared || !(3..=MAX_VALENCE).contains(&valence) {
            return Collapse::Refused;
        }
        let (_, p) = self.plan(u, v);
        if !self.keeps_orientation(u, v, p) || !self.keeps_orientation(v, u, p) {
            return Collapse::Refused;
        }
        for &t in &on_edge {
            self.alive[t as usize] = false;
            for &w in &self.tris[t as usize] {
                if w != u {
                    self.vtris[w as usize].retain(|&x| x != t);
                }
            }
        }
        let moved = std::mem::take(&mut self.vtris[u as usize]);
        for &t in &moved {
            if !self.alive[t as usize] {
                continue;
            }
            for w in self.tris[t as usize].iter_mut() {
                if *w == u {
                    *w = v;
                }
            }
            self.vtris[v as usize].push(t);
        }
        self.pos[v as usize] = p;
        self.quad[v as usize] = q_add(&self.quad[v as usize], &self.quad[u as usize]);
        Collapse::Done
    }
}

/// Simplifies `mesh` by edge collapses until it has at most `max_triangles` triangles or no
/// collapse passes the checks (module docs). Normals are dropped (recompute them, e.g. from the
/// scene's field gradient).
pub fn simplify(mesh: &Mesh, max_triangles: usize) -> Result<(Mesh, SimplifyReport)> {
    simplify_with_progress(mesh, max_triangles, &relief_heightfield::NoProgress)
}

/// [`simplify`], asking `progress` whether to stop ([`Progress::stopped`]) before every pass
/// and every 4096 queued edges; then [`Error::Stopped`], no mesh. A mesh already
/// within the budget is returned without asking.
pub fn simplify_with_progress(
    mesh: &Mesh,
    max_triangles: usize,
    progress: &dyn Progress,
) -> Result<(Mesh, SimplifyReport)> {
    let nv = mesh.positions.len();
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= nv))
    {
        return Err(Error::param(
            "triangle",
            format!("{t:?}"),
            "refers to a vertex past the end of the positions",
        ));
    }
    let mut report = SimplifyReport {
        triangles_in: mesh.triangles.len(),
        triangles_out: mesh.triangles.len(),
        refused: 0,
        passes: 0,
    };
    if mesh.triangles.len() <= max_triangles {
        let mut m = mesh.clone();
        m.normals.clear();
        return Ok((m, report));
    }
    let pos: Vec<P> = mesh
        .positions
        .iter()
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect();
    let mut valence = vec![0u32; nv];
    for t in &mesh.triangles {
        for &v in t {
            valence[v as usize] += 1;
        }
    }
    let mut vtris: Vec<Vec<u32>> = valence
        .iter()
        .map(|&n| Vec::with_capacity(n as usize + 2))
        .collect();
    let mut quad: Vec<Quadric> = vec![[0.0; 10]; nv];
    for (k, t) in mesh.triangles.iter().enumerate() {
        let q = plane_quadric(pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]);
        for &v in t {
            vtris[v as usize].push(k as u32);
            quad[v as usize] = q_add(&quad[v as usize], &q);
        }
    }
    let mut st = State {
        pos,
        tris: mesh.triangles.clone(),
        alive: vec![true; mesh.triangles.len()],
        vtris,
        quad,
    };
    let mut alive_count = mesh.triangles.len();
    // Pass number in which a vertex last received a collapse (its queued cost is stale).
    let mut touched = vec![0u32; nv];
    let mut pass = 0u32;
    let (mut nu, mut nv_) = (Vec::new(), Vec::new());
    while alive_count > max_triangles {
        if progress.stopped() {
            return Err(Error::Stopped("simplifying"));
        }
        pass += 1;
        // Every undirected edge once: a closed, consistently oriented mesh holds each edge
        // once in each direction (duplicates of other meshes are removed after the sort).
        let edges: Vec<(u32, u32)> = st
            .tris
            .iter()
            .zip(&st.alive)
            .filter(|(_, a)| **a)
            .flat_map(|(t, _)| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
            .filter(|(a, b)| a < b)
            .collect();
        let mut queue: Vec<(u64, u32, u32)> = edges
            .par_iter()
            .map(|&(u, v)| (st.plan(u, v).0.to_bits(), u, v))
            .collect();
        queue.par_sort_unstable();
        queue.dedup();
        // Collapses wanted (each removes two triangles); one pass goes at most through the
        // cheaper half of the edges, so the coarsening stays cheapest-first across passes.
        let need = (alive_count - max_triangles).div_ceil(2);
        let mut done = 0usize;
        for (k, &(_, u, v)) in queue[..queue.len().div_ceil(2)].iter().enumerate() {
            if done >= need {
                break;
            }
            if k % POLL_EVERY == POLL_EVERY - 1 && progress.stopped() {
                return Err(Error::Stopped("simplifying"));
            }
            if touched[u as usize] == pass || touched[v as usize] == pass {
                continue;
            }
            match st.try_collapse(u, v, &mut nu, &mut nv_) {
                Collapse::Done => {
                    alive_count -= 2;
                    done += 1;
                    touched[v as usize] = pass;
                    touched[u as usize] = pass;
                }
                Collapse::Refused => report.refused += 1,
                Collapse::NotAnEdge => {}
            }
        }
        report.passes += 1;
        if done == 0 {
            break;
        }
    }
    // Compact.
    let mut remap = vec![u32::MAX; nv];
    let mut out = Mesh::default();
    for (t, &a) in st.tris.iter().zip(&st.alive) {
        if !a {
            continue;
        }
        let mut tri = [0u32; 3];
        for (k, &w) in t.iter().enumerate() {
            if remap[w as usize] == u32::MAX {
                remap[w as usize] = out.positions.len() as u32;
                let p = st.pos[w as usize];
                out.positions.push([p[0] as f32, p[1] as f32, p[2] as f32]);
            }
            tri[k] = remap[w as usize];
        }
        out.triangles.push(tri);
    }
    report.triangles_out = out.triangles.len();
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology;

    /// A closed UV sphere of `n` rings.
    fn sphere(n: usize) -> Mesh {
        let mut m = Mesh::default();
        m.positions.push([0.0, 0.0, 1.0]);
        for i in 1..n {
            let th = std::f32::consts::PI * i as f32 / n as f32;
            for j in 0..2 * n {
                let ph = std::f32::consts::PI * j as f32 / n as f32;
                m.positions
                    .push([th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()]);
            }
        }
        m.positions.push([0.0, 0.0, -1.0]);
        let w = 2 * n as u32;
        let ring = |i: u32, j: u32| 1 + i * w + (j % w);
        let last = m.positions.len() as u32 - 1;
        for j in 0..w {
            m.triangles.push([0, ring(0, j), ring(0, j + 1)]);
            m.triangles
                .push([last, ring(n as u32 - 2, j + 1), ring(n as u32 - 2, j)]);
        }
        for i in 0..n as u32 - 2 {
            for j in 0..w {
                m.triangles
                    .push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
                m.triangles
                    .push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
            }
        }
        m
    }

    #[test]
    fn sphere_simplified_stays_watertight_and_round() {
        let m = sphere(40);
        let t0 = topology(&m);
        assert_eq!((t0.bad_edges, t0.misoriented_edges, t0.euler), (0, 0, 2));
        let (s, rep) = simplify(&m, 400).unwrap();
        let t = topology(&s);
        assert!(s.triangles.len() <= 400, "{rep:?}");
        assert!(s.triangles.len() > 300, "{rep:?}");
        assert_eq!(
            (t.bad_edges, t.misoriented_edges, t.euler),
            (0, 0, 2),
            "{t:?}"
        );
        for p in &s.positions {
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            assert!((r - 1.0).abs() < 0.05, "vertex off the sphere: {r}");
        }
        // Below the budget nothing changes.
        let (same, _) = simplify(&m, m.triangles.len()).unwrap();
        assert_eq!(same.triangles, m.triangles);
        assert!(
            simplify(
                &Mesh {
                    positions: vec![[0.0; 3]],
                    normals: vec![],
                    triangles: vec![[0, 1, 2]],
                    colours: vec![],
                },
                0
            )
            .is_err()
        );
    }

    /// Says stop from its `after`-th question on, and counts the questions.
    struct StopAfter(std::sync::atomic::AtomicUsize, usize);
    impl Progress for StopAfter {
        fn stopped(&self) -> bool {
            self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed) >= self.1
        }
    }

    /// The brief's `--max-time` rule: the collapse loop asks `Progress::stopped` before every
    /// pass and every `POLL_EVERY` queued edges and then ends with `Error::Stopped`, no mesh;
    /// a run never told to stop gives exactly the mesh and report of `simplify`.
    #[test]
    fn stops_when_asked_and_is_unchanged_otherwise() {
        let m = sphere(60);
        let stopped = Err(Error::Stopped("simplifying"));
        let up_front = simplify_with_progress(&m, 1000, &StopAfter(Default::default(), 0));
        assert_eq!(up_front, stopped);
        // The first question (before pass 1) says go on, the second comes inside pass 1,
        // after `POLL_EVERY` queued edges (the sphere has ~21,000 edges, so pass 1 queues
        // over 10,000 before it reaches its collapse target).
        let in_pass = simplify_with_progress(&m, 1000, &StopAfter(Default::default(), 1));
        assert_eq!(in_pass, stopped);
        let never = StopAfter(Default::default(), usize::MAX);
        let (a, ra) = simplify_with_progress(&m, 1000, &never).unwrap();
        let asked = never.0.load(std::sync::atomic::Ordering::Relaxed);
        assert!(asked > ra.passes, "{asked} questions in {ra:?}");
        let (b, rb) = simplify(&m, 1000).unwrap();
        assert_eq!((a, ra), (b, rb));
        // Within the budget there is nothing to stop.
        let (same, _) =
            simplify_with_progress(&m, m.triangles.len(), &StopAfter(Default::default(), 0))
                .unwrap();
        assert_eq!(same.triangles, m.triangles);
    }

    #[test]
    fn passes_are_independent_of_the_thread_count() {
        let m = sphere(60);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| simplify(&m, 1000).unwrap())
        };
        let (a, ra) = run(1);
        let (b, rb) = run(2);
        assert_eq!(ra, rb);
        assert!(ra.passes >= 2, "{ra:?}");
        assert_eq!(a, b);
        let t = topology(&a);
        assert_eq!((t.bad_edges, t.misoriented_edges, t.euler), (0, 0, 2));
    }
}
