//! The geology tree G (paper section 3, "Geology Model", figure 2): a construction tree whose
//! leaves are skeletal primitives giving a rock resistance `rho(p)` in `[0, 1]` (0 = softest,
//! 1 = hardest) and whose internal nodes combine (blend, max, min) or deform (warp, fold, fault)
//! their sub-trees. Nodes live in a flat arena and are addressed by [`GeoId`].

use crate::error::{Error, Result};
use crate::math::{V3, add, dot, fbm, fbm3, mul, normalize, sub};
use relief_heightfield::param::in_range;

/// Index of a node in a [`Geology`] arena.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GeoId(pub u32);

/// One horizontal stratum: a thickness (m) and a hardness in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
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
    /// Top of each layer of `layers` above its strata node's `z0` (the running sum of the
    /// node's thicknesses): a binary search finds the layer at a height in a long column.
    tops: Vec<f32>,
    root: Option<u32>,
}

fn check01(name: &'static str, v: f32) -> Result<()> {
    Ok(in_range(name, v, 0.0..=1.0, "must be in [0, 1]")?)
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
        Error::check_node("geology node id", id.0, self.nodes.len())
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
            Error::check_positive("layer.thickness", l.thickness)?;
            check01("layer.hardness", l.hardness)?;
            period += l.thickness;
        }
        let first = self.layers.len() as u32;
        self.layers.extend_from_slice(layers);
        let mut top = 0.0;
        self.tops.extend(layers.iter().map(|l| {
            top += l.thickness;
            top
        }));
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
        Error::check_positive("freq", freq)?;
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
        Error::check_positive("amp", amp)?;
        Error::check_positive("freq", freq)?;
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
        Error::check_positive("amp", amp)?;
        Error::check_positive("wavelength", wavelength)?;
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
            + self.layers.len() * (std::mem::size_of::<Layer>() + std::mem::size_of::<f32>())
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
                let t = (p[2] - z0).rem_euclid(period);
                let range = first as usize..(first + count) as usize;
                let k = self.tops[range.clone()].partition_point(|&top| top <= t);
                self.layers[range][k.min(count as usize - 1)].hardness
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
    /// Built from [`GeologySpec::layered_default`].
    pub fn layered_default(center: V3, period: f32, seed: u64) -> Result<Self> {
        GeologySpec::layered_default(center, period, seed)?.build()
    }

    /// Lengths (m) of the runs where `inside(resistance)` holds (soft rock: `rho < rho0`;
    /// resistant beds: `rho >= rho0`) met along vertical lines at the given `(x, y)` between
    /// `z0` and `z1`, sampled every `step` metres; runs cut by either end are not counted. Used
    /// to size karst passages to the soft strata of any geology, and the benches to its beds.
    pub fn runs(
        &self,
        columns: &[[f32; 2]],
        z0: f32,
        z1: f32,
        step: f32,
        inside: impl Fn(f32) -> bool,
    ) -> Vec<f32> {
        let mut runs = Vec::new();
        if !(step > 0.0 && z1 > z0) {
            return runs;
        }
        let n = (((z1 - z0) / step).ceil() as usize).min(1 << 16);
        for c in columns {
            let mut start: Option<usize> = None;
            let mut cut = true; // the run touching z0 is cut
            for k in 0..=n {
                let z = z0 + k as f32 * step;
                let soft = inside(self.resistance([c[0], c[1], z]));
                match (soft, start) {
                    (true, None) => start = Some(k),
                    (false, Some(s)) => {
                        if !cut {
                            runs.push((k - s) as f32 * step);
                        }
                        start = None;
                        cut = false;
                    }
                    (false, None) => cut = false,
                    _ => {}
                }
            }
        }
        runs
    }
}

