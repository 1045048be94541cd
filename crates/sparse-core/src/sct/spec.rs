//! Construction-tree authoring from a file (guerin2016 section 5.4): a serde description of a
//! tree whose leaves are existing trees (`layer`, resolved by the caller: an `.sct` file or a
//! DEM it compresses), constants and procedural rivers, combined by the tree's operators.
//!
//! ```json
//! {"root": {"river_valley": {
//!     "on": {"replace": {"base": {"layer": "mountains.sct"},
//!                        "overlay": {"layer": "hills.sct"},
//!                        "region": {"disk": [300, 200, 80]}, "falloff": 20}},
//!     "path": [[10, 40], [200, 180], [500, 300]],
//!     "valley_half_width": 12, "bank_height": 150,
//!     "channel_half_width": 3, "channel_depth": 8}}}
//! ```
//!
//! Coordinates are terrain pixels of the tree's grid (the first layer's, or `width`, `height`
//! and `cell_size`). `river_valley` is the paper's river sub-tree (figure 13): the valley floor
//! is smoothed by carving the terrain with a parabolic bed profile along the path (`Min`), then
//! the channel is carved into that floor (`Add`): `Add(Min(on, bed), channel)`, three levels.

use serde::Deserialize;

use super::{Node, Region, River, RiverMode, Sct};
use crate::error::{Result, SparseError};

/// A whole authored tree.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreeSpec {
    /// The root node.
    pub root: NodeSpec,
    /// Grid width in cells (default: the first layer's).
    #[serde(default)]
    pub width: Option<usize>,
    /// Grid height in cells (default: the first layer's).
    #[serde(default)]
    pub height: Option<usize>,
    /// Cell size `[x, y]` in metres (default: the first layer's).
    #[serde(default)]
    pub cell_size: Option<[f64; 2]>,
}

/// A node of an authored tree.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum NodeSpec {
    /// The root of an existing tree, named by the caller's resolver (a file path).
    Layer(String),
    /// A constant elevation (metres).
    Constant(f64),
    /// Normalised weighted sum of the children.
    Blend(Vec<NodeSpec>),
    /// Sum of the children.
    Add(Vec<NodeSpec>),
    /// Maximum of the children.
    Max(Vec<NodeSpec>),
    /// Minimum of the children (carving).
    Min(Vec<NodeSpec>),
    /// `overlay` inside `region`, `base` outside, smooth over `falloff` cells.
    Replace {
        /// Kept outside the region.
        base: Box<NodeSpec>,
        /// Used inside the region.
        overlay: Box<NodeSpec>,
        /// The region.
        region: RegionSpec,
        /// Width of the transition outside the region (cells, >= 0).
        #[serde(default)]
        falloff: f64,
    },
    /// One river primitive: a carve (`depth` below the terrain on the axis, under `add`) or,
    /// with `bed`, an absolute parabolic valley `bed + depth (d / half_width)^2` (under `min`).
    River(RiverSpec),
    /// The paper's river sub-tree on `on` (module docs).
    RiverValley(RiverValleySpec),
}

/// A region of [`NodeSpec::Replace`].
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum RegionSpec {
    /// `[x0, y0, x1, y1]`.
    Rect([f64; 4]),
    /// `[cx, cy, r]`.
    Disk([f64; 3]),
}

/// One value for every vertex, or one per vertex.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum Profile {
    /// The same value along the path.
    One(f64),
    /// One value per path vertex.
    PerVertex(Vec<f64>),
}

impl Profile {
    fn values(&self, n: usize) -> Vec<f64> {
        match self {
            Profile::One(v) => vec![*v; n],
            Profile::PerVertex(v) => v.clone(),
        }
    }
}

/// A river primitive.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RiverSpec {
    /// Polyline in terrain pixels (>= 2 vertices).
    pub path: Vec<[f64; 2]>,
    /// Half width (cells, > 0).
    pub half_width: Profile,
    /// Carve depth, or bank height at one half width for a bed (metres, >= 0).
    pub depth: Profile,
    /// Bed elevations per vertex (metres): makes the river an absolute valley profile.
    #[serde(default)]
    pub bed: Option<Vec<f64>>,
}

/// The river sub-tree of figure 13.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RiverValleySpec {
    /// The terrain the river runs through.
    pub on: Box<NodeSpec>,
    /// Polyline in terrain pixels (>= 2 vertices), upstream first.
    pub path: Vec<[f64; 2]>,
    /// Half width of the smoothed valley floor's profile (cells, > 0).
    pub valley_half_width: Profile,
    /// Height of the valley profile above its floor at one valley half width (metres, >= 0).
    pub bank_height: Profile,
    /// Half width of the channel (cells, > 0; default a third of the valley's).
    #[serde(default)]
    pub channel_half_width: Option<Profile>,
    /// Depth of the channel below the valley floor (metres, >= 0).
    pub channel_depth: Profile,
    /// Valley floor elevations per vertex (default: `on` evaluated at the vertices, never
    /// rising downstream).
    #[serde(default)]
    pub floor: Option<Vec<f64>>,
}

