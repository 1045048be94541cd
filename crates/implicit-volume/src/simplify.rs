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
//! The run is sequential and deterministic (ties broken by vertex index).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::error::{Error, Result};
use crate::mesh::Mesh;

/// Largest valence a collapse may create (keeps triangles well shaped and the cost of the
/// neighbourhood scans bounded on flat regions).
const MAX_VALENCE: usize = 16;

/// What [`simplify`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimplifyReport {
    /// Triangles before.
    pub triangles_in: usize,
    /// Triangles after.
    pub triangles_out: usize,
    /// Edge collapses refused by the topology and fold-over checks.
    pub refused: usize,
}

type Quadric = [f64; 10];
/// Queued collapse: (cost bits, u, v, stamp of u, stamp of v), cheapest first.
type Queue = BinaryHeap<Reverse<(u64, u32, u32, u32, u32)>>;
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
    stamp: Vec<u32>,
}

impl State {
    fn neighbours(&self, v: u32) -> Vec<u32> {
        let mut n: Vec<u32> = Vec::with_capacity(8);
        for &t in &self.vtris[v as usize] {
            for &w in &self.tris[t as usize] {
                if w != v {
                    n.push(w);
                }
            }
        }
        n.sort_unstable();
        n.dedup();
        n
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

/// Simplifies `mesh` by edge collapses until it has at most `max_triangles` triangles or no
/// collapse passes the checks (module docs). Normals are dropped (recompute them, e.g. from the
/// scene's field gradient).
pub fn simplify(mesh: &Mesh, max_triangles: usize) -> Result<(Mesh, SimplifyReport)> {
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
    let mut vtris: Vec<Vec<u32>> = vec![Vec::new(); nv];
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
        stamp: vec![0; nv],
    };
    let mut heap: Queue = BinaryHeap::new();
    let push_edge = |st: &State, heap: &mut Queue, a: u32, b: u32| {
        let (u, v) = if a < b { (a, b) } else { (b, a) };
        let (c, _) = st.plan(u, v);
        heap.push(Reverse((
            c.to_bits(),
            u,
            v,
            st.stamp[u as usize],
            st.stamp[v as usize],
        )));
    };
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a < b {
                push_edge(&st, &mut heap, a, b);
            } else {
                // Each undirected edge of a closed mesh appears once in each direction; the
                // lower-to-higher one is enough (open edges are pushed from either side).
                let shared = st.vtris[a as usize]
                    .iter()
                    .filter(|&&x| st.tris[x as usize].contains(&b))
                    .count();
                if shared < 2 {
                    push_edge(&st, &mut heap, a, b);
                }
            }
        }
    }
    let mut alive_count = mesh.triangles.len();
    while alive_count > max_triangles {
        let Some(Reverse((_, u, v, su, sv))) = heap.pop() else {
            break;
        };
        if st.stamp[u as usize] != su || st.stamp[v as usize] != sv {
            continue;
        }
        // The edge must be shared by exactly two triangles (interior of a closed surface).
        let on_edge: Vec<u32> = st.vtris[u as usize]
            .iter()
            .copied()
            .filter(|&t| st.tris[t as usize].contains(&v))
            .collect();
        if on_edge.len() != 2 {
            continue;
        }
        let nu = st.neighbours(u);
        let nv_ = st.neighbours(v);
        let opposite: Vec<u32> = on_edge
            .iter()
            .map(|&t| {
                *st.tris[t as usize]
                    .iter()
                    .find(|&&x| x != u && x != v)
                    .unwrap_or(&u)
            })
            .collect();
        let common = nu.iter().filter(|x| nv_.binary_search(x).is_ok()).count();
        let valence = nu.len() + nv_.len() - 2 - common;
        if common != 2
            || !opposite.iter().all(|o| nu.contains(o) && nv_.contains(o))
            || !(3..=MAX_VALENCE).contains(&valence)
        {
            report.refused += 1;
            continue;
        }
        let (_, p) = st.plan(u, v);
        if !st.keeps_orientation(u, v, p) || !st.keeps_orientation(v, u, p) {
            report.refused += 1;
            continue;
        }
        // Collapse u into v at p.
        for &t in &on_edge {
            st.alive[t as usize] = false;
            alive_count -= 1;
            for &w in &st.tris[t as usize] {
                if w != u {
                    st.vtris[w as usize].retain(|&x| x != t);
                }
            }
        }
        let moved: Vec<u32> = std::mem::take(&mut st.vtris[u as usize])
            .into_iter()
            .filter(|&t| st.alive[t as usize])
            .collect();
        for &t in &moved {
            for w in st.tris[t as usize].iter_mut() {
                if *w == u {
                    *w = v;
                }
            }
        }
        st.vtris[v as usize].extend(moved);
        st.pos[v as usize] = p;
        st.quad[v as usize] = q_add(&st.quad[v as usize], &st.quad[u as usize]);
        // Edges of u die with its stamp; edges of v change cost. Other edges keep their
        // endpoints' quadrics and positions, so their queued costs stay exact (the topology
        // checks run when they are popped).
        st.stamp[u as usize] = st.stamp[u as usize].wrapping_add(1);
        st.stamp[v as usize] = st.stamp[v as usize].wrapping_add(1);
        for w in st.neighbours(v) {
            push_edge(&st, &mut heap, v, w);
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
                    triangles: vec![[0, 1, 2]]
                },
                0
            )
            .is_err()
        );
    }
}