/// A geology tree as data (JSON through serde), built into a [`Geology`] by
/// [`GeologySpec::build`]. Lengths in metres, resistances in `[0, 1]`. Example:
/// `{"type": "fold", "amp": 20, "wavelength": 2000, "direction": [1, 0.4],
///   "child": {"type": "strata", "z0": 0, "layers": [{"thickness": 30, "hardness": 0.15},
///   {"thickness": 10, "hardness": 0.85}]}}`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum GeologySpec {
    /// Constant resistance.
    Uniform {
        /// Resistance.
        rho: f32,
    },
    /// Horizontal strata stacked upwards from `z0`, repeated periodically.
    Strata {
        /// Base elevation of the first layer (m).
        z0: f32,
        /// Layers from the bottom up.
        layers: Vec<Layer>,
    },
    /// Fractal noise `base + amp * fbm(p / wavelength)`.
    Noise {
        /// Mean resistance.
        base: f32,
        /// Amplitude.
        amp: f32,
        /// Wavelength of the first octave (m).
        wavelength: f32,
        /// Octaves (1..=12).
        octaves: u32,
        /// Seed.
        seed: u64,
    },
    /// Linear blend `(1 - t) a + t b`.
    Blend {
        /// First tree.
        a: Box<GeologySpec>,
        /// Second tree.
        b: Box<GeologySpec>,
        /// Weight of `b`.
        t: f32,
    },
    /// The harder rock wins.
    Max {
        /// First tree.
        a: Box<GeologySpec>,
        /// Second tree.
        b: Box<GeologySpec>,
    },
    /// The softer rock wins.
    Min {
        /// First tree.
        a: Box<GeologySpec>,
        /// Second tree.
        b: Box<GeologySpec>,
    },
    /// Noise warp of the child by `amp` metres at `wavelength`.
    Warp {
        /// Warped tree.
        child: Box<GeologySpec>,
        /// Displacement (m).
        amp: f32,
        /// Wavelength (m).
        wavelength: f32,
        /// Seed.
        seed: u64,
    },
    /// Sinusoidal fold of amplitude `amp` (m) along the horizontal `direction`.
    Fold {
        /// Folded tree.
        child: Box<GeologySpec>,
        /// Amplitude (m).
        amp: f32,
        /// Wavelength (m).
        wavelength: f32,
        /// Horizontal direction `[x, y]`.
        direction: [f32; 2],
    },
    /// Fault: the side of the plane `normal` points to sees the child shifted by `offset`.
    Fault {
        /// Faulted tree.
        child: Box<GeologySpec>,
        /// A point of the fault plane.
        point: V3,
        /// Normal of the plane.
        normal: V3,
        /// Throw of the fault (m).
        offset: V3,
    },
}

impl Default for GeologySpec {
    /// Uniform resistance 0.5.
    fn default() -> Self {
        GeologySpec::Uniform { rho: 0.5 }
    }
}

impl GeologySpec {
    /// Builds the geology tree, checking every value (errors name the field).
    pub fn build(&self) -> Result<Geology> {
        let mut g = Geology::new();
        let root = self.add(&mut g, 0)?;
        g.set_root(root)?;
        Ok(g)
    }

    fn add(&self, g: &mut Geology, depth: usize) -> Result<GeoId> {
        if depth > 64 {
            return Err(Error::param(
                "geology depth",
                depth,
                "must be at most 64 levels",
            ));
        }
        let d = depth + 1;
        match self {
            GeologySpec::Uniform { rho } => g.uniform(*rho),
            GeologySpec::Strata { z0, layers } => g.strata(*z0, layers),
            GeologySpec::Noise {
                base,
                amp,
                wavelength,
                octaves,
                seed,
            } => {
                Error::check_positive("noise.wavelength", *wavelength)?;
                g.noise(*base, *amp, 1.0 / wavelength, *octaves, *seed)
            }
            GeologySpec::Blend { a, b, t } => {
                let (a, b) = (a.add(g, d)?, b.add(g, d)?);
                g.blend(a, b, *t)
            }
            GeologySpec::Max { a, b } => {
                let (a, b) = (a.add(g, d)?, b.add(g, d)?);
                g.max(a, b)
            }
            GeologySpec::Min { a, b } => {
                let (a, b) = (a.add(g, d)?, b.add(g, d)?);
                g.min(a, b)
            }
            GeologySpec::Warp {
                child,
                amp,
                wavelength,
                seed,
            } => {
                Error::check_positive("warp.wavelength", *wavelength)?;
                let c = child.add(g, d)?;
                g.warp(c, *amp, 1.0 / wavelength, *seed)
            }
            GeologySpec::Fold {
                child,
                amp,
                wavelength,
                direction,
            } => {
                let c = child.add(g, d)?;
                g.fold(c, *amp, *wavelength, *direction)
            }
            GeologySpec::Fault {
                child,
                point,
                normal,
                offset,
            } => {
                let c = child.add(g, d)?;
                g.fault(c, *point, *normal, *offset)
            }
        }
    }

