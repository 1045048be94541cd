//! Chunked polygonisation by marching tetrahedra (Kuhn triangulation of each grid cube into six
//! tetrahedra around its main diagonal).
//!
//! The grid is processed in chunks of `chunk^3` cells: each chunk samples only its own
//! `(chunk + 1)^3` nodes, so memory is bounded by the chunk plus the output mesh, never a dense
//! grid of the whole scene. Chunks whose Lipschitz bound proves they hold no surface are skipped
//! without sampling (interval bounds of the field over the chunk); inside a sampled chunk, blocks
//! of 8^3 nodes proven all air or all matter (with a one-cell margin) are not evaluated either,
//! and undecided blocks are split in eight down to 2^3 nodes before any node is evaluated
//! (about 2.5x fewer evaluations than 8^3 blocks alone, the same mesh as the dense grid).
//! Edge-vertex slots are kept for two node layers only, and only vertices on a chunk face go
//! through the weld hash map.
//! Vertex normals come from the analytic field gradient
//! ([`crate::TerrainTree::eval_shading_grad`]: the DEM surface's slopes interpolated from its
//! nodes, so the relief shades smoothly). Vertices lie on lattice edges and are welded across
//! chunk borders by a
//! global edge key (lower node index, edge direction), so the mesh is watertight. Because the
//! Kuhn triangulation is consistent between neighbouring cubes and the sign test is strict
//! (`inside <=> f > T`), the piecewise-linear iso-surface is a closed 2-manifold: every edge is
//! shared by exactly two consistently oriented triangles (when `close_boundary` makes the grid
//! border air).

// Edge keys are already well spread integers: FxHash instead of SipHash (which was a third of
// the meshing time). The map is only looked up, never iterated, so the hash does not change
// the output.
use rustc_hash::FxHashMap;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::math::{Aabb, V3, add, cross, dot, mul, sub};
use crate::scene::Scene;
use crate::tree::THRESHOLD;

/// A triangle mesh as plain arrays.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions (m).
    pub positions: Vec<[f32; 3]>,
    /// Outward unit vertex normals from the field gradient (empty for [`polygonize_grid`]).
    pub normals: Vec<[f32; 3]>,
    /// Counter-clockwise triangles seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// sRGB vertex colours, alpha 255 ([`crate::material::vertex_colours`]: rock by stratum,
    /// soil on gentle slopes); empty when not computed.
    pub colours: Vec<[u8; 4]>,
}

/// Polygonisation settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshSettings {
    /// Region to mesh; `None` = the scene's box grown by one cell.
    pub bbox: Option<Aabb>,
    /// Grid cells along x, y, z.
    pub cells: [usize; 3],
    /// Chunk edge in cells.
    pub chunk: usize,
    /// Treat the grid border as air so the mesh is closed even where matter touches it.
    pub close_boundary: bool,
    /// Compute vertex normals from the field gradient.
    pub normals: bool,
}
impl Default for MeshSettings {
    fn default() -> Self {
        Self {
            bbox: None,
            cells: [128, 128, 64],
            chunk: 32,
            close_boundary: true,
            normals: true,
        }
    }
}

/// Work done by [`polygonize`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MeshReport {
    /// Chunks in the grid.
    pub chunks: usize,
    /// Chunks sampled (the others were proven empty).
    pub chunks_sampled: usize,
    /// Field evaluations for sampling (normals excluded).
    pub evaluations: usize,
}

/// Edge (in nodes) of the blocks culled by interval arithmetic inside a sampled chunk; a
/// block not proven all air or all matter is split in eight down to [`MIN_BLOCK`].
const BLOCK: usize = 8;
/// Smallest block tested by interval arithmetic (its nodes are evaluated when undecided).
const MIN_BLOCK: usize = 2;

/// Node values of one chunk, filled block by block (see [`Fill::block`]).
struct Fill<'a> {
    scene: &'a Scene,
    g: &'a Grid,
    lo: [usize; 3],
    d: [usize; 3],
    close: bool,
    vals: &'a mut [f32],
    evals: &'a mut usize,
}

