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
        (t as u64, w as u64, h as u64).put(&mut o);
        o
    }
    /// The values one after the other.
    fn all<T: Field>(&mut self, values: &[T]) {
        values.iter().for_each(|v| v.put(self));
    }
    /// A count, then the values.
    fn list<T: Field>(&mut self, values: &[T]) {
        (values.len() as u64).put(self);
        self.all(values);
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
        if <(u64, u64, u64)>::get(&mut r)? != (t as u64, w as u64, h as u64) {
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
    /// The next value.
    fn get<T: Field>(&mut self) -> Result<T> {
        T::get(self)
    }
    /// `n` values one after the other.
    fn all<T: Field>(&mut self, n: usize) -> Result<Vec<T>> {
        if n.saturating_mul(T::SIZE) > self.b.len() {
            return Err(bad(format!("{} of tile {}: truncated", self.what, self.t)));
        }
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            v.push(T::get(self)?);
        }
        Ok(v)
    }
    /// A count of at most `max` values, then the values (the count is also bounded by what is
    /// left, before anything is allocated).
    fn list<T: Field>(&mut self, max: usize) -> Result<Vec<T>> {
        let n = self.count(max, T::SIZE)?;
        self.all(n)
    }
    /// A count of at most `max` items of `size` bytes each, also bounded by what is left.
    fn count(&mut self, max: usize, size: usize) -> Result<usize> {
        let n: u64 = self.get()?;
        if n > max as u64 || n.saturating_mul(size as u64) > self.b.len() as u64 {
            return Err(bad(format!(
                "{} of tile {}: a count of {n} is out of range",
                self.what, self.t
            )));
        }
        Ok(n as usize)
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

/// A value of fixed size in the byte forms: a little-endian number, or a tuple or record of
/// them written field by field.
trait Field: Sized {
    /// Its size in bytes.
    const SIZE: usize;
    fn put(&self, o: &mut Out);
    fn get(r: &mut In<'_>) -> Result<Self>;
}

macro_rules! le_number_field {
    ($($t:ty),+) => {$(
        impl Field for $t {
            const SIZE: usize = size_of::<$t>();
            fn put(&self, o: &mut Out) {
                o.0.extend_from_slice(&self.to_le_bytes());
            }
            fn get(r: &mut In<'_>) -> Result<Self> {
                let b = r.take(Self::SIZE)?;
                Ok(Self::from_le_bytes(b.try_into().expect("the size of the type")))
            }
        }
    )+};
}

le_number_field!(u8, u32, u64, f32);

macro_rules! tuple_field {
    ($(($($v:ident: $t:ident),+)),+) => {$(
        impl<$($t: Field),+> Field for ($($t,)+) {
            const SIZE: usize = 0 $(+ $t::SIZE)+;
            fn put(&self, o: &mut Out) {
                let ($($v,)+) = self;
                $($v.put(o);)+
            }
            fn get(r: &mut In<'_>) -> Result<Self> {
                // A tuple's fields are evaluated left to right: read in the order written.
                Ok(($($t::get(r)?,)+))
            }
        }
    )+};
}

tuple_field!((a: A, b: B), (a: A, b: B, c: C), (a: A, b: B, c: C, d: D));

fn dir_ok(d: u8) -> bool {
    d < 8 || d == NO_FLOW
}

/// A flat cell: its cell, elevation and a flag byte (0 or 1) for `high`.
impl Field for FlatCell {
    const SIZE: usize = <(u32, f32, u8)>::SIZE;
    fn put(&self, o: &mut Out) {
        (self.cell, self.z, u8::from(self.high)).put(o);
    }
    fn get(r: &mut In<'_>) -> Result<Self> {
        let (cell, z, high): (u32, f32, u8) = r.get()?;
        if high > 1 {
            return Err(bad(format!(
                "{} of tile {}: a flag is not 0 or 1",
                r.what, r.t
            )));
        }
        Ok(FlatCell {
            cell,
            z,
            high: high == 1,
        })
    }
}

/// A network entry, field by field.
impl Field for Entry {
    const SIZE: usize = <(u32, u32, u8, f32)>::SIZE;
    fn put(&self, o: &mut Out) {
        (self.cell, self.target, self.out, self.base).put(o);
    }
    fn get(r: &mut In<'_>) -> Result<Self> {
        Ok(Entry {
            cell: r.get()?,
            target: r.get()?,
            out: r.get()?,
            base: r.get()?,
        })
    }
}

/// A key cell, field by field (`top` as its two bytes).
impl Field for Key {
    const SIZE: usize = <(u32, (u8, u8), u32, u8)>::SIZE;
    fn put(&self, o: &mut Out) {
        (self.cell, self.top, self.down, self.out).put(o);
    }
    fn get(r: &mut In<'_>) -> Result<Self> {
        Ok(Key {
            cell: r.get()?,
            top: r.get()?,
            down: r.get()?,
            out: r.get()?,
        })
    }
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
        o.all(&self.z);
        o.all(&self.label);
        o.0
    }

    /// Reads and checks tile `t`'s local fill.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, FILL, "local fill", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let z = r.all(w * h)?;
        let label = r.all(w * h)?;
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
        o.all(&self.band_z);
        o.all(&self.band_label);
        o.list(&self.edges);
        o.0
    }

    /// Reads and checks tile `t`'s fill graph.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, GRAPH, "fill graph", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let bl = band_len(w, h);
        let band_z = r.all(bl)?;
        let band_label = r.all(bl)?;
        let edges = r.list(8 * w * h)?;
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
        o.all(&self.level);
        o.all(&self.band);
        o.0
    }

    /// Reads and checks tile `t`'s levels.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, LEVELS, "levels", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let bl = band_len(w, h);
        let level = r.all(bl + 1)?;
        let band = r.all(bl)?;
        r.end()?;
        Ok(Levels { level, band })
    }
}

