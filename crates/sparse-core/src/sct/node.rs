//! The construction tree's nodes: layers, constants, rivers and operators, evaluated at a point
//! or rasterised band by band with the same arithmetic.

use super::*;

/// A node of the Sparse Construction Tree.
#[derive(Debug, Clone)]
pub enum Node {
    /// Sparse primitives blended by the normalised weighted sum (section 4.1).
    Layer(SparseLayer),
    /// A constant elevation (weight 1).
    Constant(f64),
    /// A procedural river (weight 1).
    River(River),
    /// A raster of samples interpolated with a kernel (weight 1).
    Field(Field),
    /// Normalised weighted sum of the children (value NaN where every weight is 0).
    Blend(Vec<Node>),
    /// Sum of the children's values; weight of the first child.
    Add(Vec<Node>),
    /// Maximum of the children's values; weight of the first child.
    Max(Vec<Node>),
    /// Minimum of the children's values (carving); weight of the first child.
    Min(Vec<Node>),
    /// `base` outside `region`, `overlay` inside, smooth over `falloff` cells; weight of `base`.
    Replace {
        /// The node kept outside the region.
        base: Box<Node>,
        /// The node used inside the region.
        overlay: Box<Node>,
        /// The region.
        region: Region,
        /// Width of the transition outside the region (>= 0, terrain pixels).
        falloff: f64,
    },
}

/// The operator of a node with children.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Op {
    /// Normalised weighted sum.
    Blend,
    /// Sum of the values.
    Add,
    /// Maximum of the values.
    Max,
    /// Minimum of the values (carving).
    Min,
}

/// Running `(value, weight)` of an operator node over its children (visited in order), before
/// [`acc_finish`]. Point evaluation and rasterisation use these same three functions, so they
/// agree bit for bit.
#[inline]
pub(super) fn acc_init(kind: Op) -> (f64, f64) {
    match kind {
        // Blend: (numerator, denominator).
        Op::Blend => (0.0, 0.0),
        // Add: the sum starts at -0.0 (the identity of IEEE addition).
        Op::Add => (-0.0, f64::NAN),
        Op::Max | Op::Min => (f64::NAN, f64::NAN),
    }
}

/// Adds one child `(v, w)` to the running value; `first` for the first child (whose weight
/// the non-blend operators keep).
#[inline]
pub(super) fn acc_step(kind: Op, acc: (f64, f64), (v, w): (f64, f64), first: bool) -> (f64, f64) {
    let keep = if first { w } else { acc.1 };
    match kind {
        Op::Blend => {
            if w > 0.0 {
                (acc.0 + v * w, acc.1 + w)
            } else {
                acc
            }
        }
        Op::Add => (acc.0 + v, keep),
        Op::Max => (acc.0.max(v), keep),
        Op::Min => (acc.0.min(v), keep),
    }
}

/// Final `(value, weight)`: blend normalises (NaN where every weight is 0).
#[inline]
pub(super) fn acc_finish(kind: Op, acc: (f64, f64)) -> (f64, f64) {
    match kind {
        Op::Blend => (if acc.1 > 0.0 { acc.0 / acc.1 } else { f64::NAN }, acc.1),
        Op::Add | Op::Max | Op::Min => acc,
    }
}

pub(super) fn replace_combine(base: (f64, f64), over: (f64, f64), t: f64) -> (f64, f64) {
    let v = if t <= 0.0 {
        base.0
    } else if t >= 1.0 {
        over.0
    } else {
        base.0 + (over.0 - base.0) * t
    };
    (v, base.1)
}

impl Node {
    pub(super) fn children_kind(&self) -> Option<(Op, &[Node])> {
        match self {
            Node::Blend(c) => Some((Op::Blend, c)),
            Node::Add(c) => Some((Op::Add, c)),
            Node::Max(c) => Some((Op::Max, c)),
            Node::Min(c) => Some((Op::Min, c)),
            _ => None,
        }
    }

    /// Checks operator arities and parameters.
    pub fn check(&self) -> Result<()> {
        if let Some((_, c)) = self.children_kind() {
            if c.is_empty() {
                return Err(SparseError::param(
                    "children",
                    0,
                    "an operator node needs at least one child",
                ));
            }
            return c.iter().try_for_each(Node::check);
        }
        match self {
            Node::Constant(v) => super::check_bounded("constant", *v, super::MAX_ABS_ELEVATION),
            Node::Replace {
                base,
                overlay,
                region,
                falloff,
            } => {
                region.check()?;
                if !(falloff.is_finite() && *falloff >= 0.0 && *falloff <= super::MAX_ABS_COORD) {
                    return Err(SparseError::param(
                        "falloff",
                        falloff,
                        "must be finite and in [0, 2^30] cells",
                    ));
                }
                base.check()?;
                overlay.check()
            }
            _ => Ok(()),
        }
    }