impl Fill<'_> {
    /// Fills the nodes `b .. b + size` (clamped to the chunk): a block whose box grown by one
    /// cell is proven all air or all matter by interval arithmetic gets a constant (no edge
    /// from it crosses the surface, so its exact values are never interpolated); an undecided
    /// one is split in eight, and evaluated node by node at [`MIN_BLOCK`].
    fn block(&mut self, b: [usize; 3], size: usize) {
        let (g, lo, d) = (self.g, self.lo, self.d);
        let e = [
            (b[0] + size).min(d[0]),
            (b[1] + size).min(d[1]),
            (b[2] + size).min(d[2]),
        ];
        let pa = g.pos(lo[0] + b[0], lo[1] + b[1], lo[2] + b[2]);
        let pb = g.pos(lo[0] + e[0] - 1, lo[1] + e[1] - 1, lo[2] + e[2] - 1);
        let bb = Aabb::new(sub(pa, g.step), add(pb, g.step));
        let (blo, bhi) = self.scene.interval(&bb);
        let fill = if bhi <= THRESHOLD {
            Some(0.0)
        } else if blo > THRESHOLD {
            Some(2.0 * THRESHOLD)
        } else {
            None
        };
        if fill.is_none() && size > MIN_BLOCK {
            let h = size / 2;
            for k in [b[2], b[2] + h] {
                for j in [b[1], b[1] + h] {
                    for i in [b[0], b[0] + h] {
                        if i < e[0] && j < e[1] && k < e[2] {
                            self.block([i, j, k], h);
                        }
                    }
                }
            }
            return;
        }
        for k in b[2]..e[2] {
            for j in b[1]..e[1] {
                for i in b[0]..e[0] {
                    let (gi, gj, gk) = (lo[0] + i, lo[1] + j, lo[2] + k);
                    let mut v = match fill {
                        Some(v) => v,
                        None => {
                            *self.evals += 1;
                            self.scene.field(g.pos(gi, gj, gk))
                        }
                    };
                    let border = gi == 0
                        || gj == 0
                        || gk == 0
                        || gi == g.n[0]
                        || gj == g.n[1]
                        || gk == g.n[2];
                    if self.close && border {
                        v = v.min(THRESHOLD);
                    }
                    self.vals[(k * d[1] + j) * d[0] + i] = v;
                }
            }
        }
    }
}