impl Routed {
    /// The byte form of tile `t`'s routed tile.
    pub fn to_bytes(&self, layout: &TileLayout, t: usize) -> Vec<u8> {
        let [_, _, w, h] = layout.window(t);
        let mut o = Out::new(ROUTED, t, w, h);
        o.all(&self.filled);
        o.all(&self.dir);
        o.0
    }

    /// Reads and checks tile `t`'s routed tile.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, ROUTED, "routed tile", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let filled = r.all(w * h)?;
        let dir: Vec<u8> = r.all(w * h)?;
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
        o.list(&self.pending);
        o.list(&self.low);
        o.list(&self.ports);
        o.list(&self.links);
        o.0
    }

    /// Reads and checks tile `t`'s port graph.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, PORTS, "port graph", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let pending: Vec<FlatCell> = r.list(n)?;
        let low: Vec<(u32, f32)> = r.list(n)?;
        let ports: Vec<(u32, u8, u64)> = r.list(n)?;
        let links: Vec<(u32, u32)> = r.list(n)?;
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
        o.list(&self.pending_dir);
        o.list(&self.entries);
        o.0
    }

    /// Reads and checks tile `t`'s inflow.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let mut r = In::new(b, INFLOW, "inflow", layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let pending_dir: Vec<(u32, u8)> = r.list(n)?;
        let entries: Vec<(u32, u64)> = r.list(n)?;
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
        o.list(&self.ends);
        o.list(&self.entries);
        o.list(&self.keys);
        o.0
    }

    /// Reads and checks tile `t`'s network summary.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let what = "network summary";
        let mut r = In::new(b, SUMMARY, what, layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let s = NetSummary {
            ends: r.list(n)?,
            entries: r.list(n)?,
            keys: r.list(n)?,
        };
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
        o.list(&self.labels);
        o.list(&self.exits);
        o.list(&self.orders);
        o.0
    }

    /// Reads and checks tile `t`'s network levels.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let what = "network levels";
        let mut r = In::new(b, NETLEVELS, what, layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let s = NetLevels {
            labels: r.list(n)?,
            exits: r.list(n)?,
            orders: r.list(n)?,
        };
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
        o.all(&[f.voids, f.raised, f.lowered, f.sinks, f.outlets]);
        o.all(&[f.max_fill, f.max_cut]);
        o.all(&f.channel_steps);
        f.largest_basin_cells.put(&mut o);
        f.max_order.put(&mut o);
        o.list(&self.channels);
        o.0
    }

    /// Reads and checks tile `t`'s channel cells and figures.
    pub fn from_bytes(b: &[u8], layout: &TileLayout, t: usize) -> Result<Self> {
        let what = "network";
        let mut r = In::new(b, NETWORK, what, layout, t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        let mut f = TileFigures {
            voids: r.get()?,
            raised: r.get()?,
            lowered: r.get()?,
            sinks: r.get()?,
            outlets: r.get()?,
            max_fill: r.get()?,
            max_cut: r.get()?,
            ..Default::default()
        };
        for k in 0..8 {
            f.channel_steps[k] = r.get()?;
        }
        f.largest_basin_cells = r.get()?;
        f.max_order = r.get()?;
        let channels: Vec<(u32, u8, u64, u8)> = r.list(n)?;
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
