//! Byte forms of the passes' products: a magic of 8 bytes naming the product, the tile index
//! and its size, then little-endian arrays. Reading checks every size and count against the
//! [`TileLayout`] before allocating, and every label, cell and direction against its range,
//! so a damaged or planted file is an error, never a panic or an absurd allocation.

use super::*;

struct Out(Vec<u8>);

impl Out {
    fn new(magic: &[u8; 8], t: usize, w: usize, h: usize) -> Self {
        let mut o = Out(Vec::new());
        o.0.extend_from_slice(magic);
        o.u64(t as u64);
        o.u64(w as u64);
        o.u64(h as u64);
        o
    }
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
}

struct In<'a> {
    b: &'a [u8],
    what: &'static str,
    t: usize,
}

impl<'a> In<'a> {
    fn new(
        b: &'a [u8],
        magic: &[u8; 8],
        what: &'static str,
        layout: &TileLayout,
        t: usize,
    ) -> Result<Self> {
        layout.check()?;
        if t >= layout.tasks() {
            return Err(bad(format!("{what}: tile {t} is not in the plan")));
        }
        let mut r = In { b, what, t };
        if r.take(8)? != magic {
            return Err(bad(format!(
                "{what} of tile {t}: not a {what} (wrong magic)"
            )));
        }
        let [_, _, w, h] = layout.window(t);
        if (r.u64()?, r.u64()?, r.u64()?) != (t as u64, w as u64, h as u64) {
            return Err(bad(format!(
                "{what} of tile {t}: written for another tile or tile size"
            )));
        }
        Ok(r)
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        if self.b.len() < n {
            return Err(bad(format!("{} of tile {}: truncated", self.what, self.t)));
        }
        let (a, b) = self.b.split_at(n);
        self.b = b;
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn f32(&mut self) -> Result<f32> {
        Ok(f32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    /// A count of at most `max` items of `size` bytes each, also bounded by what is left.
    fn count(&mut self, max: usize, size: usize) -> Result<usize> {
        let n = self.u64()?;
        if n > max as u64 || n.saturating_mul(size as u64) > self.b.len() as u64 {
            return Err(bad(format!(
                "{} of tile {}: a count of {n} is out of range",
                self.what, self.t
            )));
        }
        Ok(n as usize)
    }
    fn f32s(&mut self, n: usize) -> Result<Vec<f32>> {
        let b = self.take(n * 4)?;
        Ok(b.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect())
    }
    fn u32s(&mut self, n: usize) -> Result<Vec<u32>> {
        let b = self.take(n * 4)?;
        Ok(b.chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect())
    }
    fn end(self) -> Result<()> {
        if self.b.is_empty() {
            Ok(())
        } else {
            Err(bad(format!(
                "{} of tile {}: {} bytes after the end",
                self.what,
                self.t,
                self.b.len()
            )))
        }
    }
}

fn dir_ok(d: u8) -> bool {
    d < 8 || d == NO_FLOW
}

const FILL: &[u8; 8] = b"RLFTP1FL";
const GRAPH: &[u8; 8] = b"RLFTP1GR";
const LEVELS: &[u8; 8] = b"RLFTP2LV";
const ROUTED: &[u8; 8] = b"RLFTP3RT";
const PORTS: &[u8; 8] = b"RLFTP3PG";
const INFLOW: &[u8; 8] = b"RLFTP4IN";

impl LocalFill {
    /// The byte form of tile `t`'s local fill.
    pub fn to_bytes(&self, t: usize) -> Vec<u8> {
        let mut o = Out::new(FILL, t, self.width, self.height);
        self.z.iter().for_each(|&v| o.f32(v));
        self.label.iter().for_each(|&v| o.u32(v));
        o.0
    }

    /// Reads and checks tile `t`'s local fill.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, FILL, "local fill", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let z = r.f32s(w * h)?;
        let label = r.u32s(w * h)?;
        r.end()?;
        let f = LocalFill {
            width: w,
            height: h,
            z,
            label,
        };
        check_fill(&f, w, h, t)?;
        Ok(f)
    }
}

impl FillGraph {
    /// The byte form of tile `t`'s fill graph.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(GRAPH, t, w, h);
        self.band_z.iter().for_each(|&v| o.f32(v));
        self.band_label.iter().for_each(|&v| o.u32(v));
        o.u64(self.edges.len() as u64);
        for &(a, b, s) in &self.edges {
            o.u32(a);
            o.u32(b);
            o.f32(s);
        }
        o.0
    }

    /// Reads and checks tile `t`'s fill graph.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, GRAPH, "fill graph", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let bl = band_len(w, h);
        let band_z = r.f32s(bl)?;
        let band_label = r.u32s(bl)?;
        let ne = r.count(8 * w * h, 12)?;
        let mut edges = Vec::with_capacity(ne);
        for _ in 0..ne {
            edges.push((r.u32()?, r.u32()?, r.f32()?));
        }
        r.end()?;
        let g = FillGraph {
            band_z,
            band_label,
            edges,
        };
        check_graph(&g, w, h, t)?;
        Ok(g)
    }
}