/// The grid a built tree lives on, taken from the first layer resolved.
#[derive(Debug, Clone, Default)]
struct Grid {
    first: Option<Sct>,
}

impl TreeSpec {
    /// The names of every [`NodeSpec::Layer`], in the order [`TreeSpec::build`] resolves them.
    pub fn layers(&self) -> Vec<&str> {
        fn walk<'a>(n: &'a NodeSpec, out: &mut Vec<&'a str>) {
            match n {
                NodeSpec::Layer(name) => out.push(name),
                NodeSpec::Constant(_) | NodeSpec::River(_) => {}
                NodeSpec::Blend(c) | NodeSpec::Add(c) | NodeSpec::Max(c) | NodeSpec::Min(c) => {
                    c.iter().for_each(|c| walk(c, out));
                }
                NodeSpec::Replace { base, overlay, .. } => {
                    walk(base, out);
                    walk(overlay, out);
                }
                NodeSpec::RiverValley(v) => walk(&v.on, out),
            }
        }
        let mut out = Vec::new();
        walk(&self.root, &mut out);
        out
    }

    /// Builds the tree; `resolve` turns a [`NodeSpec::Layer`] name into a tree (its root is
    /// used, its grid is the default grid).
    pub fn build(&self, resolve: &mut dyn FnMut(&str) -> Result<Sct>) -> Result<Sct> {
        let mut grid = Grid::default();
        let root = self.root.build(resolve, &mut grid)?;
        let first = grid.first.as_ref();
        let width = self.width.or(first.map(Sct::width));
        let height = self.height.or(first.map(Sct::height));
        let cell = self
            .cell_size
            .map(|[x, y]| (x, y))
            .or(first.map(Sct::cell_size));
        let (Some(width), Some(height), Some(cell)) = (width, height, cell) else {
            return Err(SparseError::param(
                "width, height, cell_size",
                "missing",
                "a tree without a layer must give its grid",
            ));
        };
        let georef = match (first, self.width, self.height, self.cell_size) {
            (Some(f), None, None, None) => f.georef().cloned(),
            _ => None,
        };
        Ok(Sct::new(root, width, height, cell)?.with_georef(georef))
    }
}

impl NodeSpec {
    fn build(&self, resolve: &mut dyn FnMut(&str) -> Result<Sct>, grid: &mut Grid) -> Result<Node> {
        let mut list = |c: &[NodeSpec]| -> Result<Vec<Node>> {
            if c.is_empty() {
                return Err(SparseError::param(
                    "children",
                    0,
                    "an operator needs at least one child",
                ));
            }
            c.iter().map(|n| n.build(resolve, grid)).collect()
        };
        Ok(match self {
            NodeSpec::Layer(name) => {
                let mut sct = resolve(name)?;
                let root = sct.take_root();
                if grid.first.is_none() {
                    grid.first = Some(
                        Sct::new(
                            Node::Constant(0.0),
                            sct.width(),
                            sct.height(),
                            sct.cell_size(),
                        )?
                        .with_georef(sct.georef().cloned()),
                    );
                }
                root
            }
            NodeSpec::Constant(v) => {
                if !v.is_finite() {
                    return Err(SparseError::param("constant", v, "must be finite"));
                }
                Node::Constant(*v)
            }
            NodeSpec::Blend(c) => Node::Blend(list(c)?),
            NodeSpec::Add(c) => Node::Add(list(c)?),
            NodeSpec::Max(c) => Node::Max(list(c)?),
            NodeSpec::Min(c) => Node::Min(list(c)?),
            NodeSpec::Replace {
                base,
                overlay,
                region,
                falloff,
            } => Node::Replace {
                base: Box::new(base.build(resolve, grid)?),
                overlay: Box::new(overlay.build(resolve, grid)?),
                region: match *region {
                    RegionSpec::Rect([x0, y0, x1, y1]) => Region::Rect { x0, y0, x1, y1 },
                    RegionSpec::Disk([cx, cy, r]) => Region::Disk { cx, cy, r },
                },
                falloff: *falloff,
            },
            NodeSpec::River(r) => {
                let n = r.path.len();
                let mode = match &r.bed {
                    Some(b) => RiverMode::Bed(b.clone()),
                    None => RiverMode::Carve,
                };
                Node::River(River::new(
                    r.path.clone(),
                    r.half_width.values(n),
                    r.depth.values(n),
                    mode,
                )?)
            }
            NodeSpec::RiverValley(v) => v.build(resolve, grid)?,
        })
    }
}

