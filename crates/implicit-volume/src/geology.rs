//! The geology tree G (paper section 3, "Geology Model", figure 2): a construction tree whose
//! leaves are skeletal primitives giving a rock resistance `rho(p)` in `[0, 1]` (0 = softest,
//! 1 = hardest) and whose internal nodes combine (blend, max, min) or deform (warp, fold, fault)
//! their sub-trees. Nodes live in a flat arena and are addressed by [`GeoId`].

use crate::error::{Error, Result};
use crate::math::{V3, add, dot, fbm, fbm3, mul, normalize, sub};

/// Index of a node in a [`Geology`] arena.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GeoId(pub u32);

/// One horizontal stratum: a thickness (m) and a hardness in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layer {
    /// Thickness in metres (> 0).
    pub thickness: f32,
    /// Resistance of the layer in `[0, 1]`.
    pub hardness: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum GeoNode {
    Uniform(f32),
    /// Layers `first..first+count` of the side table, repeated every `period` metres from `z0`.
    Strata {
        first: u32,
        count: u32,
        z0: f32,
        period: f32,
    },
    Noise {
        base: f32,
        amp: f32,
        freq: f32,
        octaves: u32,
        seed: u64,
    },
    Blend {
        a: u32,
        b: u32,
        t: f32,
    },
    Max {
        a: u32,
        b: u32,
    },
    Min {
        a: u32,
        b: u32,
    },
    Warp {
        child: u32,
        amp: f32,
        freq: f32,
        seed: u64,
    },
    Fold {
        child: u32,
        amp: f32,
        wavelength: f32,
        dir: [f32; 2],
    },
    Fault {
        child: u32,
        normal: V3,
        d: f32,
        offset: V3,
    },
}

/// A geology construction tree giving the resistance `rho(p)` (see module docs).
#[derive(Debug, Clone, Default)]
pub struct Geology {
    nodes: Vec<GeoNode>,
    layers: Vec<Layer>,
    root: Option<u32>,
}

fn check01(name: &'static str, v: f32) -> Result<()> {
    if !(0.0..=1.0).contains(&v) {
        return Err(Error::param(name, v, "must be in [0, 1]"));
    }
    Ok(())
}
fn check_pos(name: &'static str, v: f32) -> Result<()> {
    if !(v.is_finite() && v > 0.0) {
        return Err(Error::param(name, v, "must be finite and > 0"));
    }
    Ok(())
}

impl Geology {
    /// An empty tree; its resistance is 0.5 everywhere until [`Geology::set_root`] is called.
    pub fn new() -> Self {
        Self::default()
    }

    fn push(&mut self, n: GeoNode) -> GeoId {
        self.nodes.push(n);
        GeoId(self.nodes.len() as u32 - 1)
    }
    fn check_id(&self, id: GeoId) -> Result<u32> {
        if (id.0 as usize) < self.nodes.len() {
            Ok(id.0)
        } else {
            Err(Error::param(
                "geology node id",
                id.0,
                "not a node of this tree",
            ))
        }
    }

    /// Constant resistance.
    pub fn uniform(&mut self, rho: f32) -> Result<GeoId> {
        check01("rho", rho)?;
        Ok(self.push(GeoNode::Uniform(rho)))
    }

    /// Horizontal strata: `layers` stacked upwards from `z0`, repeated periodically in z.
    pub fn strata(&mut self, z0: f32, layers: &[Layer]) -> Result<GeoId> {
        if layers.is_empty() {
            return Err(Error::param("layers", 0, "need at least one layer"));
        }
        if !z0.is_finite() {
            return Err(Error::param("z0", z0, "must be finite"));
        }
        let mut period = 0.0;
        for l in layers {
            check_pos("layer.thickness", l.thickness)?;
            check01("layer.hardness", l.hardness)?;
            period += l.thickness;
        }
        let first = self.layers.len() as u32;
        self.layers.extend_from_slice(layers);
        Ok(self.push(GeoNode::Strata {
            first,
            count: layers.len() as u32,
            z0,
            period,
        }))
    }

    /// Fractal noise resistance `base + amp * fbm(p * freq)` (clamped to `[0, 1]`).
    pub fn noise(
        &mut self,
        base: f32,
        amp: f32,
        freq: f32,
        octaves: u32,
        seed: u64,
    ) -> Result<GeoId> {
        check01("base", base)?;
        check01("amp", amp)?;
        check_pos("freq", freq)?;
        if octaves == 0 || octaves > 12 {
            return Err(Error::param("octaves", octaves, "must be in 1..=12"));
        }
        Ok(self.push(GeoNode::Noise {
            base,
            amp,
            freq,
            octaves,
            seed,
        }))
    }