impl Levels {
    /// The byte form of tile `t`'s levels.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(LEVELS, t, w, h);
        self.level.iter().for_each(|&v| o.f32(v));
        self.band.iter().for_each(|&v| o.f32(v));
        o.0
    }

    /// Reads and checks tile `t`'s levels.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, LEVELS, "levels", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let bl = band_len(w, h);
        let level = r.f32s(bl + 1)?;
        let band = r.f32s(bl)?;
        r.end()?;
        Ok(Levels { level, band })
    }
}

impl Routed {
    /// The byte form of tile `t`'s routed tile.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(ROUTED, t, w, h);
        self.filled.iter().for_each(|&v| o.f32(v));
        o.0.extend_from_slice(&self.dir);
        o.0
    }

    /// Reads and checks tile `t`'s routed tile.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, ROUTED, "routed tile", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let filled = r.f32s(w * h)?;
        let dir = r.take(w * h)?.to_vec();
        r.end()?;
        if !dir.iter().all(|&d| dir_ok(d)) {
            return Err(bad(format!(
                "routed tile of tile {t}: a direction is out of range"
            )));
        }
        Ok(Routed { filled, dir })
    }
}

impl PortGraph {
    /// The byte form of tile `t`'s port graph.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(PORTS, t, w, h);
        o.u64(self.pending.len() as u64);
        for p in &self.pending {
            o.u32(p.cell);
            o.f32(p.z);
            o.u8(u8::from(p.high));
        }
        o.u64(self.low.len() as u64);
        for &(c, z) in &self.low {
            o.u32(c);
            o.f32(z);
        }
        o.u64(self.ports.len() as u64);
        for &(c, d, n) in &self.ports {
            o.u32(c);
            o.u8(d);
            o.u64(n);
        }
        o.u64(self.links.len() as u64);
        for &(c, p) in &self.links {
            o.u32(c);
            o.u32(p);
        }
        o.0
    }

    /// Reads and checks tile `t`'s port graph.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, PORTS, "port graph", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let np = r.count(n, 9)?;
        let mut pending = Vec::with_capacity(np);
        for _ in 0..np {
            let (cell, z, hi) = (r.u32()?, r.f32()?, r.u8()?);
            if hi > 1 {
                return Err(bad(format!("port graph of tile {t}: a flag is not 0 or 1")));
            }
            pending.push(FlatCell {
                cell,
                z,
                high: hi == 1,
            });
        }
        let nl = r.count(n, 8)?;
        let mut low = Vec::with_capacity(nl);
        for _ in 0..nl {
            low.push((r.u32()?, r.f32()?));
        }
        let nq = r.count(n, 13)?;
        let mut ports = Vec::with_capacity(nq);
        for _ in 0..nq {
            ports.push((r.u32()?, r.u8()?, r.u64()?));
        }
        let nk = r.count(n, 8)?;
        let mut links = Vec::with_capacity(nk);
        for _ in 0..nk {
            links.push((r.u32()?, r.u32()?));
        }
        r.end()?;
        let (n32, cells) = (n as u32, n as u64);
        if pending.iter().any(|p| p.cell >= n32)
            || low.iter().any(|l| l.0 >= n32)
            || ports
                .iter()
                .any(|p| p.0 >= n32 || !dir_ok(p.1) || p.2 > cells)
            || links
                .iter()
                .any(|l| l.0 >= n32 || (l.1 >= n32 && l.1 != NONE))
        {
            return Err(bad(format!(
                "port graph of tile {t}: a cell is out of range"
            )));
        }
        Ok(PortGraph {
            pending,
            low,
            ports,
            links,
        })
    }
}