    /// `(value, weight)` at `(x, y)` (terrain pixel coordinates).
    pub fn eval(&self, x: f64, y: f64) -> (f64, f64) {
        if let Some((kind, c)) = self.children_kind() {
            let mut acc = acc_init(kind);
            for (i, n) in c.iter().enumerate() {
                acc = acc_step(kind, acc, n.eval(x, y), i == 0);
            }
            return acc_finish(kind, acc);
        }
        match self {
            Node::Layer(l) => {
                let (num, den) = l.eval_parts(x, y);
                (if den > 0.0 { num / den } else { f64::NAN }, den)
            }
            Node::Constant(v) => (*v, 1.0),
            Node::River(r) => (r.eval(x, y), 1.0),
            Node::Field(f) => (f.eval(x, y), 1.0),
            Node::Replace {
                base,
                overlay,
                region,
                falloff,
            } => {
                let t = region.weight(x, y, *falloff);
                let b = base.eval(x, y);
                let o = if t > 0.0 {
                    overlay.eval(x, y)
                } else {
                    (f64::NAN, 0.0)
                };
                replace_combine(b, o, t)
            }
            _ => (f64::NAN, 0.0),
        }
    }

    /// Rasterises the node into `val`/`wt` (band-sized, row-major).
    pub(super) fn raster(
        &self,
        band: &Band,
        val: &mut [f64],
        wt: &mut [f64],
        scratch: &mut StampScratch<'_>,
    ) {
        let ncols = band.cols.len();
        if let Some((kind, c)) = self.children_kind() {
            // Children are stamped one after the other into one scratch pair and folded into
            // the running value held in `val`/`wt` (memory: two buffers whatever the arity).
            let n = val.len();
            let (a0, w0) = acc_init(kind);
            val.iter_mut().for_each(|v| *v = a0);
            wt.iter_mut().for_each(|v| *v = w0);
            // The scratch pair (a nested operator finds it taken and allocates its own).
            let (mut cv, mut cw) = std::mem::take(&mut scratch.child);
            cv.clear();
            cv.resize(n, 0.0);
            cw.clear();
            cw.resize(n, 0.0);
            for (i, child) in c.iter().enumerate() {
                // A tree of millions of children takes seconds per band: ask between them.
                if i % 1024 == 1023 && scratch.should_stop() {
                    return;
                }
                child.raster(band, &mut cv, &mut cw, scratch);
                for k in 0..n {
                    let a = acc_step(kind, (val[k], wt[k]), (cv[k], cw[k]), i == 0);
                    val[k] = a.0;
                    wt[k] = a.1;
                }
            }
            scratch.child = (cv, cw);
            for k in 0..n {
                let a = acc_finish(kind, (val[k], wt[k]));
                val[k] = a.0;
                wt[k] = a.1;
            }
            return;
        }
        match self {
            Node::Layer(l) => {
                val.iter_mut().for_each(|v| *v = 0.0);
                wt.iter_mut().for_each(|v| *v = 0.0);
                l.stamp(band, val, wt, scratch);
                for (v, &w) in val.iter_mut().zip(wt.iter()) {
                    *v = if w > 0.0 { *v / w } else { f64::NAN };
                }
            }
            Node::Constant(c) => {
                val.iter_mut().for_each(|v| *v = *c);
                wt.iter_mut().for_each(|v| *v = 1.0);
            }
            Node::River(r) => {
                r.stamp(band, val);
                wt.iter_mut().for_each(|v| *v = 1.0);
            }
            Node::Field(f) => {
                f.raster(band, val);
                wt.iter_mut().for_each(|v| *v = 1.0);
            }
            Node::Replace {
                base,
                overlay,
                region,
                falloff,
            } => {
                base.raster(band, val, wt, scratch);
                // The overlay is only rasterised (stamped) on the part of the band where the
                // region's weight can be > 0: its box grown by the fall-off (and a pixel).
                // Elsewhere the weight is 0 and the base value is kept, as in `eval`.
                let Some([xa, xb, ya, yb]) = band.pixels_over(region.bounds(*falloff)) else {
                    return;
                };
                let sc = band.scale;
                let sub = Band {
                    cols: xa as usize..xb as usize + 1,
                    rows: ya as usize..yb as usize + 1,
                    scale: sc,
                };
                let sw = sub.cols.len();
                let sn = sw * sub.rows.len();
                let mut ov = vec![0.0; sn];
                let mut ow = vec![0.0; sn];
                overlay.raster(&sub, &mut ov, &mut ow, scratch);
                for j in 0..sn {
                    let (xi, yi) = (sub.cols.start + j % sw, sub.rows.start + j / sw);
                    let (x, y) = (raster_coord(xi, sc), raster_coord(yi, sc));
                    let t = region.weight(x, y, *falloff);
                    let k = (yi - band.rows.start) * ncols + (xi - band.cols.start);
                    let (v, w) = replace_combine((val[k], wt[k]), (ov[j], ow[j]), t);
                    val[k] = v;
                    wt[k] = w;
                }
            }
            _ => {}
        }
    }

    /// Visits the leaves of the tree depth first (operator children in order, then a
    /// replace node's base before its overlay).
    pub(super) fn visit_leaves<'a>(&'a self, f: &mut impl FnMut(&'a Node)) {
        if let Some((_, c)) = self.children_kind() {
            c.iter().for_each(|n| n.visit_leaves(f));
            return;
        }
        match self {
            Node::Replace { base, overlay, .. } => {
                base.visit_leaves(f);
                overlay.visit_leaves(f);
            }
            leaf => f(leaf),
        }
    }
}