// The six Kuhn tetrahedra: corner offsets as bit masks (bit 0 = x, 1 = y, 2 = z).
const TETS: [[u8; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

struct Grid {
    origin: V3,
    step: V3,
    n: [usize; 3], // cells
}
impl Grid {
    fn node_id(&self, i: usize, j: usize, k: usize) -> u64 {
        ((k * (self.n[1] + 1) + j) * (self.n[0] + 1) + i) as u64
    }
    fn pos(&self, i: usize, j: usize, k: usize) -> V3 {
        [
            self.origin[0] + i as f32 * self.step[0],
            self.origin[1] + j as f32 * self.step[1],
            self.origin[2] + k as f32 * self.step[2],
        ]
    }
}

/// Weld key of a vertex on a lattice edge inside a chunk (never shared with another chunk).
const INTERIOR: u64 = u64::MAX;

struct ChunkOut {
    keys: Vec<u64>,
    pos: Vec<V3>,
    tris: Vec<[u32; 3]>,
}

/// Marching tetrahedra over the cells `lo..hi` with node values from `val(i, j, k)` (local
/// buffer of `(hi - lo + 1)` nodes per axis).
fn march_chunk(g: &Grid, lo: [usize; 3], hi: [usize; 3], vals: &[f32], iso: f32) -> ChunkOut {
    let d = [hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1];
    let at = |i: usize, j: usize, k: usize| vals[(k * d[1] + j) * d[0] + i];
    let mut out = ChunkOut {
        keys: Vec::new(),
        pos: Vec::new(),
        tris: Vec::new(),
    };
    // Vertex ids of this chunk's lattice edges: (local node, direction bits) -> id, for two
    // node layers only: the cubes of layer k use edges from nodes of layers k and k + 1, so
    // the slots of layer k - 1 are cleared and reused for layer k + 1 (a small buffer that
    // stays in cache instead of one slot per edge of the chunk).
    let layer = d[0] * d[1] * 8;
    let mut local = vec![u32::MAX; 2 * layer];
    for k in 0..d[2] - 1 {
        if k > 0 {
            let r = ((k + 1) % 2) * layer;
            local[r..r + layer].fill(u32::MAX);
        }
        for j in 0..d[1] - 1 {
            for i in 0..d[0] - 1 {
                let mut cv = [0f32; 8];
                let mut any_in = false;
                let mut any_out = false;
                for (c, v) in cv.iter_mut().enumerate() {
                    *v = at(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                    if *v > iso {
                        any_in = true
                    } else {
                        any_out = true
                    }
                }
                if !(any_in && any_out) {
                    continue;
                }
                let (gi, gj, gk) = (lo[0] + i, lo[1] + j, lo[2] + k);
                let corner = |c: u8| {
                    [
                        gi + (c & 1) as usize,
                        gj + ((c >> 1) & 1) as usize,
                        gk + ((c >> 2) & 1) as usize,
                    ]
                };
                let mut vert = |a: u8, b: u8, out: &mut ChunkOut| -> u32 {
                    // Edge from the lower corner to the upper one (Kuhn edges are monotone).
                    let (a, b) = if a < b { (a, b) } else { (b, a) };
                    let ca = corner(a);
                    let l = [ca[0] - lo[0], ca[1] - lo[1], ca[2] - lo[2]];
                    let dir = (a ^ b) as usize;
                    let slot = (((l[2] % 2) * d[1] + l[1]) * d[0] + l[0]) * 8 + dir;
                    if local[slot] != u32::MAX {
                        return local[slot];
                    }
                    // Only edges in a face of the chunk can be shared with another chunk:
                    // those get their global key for welding, the others none.
                    let on_face =
                        (0..3).any(|x| dir & (1 << x) == 0 && (l[x] == 0 || l[x] == d[x] - 1));
                    let key = if on_face {
                        g.node_id(ca[0], ca[1], ca[2]) * 8 + dir as u64
                    } else {
                        INTERIOR
                    };
                    let (va, vb) = (cv[a as usize], cv[b as usize]);
                    let t = ((iso - va) / (vb - va)).clamp(0.0, 1.0);
                    let cb = corner(b);
                    let pa = g.pos(ca[0], ca[1], ca[2]);
                    let pb = g.pos(cb[0], cb[1], cb[2]);
                    let p = add(pa, mul(sub(pb, pa), t));
                    let id = out.pos.len() as u32;
                    out.pos.push(p);
                    out.keys.push(key);
                    local[slot] = id;
                    id
                };
                for tet in TETS {
                    let (mut ins_a, mut outs_a) = ([0u8; 4], [0u8; 4]);
                    let (mut ni, mut no) = (0, 0);
                    for c in tet {
                        if cv[c as usize] > iso {
                            ins_a[ni] = c;
                            ni += 1;
                        } else {
                            outs_a[no] = c;
                            no += 1;
                        }
                    }
                    if ni == 0 || no == 0 {
                        continue;
                    }
                    let (ins, outs) = (&ins_a[..ni], &outs_a[..no]);
                    let cen = |cs: &[u8]| {
                        let mut s = [0.0; 3];
                        for &c in cs {
                            let q = corner(c);
                            s = add(s, g.pos(q[0], q[1], q[2]));
                        }
                        mul(s, 1.0 / cs.len() as f32)
                    };
                    let outward = sub(cen(outs), cen(ins));
                    // The winding is decided on the lattice-edge midpoints, never degenerate
                    // (interpolated vertices may coincide when a value equals the iso-level).
                    let mid = |e: (u8, u8)| {
                        let (qa, qb) = (corner(e.0), corner(e.1));
                        mul(
                            add(g.pos(qa[0], qa[1], qa[2]), g.pos(qb[0], qb[1], qb[2])),
                            0.5,
                        )
                    };
                    let emit = |tri: [u32; 3], e: [(u8, u8); 3], out: &mut ChunkOut| {
                        let (p0, p1, p2) = (mid(e[0]), mid(e[1]), mid(e[2]));
                        let n = cross(sub(p1, p0), sub(p2, p0));
                        if dot(n, outward) >= 0.0 {
                            out.tris.push(tri);
                        } else {
                            out.tris.push([tri[0], tri[2], tri[1]]);
                        }
                    };
                    match (ins.len(), outs.len()) {
                        (1, 3) => {
                            let e = [(ins[0], outs[0]), (ins[0], outs[1]), (ins[0], outs[2])];
                            let t = e.map(|(a, b)| vert(a, b, &mut out));
                            emit(t, e, &mut out);
                        }
                        (3, 1) => {
                            let e = [(outs[0], ins[0]), (outs[0], ins[1]), (outs[0], ins[2])];
                            let t = e.map(|(a, b)| vert(a, b, &mut out));
                            emit(t, e, &mut out);
                        }
                        _ => {
                            let (a, b, c, dd) = (ins[0], ins[1], outs[0], outs[1]);
                            let e = [(a, c), (a, dd), (b, dd), (b, c)];
                            let q = e.map(|(x, y)| vert(x, y, &mut out));
                            emit([q[0], q[1], q[2]], [e[0], e[1], e[2]], &mut out);
                            emit([q[0], q[2], q[3]], [e[0], e[2], e[3]], &mut out);
                        }
                    }
                }
            }
        }
    }
    out
}

fn chunks_of(n: [usize; 3], c: usize) -> Vec<([usize; 3], [usize; 3])> {
    let mut v = Vec::new();
    for k in (0..n[2]).step_by(c) {
        for j in (0..n[1]).step_by(c) {
            for i in (0..n[0]).step_by(c) {
                v.push((
                    [i, j, k],
                    [(i + c).min(n[0]), (j + c).min(n[1]), (k + c).min(n[2])],
                ));
            }
        }
    }
    v
}

fn weld(chunks: Vec<ChunkOut>) -> Mesh {
    let mut map: FxHashMap<u64, u32> = FxHashMap::default();
    let mut mesh = Mesh::default();
    for ch in chunks {
        let remap: Vec<u32> = ch
            .keys
            .iter()
            .zip(&ch.pos)
            .map(|(k, p)| {
                if *k == INTERIOR {
                    mesh.positions.push(*p);
                    return mesh.positions.len() as u32 - 1;
                }
                *map.entry(*k).or_insert_with(|| {
                    mesh.positions.push(*p);
                    mesh.positions.len() as u32 - 1
                })
            })
            .collect();
        mesh.triangles.extend(ch.tris.iter().map(|t| {
            [
                remap[t[0] as usize],
                remap[t[1] as usize],
                remap[t[2] as usize],
            ]
        }));
    }
    mesh
}

/// Polygonises the surface `f = T` of `scene` (see module docs).
pub fn polygonize(scene: &Scene, s: &MeshSettings) -> Result<(Mesh, MeshReport)> {
    polygonize_with_progress(scene, s, &relief_heightfield::NoProgress)
}

/// [`polygonize`], asking `progress` whether to stop before every chunk
/// ([`relief_heightfield::Progress::stopped`]; then [`Error::Stopped`], no mesh).
pub fn polygonize_with_progress(
    scene: &Scene,
    s: &MeshSettings,
    progress: &dyn relief_heightfield::Progress,
) -> Result<(Mesh, MeshReport)> {
    if s.cells.iter().any(|&c| c == 0 || c > 1 << 14) {
        return Err(Error::param(
            "cells",
            format!("{:?}", s.cells),
            "each must be in 1..=16384",
        ));
    }
    if s.chunk < 2 || s.chunk > 256 {
        return Err(Error::param("chunk", s.chunk, "must be in 2..=256"));
    }
    let bbox = match s.bbox {
        Some(b) if b.is_finite() && b.size().iter().all(|&v| v > 0.0) => b,
        Some(b) => {
            return Err(Error::param(
                "bbox",
                format!("{b:?}"),
                "must be finite with a positive size on every axis",
            ));
        }
        None => {
            let b = scene.bbox();
            let sz = b.size();
            let pad = (0..3)
                .map(|k| sz[k] / s.cells[k] as f32)
                .fold(0.0, f32::max);
            b.inflate(pad)
        }
    };
    let sz = bbox.size();
    let g = Grid {
        origin: bbox.min,
        step: [
            sz[0] / s.cells[0] as f32,
            sz[1] / s.cells[1] as f32,
            sz[2] / s.cells[2] as f32,
        ],
        n: s.cells,
    };
    let chunks = chunks_of(s.cells, s.chunk);
    let stop = std::sync::atomic::AtomicBool::new(false);
    let results: Vec<(Option<ChunkOut>, usize)> = chunks
        .par_iter()
        .map(|&(lo, hi)| {
            use std::sync::atomic::Ordering::Relaxed;
            if stop.load(Relaxed) || progress.stopped() {
                stop.store(true, Relaxed);
                return (None, 0);
            }
            let cb = Aabb::new(g.pos(lo[0], lo[1], lo[2]), g.pos(hi[0], hi[1], hi[2]));
            let touches = (0..3).any(|k| lo[k] == 0 || hi[k] == g.n[k]);
            let (flo, fhi) = scene.interval(&cb);
            if fhi <= THRESHOLD || (flo > THRESHOLD && !(s.close_boundary && touches)) {
                return (None, 0);
            }
            let d = [hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1];
            let mut vals = vec![0f32; d[0] * d[1] * d[2]];
            let mut evals = 0usize;
            let mut fill = Fill {
                scene,
                g: &g,
                lo,
                d,
                close: s.close_boundary,
                vals: &mut vals,
                evals: &mut evals,
            };
            for bk in (0..d[2]).step_by(BLOCK) {
                for bj in (0..d[1]).step_by(BLOCK) {
                    for bi in (0..d[0]).step_by(BLOCK) {
                        fill.block([bi, bj, bk], BLOCK);
                    }
                }
            }
            (Some(march_chunk(&g, lo, hi, &vals, THRESHOLD)), evals)
        })
        .collect();
    if stop.into_inner() {
        return Err(Error::Stopped("meshing"));
    }
    let mut report = MeshReport {
        chunks: chunks.len(),
        ..Default::default()
    };
    let mut outs = Vec::new();
    for (o, e) in results {
        report.evaluations += e;
        if let Some(o) = o {
            report.chunks_sampled += 1;
            outs.push(o);
        }
    }
    let mut mesh = weld(outs);
    if s.normals {
        let h = 0.5 * g.step.iter().cloned().fold(f32::INFINITY, f32::min);
        field_normals(scene, &mut mesh, h);
    }
    Ok((mesh, report))
}

/// Outward unit normals of `mesh`'s vertices from the scene's field gradient (central
/// differences of step `h` metres where the gradient is not analytic; the DEM surface's
/// slopes interpolated from its nodes, [`Scene::shading_normal`]), in parallel.
pub fn field_normals(scene: &Scene, mesh: &mut Mesh, h: f32) {
    mesh.normals = mesh
        .positions
        .par_iter()
        .map(|&p| scene.shading_normal(p, h))
        .collect();
}

/// Samples the scene field on a grid of `dims` nodes spanning `bbox` (x fastest, then y, then
/// z), in parallel. Meant for comparisons with other meshers; [`polygonize`] never builds it.
pub fn sample_grid(scene: &Scene, bbox: &Aabb, dims: [usize; 3]) -> Result<Vec<f32>> {
    if dims.iter().any(|&d| d < 2) {
        return Err(Error::param(
            "dims",
            format!("{dims:?}"),
            "each must be >= 2",
        ));
    }
    let sz = bbox.size();
    let st = [
        sz[0] / (dims[0] - 1) as f32,
        sz[1] / (dims[1] - 1) as f32,
        sz[2] / (dims[2] - 1) as f32,
    ];
    let mut out = vec![0f32; dims[0] * dims[1] * dims[2]];
    out.par_chunks_mut(dims[0])
        .enumerate()
        .for_each(|(r, row)| {
            let (j, k) = (r % dims[1], r / dims[1]);
            for (i, v) in row.iter_mut().enumerate() {
                *v = scene.field([
                    bbox.min[0] + i as f32 * st[0],
                    bbox.min[1] + j as f32 * st[1],
                    bbox.min[2] + k as f32 * st[2],
                ]);
            }
        });
    Ok(out)
}

/// Marching tetrahedra on a precomputed grid of `dims` nodes (x fastest), chunked and parallel
/// like [`polygonize`]; no normals.
pub fn polygonize_grid(
    values: &[f32],
    dims: [usize; 3],
    origin: V3,
    spacing: V3,
    iso: f32,
    chunk: usize,
) -> Result<Mesh> {
    if dims.iter().any(|&d| d < 2) || values.len() != dims[0] * dims[1] * dims[2] {
        return Err(Error::param(
            "dims",
            format!("{dims:?} for {} values", values.len()),
            "need >= 2 nodes per axis and a matching buffer",
        ));
    }
    if chunk < 2 {
        return Err(Error::param("chunk", chunk, "must be >= 2"));
    }
    let n = [dims[0] - 1, dims[1] - 1, dims[2] - 1];
    let g = Grid {
        origin,
        step: spacing,
        n,
    };
    let outs: Vec<ChunkOut> = chunks_of(n, chunk)
        .par_iter()
        .map(|&(lo, hi)| {
            let d = [hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1];
            let mut vals = Vec::with_capacity(d[0] * d[1] * d[2]);
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    let r = (k * dims[1] + j) * dims[0];
                    vals.extend_from_slice(&values[r + lo[0]..=r + hi[0]]);
                }
            }
            march_chunk(&g, lo, hi, &vals, iso)
        })
        .collect();
    Ok(weld(outs))
}

/// Topology summary of a triangle mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Topology {
    /// Vertices referenced by triangles.
    pub vertices: usize,
    /// Distinct undirected edges.
    pub edges: usize,
    /// Triangles.
    pub faces: usize,
    /// Edges not shared by exactly two triangles.
    pub bad_edges: usize,
    /// Directed edges used twice (inconsistent orientation).
    pub misoriented_edges: usize,
    /// Euler characteristic `V - E + F`.
    pub euler: i64,
}