impl Inflow {
    /// The byte form of tile `t`'s inflow.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(INFLOW, t, w, h);
        o.u64(self.pending_dir.len() as u64);
        for &(c, d) in &self.pending_dir {
            o.u32(c);
            o.u8(d);
        }
        o.u64(self.entries.len() as u64);
        for &(c, a) in &self.entries {
            o.u32(c);
            o.u64(a);
        }
        o.0
    }

    /// Reads and checks tile `t`'s inflow.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, INFLOW, "inflow", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let np = r.count(n, 5)?;
        let mut pending_dir = Vec::with_capacity(np);
        for _ in 0..np {
            pending_dir.push((r.u32()?, r.u8()?));
        }
        let ne = r.count(n, 12)?;
        let mut entries = Vec::with_capacity(ne);
        for _ in 0..ne {
            entries.push((r.u32()?, r.u64()?));
        }
        r.end()?;
        let total = (layout.width as u64) * (layout.height as u64);
        if pending_dir
            .iter()
            .any(|p| p.0 as usize >= n || !dir_ok(p.1))
            || entries.iter().any(|e| e.0 as usize >= n || e.1 > total)
        {
            return Err(bad(format!("inflow of tile {t}: a cell is out of range")));
        }
        Ok(Inflow {
            pending_dir,
            entries,
        })
    }
}

const SUMMARY: &[u8; 8] = b"RLFTP5NS";
const NETLEVELS: &[u8; 8] = b"RLFTP6NL";
const NETWORK: &[u8; 8] = b"RLFTP7NW";

/// An error naming the product of tile `t` unless its cells and values passed the checks.
fn cells_in(t: usize, what: &str, ok: bool) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(bad(format!(
            "{what} of tile {t}: a cell or value is out of range"
        )))
    }
}

impl NetSummary {
    /// The byte form of tile `t`'s network summary.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(SUMMARY, t, w, h);
        o.u64(self.ends.len() as u64);
        for &(c, n, z) in &self.ends {
            o.u32(c);
            o.u64(n);
            o.f32(z);
        }
        o.u64(self.entries.len() as u64);
        for e in &self.entries {
            o.u32(e.cell);
            o.u32(e.target);
            o.u8(e.out);
            o.f32(e.base);
        }
        o.u64(self.keys.len() as u64);
        for k in &self.keys {
            o.u32(k.cell);
            o.u8(k.top.0);
            o.u8(k.top.1);
            o.u32(k.down);
            o.u8(k.out);
        }
        o.0
    }

    /// Reads and checks tile `t`'s network summary.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let what = "network summary";
        let mut r = In::new(b, SUMMARY, what, layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let mut s = NetSummary::default();
        for _ in 0..r.count(n, 16)? {
            s.ends.push((r.u32()?, r.u64()?, r.f32()?));
        }
        for _ in 0..r.count(n, 13)? {
            s.entries.push(Entry {
                cell: r.u32()?,
                target: r.u32()?,
                out: r.u8()?,
                base: r.f32()?,
            });
        }
        for _ in 0..r.count(n, 11)? {
            s.keys.push(Key {
                cell: r.u32()?,
                top: (r.u8()?, r.u8()?),
                down: r.u32()?,
                out: r.u8()?,
            });
        }
        r.end()?;
        let n = n as u32;
        let sorted = s.ends.windows(2).all(|p| p[0].0 < p[1].0)
            && s.entries.windows(2).all(|p| p[0].cell < p[1].cell)
            && s.keys.windows(2).all(|p| p[0].cell < p[1].cell);
        let ok = sorted
            && s.ends.iter().all(|e| e.0 < n)
            && s.entries
                .iter()
                .all(|e| e.cell < n && e.target < n && dir_ok(e.out))
            && s.keys.iter().all(|k| {
                k.cell < n && (k.down < n || k.down == NONE) && dir_ok(k.out) && k.top.1 <= 2
            });
        cells_in(t, what, ok)?;
        Ok(s)
    }
}