    /// The layered default (figure 2's construction, with a natural column): a stratigraphic
    /// column of [`COLUMN_PERIODS`] `period`s ([`stratigraphic_column`]: cliff-forming beds and
    /// soft slope-forming units with thin ledges, of irregular thicknesses drawn from `seed`)
    /// stacked from `center`'s elevation, folded (amplitude 0.3 `period`, wavelength 20
    /// `period`), blended 25 % with noise and cut by a fault through `center` with a throw of
    /// 0.4 `period`. `period` is the mean thickness of a formation.
    pub fn layered_default(center: V3, period: f32, seed: u64) -> Result<Self> {
        Error::check_positive("period", period)?;
        if !center.iter().all(|v| v.is_finite()) {
            return Err(Error::param(
                "center",
                format!("{center:?}"),
                "must be finite",
            ));
        }
        let strata = GeologySpec::Strata {
            z0: center[2],
            layers: stratigraphic_column(period, seed),
        };
        let fold = GeologySpec::Fold {
            child: Box::new(strata),
            amp: period * 0.3,
            wavelength: period * 20.0,
            direction: [1.0, 0.4],
        };
        let noise = GeologySpec::Noise {
            base: 0.5,
            amp: 0.5,
            wavelength: period * 2.0,
            octaves: 3,
            seed,
        };
        Ok(GeologySpec::Fault {
            child: Box::new(GeologySpec::Blend {
                a: Box::new(fold),
                b: Box::new(noise),
                t: 0.25,
            }),
            point: center,
            normal: [1.0, 0.3, 0.0],
            offset: [0.0, 0.0, period * 0.4],
        })
    }
}

/// Height of the default geology's column in `period`s before it repeats: more than the relief
/// of most DEMs (2 km at the default 20 m), so no sequence of beds is seen twice in a canyon
/// wall.
pub const COLUMN_PERIODS: f32 = 100.0;

/// A stratigraphic column [`COLUMN_PERIODS`] `period`s high, drawn from `seed`: formations
/// alternate between
/// * **cliff-formers** (sandstone, limestone): one resistant bed (hardness 0.74-0.94),
///   log-normal in thickness around `period` (`sigma` 0.6, within `[0.4, 4] period`);
/// * **slope-formers** (shale, mudstone): soft rock (0.10-0.35) log-normal around 1.6 `period`
///   (within `[0.5, 5] period`), split by about one thin ledge of harder rock (0.60-0.70,
///   0.05-0.15 `period` thick) per `period` into soft beds of uneven thickness.
///
/// The walls cut through it show what canyon walls do (as the Grand Canyon's Kaibab, Coconino,
/// Hermit and Redwall): thick cliffs and ledgy slopes of every size, not a staircase of equal
/// steps. The mean hard share is about 40 %.
pub fn stratigraphic_column(period: f32, seed: u64) -> Vec<Layer> {
    use relief_heightfield::rng::{hash, unit_f32};
    const TAG: u64 = 0x636f_6c75_6d6e;
    let mut draw = {
        let mut k = 0u64;
        move || {
            k += 1;
            unit_f32(hash(seed, k, TAG, 0))
        }
    };
    let lognormal = |median: f32, lo: f32, hi: f32, u1: f32, u2: f32| {
        let g = (-2.0 * u1.max(1e-6).ln()).sqrt() * (std::f32::consts::TAU * u2).cos();
        period * (median * (0.6 * g).exp()).clamp(lo, hi)
    };
    let target = COLUMN_PERIODS * period;
    let mut layers = Vec::new();
    let mut total = 0.0;
    let mut cliff = draw() < 0.5;
    while total < target {
        let (u1, u2) = (draw(), draw());
        if cliff {
            let t = lognormal(1.0, 0.4, 4.0, u1, u2);
            layers.push(Layer {
                thickness: t,
                hardness: 0.74 + 0.2 * draw(),
            });
            total += t;
        } else {
            let t = lognormal(1.6, 0.5, 5.0, u1, u2);
            let ledges = (t / period * (0.4 + 1.2 * draw())).floor() as usize;
            let weights: Vec<f32> = (0..=ledges).map(|_| 0.4 + draw()).collect();
            let sum: f32 = weights.iter().sum();
            for (i, w) in weights.iter().enumerate() {
                if i > 0 {
                    let lt = period * (0.05 + 0.1 * draw());
                    layers.push(Layer {
                        thickness: lt,
                        hardness: 0.6 + 0.1 * draw(),
                    });
                    total += lt;
                }
                let st = t * w / sum;
                layers.push(Layer {
                    thickness: st,
                    hardness: 0.10 + 0.25 * draw(),
                });
                total += st;
            }
        }
        cliff = !cliff;
    }
    layers
}