impl RiverValleySpec {
    fn build(&self, resolve: &mut dyn FnMut(&str) -> Result<Sct>, grid: &mut Grid) -> Result<Node> {
        let base = self.on.build(resolve, grid)?;
        let n = self.path.len();
        let valley = self.valley_half_width.values(n);
        let channel = match &self.channel_half_width {
            Some(p) => p.values(n),
            None => valley.iter().map(|w| w / 3.0).collect(),
        };
        let floor = match &self.floor {
            Some(f) => f.clone(),
            None => {
                // The terrain along the path, never rising downstream.
                let mut last = f64::INFINITY;
                let mut f = Vec::with_capacity(n);
                for p in &self.path {
                    let (v, w) = base.eval(p[0], p[1]);
                    if !(v.is_finite() && w > 0.0) {
                        return Err(SparseError::param(
                            "path",
                            format!("[{}, {}]", p[0], p[1]),
                            "a river vertex lies where the terrain is undefined",
                        ));
                    }
                    last = last.min(v);
                    f.push(last);
                }
                f
            }
        };
        let bed = River::new(
            self.path.clone(),
            valley,
            self.bank_height.values(n),
            RiverMode::Bed(floor),
        )?;
        let carve = River::new(
            self.path.clone(),
            channel,
            self.channel_depth.values(n),
            RiverMode::Carve,
        )?;
        Ok(Node::Add(vec![
            Node::Min(vec![base, Node::River(bed)]),
            Node::River(carve),
        ]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(json: &str) -> TreeSpec {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn a_river_valley_smooths_the_floor_and_carves_the_channel() {
        // A V-shaped valley (100 m on its axis), 64 x 32 cells of 10 m.
        let t = spec(
            r#"{"width": 64, "height": 32, "cell_size": [10, 10],
                "root": {"river_valley": {
                    "on": {"add": [{"constant": 100}, {"river": {"path": [[0, 16], [63, 16]],
                           "half_width": 30, "depth": -1, "bed": [100, 100]}}]},
                    "path": [[2, 16], [60, 16]],
                    "valley_half_width": 8, "bank_height": 40,
                    "channel_depth": 5}}}"#,
        );
        // depth -1 is refused by the river primitive, by name.
        let e = t.build(&mut |_| unreachable!()).unwrap_err().to_string();
        assert!(e.contains("depth"), "{e}");
        let t = spec(
            r#"{"width": 64, "height": 32, "cell_size": [10, 10],
                "root": {"river_valley": {
                    "on": {"max": [{"constant": 100},
                                   {"river": {"path": [[0, 16], [63, 16]], "half_width": 12,
                                              "depth": 80, "bed": [100, 100]}}]},
                    "path": [[2, 16], [60, 16]],
                    "valley_half_width": 8, "bank_height": 20,
                    "channel_depth": 5}}}"#,
        );
        let sct = t.build(&mut |_| unreachable!()).unwrap();
        assert_eq!((sct.width(), sct.height()), (64, 32));
        // The base is a V-ish valley 100 m on the axis, rising away from it; the floor
        // follows the base along the path (100 m) and the channel is 5 m below it.
        let axis = sct.eval(30.0, 16.0);
        assert!((axis - 95.0).abs() < 1e-9, "{axis}");
        // Outside the channel: the smoothed floor, the lower of the base and the bed profile.
        let base = |d: f64| 100.0 + 80.0 * (d / 12.0).powi(2);
        let bed = |d: f64| 100.0 + 20.0 * (d / 8.0).powi(2);
        for d in [4.0, 6.0, 14.0] {
            let v = sct.eval(30.0, 16.0 + d);
            assert!((v - base(d).min(bed(d))).abs() < 1e-9, "{d}: {v}");
        }
        assert!(bed(6.0) < base(6.0), "the bed profile smooths the floor");
    }

    #[test]
    fn layers_come_from_the_resolver_and_give_the_grid() {
        let t = spec(
            r#"{"root": {"replace": {"base": {"layer": "a"}, "overlay": {"constant": 5},
                                      "region": {"rect": [0, 0, 3, 3]}, "falloff": 1}}}"#,
        );
        assert_eq!(t.layers(), vec!["a"]);
        let mut seen = Vec::new();
        let sct = t
            .build(&mut |name| {
                seen.push(name.to_string());
                Sct::new(Node::Constant(1.0), 8, 6, (2.0, 3.0))
            })
            .unwrap();
        assert_eq!(seen, vec!["a"]);
        assert_eq!(
            (sct.width(), sct.height(), sct.cell_size()),
            (8, 6, (2.0, 3.0))
        );
        assert_eq!(sct.eval(1.0, 1.0), 5.0);
        assert_eq!(sct.eval(7.0, 5.0), 1.0);
        // No layer and no grid: refused by name.
        let e = spec(r#"{"root": {"constant": 1}}"#)
            .build(&mut |_| unreachable!())
            .unwrap_err()
            .to_string();
        assert!(e.contains("width, height, cell_size"), "{e}");
        // Unknown fields and empty operators are refused.
        assert!(serde_json::from_str::<TreeSpec>(r#"{"root": {"constant": 1}, "x": 1}"#).is_err());
        let e = spec(r#"{"width": 2, "height": 2, "cell_size": [1, 1], "root": {"blend": []}}"#)
            .build(&mut |_| unreachable!())
            .unwrap_err()
            .to_string();
        assert!(e.contains("children"), "{e}");
    }
}