/// Counts edges, checks that every edge is shared by exactly two triangles with opposite
/// directions, and computes the Euler characteristic.
pub fn topology(mesh: &Mesh) -> Topology {
    // Sorted edge lists (8 bytes per half-edge) instead of hash maps: a 20M-triangle mesh is
    // checked in ~0.5 GB.
    let mut used = vec![false; mesh.positions.len()];
    let mut e: Vec<u64> = Vec::with_capacity(mesh.triangles.len() * 3);
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if let Some(u) = used.get_mut(a as usize) {
                *u = true;
            }
            e.push(((a as u64) << 32) | b as u64);
        }
    }
    // Runs of equal keys in a sorted list: (number of distinct keys, keys whose run != want).
    let runs = |v: &[u64], want: usize| {
        let (mut distinct, mut off, mut i) = (0usize, 0usize, 0usize);
        while i < v.len() {
            let mut j = i + 1;
            while j < v.len() && v[j] == v[i] {
                j += 1;
            }
            distinct += 1;
            if j - i != want {
                off += 1;
            }
            i = j;
        }
        (distinct, off)
    };
    e.sort_unstable();
    let (_, misoriented_edges) = runs(&e, 1);
    for x in e.iter_mut() {
        let (a, b) = (*x >> 32, *x & 0xffff_ffff);
        *x = (a.min(b) << 32) | a.max(b);
    }
    e.sort_unstable();
    let (edges, bad_edges) = runs(&e, 2);
    let vertices = used.iter().filter(|&&u| u).count();
    Topology {
        vertices,
        edges,
        faces: mesh.triangles.len(),
        bad_edges,
        misoriented_edges,
        euler: vertices as i64 - edges as i64 + mesh.triangles.len() as i64,
    }
}