impl NetLevels {
    /// The byte form of tile `t`'s network levels.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(NETLEVELS, t, w, h);
        o.u64(self.labels.len() as u64);
        for &(c, l) in &self.labels {
            o.u32(c);
            o.u32(l);
        }
        o.u64(self.exits.len() as u64);
        for &(c, l, b) in &self.exits {
            o.u32(c);
            o.u32(l);
            o.f32(b);
        }
        o.u64(self.orders.len() as u64);
        for &(c, k) in &self.orders {
            o.u32(c);
            o.u8(k);
        }
        o.0
    }

    /// Reads and checks tile `t`'s network levels.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let what = "network levels";
        let mut r = In::new(b, NETLEVELS, what, layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let mut s = NetLevels::default();
        for _ in 0..r.count(n, 8)? {
            s.labels.push((r.u32()?, r.u32()?));
        }
        for _ in 0..r.count(n, 12)? {
            s.exits.push((r.u32()?, r.u32()?, r.f32()?));
        }
        for _ in 0..r.count(n, 5)? {
            s.orders.push((r.u32()?, r.u8()?));
        }
        r.end()?;
        let n = n as u32;
        let ok = s.labels.iter().all(|l| l.0 < n)
            && s.exits.iter().all(|e| e.0 < n)
            && s.orders.iter().all(|o| o.0 < n);
        cells_in(t, what, ok)?;
        Ok(s)
    }
}

impl TileNetwork {
    /// The byte form of tile `t`'s channel cells and figures.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(NETWORK, t, w, h);
        let f = &self.figures;
        for v in [f.voids, f.raised, f.lowered, f.sinks, f.outlets] {
            o.u64(v);
        }
        o.f32(f.max_fill);
        o.f32(f.max_cut);
        f.channel_steps.iter().for_each(|&v| o.u64(v));
        o.u64(f.largest_basin_cells);
        o.u8(f.max_order);
        o.u64(self.channels.len() as u64);
        for &(c, d, n, k) in &self.channels {
            o.u32(c);
            o.u8(d);
            o.u64(n);
            o.u8(k);
        }
        o.0
    }

    /// Reads and checks tile `t`'s channel cells and figures.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let what = "network";
        let mut r = In::new(b, NETWORK, what, layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let mut f = TileFigures {
            voids: r.u64()?,
            raised: r.u64()?,
            lowered: r.u64()?,
            sinks: r.u64()?,
            outlets: r.u64()?,
            max_fill: r.f32()?,
            max_cut: r.f32()?,
            ..Default::default()
        };
        for k in 0..8 {
            f.channel_steps[k] = r.u64()?;
        }
        f.largest_basin_cells = r.u64()?;
        f.max_order = r.u8()?;
        let mut channels = Vec::new();
        for _ in 0..r.count(n, 14)? {
            channels.push((r.u32()?, r.u8()?, r.u64()?, r.u8()?));
        }
        r.end()?;
        let counts = [
            f.voids,
            f.raised,
            f.lowered,
            f.sinks,
            f.outlets,
            f.largest_basin_cells,
        ];
        let ok = counts.iter().all(|&v| v <= n as u64)
            && f.channel_steps.iter().sum::<u64>() <= n as u64
            && channels
                .iter()
                .all(|&(c, d, _, k)| (c as usize) < n && dir_ok(d) && k > 0);
        cells_in(t, what, ok)?;
        Ok(TileNetwork {
            channels,
            figures: f,
        })
    }
}