    /// Linear blend `(1 - t) a + t b`.
    pub fn blend(&mut self, a: GeoId, b: GeoId, t: f32) -> Result<GeoId> {
        check01("t", t)?;
        let (a, b) = (self.check_id(a)?, self.check_id(b)?);
        Ok(self.push(GeoNode::Blend { a, b, t }))
    }
    /// Pointwise maximum (the harder rock wins).
    pub fn max(&mut self, a: GeoId, b: GeoId) -> Result<GeoId> {
        let (a, b) = (self.check_id(a)?, self.check_id(b)?);
        Ok(self.push(GeoNode::Max { a, b }))
    }
    /// Pointwise minimum (the softer rock wins).
    pub fn min(&mut self, a: GeoId, b: GeoId) -> Result<GeoId> {
        let (a, b) = (self.check_id(a)?, self.check_id(b)?);
        Ok(self.push(GeoNode::Min { a, b }))
    }
    /// Noise warp: the child is evaluated at `p + amp * fbm3(p * freq)`.
    pub fn warp(&mut self, child: GeoId, amp: f32, freq: f32, seed: u64) -> Result<GeoId> {
        check_pos("amp", amp)?;
        check_pos("freq", freq)?;
        let child = self.check_id(child)?;
        Ok(self.push(GeoNode::Warp {
            child,
            amp,
            freq,
            seed,
        }))
    }
    /// Sinusoidal fold (a continuous warp): the child is evaluated at
    /// `z - amp * sin(2 pi (p . dir) / wavelength)`, with `dir` the horizontal fold direction.
    pub fn fold(
        &mut self,
        child: GeoId,
        amp: f32,
        wavelength: f32,
        direction: [f32; 2],
    ) -> Result<GeoId> {
        check_pos("amp", amp)?;
        check_pos("wavelength", wavelength)?;
        let n = (direction[0] * direction[0] + direction[1] * direction[1]).sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Err(Error::param(
                "direction",
                format!("{direction:?}"),
                "must be non-zero",
            ));
        }
        let child = self.check_id(child)?;
        Ok(self.push(GeoNode::Fold {
            child,
            amp,
            wavelength,
            dir: [direction[0] / n, direction[1] / n],
        }))
    }
    /// Fault: a half-space offset with a discontinuity across the plane `n . p = n . point`;
    /// points on the side `n` points to see the child shifted by `offset` (throw of the fault).
    pub fn fault(&mut self, child: GeoId, point: V3, normal: V3, offset: V3) -> Result<GeoId> {
        if !(point
            .iter()
            .chain(normal.iter())
            .chain(offset.iter())
            .all(|v| v.is_finite()))
            || dot(normal, normal) == 0.0
        {
            return Err(Error::param(
                "fault",
                format!("{point:?} {normal:?} {offset:?}"),
                "plane and offset must be finite, normal non-zero",
            ));
        }
        let child = self.check_id(child)?;
        let normal = normalize(normal);
        Ok(self.push(GeoNode::Fault {
            child,
            normal,
            d: dot(normal, point),
            offset,
        }))
    }
    /// Makes `id` the root of the tree.
    pub fn set_root(&mut self, id: GeoId) -> Result<()> {
        self.root = Some(self.check_id(id)?);
        Ok(())
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
    /// Bytes used by the arena (nodes and layer table).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<GeoNode>()
            + self.layers.len() * std::mem::size_of::<Layer>()
    }

    /// Resistance `rho(p)` in `[0, 1]` (0.5 for a tree without root).
    pub fn resistance(&self, p: V3) -> f32 {
        match self.root {
            Some(r) => self.eval(r, p).clamp(0.0, 1.0),
            None => 0.5,
        }
    }

    fn eval(&self, id: u32, p: V3) -> f32 {
        match self.nodes[id as usize] {
            GeoNode::Uniform(v) => v,
            GeoNode::Strata {
                first,
                count,
                z0,
                period,
            } => {
                let mut t = (p[2] - z0).rem_euclid(period);
                let ls = &self.layers[first as usize..(first + count) as usize];
                for l in ls {
                    if t < l.thickness {
                        return l.hardness;
                    }
                    t -= l.thickness;
                }
                ls[ls.len() - 1].hardness
            }
            GeoNode::Noise {
                base,
                amp,
                freq,
                octaves,
                seed,
            } => (base + amp * fbm(seed, mul(p, freq), octaves)).clamp(0.0, 1.0),
            GeoNode::Blend { a, b, t } => (1.0 - t) * self.eval(a, p) + t * self.eval(b, p),
            GeoNode::Max { a, b } => self.eval(a, p).max(self.eval(b, p)),
            GeoNode::Min { a, b } => self.eval(a, p).min(self.eval(b, p)),
            GeoNode::Warp {
                child,
                amp,
                freq,
                seed,
            } => self.eval(child, add(p, mul(fbm3(seed, mul(p, freq), 3), amp))),
            GeoNode::Fold {
                child,
                amp,
                wavelength,
                dir,
            } => {
                let s = (p[0] * dir[0] + p[1] * dir[1]) * std::f32::consts::TAU / wavelength;
                self.eval(child, [p[0], p[1], p[2] - amp * s.sin()])
            }
            GeoNode::Fault {
                child,
                normal,
                d,
                offset,
            } => {
                if dot(normal, p) > d {
                    self.eval(child, sub(p, offset))
                } else {
                    self.eval(child, p)
                }
            }
        }
    }

    /// A layered limestone-like default: alternating soft and hard strata of `period` metres,
    /// folded, blended with noise, and cut by a fault through `center` (figure 2's construction).
    pub fn layered_default(center: V3, period: f32, seed: u64) -> Result<Self> {
        let z0 = center[2];
        check_pos("period", period)?;
        let mut g = Geology::new();
        let s = g.strata(
            z0,
            &[
                Layer {
                    thickness: period * 0.35,
                    hardness: 0.15,
                },
                Layer {
                    thickness: period * 0.15,
                    hardness: 0.85,
                },
                Layer {
                    thickness: period * 0.3,
                    hardness: 0.35,
                },
                Layer {
                    thickness: period * 0.2,
                    hardness: 0.7,
                },
            ],
        )?;
        let f = g.fold(s, period * 0.3, period * 20.0, [1.0, 0.4])?;
        let n = g.noise(0.5, 0.5, 1.0 / (period * 2.0), 3, seed)?;
        let b = g.blend(f, n, 0.25)?;
        let fa = g.fault(b, center, [1.0, 0.3, 0.0], [0.0, 0.0, period * 0.4])?;
        g.set_root(fa)?;
        Ok(g)
    }
}