/// Test strata: from `z0` up, a soft bed under a resistant one, each `(thickness m,
/// hardness)`, repeated, as the whole geology (the layered rock the landform tests carve).
#[cfg(test)]
pub(crate) fn test_beds(z0: f32, soft: (f32, f32), hard: (f32, f32)) -> Geology {
    let mut g = Geology::new();
    let layers = [soft, hard].map(|(thickness, hardness)| Layer {
        thickness,
        hardness,
    });
    let id = g.strata(z0, &layers).unwrap();
    g.set_root(id).unwrap();
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_column_has_cliffs_and_ledgy_slopes_of_uneven_thickness() {
        let period = 20.0;
        let col = stratigraphic_column(period, 7);
        let total: f32 = col.iter().map(|l| l.thickness).sum();
        assert!(total >= COLUMN_PERIODS * period, "{total}");
        let hard: f32 = col
            .iter()
            .filter(|l| l.hardness >= 0.6)
            .map(|l| l.thickness)
            .sum();
        let share = hard / total;
        assert!((0.3..0.55).contains(&share), "hard share {share}");
        // Cliff beds of every size: the thickest is several times the thinnest.
        let cliffs: Vec<f32> = col
            .iter()
            .filter(|l| l.hardness >= 0.72)
            .map(|l| l.thickness)
            .collect();
        let (lo, hi) = cliffs
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &t| (a.min(t), b.max(t)));
        assert!(hi > 4.0 * lo && lo >= 0.4 * period - 1e-3, "{lo} {hi}");
        // No repeating unit: consecutive pairs of beds are never the same twice.
        let pairs: std::collections::HashSet<(u32, u32)> = col
            .windows(2)
            .map(|w| (w[0].thickness.to_bits(), w[1].thickness.to_bits()))
            .collect();
        assert_eq!(pairs.len(), col.len() - 1);
        // Another seed, another column; the same seed, the same one.
        assert_ne!(col, stratigraphic_column(period, 8));
        assert_eq!(col, stratigraphic_column(period, 7));
        // The tree finds each bed by its height (binary search over the running tops).
        let mut g = Geology::new();
        let id = g.strata(0.0, &col).unwrap();
        g.set_root(id).unwrap();
        let mut z = 0.0;
        for l in &col {
            assert_eq!(g.resistance([0.0, 0.0, z + 0.5 * l.thickness]), l.hardness);
            z += l.thickness;
        }
        assert_eq!(g.resistance([0.0, 0.0, total + 0.01]), col[0].hardness);
    }

    #[test]
    fn json_geology_round_trips_and_builds() {
        let text = r#"{"type": "fold", "amp": 20, "wavelength": 2000, "direction": [1, 0.4],
            "child": {"type": "strata", "z0": 0, "layers": [{"thickness": 30, "hardness": 0.15},
            {"thickness": 10, "hardness": 0.85}]}}"#;
        let spec: GeologySpec = serde_json::from_str(text).unwrap();
        let g = spec.build().unwrap();
        // Far from the fold's influence at x = y = 0 (sin 0 = 0): the strata themselves.
        assert_eq!(g.resistance([0.0, 0.0, 5.0]), 0.15);
        assert_eq!(g.resistance([0.0, 0.0, 35.0]), 0.85);
        assert_eq!(
            g.resistance([0.0, 0.0, 45.0]),
            0.15,
            "the strata repeat every 40 m"
        );
        let back: GeologySpec =
            serde_json::from_str(&serde_json::to_string(&spec).unwrap()).unwrap();
        assert_eq!(back, spec);
        // The default model as data gives the same resistance as before.
        let d = GeologySpec::layered_default([100.0, 50.0, 20.0], 30.0, 4).unwrap();
        let a = d.build().unwrap();
        let b = Geology::layered_default([100.0, 50.0, 20.0], 30.0, 4).unwrap();
        for k in 0..50 {
            let p = [k as f32 * 7.0, 50.0 - k as f32, k as f32 * 3.0 - 40.0];
            assert_eq!(a.resistance(p), b.resistance(p));
        }
        // Soft runs of the two-layer strata are 30 m.
        let runs = g.runs(&[[0.0, 0.0]], -100.0, 100.0, 0.5, |rho| rho < 0.5);
        assert!(
            !runs.is_empty() && runs.iter().all(|r| (r - 30.0).abs() <= 1.0),
            "{runs:?}"
        );
        // Bad values are named; unknown fields are refused.
        let bad = r#"{"type": "strata", "z0": 0, "layers": [{"thickness": 3, "hardness": 2}]}"#;
        let e = serde_json::from_str::<GeologySpec>(bad)
            .unwrap()
            .build()
            .unwrap_err();
        assert!(e.to_string().contains("layer.hardness"), "{e}");
        assert!(
            serde_json::from_str::<GeologySpec>(r#"{"type": "uniform", "rho": 0.5, "x": 1}"#)
                .is_err()
        );
    }
}
